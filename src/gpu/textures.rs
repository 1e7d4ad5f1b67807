//! GPU-side textures: the clipmap's toroidal levels (heights, and slopes for
//! per-vertex normals), the lightmap and normal-map atlases, and readback.

use super::Gpu;
use crate::clipmap::toroid::{TexRect, TexRects, Toroid};
use crate::clipmap::{Clipmap, UpdateStats};
use crate::error::{Error, Result};
use crate::raster::Image;
use crate::shade::normal_map::NormalMap;
use crate::shade::normals;
use crate::shade::shadows::Lightmap;
use crate::terrain::world::WorldMap;

fn texture(gpu: &Gpu, size: [u32; 3], format: wgpu::TextureFormat, label: &str) -> wgpu::Texture {
    texture_for(gpu, size, format, label, wgpu::TextureUsages::empty())
}

/// A toroid layer stack: also written by the GPU's update pass and read
/// back by `check-gpu`.
pub(super) fn toroid_texture(
    gpu: &Gpu,
    size: [u32; 3],
    format: wgpu::TextureFormat,
    label: &str,
) -> wgpu::Texture {
    let storage = if gpu.toroid_storage {
        wgpu::TextureUsages::STORAGE_BINDING
    } else {
        wgpu::TextureUsages::empty()
    };
    let extra = storage | wgpu::TextureUsages::COPY_SRC;
    texture_for(gpu, size, format, label, extra)
}

fn texture_for(
    gpu: &Gpu,
    size: [u32; 3],
    format: wgpu::TextureFormat,
    label: &str,
    extra: wgpu::TextureUsages,
) -> wgpu::Texture {
    gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: size[0].max(1),
            height: size[1].max(1),
            depth_or_array_layers: size[2].max(1),
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST | extra,
        view_formats: &[],
    })
}

/// Writes `data` (rows of `row_texels` texels of `texel` bytes) into the
/// rectangle at (x, y) of layer `layer`.
fn write(gpu: &Gpu, t: &wgpu::Texture, at: [u32; 3], size: [u32; 2], data: &[u8], row_bytes: u32) {
    gpu.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: t,
            mip_level: 0,
            origin: wgpu::Origin3d {
                x: at[0],
                y: at[1],
                z: at[2],
            },
            aspect: wgpu::TextureAspect::All,
        },
        data,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(row_bytes),
            rows_per_image: Some(size[1]),
        },
        wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        },
    );
}

/// Array layers for `levels` toroids: one each, and one unused more when
/// that would make a multiple of 6. wgpu's GL back end fixes a texture's
/// GL target when it is made, from its shape alone: a square 2D texture
/// with 6k layers becomes a cube map (wgpu-hal's `gles`
/// `Texture::get_info_from_desc`), and a cube map bound where the shader
/// reads a 2D array reads zeros. On GL, a 6-level clipmap drew flat.
fn array_layers(levels: usize) -> u32 {
    let extra = usize::from(levels % 6 == 0);
    (levels + extra) as u32
}

/// One n×n layer per clipmap level, mirroring each level's toroid.
pub struct ToroidTextures {
    pub heights: wgpu::Texture,
    pub gradients: wgpu::Texture,
    n: usize,
    layers: usize,
    has_gradients: bool,
    /// Texels written by the last sync (for the statistics).
    pub texels_written: u64,
}

impl ToroidTextures {
    /// Placeholders for draws that use no clipmap.
    pub fn empty(gpu: &Gpu) -> Self {
        ToroidTextures {
            heights: toroid_texture(gpu, [1, 1, 1], wgpu::TextureFormat::R32Float, "heights"),
            gradients: toroid_texture(gpu, [1, 1, 1], wgpu::TextureFormat::Rg32Float, "slopes"),
            n: 0,
            layers: 0,
            has_gradients: false,
            texels_written: 0,
        }
    }

    /// Brings the textures up to date with `cm`: only the update's dirty
    /// rectangles when the textures already mirror the previous state,
    /// everything otherwise. The levels `on_gpu` marks are not uploaded:
    /// their rectangles come back, for the GPU's update pass.
    pub fn sync(
        &mut self,
        gpu: &Gpu,
        cm: &Clipmap,
        world: &WorldMap,
        update: Option<&UpdateStats>,
        need_gradients: bool,
        on_gpu: &[bool],
    ) -> Vec<(usize, TexRects)> {
        let n = cm.n() as usize;
        let layers = cm.levels().len();
        let fresh = self.n != n || self.layers != layers;
        let size = [n as u32, n as u32, array_layers(layers)];
        if fresh {
            self.heights = toroid_texture(gpu, size, wgpu::TextureFormat::R32Float, "heights");
            self.n = n;
            self.layers = layers;
            self.has_gradients = false;
        }
        let full_gradients = need_gradients && !self.has_gradients;
        if full_gradients {
            self.gradients = toroid_texture(gpu, size, wgpu::TextureFormat::Rg32Float, "slopes");
            self.has_gradients = true;
        }
        let all = TexRect {
            x0: 0,
            y0: 0,
            x1: n,
            y1: n,
        };
        self.texels_written = 0;
        let mut jobs = Vec::new();
        for l in 0..cm.levels().len() {
            let rects: TexRects = match update {
                Some(u) if !fresh => u.rects_per_level.get(l).copied().unwrap_or_default(),
                _ => TexRects::one(all),
            };
            if on_gpu.get(l).copied().unwrap_or(false) {
                // New slopes need the whole layer; its heights come out the
                // same where they were already right.
                let r = if full_gradients {
                    TexRects::one(all)
                } else {
                    rects
                };
                if !r.is_empty() {
                    jobs.push((l, r));
                }
                continue;
            }
            let grads = if full_gradients {
                TexRects::one(all)
            } else {
                rects
            };
            self.upload(gpu, cm, world, l, &rects, &grads);
        }
        jobs
    }

