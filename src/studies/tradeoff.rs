//! What accuracy costs in time: every LOD scheme, over several settings,
//! rendered on the same views by the same rasteriser and compared with the
//! brute-force render of each view (colour RMSE and largest difference as
//! ATLOD measured, depth error in metres), with the frame time split into
//! LOD update, mesh generation, vertex work, raster and shading, and the
//! popping along a short camera path. The rasteriser's own accuracy knob,
//! supersampling, is measured the same way against a 64× render of the
//! same mesh.

use crate::camera::Camera;
use crate::check::compare::{self, ImageError};
use crate::clipmap::Layout;
use crate::error::Result;
use crate::frame::stats::Passes;
use crate::pyramid::Filter;
use crate::render::{Image, RenderOptions, RenderStats, Session};
use crate::scene::{Effect, LodScheme, Scene};
use crate::shard::Shard;
use crate::studies::gpu_side::GpuSide;
use crate::studies::metrics;
use crate::studies::views::{self, NamedView};
use serde::{Deserialize, Serialize};

/// One scheme at one setting.
#[derive(Clone, Debug)]
pub struct Setting {
    /// Series name: the scheme, or "supersample".
    pub lod: String,
    /// The setting, human readable ("n=63 strips", "tau=4px").
    pub config: String,
    /// The scene rendered with this setting.
    pub scene: Scene,
    /// Samples per pixel (1, 4, 16); the reference is then a 64× render
    /// of the same setting instead of brute force.
    pub samples: u32,
}

/// One row of the report (the JSON `rows`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Row {
    /// Series name: the scheme, or "supersample".
    pub lod: String,
    /// The setting, human readable.
    pub config: String,
    /// Mean over the views of each view's median frame time (3 frames,
    /// after a warm-up frame one step back), and its parts (ms).
    pub ms: f64,
    /// LOD update (ms).
    pub ms_lod: f64,
    /// Mesh generation (ms).
    pub ms_mesh: f64,
    /// Vertex stage, with the CPU back end's cull of triangles that
    /// cannot reach a pixel, and the effects' precomputations (ms).
    pub ms_vertex: f64,
    /// Rasterisation (ms).
    pub ms_raster: f64,
    /// Shading (ms).
    pub ms_shade: f64,
    /// Mean RMSE over all views, the wide views and the low-FOV views.
    pub rmse: f64,
    /// Mean RMSE over the wide views.
    pub rmse_wide: f64,
    /// Mean RMSE over the low-FOV views.
    pub rmse_low_fov: f64,
    /// The largest RGB channel difference over all views.
    pub max_abs: u8,
    /// Mean depth error (metres) over all views.
    pub depth_m: f64,
    /// Mean triangles drawn per view.
    pub triangles: f64,
    /// Largest per-frame popping along the path (RMS, 0–255 units).
    pub popping: f64,
    /// "brute-force" or "64x same mesh".
    pub reference: String,
    /// On the Pareto front of (ms, rmse) among brute-force-referenced rows.
    pub pareto: bool,
    /// Mean frame time over the low-FOV views alone (ms): the time the
    /// low-FOV RMSE is bought with.
    #[serde(default)]
    pub ms_low_fov: f64,
    /// Mean triangles drawn over the low-FOV views.
    #[serde(default)]
    pub triangles_low_fov: f64,
    /// The wgpu back end's costs, measured with `--gpu`.
    #[serde(default)]
    pub gpu: Option<GpuCosts>,
}

/// What the same setting costs a GPU renderer: the wgpu back end, keeping
/// its buffers and toroids resident, draws the views and the path on the
/// adapter at hand.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GpuCosts {
    /// The adapter, as its driver names it.
    pub adapter: String,
    /// Mean bytes written to the device per frame along the path, the
    /// first frame (a full upload) left out: uniforms, changed vertex and
    /// index words, toroid texels.
    pub upload_bytes: Option<f64>,
    /// Mean draw calls per view.
    pub draw_calls: Option<f64>,
    /// Mean over the views of each view's median render-pass time on the
    /// GPU's clock (ms, 3 frames).
    pub ms: Option<f64>,
    /// Why a figure is missing: the adapter has no timestamp queries, or
    /// what stopped the row's GPU frames (a mesh over the adapter's
    /// binding limit).
    pub note: Option<String>,
}

