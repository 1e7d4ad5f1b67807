//! The scaling stage: what frame time, pyramid building, incremental updates
//! and memory cost as the terrain grows (the targets are in
//! `docs/explanation/performance.md`).
//!
//! - **Size independence** (Holkner's claim for clipmaps): one view of
//!   procedural terrains of several sizes with the same n and L. The clipmap
//!   covers the same ground on each, so its frame time should not change;
//!   brute force draws every cell and should grow with the map. Frames of
//!   all sizes are interleaved, so drift of a noisy machine hits them alike.
//! - **Pyramid**: the build time per size (sinc-Blackman by default).
//! - **Incremental update**: a viewer moving one texel per frame against a
//!   full rebuild, compared with the ratio of texels each writes.
//! - **Memory**: peak resident memory while the terrains and pyramids are
//!   built, against their own size.

use crate::clipmap::{Clipmap, ClipmapConfig};
use crate::error::{Error, Result};
use crate::frame::stats::{median, Passes};
use crate::pyramid::Pyramid;
use crate::render::{self, RenderOptions, Session};
use crate::scene::{LodScheme, Scene};
use crate::terrain::procedural::Procedural;
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug)]
pub struct Options {
    /// Square procedural terrains, texels per side, smallest first.
    pub sizes: Vec<usize>,
    /// Packs to time instead of the procedural sizes (smallest first),
    /// each decoded tile by tile as the clipmap reaches it: the same
    /// interleaved frames, so a small and a large pack compare in one
    /// process. Brute force does not run on them.
    pub packs: Vec<std::path::PathBuf>,
    /// Clipmap n and level count for the size test (the clipmap must fit in
    /// the smallest map for the views to match).
    pub n: i64,
    /// Clipmap levels for the size test.
    pub levels: usize,
    /// Frames per size (the camera pans one texel per frame).
    pub frames: usize,
    /// Brute force only up to this size (its frame grows with the map).
    pub brute_max: usize,
    /// n and L of the incremental-update test, on its own map.
    pub update_n: i64,
    /// Levels of the incremental-update test.
    pub update_levels: usize,
    /// Repeats of the update test's walks and rebuilds; medians reported.
    pub update_repeats: usize,
    /// Image width and height.
    pub image: [u32; 2],
    /// n of the lazy first-frame test on the largest size (every level
    /// the map allows), and the lazy pyramid's samples per frame.
    pub first_n: i64,
    /// Samples per frame of the lazy pyramid in the first-frame test.
    pub first_budget: u64,
    /// Frames the first-frame test may render until every level is drawn.
    pub first_max_frames: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            sizes: vec![1024, 2048, 4096, 16384],
            packs: Vec::new(),
            n: 127,
            levels: 3,
            frames: 40,
            brute_max: 2048,
            update_n: 255,
            update_levels: 10,
            update_repeats: 5,
            image: [960, 540],
            first_n: 255,
            first_budget: crate::scene::DEFAULT_LAZY_BUDGET,
            first_max_frames: 100,
        }
    }
}

/// One terrain size.
#[derive(Clone, Debug, Serialize)]
pub struct SizeRow {
    /// Texels per side.
    pub size: usize,
    /// Generating the terrain (ms).
    pub terrain_ms: f64,
    /// Building its pyramid (ms).
    pub pyramid_ms: f64,
    /// Pyramid levels built.
    pub pyramid_levels: usize,
    /// Median frame (LOD update, mesh, vertex, raster, shade), ms.
    pub clipmap_frame_ms: f64,
    /// Triangles in the clipmap's frame.
    pub clipmap_triangles: usize,
    /// Brute force's median frame (ms), up to `brute_max`.
    pub brute_frame_ms: Option<f64>,
    /// Brute force's triangles.
    pub brute_triangles: Option<usize>,
}

