//! `check-gpu` and `bench`: the wgpu back end against the CPU reference on
//! the same frames, in one process.

use crate::check::compare::{difference_image, tie_band, Difference};
use crate::error::{write_atomic, Result};
use crate::frame::stats::{median, Passes};
use crate::gpu::GpuRenderer;
use crate::render::{self, Image, RenderOptions, Session};
use crate::scene::Scene;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// One scene's parity result (the CLI contract's keys plus detail).
#[derive(Clone, Debug, Serialize)]
pub struct SceneParity {
    /// The scene's name as `check-gpu` reports it.
    pub scene: String,
    /// Over every frame: counts summed, largest differences the largest;
    /// `unmatched_example` from the worst frame (CPU as `a`).
    #[serde(flatten)]
    pub diff: Difference,
    /// Every frame passed in the chosen mode ([`Difference::passes`]).
    pub pass: bool,
    /// The most triangles one GPU frame drew.
    pub triangles: usize,
    /// Frames compared (1, or the path's length).
    pub frames: usize,
    /// The path frame whose images are written: the most unmatched, then
    /// shifted pixels, then the largest channel difference.
    pub worst_frame: usize,
    /// Toroid texels the GPU rewrote over the path after its first frame,
    /// and what full uploads would have written.
    pub texels_uploaded: u64,
    /// What uploading every level's toroid in full each frame would have written.
    pub texels_full: u64,
    /// With a lazy pyramid: the coarsest levels not yet drawn after each
    /// frame of the GPU's session (absent otherwise), so a path can show
    /// levels joining while the images still match.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub levels_unbuilt: Option<Vec<usize>>,
    /// With `[gpu] update = "gpu"`: every level's toroid texels read back
    /// after each update and compared with the CPU's, before any image
    /// (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texels: Option<crate::gpu::TexelCheck>,
    /// With `[gpu] update = "gpu"`: texels the GPU's update pass made
    /// over the path, none of them uploaded.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texels_made: Option<u64>,
    /// With `[gpu] update = "gpu"`: bytes of residual codes uploaded for
    /// the pack levels among them, over the path.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_bytes: Option<u64>,
}

pub use crate::camera::path_camera;
use crate::render::gpu::{draw_session, frame as gpu_frame};

/// Renders `frames` views of the path on both back ends and compares each;
/// the GPU's toroids are updated only by each frame's dirty rectangles.
/// Writes -cpu/-gpu/-diff PNGs of the worst frame (or of the one view).
pub fn check(
    r: &mut GpuRenderer,
    scene: &Scene,
    name: &str,
    frames: usize,
    step: f64,
    out: &Path,
    exact: bool,
) -> Result<SceneParity> {
    let opts = RenderOptions::default();
    let mut passes = Passes::default();
    let mut cpu = Session::new(scene, &mut passes)?;
    let mut gpu = Session::new(scene, &mut passes)?;
    r.forget_textures();
    let base = scene.camera();
    let mut worst: Option<(usize, Difference, Image, Image)> = None;
    let mut total = Difference::default();
    let mut triangles = 0;
    let mut pass = true;
    let (mut uploaded, mut full) = (0, 0);
    let mut unbuilt: Option<Vec<usize>> = None;
    let on_gpu = gpu.gpu_update == crate::scene::GpuUpdate::Gpu;
    let (mut texels, mut made, mut residual) = (
        on_gpu.then(crate::gpu::TexelCheck::default),
        on_gpu.then_some(0u64),
        on_gpu.then_some(0u64),
    );
    for i in 0..frames.max(1) {
        let cam = path_camera(&base, i, step);
        let (frame, _) = cpu.frame(&cam, &mut passes)?;
        let (want, _) = render::draw(&frame, &opts, &mut passes);
        let (gframe, got, lazy) = gpu_frame(r, &mut gpu, &cam, &mut passes)?;
        if let (Some(t), Some(cm)) = (texels.as_mut(), gpu.lod.clipmap()) {
            t.merge(&r.check_toroids(cm, &gpu.world)?);
        }
        if let (Some(m), Some(b)) = (made.as_mut(), residual.as_mut()) {
            *m += r.texels_made();
            *b += r.residual_bytes();
        }
        if let Some(l) = lazy {
            unbuilt.get_or_insert_with(Vec::new).push(l.levels_unbuilt);
        }
        triangles = triangles.max(gframe.triangle_count());
        if i > 0 {
            uploaded += r.texels_uploaded();
            full += gpu
                .lod
                .clipmap()
                .map_or(0, |cm| (cm.n() * cm.n()) as u64 * cm.levels().len() as u64);
        }
        // GL reads back no depth: compare colour alone there; anywhere else
        // a readback without depth is a failure (`size_mismatch`).
        let band = tie_band(&render::raster(&frame, opts.path), frame.effects.wireframe);
        let d = if r.gpu.api == crate::gpu::Api::Gl {
            let colour = Image {
                depth: vec![],
                ..want.clone()
            };
            Difference::within(&colour, &got, Some(&band))
        } else {
            Difference::within(&want, &got, Some(&band))
        };
        pass &= d.passes(exact);
        total.add(&d);
        let severity = |d: &Difference| {
            (
                d.holes_px,
                d.outside_band_px,
                d.unmatched_px,
                d.shifted_px,
                d.max_channel_diff,
                d.colour_px_differ,
            )
        };
        if worst.as_ref().is_none_or(|w| severity(&d) > severity(&w.1)) {
            worst = Some((i, d, want, got));
        }
    }
    if let Some((_, _, want, got)) = &worst {
        std::fs::create_dir_all(out).map_err(|e| crate::Error::io(out, e))?;
        write_atomic(&out.join(format!("{name}-cpu.png")), &want.png()?)?;
        write_atomic(&out.join(format!("{name}-gpu.png")), &got.png()?)?;
        let diff = difference_image(got, &want.rgba);
        write_atomic(&out.join(format!("{name}-diff.png")), &diff.png()?)?;
    }
    total.unmatched_example = worst.as_ref().and_then(|w| w.1.unmatched_example);
    // Where the images must be exact, so must the texels they came from.
    pass &= !exact || texels.is_none_or(|t| t.differ == 0);
    Ok(SceneParity {
        scene: name.to_string(),
        diff: total,
        pass,
        triangles,
        frames: frames.max(1),
        worst_frame: worst.as_ref().map_or(0, |w| w.0),
        texels_uploaded: uploaded,
        texels_full: full,
        levels_unbuilt: unbuilt,
        texels,
        texels_made: made,
        residual_bytes: residual,
    })
}

