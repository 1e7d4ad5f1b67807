//! `check-gpu` and `bench`: the wgpu back end against the CPU reference on
//! the same frames, in one process.

use super::{ClipDraw, GpuRenderer};
use crate::camera::Camera;
use crate::error::{write_atomic, Result};
use crate::render::{self, ClipFrame, Image, RenderOptions, RenderStats, Session};
use crate::scene::Scene;
use crate::stats::{median, Passes};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Tolerance on adapters other than the pinned lavapipe (RASTER_RULES.md):
/// at most 1 per channel, on at most 0.1 % of pixels, depth within 4 ULP.
pub const TOLERANCE_CHANNEL: u8 = 1;
pub const TOLERANCE_PX_FRACTION: f64 = 0.001;
pub const TOLERANCE_DEPTH_ULP: u32 = 4;

/// How two images differ.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Difference {
    pub colour_px_differ: usize,
    pub depth_px_differ: usize,
    pub max_channel_diff: u8,
    pub max_depth_ulp: u32,
}

impl Difference {
    pub fn of(a: &Image, b: &Image) -> Difference {
        let mut d = Difference::default();
        for (p, q) in a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)) {
            let m = p
                .iter()
                .zip(q)
                .map(|(x, y)| x.abs_diff(*y))
                .max()
                .unwrap_or(0);
            if m > 0 {
                d.colour_px_differ += 1;
                d.max_channel_diff = d.max_channel_diff.max(m);
            }
        }
        for (p, q) in a.depth.iter().zip(&b.depth) {
            if p.to_bits() != q.to_bits() {
                d.depth_px_differ += 1;
                // Depths are ≥ 0, so bit patterns order like the values.
                let ulp = (p.to_bits() as i64 - q.to_bits() as i64).unsigned_abs();
                d.max_depth_ulp = d.max_depth_ulp.max(ulp.min(u32::MAX as u64) as u32);
            }
        }
        d
    }

    /// Exact: nothing differs. Otherwise the stated tolerance.
    pub fn passes(&self, exact: bool, pixels: usize) -> bool {
        if exact {
            return self.colour_px_differ == 0 && self.depth_px_differ == 0;
        }
        self.max_channel_diff <= TOLERANCE_CHANNEL
            && self.colour_px_differ as f64 <= TOLERANCE_PX_FRACTION * pixels as f64
            && self.max_depth_ulp <= TOLERANCE_DEPTH_ULP
    }
}

/// One scene's parity result (the CLI contract's keys plus detail).
#[derive(Clone, Debug, Serialize)]
pub struct SceneParity {
    pub scene: String,
    pub colour_px_differ: usize,
    pub depth_px_differ: usize,
    pub max_channel_diff: u8,
    pub max_depth_ulp: u32,
    pub pass: bool,
    pub triangles: usize,
    /// Frames compared (1, or the path's length).
    pub frames: usize,
    /// Toroid texels the GPU rewrote over the path after its first frame,
    /// and what full uploads would have written.
    pub texels_uploaded: u64,
    pub texels_full: u64,
}

/// Draws `session`'s frame for `camera` on the GPU (the clipmap path when the
/// scene has a clipmap), with the update since the previous call; also the
/// lazy pyramid's state after it, for a lazy scene.
pub fn gpu_frame(
    r: &mut GpuRenderer,
    session: &mut Session,
    camera: &Camera,
    passes: &mut Passes,
) -> Result<(crate::frame::Frame, Image, Option<render::LazyFrame>)> {
    let (frame, clip) = session.frame(camera, passes)?;
    let lazy = session.lazy_frame(clip.as_ref());
    let image = passes.time("gpu", || {
        draw_session(
            r,
            &frame,
            clip.as_ref(),
            session,
            clip.as_ref().map(|c| &c.update),
        )
    })?;
    Ok((frame, image, lazy))
}

/// Draws `frame` from the session's clipmap textures when it has a
/// clipmap, passed through otherwise.
fn draw_session(
    r: &mut GpuRenderer,
    frame: &crate::frame::Frame,
    clip: Option<&ClipFrame>,
    session: &Session,
    update: Option<&crate::clipmap::UpdateStats>,
) -> Result<Image> {
    match (clip, session.lod.clipmap()) {
        (Some(c), Some(cm)) => r.draw(
            frame,
            Some(ClipDraw {
                clipmap: cm,
                meshes: &c.meshes,
                world: &session.world,
                update,
            }),
        ),
        _ => r.draw(frame, None),
    }
}