/// Moving one texel per frame against rebuilding every texel.
#[derive(Clone, Debug, Serialize)]
pub struct UpdateRow {
    /// The map's width (its height is a quarter of it).
    pub size: usize,
    /// Clipmap n.
    pub n: i64,
    /// Clipmap levels.
    pub levels: usize,
    /// Median of full rebuilds (every texel of every level written) after
    /// jumps to places not read before, which is when a rebuild happens
    /// and what the walks read too: the incremental overhead is taken
    /// against this.
    pub full_ms: f64,
    /// The same, with the rebuild confined to one thread like a step: what
    /// a step's cost per texel is up against without the second core.
    pub full_one_core_ms: f64,
    /// Median of rebuilds of one window again and again, its source
    /// already in cache: the best a rebuild can do.
    pub full_same_window_ms: f64,
    /// Texels a full rebuild writes.
    pub full_texels: u64,
    /// Bytes of the update map's pyramid (heights and no-data masks, all
    /// levels), and how many of them the kernel put on huge pages (the
    /// process's `AnonHugePages` grew by this much while it was built;
    /// `null` off Linux). See `huge`: with them, a window's rows cost a
    /// TLB entry per 2 MB instead of one per row, so a machine that grants
    /// none reads slower walks.
    pub map_bytes: u64,
    /// Of `map_bytes`, those on huge pages (`null` off Linux).
    pub map_huge_page_bytes: Option<u64>,
    /// Each repeat walks from its own start, on terrain the others did
    /// not read, with its own rebuilds; the walks' figures are medians.
    pub repeats: usize,
    /// Walks east (each level writes columns), south (rows) and
    /// south-east (both; coarse levels often move one way in a frame).
    pub walks: Vec<Walk>,
}

/// One walk of `frames` one-texel steps.
#[derive(Clone, Debug, Serialize)]
pub struct Walk {
    /// `east`, `south` or `south-east`.
    pub direction: &'static str,
    /// Steps walked.
    pub frames: usize,
    /// Mean per frame (median of the repeats).
    pub incremental_ms: f64,
    /// Texels rewritten per frame (median of the repeats).
    pub incremental_texels: f64,
    /// Source rows copied into column blocks per frame (median of the
    /// repeats; see `clipmap::columns`): the fresh reads a walk makes
    /// beyond its texels, counted rather than timed.
    pub column_rows: f64,
    /// incremental_ms ÷ full_ms.
    pub time_ratio: f64,
    /// incremental texels ÷ full texels.
    pub texel_ratio: f64,
    /// Median over repeats of (walk ÷ that repeat's rebuilds) ÷
    /// texel_ratio; the target is ≤ 1.2.
    pub overhead: f64,
    /// Each repeat's overhead.
    pub overheads: Vec<f64>,
    /// The overhead against the one-thread rebuilds.
    pub overhead_one_core: f64,
}

/// Peak resident memory while every size was loaded and its pyramid built.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryRow {
    /// Peak resident set size (bytes; `null` off Linux).
    pub peak_rss_bytes: Option<u64>,
    /// Heightmaps (f32 + no-data flag per texel), all sizes.
    pub heightmap_bytes: u64,
    /// Pyramids (all levels, f32 + flag per sample), all sizes.
    pub pyramid_bytes: u64,
    /// peak ÷ (heightmaps + pyramids); the target is < 2.
    pub ratio: Option<f64>,
}

/// The first frame of the largest terrain with a lazy pyramid: nothing is
/// generated before the clipmap's first update asks for its tiles.
#[derive(Clone, Debug, Serialize)]
pub struct FirstFrameRow {
    /// Texels per side of the map.
    pub size: usize,
    /// Clipmap n.
    pub n: i64,
    /// Clipmap levels (all the map allows) and how many the first frame
    /// drew; the coarser ones wait for their tiles.
    pub levels: usize,
    /// Levels the first frame drew.
    pub levels_drawn: usize,
    /// Lazy pyramid samples per frame.
    pub budget: u64,
    /// Scene to image: session, pyramid tiles, LOD, mesh, raster, shade.
    pub first_frame_ms: f64,
    /// Triangles in the first frame.
    pub triangles: usize,
    /// Pyramid samples the first frame built, and an eager pyramid's.
    pub samples_built: u64,
    /// Samples an eager pyramid builds before its first frame.
    pub eager_samples: u64,
    /// Peak resident memory up to the first frame.
    pub peak_rss_bytes: Option<u64>,
    /// The same view kept still: frames until every level is drawn, and
    /// their total time (`None` if `first_max_frames` did not suffice).
    pub frames_to_all_levels: Option<usize>,
    /// Their total time (ms).
    pub all_levels_ms: Option<f64>,
}