/// One update's cost both ways ([`update_bench`]).
#[derive(Clone, Debug, Default, Serialize)]
pub struct UpdateTimes {
    /// The CPU's clipmap update (every level: synthesised tiles made and
    /// toroids filled), ms.
    pub cpu_update_ms: f64,
    /// Uploading the synthesised levels' rewritten texels (and slopes, when
    /// lit), ms.
    pub upload_ms: f64,
    /// The GPU's update pass making the same texels, ms.
    pub gpu_pass_ms: f64,
    /// Synthesised-level texels rewritten.
    pub texels: u64,
}

/// `bench --update`: the synthesised levels' update on the CPU (its
/// update plus the upload) against the GPU's update pass.
#[derive(Clone, Debug, Serialize)]
pub struct UpdateBench {
    /// The adapter's name, driver and API.
    pub adapter: String,
    /// Levels the GPU's update pass makes: synthesised ones, and those of
    /// a pack coded with `--predictor upsampled`.
    pub levels: usize,
    /// Toroid side.
    pub n: i64,
    /// The first frame: every level rebuilt.
    pub jump: UpdateTimes,
    /// The walk's frames after it, each figure the median.
    pub walk: UpdateTimes,
    /// Frames walked after the jump.
    pub frames: usize,
}

/// Times a jump (the first frame, every level built) and a walk of
/// `frames` frames, `step` metres each, of a scene with synthesised
/// levels ([`UpdateBench`]).
pub fn update_bench(
    r: &mut GpuRenderer,
    scene: &Scene,
    frames: usize,
    step: f64,
) -> Result<UpdateBench> {
    let mut passes = Passes::default();
    let mut session = Session::new(scene, &mut passes)?;
    let how = session.synthesis.clone();
    let residuals = session
        .lod
        .clipmap()
        .is_some_and(|cm| (0..cm.levels().len()).any(|l| cm.pyramid().residual_step(l).is_some()));
    if how.is_none() && !residuals {
        return Err(crate::Error::value(
            "bench --update",
            "the scene has no level the GPU can make: it synthesises none ([terrain] synthesis) \
             and its terrain is no pack coded with --predictor upsampled",
        ));
    }
    r.forget_textures();
    let base = scene.camera();
    let mut times = Vec::new();
    let mut levels = 0;
    for i in 0..=frames {
        let mut p = Passes::default();
        let (frame, clip) = session.frame(&path_camera(&base, i, step), &mut p)?;
        let (Some(c), Some(cm)) = (clip, session.lod.clipmap()) else {
            return Err(crate::Error::value(
                "bench --update",
                "the scene has no clipmap",
            ));
        };
        let slopes = frame.effects.lit() && !frame.effects.normal_map;
        levels = GpuRenderer::update_levels(cm, slopes, how.is_some());
        let update = (i > 0).then_some(&c.update);
        if i == 0 {
            // Once untimed, so the jump pays no pipeline compilation or
            // first-use costs; then again from empty textures.
            r.time_update(cm, &session.world, how.as_ref(), None, slopes)?;
            r.forget_textures();
        }
        let (upload_ms, gpu_pass_ms, texels) =
            r.time_update(cm, &session.world, how.as_ref(), update, slopes)?;
        times.push(UpdateTimes {
            cpu_update_ms: crate::frame::stats::pass_ms(&p.0, &["lod"]),
            upload_ms,
            gpu_pass_ms,
            texels,
        });
    }
    let walk = &times[1..];
    let med = |f: fn(&UpdateTimes) -> f64| median(&walk.iter().map(f).collect::<Vec<_>>());
    let cm = session.lod.clipmap().expect("a clipmap");
    Ok(UpdateBench {
        adapter: r.gpu.adapter(),
        levels,
        n: cm.n(),
        jump: times[0].clone(),
        walk: UpdateTimes {
            cpu_update_ms: med(|t| t.cpu_update_ms),
            upload_ms: med(|t| t.upload_ms),
            gpu_pass_ms: med(|t| t.gpu_pass_ms),
            texels: median(&walk.iter().map(|t| t.texels as f64).collect::<Vec<_>>()) as u64,
        },
        frames,
    })
}