    /// Uploads the CPU's heights of level `l` over `rects`, and its slopes
    /// over `grads` where slopes are in use.
    pub fn upload(
        &mut self,
        gpu: &Gpu,
        cm: &Clipmap,
        world: &WorldMap,
        l: usize,
        rects: &TexRects,
        grads: &TexRects,
    ) {
        let n = self.n;
        let heights = cm.levels()[l].heights.texels();
        for r in rects {
            let (w, h) = ((r.x1 - r.x0) as u32, (r.y1 - r.y0) as u32);
            let data: &[f32] = &heights[r.y0 * n + r.x0..];
            let rows = (h as usize - 1) * n + w as usize;
            write(
                gpu,
                &self.heights,
                [r.x0 as u32, r.y0 as u32, l as u32],
                [w, h],
                bytemuck::cast_slice(&data[..rows]),
                4 * n as u32,
            );
            self.texels_written += r.area() as u64;
        }
        if self.has_gradients {
            for r in grads {
                self.write_gradients(gpu, cm, world, l, r);
            }
        }
    }

    /// Whether the slopes texture is in use.
    pub fn has_gradients(&self) -> bool {
        self.has_gradients
    }

    /// Slopes of level `l` over toroid rectangle `r`, by the CPU's own
    /// `normals::gradient` (its f64 scale factors, rounded to f32, are all
    /// a shader needs to repeat it).
    fn write_gradients(&self, gpu: &Gpu, cm: &Clipmap, world: &WorldMap, l: usize, r: &TexRect) {
        let Some(data) = slopes(cm, world, l, r) else {
            return;
        };
        let w = (r.x1 - r.x0) as u32;
        write(
            gpu,
            &self.gradients,
            [r.x0 as u32, r.y0 as u32, l as u32],
            [w, (r.y1 - r.y0) as u32],
            bytemuck::cast_slice(&data),
            8 * w,
        );
    }
}

/// The CPU's slopes of level `l` over toroid rectangle `r` (`None` for a
/// level with no window).
pub(crate) fn slopes(
    cm: &Clipmap,
    world: &WorldMap,
    l: usize,
    r: &TexRect,
) -> Option<Vec<[f32; 2]>> {
    let o = cm.levels()[l].heights.origin()?;
    let p = &cm.pyramid().levels[l];
    let s = cm.n() as usize;
    let spacing = (1u64 << l) as f64;
    let mut data = Vec::with_capacity(r.area());
    for ty in r.y0..r.y1 {
        let y = Toroid::<f32>::world_of(ty, o[1], s);
        for tx in r.x0..r.x1 {
            let x = Toroid::<f32>::world_of(tx, o[0], s);
            data.push(normals::gradient(p, x, y, spacing, world));
        }
    }
    Some(data)
}

/// Reads back every layer of a toroid texture of `texel` bytes a texel
/// (n × n × layers), as f32 values, layer by layer, row by row.
pub(crate) fn read_layers(gpu: &Gpu, t: &wgpu::Texture, texel: u32) -> Result<Vec<f32>> {
    let (w, h, layers) = (t.width(), t.height(), t.depth_or_array_layers());
    let row = (texel * w).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
        * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("toroid readback"),
        size: row as u64 * h as u64 * layers as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: t,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(h),
            },
        },
        wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: layers,
        },
    );
    gpu.queue.submit([enc.finish()]);
    buf.slice(..).map_async(wgpu::MapMode::Read, |_| {});
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::value("gpu", format!("readback failed: {e}")))?;
    let view = buf
        .slice(..)
        .get_mapped_range()
        .map_err(|e| Error::value("gpu", format!("readback failed: {e}")))?;
    let mut out = Vec::with_capacity((w * h * layers * texel / 4) as usize);
    for r in 0..(h * layers) as usize {
        let bytes = &view[r * row as usize..r * row as usize + (texel * w) as usize];
        out.extend(
            bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])),
        );
    }
    Ok(out)
}

/// Per-level images stacked vertically in one texture; `rows[l]` is level
/// l's first row.
pub struct Atlas {
    pub texture: wgpu::Texture,
    rows: Vec<i32>,
}

impl Atlas {
    pub fn row(&self, l: usize) -> i32 {
        self.rows.get(l).copied().unwrap_or(0)
    }