/// `scaling --json`: cost against terrain size, incremental update against rebuilds,
/// memory, and the lazy first frame.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Lazy first frame of the largest size; the target is < 1 s.
    pub first_frame: FirstFrameRow,
    /// One row per terrain size, smallest first.
    pub sizes: Vec<SizeRow>,
    /// Clipmap frame time, largest ÷ smallest size; the target is ≤ 1.05.
    pub clipmap_ratio: f64,
    /// Brute force, largest ÷ smallest size it ran on.
    pub brute_ratio: Option<f64>,
    /// Incremental update against full rebuilds.
    pub update: UpdateRow,
    /// Peak memory against the data's size.
    pub memory: MemoryRow,
}

/// Where a study's terrain comes from.
#[derive(Clone, Copy)]
enum Source<'a> {
    /// A procedural map of this size².
    Size(usize),
    /// A pack, read as a scene names one.
    Pack(&'a std::path::Path),
}

/// The scene for one source: the default scene's camera and shading over
/// `source`, with scheme `lod`.
fn scene(base: &Scene, source: Source, lod: LodScheme, opts: &Options) -> Result<Scene> {
    let mut s = base.clone();
    match source {
        Source::Size(size) => {
            let seed = base.terrain.procedural.as_ref().map_or(20041, |p| p.seed);
            s.terrain.file = None;
            s.terrain.procedural = Some(Procedural::new(seed, size, size));
        }
        Source::Pack(pack) => {
            s.terrain.procedural = None;
            s.terrain.file = Some(std::path::absolute(pack).map_err(|e| Error::io(pack, e))?);
        }
    }
    s.lod.scheme = lod;
    s.lod.n = opts.n;
    s.lod.levels = Some(opts.levels);
    s.image.width = opts.image[0];
    s.image.height = opts.image[1];
    Ok(s)
}

fn time_frame(session: &mut Session, cam: &crate::camera::Camera) -> Result<(f64, usize)> {
    let t = Instant::now();
    let mut passes = Passes::default();
    let (frame, _) = session.frame(cam, &mut passes)?;
    let tris = frame.triangle_count();
    std::hint::black_box(render::draw(&frame, &RenderOptions::default(), &mut passes));
    Ok((t.elapsed().as_secs_f64() * 1e3, tris))
}

/// Heightmap and pyramid bytes of one size.
fn bytes(p: &Pyramid) -> (u64, u64) {
    let per = |w: usize, h: usize| (w * h) as u64 * 5;
    let base = &p.levels[0];
    let all = p.levels.iter().map(|l| per(l.width, l.height)).sum();
    (per(base.width, base.height), all)
}