impl Row {
    /// CPU time a GPU renderer spends on LOD per frame: the LOD update and
    /// the mesh or index generation (ms).
    pub fn ms_cpu_lod(&self) -> f64 {
        self.ms_lod + self.ms_mesh
    }
}

/// The report: rows, and the answer to "within 1/10 of brute force's time,
/// which scheme has the lowest RMSE?".
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Report {
    /// The charts' title: the terrain and the image size.
    pub title: String,
    /// The views' names, wide first.
    pub views: Vec<String>,
    /// Image width and height.
    pub size: [u32; 2],
    /// Frames along the popping path.
    pub path_frames: usize,
    /// Every setting measured.
    pub rows: Vec<Row>,
    /// A tenth of brute force's time (ms): the budget `best_in_budget` answers for.
    pub budget_ms: f64,
    /// The row with the lowest RMSE within the budget.
    pub best_in_budget: Option<Row>,
}

/// How much to measure.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Image width and height.
    pub size: [u32; 2],
    /// Frames along the popping path.
    pub path_frames: usize,
    /// Fewer settings per scheme (for tests).
    pub quick: bool,
    /// The settings measured: k with k mod N = i of [`settings`].
    pub shard: Shard,
    /// Also draw each setting with the wgpu back end on Vulkan and
    /// report [`GpuCosts`].
    pub gpu: bool,
}

fn variant(
    scene: &Scene,
    lod: LodScheme,
    layout: Option<Layout>,
    edit: impl FnOnce(&mut Scene),
) -> Result<Scene> {
    let mut s = scene.with_scheme(lod, layout)?;
    edit(&mut s);
    s.validate()?;
    Ok(s)
}

