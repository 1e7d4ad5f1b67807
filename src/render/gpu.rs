//! The GPU back end's side of rendering a scene: a [`Session`]'s frame
//! drawn by wgpu, the clipmap's toroids updated by the frame's dirty
//! rectangles (or by the GPU's own update pass). `render --backend gpu`,
//! `check-gpu` and `bench` all draw through here.

use super::{ClipFrame, Image, LazyFrame, RenderStats, Session};
use crate::camera::Camera;
use crate::error::Result;
use crate::frame::stats::Passes;
use crate::gpu::{ClipDraw, GpuRenderer};
use crate::scene::{GpuUpdate, Scene};

/// Draws `session`'s frame for `camera` on the GPU (the clipmap path when the
/// scene has a clipmap), with the update since the previous call; also the
/// lazy pyramid's state after it, for a lazy scene.
pub fn frame(
    r: &mut GpuRenderer,
    session: &mut Session,
    camera: &Camera,
    passes: &mut Passes,
) -> Result<(crate::frame::Frame, Image, Option<LazyFrame>)> {
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
pub fn draw_session(
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
                gpu_update: session.gpu_update == GpuUpdate::Gpu,
                synthesis: session
                    .synthesis
                    .as_ref()
                    .filter(|_| session.gpu_update == GpuUpdate::Gpu),
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
    let (frame, image, lazy) = frame(r, &mut session, &scene.camera(), &mut passes)?;
    let mut stats = super::stats(
        &frame,
        super::Drawn::of(&frame),
        super::Backend::Gpu.name(),
        Default::default(),
        passes,
    );
    stats.lazy = lazy;
    Ok((image, stats))
}