/// Runs every measurement; `tick` reports progress.
pub fn run(base: &Scene, opts: &Options, mut tick: impl FnMut(&str)) -> Result<Report> {
    if opts.sizes.is_empty() || opts.frames == 0 {
        return Err(Error::value(
            "scaling",
            "need at least one size and one frame",
        ));
    }
    if opts.sizes.windows(2).any(|w| w[0] >= w[1]) {
        return Err(Error::value("scaling.sizes", "must be increasing"));
    }
    // Checked before the long work, not after it.
    update_dims(opts.update_n, opts.update_levels)?;
    if !(1..=1000).contains(&opts.update_repeats) {
        return Err(Error::value(
            "scaling.update_repeats",
            "must be within 1..=1000",
        ));
    }
    scene(base, Source::Size(opts.sizes[0]), LodScheme::Clipmap, opts)?.validate()?;
    // First, in a process that has built nothing yet.
    tick("lazy first frame");
    let first_frame = first_frame(base, opts)?;
    reset_peak_rss();
    let mut sessions = Vec::new();
    let mut rows = Vec::new();
    let (mut hm_bytes, mut pyr_bytes) = (0, 0);
    let sources: Vec<Source> = if opts.packs.is_empty() {
        opts.sizes.iter().map(|&n| Source::Size(n)).collect()
    } else {
        opts.packs.iter().map(|p| Source::Pack(p)).collect()
    };
    for &source in &sources {
        tick(&match source {
            Source::Size(n) => format!("building {n}²"),
            Source::Pack(p) => format!("opening {}", p.display()),
        });
        let s = scene(base, source, LodScheme::Clipmap, opts)?;
        s.validate()?;
        let mut passes = Passes::default();
        let session = Session::new(&s, &mut passes)?;
        let size = session.pyramid().levels[0].width;
        let (h, p) = bytes(session.pyramid());
        hm_bytes += h;
        pyr_bytes += p;
        rows.push(SizeRow {
            size,
            terrain_ms: passes.ms(&["terrain"]),
            pyramid_ms: passes.ms(&["pyramid"]),
            pyramid_levels: session.pyramid().levels.len(),
            clipmap_frame_ms: 0.0,
            clipmap_triangles: 0,
            brute_frame_ms: None,
            brute_triangles: None,
        });
        sessions.push(session);
    }
    let peak = peak_rss();
    let memory = MemoryRow {
        peak_rss_bytes: peak,
        heightmap_bytes: hm_bytes,
        pyramid_bytes: pyr_bytes,
        ratio: peak.map(|p| p as f64 / (hm_bytes + pyr_bytes) as f64),
    };

    // Interleaved frames: one of each size per step of the pan, eye over
    // the smallest map's centre.
    let cam = centred_camera(base, &sessions[0], rows[0].size, opts);
    let step = sessions[0].world.cell[0];
    let mut times = vec![Vec::new(); sessions.len()];
    for f in 0..=opts.frames {
        tick(&format!("clipmap frame {f}/{}", opts.frames));
        let mut c = cam;
        c.eye.x += f as f64 * step;
        c.target.x += f as f64 * step;
        // The order rotates each step, so no size always runs first.
        let count = sessions.len();
        for i in (0..count).map(|k| (k + f) % count) {
            let (ms, tris) = time_frame(&mut sessions[i], &c)?;
            // Frame 0 builds every level from scratch: not a steady frame.
            if f > 0 {
                times[i].push(ms);
            }
            rows[i].clipmap_triangles = tris;
        }
    }
    for (row, t) in rows.iter_mut().zip(&times) {
        row.clipmap_frame_ms = median(t);
    }
    drop(sessions);

    // Brute force on the sizes it can afford (procedural ones).
    let procedural = opts.packs.is_empty();
    for row in rows
        .iter_mut()
        .filter(|r| procedural && r.size <= opts.brute_max)
    {
        tick(&format!("brute force {}²", row.size));
        let s = scene(base, Source::Size(row.size), LodScheme::BruteForce, opts)?;
        let mut session = Session::new(&s, &mut Passes::default())?;
        let mut t = Vec::new();
        for _ in 0..3 {
            let (ms, tris) = time_frame(&mut session, &cam)?;
            t.push(ms);
            row.brute_triangles = Some(tris);
        }
        row.brute_frame_ms = Some(median(&t));
    }

    tick("incremental update");
    let update = update_test(opts)?;
    let first = &rows[0];
    let last = rows.last().expect("one size at least");
    let brute: Vec<&SizeRow> = rows.iter().filter(|r| r.brute_frame_ms.is_some()).collect();
    let brute_ratio = (brute.len() > 1).then(|| {
        brute[brute.len() - 1].brute_frame_ms.expect("ran") / brute[0].brute_frame_ms.expect("ran")
    });
    Ok(Report {
        first_frame,
        clipmap_ratio: last.clipmap_frame_ms / first.clipmap_frame_ms,
        brute_ratio,
        sizes: rows,
        update,
        memory,
    })
}