/// The sweep: every scheme at several settings (fewer when `quick`).
pub fn settings(scene: &Scene, quick: bool) -> Result<Vec<Setting>> {
    let mut out = Vec::new();
    let mut add = |config: String, s: Scene, samples: u32| {
        out.push(Setting {
            lod: s.lod.scheme.to_string(),
            config,
            scene: s,
            samples,
        })
    };
    let morph = |s: &mut Scene, on: bool| {
        s.effects.retain(|e| *e != Effect::Morph);
        if on {
            s.effects.push(Effect::Morph);
        }
    };
    add(
        "full".into(),
        scene.with_scheme(LodScheme::BruteForce, None)?,
        1,
    );
    let ns: &[i64] = if quick { &[15, 31] } else { &[15, 31, 63, 127] };
    for &n in ns {
        let s = variant(scene, LodScheme::Clipmap, Some(Layout::Strips), |s| {
            s.lod.n = n;
            s.lod.levels = None;
            morph(s, true);
        })?;
        add(format!("n={n} strips"), s, 1);
    }
    // The view-dependent clipmap: each level placed over the terrain that
    // needs it, for texels of at most τ pixels.
    let view_ns: &[(i64, f64)] = if quick {
        &[(15, 4.0)]
    } else {
        &[(63, 4.0), (127, 4.0), (127, 16.0), (255, 16.0), (511, 16.0)]
    };
    for &(n, tau) in view_ns {
        let s = variant(scene, LodScheme::Clipmap, Some(Layout::Strips), |s| {
            s.lod.n = n;
            s.lod.levels = None;
            s.lod.centre = Some("view".into());
            s.lod.tau = Some(tau);
            morph(s, true);
        })?;
        add(format!("n={n} tau={tau}px view"), s, 1);
    }
    let n = if quick { 15 } else { 31 };
    add(
        format!("n={n} footprints"),
        variant(scene, LodScheme::Clipmap, Some(Layout::Footprints), |s| {
            s.lod.n = n;
            morph(s, true);
        })?,
        1,
    );
    add(
        format!("n={n} morph off"),
        variant(scene, LodScheme::Clipmap, Some(Layout::Strips), |s| {
            s.lod.n = n;
            morph(s, false);
        })?,
        1,
    );
    if !quick {
        for (f, filter) in [("point", Filter::Point), ("box", Filter::Box)] {
            add(
                format!("n={n} {f} filter"),
                variant(scene, LodScheme::Clipmap, Some(Layout::Strips), |s| {
                    s.lod.n = n;
                    s.pyramid.filter = filter;
                    morph(s, true);
                })?,
                1,
            );
        }
        // The narrowest band and the widest that never reaches a level's
        // inner edge (m − 3, m = (n+1)/4).
        for w in [1.0f32, ((n + 1) / 4 - 3) as f32] {
            add(
                format!("n={n} w={w}"),
                variant(scene, LodScheme::Clipmap, Some(Layout::Strips), |s| {
                    s.lod.n = n;
                    s.lod.transition = Some(w);
                    morph(s, true);
                })?,
                1,
            );
        }
    }
    let taus: &[f64] = if quick {
        &[2.0, 8.0]
    } else {
        &[0.5, 1.0, 2.0, 4.0, 8.0, 16.0]
    };
    for &tau in taus {
        add(
            format!("error tau={tau}px"),
            variant(scene, LodScheme::Geomipmap, None, |s| {
                s.lod.mode = Some("error".into());
                s.lod.tau = Some(tau);
                morph(s, true);
            })?,
            1,
        );
        for lod in [LodScheme::Roam, LodScheme::Cbt] {
            add(
                format!("tau={tau}px"),
                variant(scene, lod, None, |s| s.lod.tau = Some(tau))?,
                1,
            );
        }
    }
    {
        // The CBT's morph is this project's (the paper has none): off, to
        // see what it saves in popping.
        let tau = if quick { 2.0 } else { 4.0 };
        add(
            format!("tau={tau}px morph off"),
            variant(scene, LodScheme::Cbt, None, |s| {
                s.lod.tau = Some(tau);
                morph(s, false);
            })?,
            1,
        );
    }
    if !quick {
        // ATLOD's distance modes, at steps of a few blocks.
        let cell = scene.terrain.cell_size.as_ref().map_or(10.0, |c| match c {
            crate::terrain::CellSize::Square(s) => *s,
            crate::terrain::CellSize::Xy(xy) => xy[0].max(xy[1]),
        });
        for mode in ["linear", "exponential"] {
            for blocks in [2.0, 8.0] {
                let d = blocks * 32.0 * cell;
                add(
                    format!("{mode} d={d:.0}m"),
                    variant(scene, LodScheme::Geomipmap, None, |s| {
                        s.lod.mode = Some(mode.into());
                        s.lod.distance = Some(d);
                        morph(s, true);
                    })?,
                    1,
                );
            }
        }
    }
    let ranges: &[f64] = if quick { &[2.0] } else { &[1.0, 2.0, 4.0, 8.0] };
    for &r in ranges {
        add(
            format!("grid=32 range={r}"),
            variant(scene, LodScheme::Cdlod, None, |s| {
                s.lod.grid = Some(32);
                s.lod.range = Some(r);
                morph(s, true);
            })?,
            1,
        );
    }
    let an: &[i64] = if quick { &[31] } else { &[31, 63, 127, 255] };
    for &n in an {
        add(
            format!("n={n}"),
            variant(scene, LodScheme::Annulus, None, |s| {
                s.lod.n = n;
                s.lod.levels = Some(12);
            })?,
            1,
        );
    }
    let ss = variant(scene, LodScheme::Clipmap, Some(Layout::Strips), |s| {
        s.lod.n = 31;
        s.lod.levels = None;
        morph(s, true);
    })?;
    for k in [1u32, 4, 16] {
        out.push(Setting {
            lod: "supersample".into(),
            config: format!("{k}x (clipmap n=31)"),
            scene: ss.clone(),
            samples: k,
        });
    }
    Ok(out)
}

/// Per-axis factor of `samples` per pixel (1, 4, 16, 64).
fn axis(samples: u32) -> u32 {
    (samples as f64).sqrt().round() as u32
}

/// Renders `cam` in `session` (made at `samples`× the pixels) and boxes it
/// down to the target size.
fn shot(session: &mut Session, cam: &Camera, samples: u32) -> Result<(Image, RenderStats)> {
    let (img, stats) = session.render(cam, &RenderOptions::default(), Passes::default())?;
    let k = axis(samples);
    Ok((
        if k > 1 {
            metrics::downsample(&img, k)
        } else {
            img
        },
        stats,
    ))
}

