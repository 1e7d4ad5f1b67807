//! The wgpu back end as a study's second renderer (`tradeoff --gpu`,
//! `fly --gpu`): each frame it draws, and what the frame cost the device,
//! counted from what the back end wrote. Without the `gpu` feature it
//! cannot be opened, and says so.

use crate::camera::Camera;
use crate::error::Result;
use crate::render::Session;
use serde::{Deserialize, Serialize};

/// What one frame cost the device.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct FrameGpu {
    /// Bytes written to the device: uniforms, changed vertex and index
    /// words, toroid texels, atlases.
    pub upload_bytes: u64,
    /// Draw calls issued.
    pub draw_calls: u64,
    /// The render pass's time on the GPU's clock (ms); `None` where the
    /// adapter has no timestamp queries.
    pub ms: Option<f64>,
}

/// The back end, or nothing when a study was not asked to draw on it.
pub struct GpuSide {
    #[cfg(feature = "gpu")]
    r: Option<crate::gpu::GpuRenderer>,
}

impl GpuSide {
    /// The first Vulkan adapter's renderer when `want`, else none.
    pub fn open(want: bool) -> Result<GpuSide> {
        #[cfg(feature = "gpu")]
        {
            use crate::gpu::{Api, Gpu, GpuRenderer};
            let r = match want {
                true => Some(GpuRenderer::new(Gpu::new(Api::Vulkan)?)),
                false => None,
            };
            Ok(GpuSide { r })
        }
        #[cfg(not(feature = "gpu"))]
        match want {
            true => Err(crate::error::Error::value(
                "--gpu",
                "this build has no GPU back end (build with the `gpu` feature)",
            )),
            false => Ok(GpuSide {}),
        }
    }

    /// The adapter's name, when open.
    pub fn adapter(&self) -> Option<String> {
        #[cfg(feature = "gpu")]
        if let Some(r) = &self.r {
            return Some(r.gpu.adapter());
        }
        None
    }

    /// Makes the next frame upload every toroid level: the session moved
    /// the clipmap without the GPU seeing its updates.
    pub fn forget(&mut self) {
        #[cfg(feature = "gpu")]
        if let Some(r) = &mut self.r {
            r.forget_textures();
        }
    }

    /// Draws `session`'s frame of `cam` (updating its LOD) and returns its
    /// cost; `None` when not open.
    pub fn frame(&mut self, session: &mut Session, cam: &Camera) -> Result<Option<FrameGpu>> {
        #[cfg(feature = "gpu")]
        if let Some(r) = &mut self.r {
            let mut passes = crate::frame::stats::Passes::default();
            crate::render::gpu::frame(r, session, cam, &mut passes)?;
            let c = r.costs();
            return Ok(Some(FrameGpu {
                upload_bytes: c.upload_bytes,
                draw_calls: c.draw_calls,
                ms: c.gpu_ms,
            }));
        }
        let _ = (session, cam);
        Ok(None)
    }
}