/// The lazy first frame of the largest size with every level the map
/// allows, eye over the map's centre, then the same view until all levels
/// are drawn.
fn first_frame(base: &Scene, opts: &Options) -> Result<FirstFrameRow> {
    let size = *opts.sizes.last().expect("one size at least");
    let mut s = scene(base, Source::Size(size), LodScheme::Clipmap, opts)?;
    s.lod.n = opts.first_n;
    s.lod.levels = None;
    s.pyramid.lazy = true;
    s.pyramid.budget = opts.first_budget;
    if s.shading.height_range.is_none() {
        // A ramp over ± amplitude / 2, most of the generator's heights
        // (the ramp clamps beyond): colours do not change the timing.
        let a = s.terrain.procedural.as_ref().map_or(600.0, |p| p.amplitude) as f32;
        s.shading.height_range = Some([-a / 2.0, a / 2.0]);
    }
    s.validate()?;
    reset_peak_rss();
    let t = Instant::now();
    let mut session = Session::new(&s, &mut Passes::default())?;
    let cam = centred_camera(base, &session, size, opts);
    let opts_r = RenderOptions::default();
    let (img, stats) = session.render(&cam, &opts_r, Passes::default())?;
    let first_frame_ms = t.elapsed().as_secs_f64() * 1e3;
    std::hint::black_box(img);
    let peak_rss_bytes = peak_rss();
    let lazy = stats.lazy.clone().expect("lazy scene");
    let levels = session.lod.clipmap().map_or(0, |c| c.levels().len());
    let eager_samples = session
        .pyramid()
        .levels
        .iter()
        .map(|l| (l.width * l.height) as u64)
        .sum();
    let mut rest = None;
    if lazy.levels_unbuilt > 0 {
        let t = Instant::now();
        for f in 1..=opts.first_max_frames {
            let (_, st) = session.render(&cam, &opts_r, Passes::default())?;
            if st.lazy.is_some_and(|z| z.levels_unbuilt == 0) {
                rest = Some((f, t.elapsed().as_secs_f64() * 1e3));
                break;
            }
        }
    } else {
        rest = Some((0, 0.0));
    }
    Ok(FirstFrameRow {
        size,
        n: opts.first_n,
        levels,
        levels_drawn: stats.levels_drawn,
        budget: opts.first_budget,
        first_frame_ms,
        triangles: stats.triangles,
        samples_built: lazy.pyramid.samples_built,
        eager_samples,
        peak_rss_bytes,
        frames_to_all_levels: rest.map(|r| r.0),
        all_levels_ms: rest.map(|r| r.1),
    })
}

/// The scene's view, moved so its eye is over the centre of a `size`² map.
fn centred_camera(
    base: &Scene,
    session: &Session,
    size: usize,
    opts: &Options,
) -> crate::camera::Camera {
    let mut cam = base.camera();
    cam.aspect = opts.image[0] as f64 / opts.image[1] as f64;
    let mid = size as f64 / 2.0;
    let centre = session.world.to_world(mid, mid, 0.0);
    let shift = glam::DVec3::new(centre.x - cam.eye.x, centre.y - cam.eye.y, 0.0);
    cam.eye += shift;
    cam.target += shift;
    cam
}

/// The map of the update test: wide enough that the clipmap bounds allow
/// L levels of n (the coarsest window must not already hold the whole map),
/// a quarter as high (or 2^L + 1 rows if that is more). Its heights are a
/// cheap pattern and its pyramid a box filter: writing a texel costs the
/// same whatever its value.
pub fn update_map(n: i64, levels: usize) -> Result<Pyramid> {
    let (w, h) = update_dims(n, levels)?;
    let values = crate::terrain::huge::collect(
        (0..w * h).map(|i| ((i % w) * 7 + (i / w) * 13) as f32 % 1000.0),
    );
    let map = crate::terrain::Heightmap::from_values(w, h, values, None, [1.0, 1.0], "update")
        .map_err(|r| Error::value("scaling.update", r))?;
    Ok(Pyramid::from_heightmap(
        map,
        crate::pyramid::Filter::Box,
        levels,
    ))
}