fn session_for(scene: &Scene, size: [u32; 2], samples: u32) -> Result<Session> {
    let mut s = scene.clone();
    let k = axis(samples);
    s.image.width = size[0] * k;
    s.image.height = size[1] * k;
    Session::new(&s, &mut Passes::default())
}

/// A row's GPU figures, summed over its views and path.
#[derive(Default)]
struct GpuSums {
    upload: f64,
    upload_frames: f64,
    draw_calls: f64,
    ms: f64,
    timed: bool,
    /// What stopped the row's GPU frames.
    failed: Option<String>,
}

/// Three GPU frames of `cam` after the CPU's: the median pass time and
/// the last frame's draw calls. The CPU frames moved the clipmap without
/// the GPU, so its toroids are uploaded afresh first.
fn gpu_view(
    gpu: &mut GpuSide,
    session: &mut Session,
    cam: &Camera,
    sums: &mut GpuSums,
) -> Result<()> {
    if sums.failed.is_some() {
        return Ok(());
    }
    gpu.forget();
    let mut frames = Vec::new();
    for _ in 0..3 {
        match gpu.frame(session, cam)? {
            Some(f) => frames.push(f),
            None => return Ok(()),
        }
    }
    sums.draw_calls += frames[2].draw_calls as f64;
    let mut t: Vec<f64> = frames.iter().filter_map(|f| f.ms).collect();
    if t.len() == 3 {
        t.sort_by(f64::total_cmp);
        sums.ms += t[1];
        sums.timed = true;
    }
    Ok(())
}

/// The path drawn on the GPU alone, from fresh toroids: the bytes each
/// frame after the first uploads.
fn gpu_path(
    gpu: &mut GpuSide,
    session: &mut Session,
    path: &[Camera],
    sums: &mut GpuSums,
) -> Result<()> {
    if sums.failed.is_some() {
        return Ok(());
    }
    gpu.forget();
    for (k, c) in path.iter().enumerate() {
        if let (Some(f), true) = (gpu.frame(session, c)?, k > 0) {
            sums.upload += f.upload_bytes as f64;
            sums.upload_frames += 1.0;
        }
    }
    Ok(())
}

/// The row's [`GpuCosts`] over `views` views, when drawn.
fn gpu_costs(gpu: &GpuSide, sums: &GpuSums, views: f64) -> Option<GpuCosts> {
    let adapter = gpu.adapter()?;
    let ok = sums.failed.is_none();
    Some(GpuCosts {
        adapter,
        upload_bytes: ok.then(|| sums.upload / sums.upload_frames.max(1.0)),
        draw_calls: ok.then(|| sums.draw_calls / views),
        ms: (ok && sums.timed).then(|| sums.ms / views),
        note: match &sums.failed {
            Some(e) => Some(e.clone()),
            None if !sums.timed => Some("no timestamp queries".into()),
            None => None,
        },
    })
}