/// `bench`: frames per second of both back ends on the same frame, warm.
#[derive(Clone, Debug, Serialize)]
pub struct Bench {
    /// CPU frames per second (raster and shade), the median repeat.
    pub cpu_fps: f64,
    /// GPU frames per second (upload, draw and readback), the median repeat.
    pub gpu_fps: f64,
    /// cpu_fps ÷ gpu_fps.
    pub ratio: f64,
    /// The adapter's name, driver and API.
    pub adapter: String,
    /// Image width and height in pixels.
    pub size: [u32; 2],
    /// Triangles in the frame.
    pub triangles: usize,
    /// Frames per repeat.
    pub frames: usize,
    /// Repeats, alternating back ends.
    pub repeats: usize,
    /// Per repeat, ms per frame.
    pub cpu_ms: Vec<f64>,
    /// Per repeat, GPU ms per frame.
    pub gpu_ms: Vec<f64>,
}

/// Times raster + shade (CPU) against upload + draw + readback (GPU) of the
/// same frame, alternating back ends per repeat; reports medians.
pub fn bench(r: &mut GpuRenderer, scene: &Scene, frames: usize, repeats: usize) -> Result<Bench> {
    let opts = RenderOptions::default();
    let mut passes = Passes::default();
    let mut session = Session::new(scene, &mut passes)?;
    let camera = scene.camera();
    let (frame, clip) = session.frame(&camera, &mut passes)?;
    let still = crate::clipmap::UpdateStats::default();
    // A still camera: a real frame would upload the update's rectangles,
    // which are empty here.
    let draw_gpu = |r: &mut GpuRenderer, session: &Session| {
        draw_session(r, &frame, clip.as_ref(), session, Some(&still))
    };
    r.forget_textures();
    // Warm up both (pipeline compilation, first full upload, caches); the
    // CPU draws in the session's kept buffers, as a renderer drawing frame
    // after frame would.
    draw_gpu(r, &session)?;
    session.draw(&frame, &opts, &mut Passes::default());
    let (mut cpu_ms, mut gpu_ms) = (vec![], vec![]);
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        for _ in 0..frames {
            std::hint::black_box(session.draw(&frame, &opts, &mut Passes::default()));
        }
        cpu_ms.push(t.elapsed().as_secs_f64() * 1e3 / frames as f64);
        let t = Instant::now();
        for _ in 0..frames {
            std::hint::black_box(draw_gpu(r, &session)?);
        }
        gpu_ms.push(t.elapsed().as_secs_f64() * 1e3 / frames as f64);
    }
    let (c, g) = (median(&cpu_ms), median(&gpu_ms));
    Ok(Bench {
        cpu_fps: 1e3 / c,
        gpu_fps: 1e3 / g,
        ratio: g / c,
        adapter: r.gpu.adapter(),
        size: [frame.width, frame.height],
        triangles: frame.triangle_count(),
        frames,
        repeats: repeats.max(1),
        cpu_ms,
        gpu_ms,
    })
}