/// The update map's size for n and L, or why there is none.
fn update_dims(n: i64, levels: usize) -> Result<(usize, usize)> {
    crate::clipmap::region::check_n(n).map_err(|r| Error::value("scaling.update_n", r))?;
    if !(1..=20).contains(&levels) {
        return Err(Error::value(
            "scaling.update_levels",
            "must be within 1..=20",
        ));
    }
    let need = (n as usize - 1) / 2 * (1usize << levels.saturating_sub(2)) + 2;
    let w = need.next_power_of_two().max(64);
    // At least 2^L + 1 rows, so the coarsest level still has two cells.
    let h = (w / 4).max((1 << levels) + 1);
    crate::terrain::check_dimensions(w as u64, h as u64).map_err(|r| {
        Error::value(
            "scaling.update",
            format!("n = {n} with L = {levels} needs a {w}×{h} map: {r}"),
        )
    })?;
    Ok((w, h))
}

/// One repeat of one walk direction: per frame, and its own rebuilds'
/// medians on both pools.
#[derive(Clone, Copy)]
struct Repeat {
    ms: f64,
    texels: f64,
    column_rows: f64,
    full_ms: f64,
    one_core_ms: f64,
}

/// One-texel-per-frame walks of 4 · 2^(L−1) frames (every level moves at
/// least four times) against full rebuilds, repeated.
fn update_test(opts: &Options) -> Result<UpdateRow> {
    let huge_before = anon_huge_bytes();
    let pyramid = Arc::new(update_map(opts.update_n, opts.update_levels)?);
    let map_huge_page_bytes = anon_huge_bytes()
        .zip(huge_before)
        .map(|(after, before)| after.saturating_sub(before));
    let map_bytes = bytes(&pyramid).1;
    let (size, rows) = (pyramid.levels[0].width, pyramid.levels[0].height);
    let cfg = ClipmapConfig {
        n: opts.update_n,
        levels: Some(opts.update_levels),
        ..Default::default()
    };
    let repeats = opts.update_repeats;
    let centre = [size as f64 / 2.0, rows as f64 / 2.0];
    // Rebuilds run on a second clipmap, interleaved with the walks' frames
    // (8 chunks per walk), so a slow spell of this machine hits both
    // sides of the ratio. Each rewrites every texel of every level, in
    // memory already in use (a fresh clipmap would also time page faults),
    // after a jump to one of 32 places across the map, an eighth of its
    // height from the top or bottom, clear of the walks from the centre.
    // After each chunk come one rebuild on the global pool and one on a
    // pool of one thread.
    let mut walker = Clipmap::new(pyramid, cfg)?;
    walker.update(centre);
    let mut jumper = walker.clone();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| Error::value("scaling.update", format!("no one-thread pool: {e}")))?;
    let mut full_texels = 0;
    let mut rebuild = |at: [f64; 2], single: bool| {
        jumper.invalidate();
        let t = Instant::now();
        full_texels = if single {
            one.install(|| jumper.update(at).texels_total)
        } else {
            jumper.update(at).texels_total
        };
        t.elapsed().as_secs_f64() * 1e3
    };
    let jump = |k: usize| {
        let y = if (k / 16) % 2 == 0 { 0.125 } else { 0.875 };
        [
            size as f64 * ((k % 16) as f64 + 0.5) / 16.0,
            rows as f64 * y,
        ]
    };
    // Four cycles of the coarsest level, so one preempted frame does not
    // decide the mean.
    let frames = 4usize << (opts.update_levels - 1);
    let chunks = frames.min(8);
    let dirs = [
        ("east", [1.0, 0.0]),
        ("south", [0.0, 1.0]),
        ("south-east", [1.0, 1.0]),
    ];
    let (mut all_full, mut all_one) = (Vec::new(), Vec::new());
    let mut runs: Vec<Vec<Repeat>> = vec![Vec::new(); dirs.len()];
    let mut k = 0;
    for r in 0..repeats {
        // Each repeat starts a 32nd of the width and a 16th of the height
        // further on, so its walks read terrain the others did not.
        let shift = r as f64 - (repeats - 1) as f64 / 2.0;
        let start = [
            centre[0] + shift * size as f64 / 32.0,
            centre[1] + shift * rows as f64 / 16.0,
        ];
        for (run, (_, d)) in runs.iter_mut().zip(dirs) {
            walker.update(start);
            let (mut ms, mut texels, mut column_rows) = (0.0, 0u64, 0u64);
            let (mut full, mut single) = (Vec::new(), Vec::new());
            for c in 0..chunks {
                let t = Instant::now();
                for f in c * frames / chunks + 1..=(c + 1) * frames / chunks {
                    let f = f as f64;
                    let st = walker.update([start[0] + f * d[0], start[1] + f * d[1]]);
                    texels += st.texels_total;
                    column_rows += st.column_rows_copied;
                }
                ms += t.elapsed().as_secs_f64() * 1e3;
                full.push(rebuild(jump(k), false));
                single.push(rebuild(jump(k + 1), true));
                k += 2;
            }
            all_full.extend_from_slice(&full);
            all_one.extend_from_slice(&single);
            run.push(Repeat {
                ms: ms / frames as f64,
                texels: texels as f64 / frames as f64,
                column_rows: column_rows as f64 / frames as f64,
                full_ms: median(&full),
                one_core_ms: median(&single),
            });
        }
    }
    let same: Vec<f64> = (0..15).map(|_| rebuild(centre, false)).collect();
    let (full_ms, full_one_core_ms) = (median(&all_full), median(&all_one));
    let walks = dirs
        .iter()
        .zip(&runs)
        .map(|((direction, _), run)| {
            let all = full_texels as f64;
            // (walk ÷ rebuild) ÷ (texels ÷ all texels), per repeat.
            let over = |full: fn(&Repeat) -> f64| -> Vec<f64> {
                run.iter()
                    .map(|x| x.ms / full(x) / (x.texels / all))
                    .collect()
            };
            let (overheads, one_core) = (over(|x| x.full_ms), over(|x| x.one_core_ms));
            let median_of = |f: fn(&Repeat) -> f64| median(&run.iter().map(f).collect::<Vec<_>>());
            let (incremental_ms, incremental_texels) =
                (median_of(|x| x.ms), median_of(|x| x.texels));
            Walk {
                direction,
                frames,
                incremental_ms,
                incremental_texels,
                column_rows: median_of(|x| x.column_rows),
                time_ratio: incremental_ms / full_ms,
                texel_ratio: incremental_texels / all,
                overhead: median(&overheads),
                overheads,
                overhead_one_core: median(&one_core),
            }
        })
        .collect();
    Ok(UpdateRow {
        size,
        n: opts.update_n,
        levels: opts.update_levels,
        full_ms,
        full_one_core_ms,
        full_same_window_ms: median(&same),
        full_texels,
        map_bytes,
        map_huge_page_bytes,
        repeats,
        walks,
    })
}

/// Resets the kernel's peak-RSS mark for this process (Linux ≥ 4.0), so the
/// peak read later belongs to this measurement.
fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// This process's anonymous memory on transparent huge pages, where the
/// system reports it.
fn anon_huge_bytes() -> Option<u64> {
    proc_kb("/proc/self/smaps_rollup", "AnonHugePages:")
}

/// Peak resident memory (VmHWM), where the system reports it.
pub fn peak_rss() -> Option<u64> {
    proc_kb("/proc/self/status", "VmHWM:")
}

/// The "`key` N kB" line of a /proc file, in bytes.
fn proc_kb(path: &str, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