/// Measures every setting; `tick(label)` is called after each.
pub fn run(scene: &Scene, opts: &Options, mut tick: impl FnMut(&str)) -> Result<Report> {
    let settings = settings(scene, opts.quick)?;
    let mut probe = session_for(&settings[0].scene, opts.size, 1)?;
    let mut template = settings[0].scene.camera();
    template.aspect = opts.size[0] as f64 / opts.size[1] as f64;
    let views: Vec<NamedView> = views::atlod_views(&probe, &template);
    let cell = probe.world.cell[0].max(probe.world.cell[1]);
    let path = crate::camera::path(&views[0].camera, opts.path_frames.max(2), 0.5 * cell);
    // References: brute force per view and along the path.
    let mut bf_views = Vec::new();
    for v in &views {
        bf_views.push(shot(&mut probe, &v.camera, 1)?.0);
    }
    let mut bf_path = Vec::new();
    for c in &path {
        bf_path.push(shot(&mut probe, c, 1)?.0);
    }
    drop(probe);
    let mut gpu = GpuSide::open(opts.gpu)?;
    let mut rows = Vec::new();
    let mine = settings
        .iter()
        .enumerate()
        .filter(|(k, _)| opts.shard.owns(*k));
    for (_, st) in mine {
        let mut session = session_for(&st.scene, opts.size, st.samples)?;
        let mut reference_session = if st.samples > 1 || st.lod == "supersample" {
            Some(session_for(&st.scene, opts.size, 64)?)
        } else {
            None
        };
        let mut errs: Vec<(ImageError, &'static str)> = Vec::new();
        // Time, triangles and count of the low-FOV views.
        let mut low = [0.0f64; 3];
        let (mut ms, mut parts, mut tris) = (0.0, [0.0f64; 5], 0.0);
        let mut gpu_sums = GpuSums::default();
        for (i, v) in views.iter().enumerate() {
            // A warm-up frame one step back, so incremental schemes pay
            // their steady-state update, not a rebuild.
            let back = crate::camera::path_camera(&v.camera, 1, -0.5 * cell);
            shot(&mut session, &back, st.samples)?;
            // Times are the median of three frames of the view (the
            // machines are noisy). The image and triangles are the last
            // frame's whatever the timing: a scheme that refines over
            // frames (ROAM's queues) draws each frame differently.
            let mut timed = Vec::new();
            for _ in 0..3 {
                timed.push(shot(&mut session, &v.camera, st.samples)?);
            }
            let mut ms_order = [0, 1, 2];
            ms_order.sort_by(|&a, &b| timed[a].1.ms_total.total_cmp(&timed[b].1.ms_total));
            let stats = timed[ms_order[1]].1.clone();
            let (img, last) = timed.pop().expect("three frames");
            let triangles = last.triangles;
            let reference = match &mut reference_session {
                Some(r) => shot(r, &v.camera, 64)?.0,
                None => bf_views[i].clone(),
            };
            errs.push((compare::image_error(&img, &reference, &v.camera), v.kind));
            ms += stats.ms_total;
            if v.kind == "low-fov" {
                low[0] += stats.ms_total;
                low[1] += triangles as f64;
                low[2] += 1.0;
            }
            parts[0] += stats.pass_ms(&["lod"]);
            parts[1] += stats.pass_ms(&["mesh"]);
            parts[2] += stats.pass_ms(&["cull", "vertex", "normals", "normal-map", "lightmap"]);
            parts[3] += stats.pass_ms(&["raster"]);
            parts[4] += stats.pass_ms(&["shade"]);
            tris += triangles as f64;
            if let Err(e) = gpu_view(&mut gpu, &mut session, &v.camera, &mut gpu_sums) {
                gpu_sums.failed = Some(e.to_string());
            }
        }
        // Popping along the path (brute-force referenced settings only).
        let mut popping = 0.0f64;
        if reference_session.is_none() {
            let mut prev: Option<Image> = None;
            for (k, c) in path.iter().enumerate() {
                let (img, _) = shot(&mut session, c, 1)?;
                if let Some(p) = &prev {
                    popping =
                        popping.max(metrics::popping([p, &img], [&bf_path[k - 1], &bf_path[k]]));
                }
                prev = Some(img);
            }
        }
        if let Err(e) = gpu_path(&mut gpu, &mut session, &path, &mut gpu_sums) {
            gpu_sums.failed = Some(e.to_string());
        }
        let nv = views.len() as f64;
        let mean = |kind: Option<&str>| {
            let sel: Vec<f64> = errs
                .iter()
                .filter(|(_, k)| kind.is_none_or(|want| *k == want))
                .map(|(e, _)| e.rmse)
                .collect();
            sel.iter().sum::<f64>() / sel.len().max(1) as f64
        };
        rows.push(Row {
            lod: st.lod.clone(),
            config: st.config.clone(),
            ms: ms / nv,
            ms_lod: parts[0] / nv,
            ms_mesh: parts[1] / nv,
            ms_vertex: parts[2] / nv,
            ms_raster: parts[3] / nv,
            ms_shade: parts[4] / nv,
            rmse: mean(None),
            rmse_wide: mean(Some("wide")),
            rmse_low_fov: mean(Some("low-fov")),
            max_abs: errs.iter().map(|(e, _)| e.max_abs).max().unwrap_or(0),
            depth_m: errs.iter().map(|(e, _)| e.depth_m).sum::<f64>() / nv,
            triangles: tris / nv,
            popping,
            reference: if reference_session.is_some() {
                "64x same mesh"
            } else {
                "brute-force"
            }
            .into(),
            pareto: false,
            ms_low_fov: low[0] / low[2].max(1.0),
            triangles_low_fov: low[1] / low[2].max(1.0),
            gpu: gpu_costs(&gpu, &gpu_sums, nv),
        });
        tick(&format!("{} {}", st.lod, st.config));
    }
    Ok(finish(
        views.iter().map(|v| v.name.clone()).collect(),
        opts.size,
        path.len(),
        rows,
    ))
}

/// The report of `rows`: the Pareto front, brute force's budget and the
/// best row within it are worked out over the rows given, so a shard's
/// report answers for its own rows and [`merge`] answers for the sweep.
pub fn finish(
    views: Vec<String>,
    size: [u32; 2],
    path_frames: usize,
    mut rows: Vec<Row>,
) -> Report {
    mark_pareto(&mut rows);
    let budget_ms = rows
        .iter()
        .find(|r| r.lod == "brute-force")
        .map_or(0.0, |r| r.ms / 10.0);
    let best_in_budget = rows
        .iter()
        .filter(|r| r.reference == "brute-force" && r.lod != "brute-force" && r.ms <= budget_ms)
        .min_by(|a, b| a.rmse.total_cmp(&b.rmse))
        .cloned();
    Report {
        title: String::new(),
        views,
        size,
        path_frames,
        rows,
        budget_ms,
        best_in_budget,
    }
}

/// The parts' reports (in part order) as one run's: their rows put back
/// in sweep order, then [`finish`]ed over the whole sweep.
pub fn merge(parts: &[Report]) -> std::result::Result<Report, String> {
    let first = parts.first().ok_or("no parts")?;
    for (i, p) in parts.iter().enumerate() {
        if (&p.views, p.size, p.path_frames) != (&first.views, first.size, first.path_frames) {
            return Err(format!(
                "part {i} measured other views, sizes or paths than part 0"
            ));
        }
    }
    let lists: Vec<&[Row]> = parts.iter().map(|p| p.rows.as_slice()).collect();
    let rows = crate::shard::interleave_items(&lists)?;
    Ok(Report {
        title: first.title.clone(),
        ..finish(
            first.views.clone(),
            first.size,
            first.path_frames,
            rows.into_iter().cloned().collect(),
        )
    })
}

/// Marks the rows no other brute-force-referenced row beats in both time
/// and RMSE.
pub fn mark_pareto(rows: &mut [Row]) {
    let pts: Vec<(f64, f64, bool)> = rows
        .iter()
        .map(|r| (r.ms, r.rmse, r.reference == "brute-force"))
        .collect();
    for (r, p) in rows.iter_mut().zip(front_of(&pts)) {
        r.pareto = p;
    }
}

/// Which of the (time, error, eligible) points no other eligible point
/// beats in both.
fn front_of(pts: &[(f64, f64, bool)]) -> Vec<bool> {
    pts.iter()
        .enumerate()
        .map(|(i, &(ms, e, eligible))| {
            eligible
                && !pts.iter().enumerate().any(|(j, &(m2, e2, ok))| {
                    j != i && ok && m2 <= ms && e2 <= e && (m2 < ms || e2 < e)
                })
        })
        .collect()
}

/// The rows as CSV.
pub fn csv(rows: &[Row]) -> String {
    let mut out = String::from(
        "lod,config,ms,ms_lod,ms_mesh,ms_vertex,ms_raster,ms_shade,rmse,rmse_wide,rmse_low_fov,max_abs,depth_m,triangles,popping,reference,pareto,ms_low_fov,triangles_low_fov,ms_cpu_lod,gpu_adapter,upload_bytes,draw_calls,gpu_ms,gpu_note\n",
    );
    for r in rows {
        out += &format!(
            "{},\"{}\",{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.4},{:.4},{:.4},{},{:.3},{:.0},{:.4},{},{},{:.3},{:.0},{:.3},{}\n",
            r.lod,
            r.config,
            r.ms,
            r.ms_lod,
            r.ms_mesh,
            r.ms_vertex,
            r.ms_raster,
            r.ms_shade,
            r.rmse,
            r.rmse_wide,
            r.rmse_low_fov,
            r.max_abs,
            r.depth_m,
            r.triangles,
            r.popping,
            r.reference,
            r.pareto,
            r.ms_low_fov,
            r.triangles_low_fov,
            r.ms_cpu_lod(),
            gpu_columns(r.gpu.as_ref()),
        );
    }
    out
}

/// The CSV's GPU columns: adapter, upload bytes, draw calls, pass ms and
/// the note saying why a figure is missing; empty without `--gpu`.
fn gpu_columns(g: Option<&GpuCosts>) -> String {
    let f = |v: Option<f64>, digits: usize| v.map_or(String::new(), |v| format!("{v:.digits$}"));
    match g {
        None => ",,,,".into(),
        Some(g) => format!(
            "\"{}\",{},{},{},\"{}\"",
            g.adapter,
            f(g.upload_bytes, 0),
            f(g.draw_calls, 1),
            f(g.ms, 3),
            g.note.as_deref().unwrap_or("").replace('"', "'")
        ),
    }
}

/// Error against time, one series per scheme, the Pareto front marked.
pub fn chart(report: &Report) -> crate::studies::report::chart::Chart {
    let pareto: Vec<bool> = report.rows.iter().map(|r| r.pareto).collect();
    chart_of(
        report,
        |r| (r.ms, r.rmse),
        &pareto,
        report.title.clone(),
        "ms per frame (log)",
        "RMSE vs reference (8-bit)",
    )
}

/// The low-FOV views alone: their RMSE against their frame time, with
/// the front of those two.
pub fn chart_low_fov(report: &Report) -> crate::studies::report::chart::Chart {
    let pts: Vec<(f64, f64, bool)> = report
        .rows
        .iter()
        .map(|r| (r.ms_low_fov, r.rmse_low_fov, r.reference == "brute-force"))
        .collect();
    let pareto = front_of(&pts);
    chart_of(
        report,
        |r| (r.ms_low_fov, r.rmse_low_fov),
        &pareto,
        format!("{}: low-FOV views", report.title),
        "ms per low-FOV frame (log)",
        "low-FOV RMSE vs reference (8-bit)",
    )
}

/// RMSE against one cost per row (`cost`, `None` where the row lacks it),
/// with the front of those two among brute-force-referenced rows; `None`
/// when no row has the cost.
fn chart_cost(
    report: &Report,
    cost: impl Fn(&Row) -> Option<f64>,
    title: &str,
    x_label: &str,
) -> Option<crate::studies::report::chart::Chart> {
    let rows: Vec<Row> = report
        .rows
        .iter()
        .filter(|r| cost(r).is_some_and(|c| c > 0.0))
        .cloned()
        .collect();
    if rows.is_empty() {
        return None;
    }
    let pts: Vec<(f64, f64, bool)> = rows
        .iter()
        .map(|r| (cost(r).unwrap_or(0.0), r.rmse, r.reference == "brute-force"))
        .collect();
    let pareto = front_of(&pts);
    let sub = Report {
        rows,
        ..report.clone()
    };
    Some(chart_of(
        &sub,
        |r| (cost(r).unwrap_or(0.0), r.rmse),
        &pareto,
        format!("{}: {title}", report.title),
        x_label,
        "RMSE vs reference (8-bit)",
    ))
}

/// The per-cost charts, by file stem: RMSE against CPU LOD time, against
/// the bytes uploaded per frame, and against GPU time (those two with
/// `--gpu`, the last where the adapter has timestamp queries).
pub fn cost_charts(report: &Report) -> Vec<(&'static str, crate::studies::report::chart::Chart)> {
    let charts = [
        (
            "tradeoff-cpu-lod",
            chart_cost(
                report,
                |r| Some(r.ms_cpu_lod()),
                "CPU LOD work",
                "ms of LOD update and mesh generation per frame (log)",
            ),
        ),
        (
            "tradeoff-upload",
            chart_cost(
                report,
                |r| r.gpu.as_ref().and_then(|g| g.upload_bytes),
                "upload",
                "bytes uploaded per frame along the path (log)",
            ),
        ),
        (
            "tradeoff-gpu",
            chart_cost(
                report,
                |r| r.gpu.as_ref().and_then(|g| g.ms),
                "GPU time",
                "render-pass ms on the GPU's clock (log)",
            ),
        ),
    ];
    charts
        .into_iter()
        .filter_map(|(stem, c)| c.map(|c| (stem, c)))
        .collect()
}

fn chart_of(
    report: &Report,
    at: impl Fn(&Row) -> (f64, f64),
    pareto: &[bool],
    title: String,
    x_label: &str,
    y_label: &str,
) -> crate::studies::report::chart::Chart {
    use crate::studies::report::chart::{Chart, Series};
    let mut series: Vec<Series> = Vec::new();
    for r in &report.rows {
        // The view-dependent clipmap is its own series.
        let name = if r.lod == "clipmap" && r.config.ends_with(" view") {
            "clipmap (view)".to_string()
        } else {
            r.lod.clone()
        };
        match series.iter_mut().find(|s| s.name == name) {
            Some(s) => s.points.push(at(r)),
            None => series.push(Series {
                name,
                points: vec![at(r)],
            }),
        }
    }
    let mut front: Vec<(f64, f64)> = report
        .rows
        .iter()
        .zip(pareto)
        .filter(|(_, &p)| p)
        .map(|(r, _)| at(r))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    Chart {
        title,
        x_label: x_label.into(),
        y_label: y_label.into(),
        series,
        front,
        linear_x: false,
    }
}

/// Writes `tradeoff.csv`, `.svg` and `.png`, the low-FOV chart
/// `tradeoff-low-fov.svg` and `.png`, and the [`cost_charts`], into `dir`
/// (each atomically).
pub fn write(report: &Report, dir: &std::path::Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
    let c = chart(report);
    crate::error::write_atomic(&dir.join("tradeoff.csv"), csv(&report.rows).as_bytes())?;
    crate::error::write_atomic(&dir.join("tradeoff.svg"), c.svg().as_bytes())?;
    crate::error::write_atomic(&dir.join("tradeoff.png"), &c.png()?)?;
    let low = chart_low_fov(report);
    crate::error::write_atomic(&dir.join("tradeoff-low-fov.svg"), low.svg().as_bytes())?;
    crate::error::write_atomic(&dir.join("tradeoff-low-fov.png"), &low.png()?)?;
    for (stem, c) in cost_charts(report) {
        crate::error::write_atomic(&dir.join(format!("{stem}.svg")), c.svg().as_bytes())?;
        crate::error::write_atomic(&dir.join(format!("{stem}.png")), &c.png()?)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(ms: f64, rmse: f64) -> Row {
        Row {
            lod: "x".into(),
            config: String::new(),
            ms,
            ms_lod: 0.0,
            ms_mesh: 0.0,
            ms_vertex: 0.0,
            ms_raster: 0.0,
            ms_shade: 0.0,
            rmse,
            rmse_wide: 0.0,
            rmse_low_fov: 0.0,
            max_abs: 0,
            depth_m: 0.0,
            triangles: 0.0,
            popping: 0.0,
            reference: "brute-force".into(),
            pareto: false,
            ms_low_fov: ms,
            triangles_low_fov: 0.0,
            gpu: None,
        }
    }

    #[test]
    fn pareto_front_keeps_only_undominated_rows() {
        let mut rows = vec![row(1.0, 5.0), row(2.0, 3.0), row(3.0, 4.0), row(4.0, 0.0)];
        mark_pareto(&mut rows);
        let front: Vec<bool> = rows.iter().map(|r| r.pareto).collect();
        assert_eq!(front, [true, true, false, true]);
        // The low-FOV chart's front is of its own two columns.
        rows[2].rmse_low_fov = -1.0;
        let c = chart_low_fov(&Report {
            title: "t".into(),
            views: vec![],
            size: [1, 1],
            path_frames: 0,
            rows,
            budget_ms: 0.0,
            best_in_budget: None,
        });
        assert_eq!(c.front, [(1.0, 0.0), (3.0, -1.0)]);
    }
}