    fn check(gpu: &Gpu, w: usize, h: usize, what: &str) -> Result<()> {
        let max = gpu.device.limits().max_texture_dimension_2d as usize;
        if w > max || h > max {
            return Err(Error::value(
                "gpu",
                format!("{what} atlas {w}×{h} exceeds the adapter's {max} texels"),
            ));
        }
        Ok(())
    }

    /// Stacks `parts` (size and texel bytes, or none) one under another in
    /// a `format` texture with `texel` bytes per texel; `rows` gets each
    /// part's first row (an absent part gets the row the next one starts).
    fn stack(
        gpu: &Gpu,
        what: &str,
        format: wgpu::TextureFormat,
        texel: u32,
        parts: &[Option<([usize; 2], &[u8])>],
    ) -> Result<Atlas> {
        let w = parts.iter().flatten().map(|p| p.0[0]).max().unwrap_or(1);
        let h: usize = parts.iter().flatten().map(|p| p.0[1]).sum();
        Self::check(gpu, w, h, what)?;
        let texture = texture(gpu, [w as u32, h as u32, 1], format, what);
        let mut rows = vec![];
        let mut y = 0;
        for part in parts {
            rows.push(y as i32);
            if let Some((size, data)) = part {
                let sz = [size[0] as u32, size[1] as u32];
                write(gpu, &texture, [0, y as u32, 0], sz, data, texel * sz[0]);
                y += size[1];
            }
        }
        Ok(Atlas { texture, rows })
    }

    /// The lightmap's pyramid, one R32Float level under another.
    pub fn lightmap(gpu: &Gpu, lm: Option<&Lightmap>) -> Result<Atlas> {
        let levels = lm.map_or(&[][..], |l| &l.pyramid.levels[..]);
        let parts: Vec<_> = levels
            .iter()
            .map(|p| Some(([p.width, p.height], bytemuck::cast_slice(&p.data))))
            .collect();
        Self::stack(gpu, "lightmap", wgpu::TextureFormat::R32Float, 4, &parts)
    }

    /// The drawn levels' normal maps, RGBA32Float (xyz used).
    pub fn normal_maps(gpu: &Gpu, maps: &[Option<NormalMap>]) -> Result<Atlas> {
        let data: Vec<Option<Vec<[f32; 4]>>> = maps
            .iter()
            .map(|m| {
                m.as_ref()
                    .map(|m| m.data.iter().map(|n| [n[0], n[1], n[2], 0.0]).collect())
            })
            .collect();
        let parts: Vec<_> = maps
            .iter()
            .zip(&data)
            .map(|(m, d)| match (m, d) {
                (Some(m), Some(d)) => Some((m.size, bytemuck::cast_slice(d))),
                _ => None,
            })
            .collect();
        Self::stack(
            gpu,
            "normal-map",
            wgpu::TextureFormat::Rgba32Float,
            16,
            &parts,
        )
    }
}

/// Submits `enc` with copies of the colour and depth targets appended and
/// returns them, unpadding the 256-byte rows.
pub fn read_back(
    gpu: &Gpu,
    mut enc: wgpu::CommandEncoder,
    colour: &wgpu::Texture,
    depth: &wgpu::Texture,
    w: u32,
    h: u32,
) -> Result<Image> {
    let row =
        (4 * w).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let size = row as u64 * h as u64;
    let buf = |label| {
        gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let (cb, db) = (buf("colour readback"), buf("depth readback"));
    // wgpu's GL backend cannot copy depth out; GL images carry no depth.
    let with_depth = gpu.api != super::Api::Gl;
    let extent = wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: 1,
    };
    let copies = [
        (colour, &cb, wgpu::TextureAspect::All),
        (depth, &db, wgpu::TextureAspect::DepthOnly),
    ];
    for (tex, b, aspect) in copies.into_iter().take(1 + with_depth as usize) {
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: tex,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: b,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(h),
                },
            },
            extent,
        );
    }
    gpu.queue.submit([enc.finish()]);
    for b in [&cb, &db].into_iter().take(1 + with_depth as usize) {
        b.slice(..).map_async(wgpu::MapMode::Read, |_| {});
    }
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::value("gpu", format!("readback failed: {e}")))?;
    let unpad = |b: &wgpu::Buffer| -> Result<Vec<u8>> {
        let view = b
            .slice(..)
            .get_mapped_range()
            .map_err(|e| Error::value("gpu", format!("readback failed: {e}")))?;
        let mut out = Vec::with_capacity((4 * w * h) as usize);
        for r in 0..h as usize {
            out.extend_from_slice(&view[r * row as usize..r * row as usize + 4 * w as usize]);
        }
        Ok(out)
    };
    let rgba = unpad(&cb)?;
    if !with_depth {
        return Ok(Image {
            width: w,
            height: h,
            rgba,
            depth: vec![],
        });
    }
    let depth: Vec<f32> = unpad(&db)?
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(Image {
        width: w,
        height: h,
        rgba,
        depth,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn toroid_arrays_never_have_a_multiple_of_6_layers() {
        let layers: Vec<u32> = (1..=13).map(super::array_layers).collect();
        assert_eq!(layers, [1, 2, 3, 4, 5, 7, 7, 8, 9, 10, 11, 13, 13]);
    }
}