/// Renders a scene on the GPU (`render --backend gpu`).
pub fn render(r: &mut GpuRenderer, scene: &Scene) -> Result<(Image, RenderStats)> {
    let mut passes = Passes::default();
    let mut session = Session::new(scene, &mut passes)?;
    // A new session's textures must be written in full.
    r.forget_textures();
    let (frame, image, lazy) = gpu_frame(r, &mut session, &scene.camera(), &mut passes)?;
    let mut stats = render::stats(&frame, "gpu", Default::default(), passes);
    stats.lazy = lazy;
    Ok((image, stats))
}

pub use crate::views::path_camera;

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
    let mut worst: Option<(Difference, Image, Image)> = None;
    let mut total = Difference::default();
    let mut triangles = 0;
    let mut pass = true;
    let (mut uploaded, mut full) = (0, 0);
    for i in 0..frames.max(1) {
        let cam = path_camera(&base, i, step);
        let (frame, _) = cpu.frame(&cam, &mut passes)?;
        let (want, _) = render::draw(&frame, &opts, &mut passes);
        let (gframe, got, _) = gpu_frame(r, &mut gpu, &cam, &mut passes)?;
        triangles = triangles.max(gframe.triangle_count());
        if i > 0 {
            uploaded += r.texels_uploaded();
            full += gpu
                .lod
                .clipmap()
                .map_or(0, |cm| (cm.n() * cm.n()) as u64 * cm.levels().len() as u64);
        }
        let d = Difference::of(&want, &got);
        pass &= d.passes(exact, (want.width * want.height) as usize);
        total.colour_px_differ += d.colour_px_differ;
        total.depth_px_differ += d.depth_px_differ;
        total.max_channel_diff = total.max_channel_diff.max(d.max_channel_diff);
        total.max_depth_ulp = total.max_depth_ulp.max(d.max_depth_ulp);
        let worse = worst
            .as_ref()
            .is_none_or(|w| d.colour_px_differ > w.0.colour_px_differ);
        if worse {
            worst = Some((d, want, got));
        }
    }
    if let Some((_, want, got)) = &worst {
        std::fs::create_dir_all(out).map_err(|e| crate::Error::io(out, e))?;
        write_atomic(&out.join(format!("{name}-cpu.png")), &want.png()?)?;
        write_atomic(&out.join(format!("{name}-gpu.png")), &got.png()?)?;
        let diff = crate::golden::diff(got, &want.rgba).1;
        write_atomic(&out.join(format!("{name}-diff.png")), &diff.png()?)?;
    }
    Ok(SceneParity {
        scene: name.to_string(),
        colour_px_differ: total.colour_px_differ,
        depth_px_differ: total.depth_px_differ,
        max_channel_diff: total.max_channel_diff,
        max_depth_ulp: total.max_depth_ulp,
        pass,
        triangles,
        frames: frames.max(1),
        texels_uploaded: uploaded,
        texels_full: full,
    })
}

/// `bench`: frames per second of both back ends on the same frame, warm.
#[derive(Clone, Debug, Serialize)]
pub struct Bench {
    pub cpu_fps: f64,
    pub gpu_fps: f64,
    /// cpu_fps ÷ gpu_fps.
    pub ratio: f64,
    pub adapter: String,
    pub size: [u32; 2],
    pub triangles: usize,
    pub frames: usize,
    pub repeats: usize,
    /// Per repeat, ms per frame.
    pub cpu_ms: Vec<f64>,
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
    let draw_gpu =
        |r: &mut GpuRenderer| draw_session(r, &frame, clip.as_ref(), &session, Some(&still));
    r.forget_textures();
    // Warm up both (pipeline compilation, first full upload, caches).
    draw_gpu(r)?;
    render::draw(&frame, &opts, &mut Passes::default());
    let (mut cpu_ms, mut gpu_ms) = (vec![], vec![]);
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        for _ in 0..frames {
            std::hint::black_box(render::draw(&frame, &opts, &mut Passes::default()));
        }
        cpu_ms.push(t.elapsed().as_secs_f64() * 1e3 / frames as f64);
        let t = Instant::now();
        for _ in 0..frames {
            std::hint::black_box(draw_gpu(r)?);
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
