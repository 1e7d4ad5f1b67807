//! The wgpu back end: the same [`Frame`] the CPU rasteriser draws, drawn by a
//! GPU, so terraclip can check GPU terrain renderers (and be checked by
//! lavapipe, which follows docs/reference/raster-rules.md exactly).
//!
//! It does what GPU clipmaps do (GPU Gems 2 ch. 2): heights live in one
//! toroidal texture layer per level, rewritten only in the update's dirty
//! rectangles; the vertex shader fetches z and the coarser level's z_c with
//! `textureLoad` and morphs by α; footprint layouts draw static shapes
//! translated per block, strip layouts draw the per-frame index list over the
//! toroid (Brettell). Effects run in the fragment shader, reading the
//! lightmap and normal maps as textures with explicit texel loads.
//!
//! Meshes no clipmap made (brute force, ROAM, CBT, …) are drawn on Vulkan
//! from a resident buffer of their view-independent vertices, which the
//! shader transforms each frame as the CPU vertex stage does. Frames with
//! no grid places (read back from an export), and every CPU-made mesh on
//! GL, are passed through instead: the CPU vertex stage's clip positions
//! and varyings, written each frame. GL's compiler may fuse the shader's
//! multiply-adds, and on the CBT golden that put 176 pixels outside the
//! tie band that the passed-through vertices stay within.
//!
//! Buffers persist across frames and only their changed words are written,
//! and every write is counted ([`Gpu::uploaded`]), so a frame's
//! [`FrameCosts`] say what a GPU renderer built this way uploads, how many
//! draw calls it makes, and, where the adapter has timestamp queries, how
//! long the GPU took.

pub(crate) mod device;
mod textures;
pub(crate) mod uniforms;
mod update;

pub use device::{Api, Gpu};

use crate::clipmap::footprint::{self, ShapeId};
use crate::clipmap::{Clipmap, LevelGeometry, LevelMesh, UpdateStats};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::raster::unorm8;
use crate::raster::Image;
use crate::shade::{level_tint, Effects};
use crate::terrain::world::WorldMap;
use std::collections::HashMap;
use textures::{Atlas, ToroidTextures};
use uniforms::{
    Draw, Globals, MeshVertex, PassVertex, MAX_LEVELS, MODE_FOOTPRINT, MODE_MESH, MODE_PASSTHROUGH,
    MODE_STRIPS,
};

/// The terrain shader, after the helpers it shares with the update pass.
pub(crate) const SHADER: &str = concat!(
    include_str!("shaders/wrap.wgsl"),
    include_str!("shaders/terrain.wgsl")
);
/// Bytes of one `Draw` uniform slot (the dynamic-offset alignment).
const DRAW_STRIDE: u64 = 256;

/// What a clipmap contributes to a GPU draw besides the frame.
pub struct ClipDraw<'a> {
    /// The clipmap whose toroids the draw samples.
    pub clipmap: &'a Clipmap,
    /// The frame's level meshes.
    pub meshes: &'a [LevelMesh],
    /// Grid-to-world placement.
    pub world: &'a WorldMap,
    /// The update since the last draw; `None` uploads every level in full.
    pub update: Option<&'a UpdateStats>,
    /// `[gpu] update = "gpu"`: the GPU's update pass makes the levels it
    /// can (synthesised ones, and those of a pack coded against the
    /// upsampled coarser level) instead of the CPU uploading them.
    pub gpu_update: bool,
    /// With synthesised levels: how they are made, for the update pass.
    pub synthesis: Option<&'a crate::synthesis::source::Continuation>,
}

/// The GPU's toroid texels against the CPU's ([`GpuRenderer::check_toroids`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TexelCheck {
    /// Texel values compared (heights and slope components).
    pub checked: u64,
    /// Those whose bits differ.
    pub differ: u64,
    /// Of those, heights (the rest are slope components): a slope is a
    /// difference of heights times a scale, so slopes alone differing
    /// points at how the GPU evaluates that product, heights at the
    /// synthesis or the residuals.
    pub heights_differ: u64,
    /// The largest difference in units in the last place.
    pub max_ulp: u64,
    /// The largest among heights.
    pub heights_max_ulp: u64,
}

impl TexelCheck {
    fn add(&mut self, cpu: &[f32], gpu: &[f32], heights: bool) {
        for (&a, &b) in cpu.iter().zip(gpu) {
            self.checked += 1;
            if a.to_bits() != b.to_bits() {
                let ulp = crate::raster::ulp_distance(a, b);
                self.differ += 1;
                self.max_ulp = self.max_ulp.max(ulp);
                if heights {
                    self.heights_differ += 1;
                    self.heights_max_ulp = self.heights_max_ulp.max(ulp);
                }
            }
        }
    }

    /// Sums `o` into this one.
    pub fn merge(&mut self, o: &TexelCheck) {
        self.checked += o.checked;
        self.differ += o.differ;
        self.heights_differ += o.heights_differ;
        self.max_ulp = self.max_ulp.max(o.max_ulp);
        self.heights_max_ulp = self.heights_max_ulp.max(o.heights_max_ulp);
    }
}

/// What `GpuRenderer::draw_list` builds: per-draw uniforms with the index
/// range each draws, and the buffers those ranges index.
struct DrawList {
    draws: Vec<(Draw, std::ops::Range<u32>)>,
    strips: Vec<u32>,
    mesh: Vec<MeshVertex>,
    passthrough: Vec<PassVertex>,
}

/// What one [`GpuRenderer::draw`] cost the device: the figures a GPU
/// renderer's frame is judged by besides its image.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameCosts {
    /// Bytes written to the device in the frame: uniforms, the changed
    /// words of the index and vertex buffers, toroid texels, residuals,
    /// and the shading atlases.
    pub upload_bytes: u64,
    /// Draw calls issued.
    pub draw_calls: u64,
    /// The render pass's time on the GPU's clock (ms), from timestamp
    /// queries; `None` where the adapter has none.
    pub gpu_ms: Option<f64>,
}

/// A storage buffer kept across frames: each frame writes only the runs of
/// 32-bit words that differ from what it holds, so the upload counted is
/// the change, as a renderer keeping its geometry resident would send.
struct Resident {
    buffer: wgpu::Buffer,
    /// What the buffer holds, for the next frame's comparison.
    held: Vec<u32>,
}

/// Words equal between runs shorter than this are written with them: one
/// write of a few extra bytes costs less than two writes.
const RUN_GAP_WORDS: usize = 8;

/// The runs of `new` to write over `old` (word ranges): words past `old`'s
/// end are all written, and runs closer than [`RUN_GAP_WORDS`] are joined.
fn changed_runs(old: &[u32], new: &[u32]) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = vec![];
    for (i, w) in new.iter().enumerate() {
        if old.get(i) == Some(w) {
            continue;
        }
        match runs.last_mut() {
            Some(r) if i - r.end < RUN_GAP_WORDS => r.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    runs
}

impl Resident {
    /// Makes the buffer hold `words` (its first `words.len()`), writing
    /// the changed runs, or a new buffer with room to grow when it is too
    /// small.
    fn hold(
        gpu: &Gpu,
        slot: &mut Option<Resident>,
        words: &[u32],
        label: &str,
        usage: wgpu::BufferUsages,
    ) -> Result<()> {
        let need = 4 * words.len().max(4) as u64;
        // Uniform slots are bound 256 bytes at a time; storage is bound whole.
        let limits = gpu.device.limits();
        let limit = match usage.contains(wgpu::BufferUsages::UNIFORM) {
            true => limits.max_buffer_size,
            false => limits.max_storage_buffer_binding_size,
        };
        if need > limit {
            return Err(Error::value(
                "gpu",
                format!(
                    "{label}: {need} bytes exceed {}'s binding limit of {limit}",
                    gpu.adapter()
                ),
            ));
        }
        let fits = slot.as_ref().is_some_and(|r| r.buffer.size() >= need);
        if !fits {
            let size = need.next_power_of_two().min(limit);
            let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            *slot = Some(Resident {
                buffer,
                held: vec![],
            });
        }
        let r = slot.as_mut().expect("made above");
        for run in changed_runs(&r.held, words) {
            let (a, b) = (run.start, run.end);
            gpu.write_buffer(&r.buffer, 4 * a as u64, bytemuck::cast_slice(&words[a..b]));
        }
        r.held.clear();
        r.held.extend_from_slice(words);
        Ok(())
    }
}

/// Corner range of each static shape in the footprint buffer.
type ShapeRanges = HashMap<ShapeId, (u32, u32)>;

/// A device plus the pipelines and textures that persist across frames.
pub struct GpuRenderer {
    /// The device drawn on.
    pub gpu: Gpu,
    module: wgpu::ShaderModule,
    layouts: [wgpu::BindGroupLayout; 2],
    pipeline_layout: wgpu::PipelineLayout,
    pipelines: HashMap<Effects, wgpu::RenderPipeline>,
    toroid: Option<ToroidTextures>,
    /// The update pass, made when a scene first asks for it.
    update: Option<update::UpdatePass>,
    /// Toroid texels the update pass made in the last clipmap draw.
    texels_made: u64,
    /// Bytes of residuals uploaded for it.
    residual_bytes: u64,
    /// Static footprint corners for the current n: (n, buffer, range per shape).
    footprints: Option<(i64, wgpu::Buffer, ShapeRanges)>,
    /// The clipmap's strip indices, kept across frames.
    strips: Option<Resident>,
    /// Resident vertices of meshes no clipmap made.
    mesh: Option<Resident>,
    /// The per-draw uniforms (one 256-byte slot each), kept across frames.
    draw_slots: Option<Resident>,
    /// Two timestamps around the render pass, where the device has them:
    /// the query set, its resolve buffer and a mappable copy.
    timer: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
    /// What the last [`GpuRenderer::draw`] cost.
    costs: FrameCosts,
}

fn i32_of(v: i64, what: &str) -> Result<i32> {
    i32::try_from(v).map_err(|_| Error::value("gpu", format!("{what} {v} does not fit in i32")))
}

impl GpuRenderer {
    /// Compiles the shader and creates the pipelines' layouts on `gpu`.
    pub fn new(gpu: Gpu) -> Self {
        let d = &gpu.device;
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("terrain.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let vf = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let tex = |binding, dim| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: vf,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: dim,
                multisampled: false,
            },
            count: None,
        };
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let uniform = |binding, dynamic| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: vf,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: dynamic,
                min_binding_size: None,
            },
            count: None,
        };
        let g0 = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("globals"),
            entries: &[
                uniform(0, false),
                tex(1, wgpu::TextureViewDimension::D2Array),
                tex(2, wgpu::TextureViewDimension::D2Array),
                tex(3, wgpu::TextureViewDimension::D2),
                tex(4, wgpu::TextureViewDimension::D2),
            ],
        });
        let g1 = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("draw"),
            entries: &[
                uniform(0, true),
                storage(1),
                storage(2),
                storage(3),
                storage(4),
            ],
        });
        let pipeline_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("terrain"),
            bind_group_layouts: &[Some(&g0), Some(&g1)],
            immediate_size: 0,
        });
        GpuRenderer {
            gpu,
            module,
            layouts: [g0, g1],
            pipeline_layout,
            pipelines: HashMap::new(),
            toroid: None,
            update: None,
            texels_made: 0,
            residual_bytes: 0,
            footprints: None,
            strips: None,
            mesh: None,
            draw_slots: None,
            timer: None,
            costs: FrameCosts::default(),
        }
    }

    /// What the last [`GpuRenderer::draw`] uploaded, drew and took.
    pub fn costs(&self) -> FrameCosts {
        self.costs
    }

    /// Drops the toroidal textures, so the next clipmap draw uploads every
    /// level (a new session, or a clipmap that was not updated in step).
    pub fn forget_textures(&mut self) {
        self.toroid = None;
    }

    /// Texels the last clipmap draw wrote to the toroidal textures.
    pub fn texels_uploaded(&self) -> u64 {
        self.toroid.as_ref().map_or(0, |t| t.texels_written)
    }

    /// Texels the GPU's update pass made in the last clipmap draw
    /// (`[gpu] update = "gpu"`), none of them uploaded.
    pub fn texels_made(&self) -> u64 {
        self.texels_made
    }

    /// How many of `cm`'s levels the GPU's update pass makes with
    /// `[gpu] update = "gpu"` (slopes too with `slopes`; synthesised
    /// levels with `synthesis`).
    pub fn update_levels(cm: &Clipmap, slopes: bool, synthesis: bool) -> usize {
        update::UpdatePass::levels(cm, slopes, synthesis)
            .iter()
            .filter(|&&m| m)
            .count()
    }

    /// Bytes of residuals the update pass was given in the last clipmap
    /// draw (a pack's levels made on the GPU).
    pub fn residual_bytes(&self) -> u64 {
        self.residual_bytes
    }

    /// Times the update of `cm`'s synthesised levels both ways, after
    /// bringing the map's own levels up to date: the CPU's texels (and
    /// slopes, with `slopes`) uploaded over the update's rectangles, and
    /// the GPU's update pass making them; each waited for. Returns
    /// (upload ms, pass ms, texels).
    pub fn time_update(
        &mut self,
        cm: &Clipmap,
        world: &WorldMap,
        how: Option<&crate::synthesis::source::Continuation>,
        update: Option<&UpdateStats>,
        slopes: bool,
    ) -> Result<(f64, f64, u64)> {
        let wait = |gpu: &Gpu| {
            gpu.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map(|_| ())
                .map_err(|e| Error::value("gpu", format!("wait failed: {e}")))
        };
        let on_gpu = update::UpdatePass::levels(cm, slopes, how.is_some());
        let tt = self
            .toroid
            .get_or_insert_with(|| ToroidTextures::empty(&self.gpu));
        let jobs = tt.sync(&self.gpu, cm, world, update, slopes, &on_gpu);
        self.gpu.queue.submit([]);
        wait(&self.gpu)?;
        let t = std::time::Instant::now();
        for (l, rects) in &jobs {
            tt.upload(&self.gpu, cm, world, *l, rects, rects);
        }
        self.gpu.queue.submit([]);
        wait(&self.gpu)?;
        let upload = t.elapsed().as_secs_f64() * 1e3;
        let pass = self
            .update
            .get_or_insert_with(|| update::UpdatePass::new(&self.gpu));
        let t = std::time::Instant::now();
        let (made, _) = pass.run(&self.gpu, tt, cm, world, how, &jobs);
        wait(&self.gpu)?;
        Ok((upload, t.elapsed().as_secs_f64() * 1e3, made))
    }

    /// Every level's toroid texels (heights, and slopes where they are in
    /// use) read back and compared with the CPU's for `cm`: what
    /// `check-gpu` asks after each update, before any image.
    pub fn check_toroids(&self, cm: &Clipmap, world: &WorldMap) -> Result<TexelCheck> {
        let Some(tt) = &self.toroid else {
            return Ok(TexelCheck::default());
        };
        let n = cm.n() as usize;
        let heights = textures::read_layers(&self.gpu, &tt.heights, 4)?;
        let slopes = if tt.has_gradients() {
            Some(textures::read_layers(&self.gpu, &tt.gradients, 8)?)
        } else {
            None
        };
        let mut c = TexelCheck::default();
        let all = crate::clipmap::toroid::TexRect {
            x0: 0,
            y0: 0,
            x1: n,
            y1: n,
        };
        for (l, lv) in cm.levels().iter().enumerate() {
            if lv.heights.origin().is_none() {
                continue;
            }
            let gpu = &heights[l * n * n..(l + 1) * n * n];
            c.add(lv.heights.texels(), gpu, true);
            if let (Some(s), Some(cpu)) = (&slopes, textures::slopes(cm, world, l, &all)) {
                let cpu: Vec<f32> = cpu.iter().flatten().copied().collect();
                c.add(&cpu, &s[2 * l * n * n..2 * (l + 1) * n * n], false);
            }
        }
        Ok(c)
    }

    /// The pipeline for an effect set: effects are override constants, so an
    /// effect the scene does not list is compiled out of both stages.
    fn pipeline(&mut self, e: &Effects) -> &wgpu::RenderPipeline {
        let (d, module, layout) = (&self.gpu.device, &self.module, &self.pipeline_layout);
        self.pipelines.entry(*e).or_insert_with(|| {
            let b = |v: bool| if v { 1.0 } else { 0.0 };
            let constants = [
                ("LIT", b(e.lit())),
                ("PHONG", b(e.phong)),
                ("FOG", b(e.fog)),
                ("SHADOWS", b(e.shadows)),
                ("NORMAL_MAP", b(e.normal_map)),
                ("VERTEX_NORMALS", b(e.lit() && !e.normal_map)),
                ("LEVEL_TINT", b(e.level_tint)),
                ("WIREFRAME", b(e.wireframe)),
            ];
            let opts = wgpu::PipelineCompilationOptions {
                constants: &constants,
                zero_initialize_workgroup_memory: true,
            };
            d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("terrain"),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some("vs_main"),
                    compilation_options: opts.clone(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: wgpu::TextureFormat::Depth32Float,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module,
                    entry_point: Some("fs_main"),
                    compilation_options: opts,
                    targets: &[Some(wgpu::ColorTargetState {
                        format: wgpu::TextureFormat::Rgba8Unorm,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        })
    }

    /// The static footprint corners for grid size n, built once per n.
    fn footprint_buffer(&mut self, cm: &Clipmap) {
        let n = cm.n();
        if self.footprints.as_ref().is_some_and(|f| f.0 == n) {
            return;
        }
        let fp = cm.footprints();
        let mut ids = vec![
            ShapeId::Block,
            ShapeId::FixupVertical,
            ShapeId::FixupHorizontal,
            ShapeId::Centre,
        ];
        ids.extend((0..4).map(ShapeId::Trim));
        let mut corners: Vec<[i32; 2]> = vec![];
        let mut ranges = HashMap::new();
        for id in ids {
            let s = fp.shape(id);
            let start = corners.len() as u32;
            for t in &s.triangles {
                corners.extend(t.iter().map(|&k| s.vertices[k as usize]));
            }
            ranges.insert(id, (start, corners.len() as u32));
        }
        let buf = self.gpu.buffer_init(
            "footprints",
            bytemuck::cast_slice(&corners),
            wgpu::BufferUsages::STORAGE,
        );
        self.footprints = Some((n, buf, ranges));
    }

    /// The per-draw uniforms and the geometry they index: a clipmap's
    /// level strips and footprint instances (its toroid textures synced
    /// first), or runs of passed-through triangles, one per level.
    fn draw_list(&mut self, frame: &Frame, clip: Option<&ClipDraw>) -> Result<DrawList> {
        let u = &frame.uniforms;
        let e = frame.effects;
        let need_gradients = e.lit() && !e.normal_map;
        let mut draws: Vec<(Draw, std::ops::Range<u32>)> = vec![];
        let mut strips: Vec<u32> = vec![];
        let mut mesh: Vec<MeshVertex> = vec![];
        let mut passthrough: Vec<PassVertex> = vec![];
        if let Some(c) = clip {
            let cm = c.clipmap;
            let tt = self
                .toroid
                .get_or_insert_with(|| ToroidTextures::empty(&self.gpu));
            // The levels the GPU makes itself: those whose windows read
            // only their coarser level's (the rest uploaded).
            let on_gpu = match c.gpu_update {
                true => update::UpdatePass::levels(cm, need_gradients, c.synthesis.is_some()),
                false => vec![],
            };
            if on_gpu.contains(&true) && !self.gpu.toroid_storage {
                return Err(Error::value(
                    "[gpu] update",
                    format!(
                        "'gpu' needs storage textures of R32Float and Rg32Float, which {} \
                         does not allow (GL's downlevel rules); use update = \"cpu\"",
                        self.gpu.adapter()
                    ),
                ));
            }
            let jobs = tt.sync(&self.gpu, cm, c.world, c.update, need_gradients, &on_gpu);
            (self.texels_made, self.residual_bytes) = (0, 0);
            if !jobs.is_empty() {
                let pass = self
                    .update
                    .get_or_insert_with(|| update::UpdatePass::new(&self.gpu));
                (self.texels_made, self.residual_bytes) =
                    pass.run(&self.gpu, tt, cm, c.world, c.synthesis, &jobs);
            }
            self.footprint_buffer(cm);
            let n = cm.n();
            for mesh in c.meshes {
                let l = mesh.level;
                let lv = &cm.levels()[l];
                let o = lv.regions.origin;
                let g = 1i64 << l;
                let m = &lv.morph;
                let rel = [
                    i32_of(o[0] * g - u.origin[0], "window offset")?,
                    i32_of(u.origin[1] - o[1] * g, "window offset")?,
                ];
                let base = Draw {
                    level: [l as i32, g as i32, n as i32, MODE_STRIPS],
                    origin: [
                        i32_of(o[0], "window origin")?,
                        i32_of(o[1], "window origin")?,
                        o[0].rem_euclid(n) as i32,
                        o[1].rem_euclid(n) as i32,
                    ],
                    rel: [rel[0], rel[1], 0, 0],
                    morph: [m.viewer[0], m.viewer[1], m.half, m.width],
                    boundary: m.boundary,
                    stitched: m.stitched.map(i32::from),
                    flags: [m.enabled as i32, m.enabled as i32, 0, 0],
                };
                // Toroid address → window-local index: the list then
                // changes only where the level's regions move within the
                // window, not each time the window scrolls.
                let t0 = [o[0].rem_euclid(n), o[1].rem_euclid(n)];
                let local = |i: u32| {
                    let (x, y) = (i as i64 % n, i as i64 / n);
                    ((x - t0[0]).rem_euclid(n) + n * (y - t0[1]).rem_euclid(n)) as u32
                };
                let mut slot = |mode: i32, inst: [i32; 2], range: std::ops::Range<u32>| {
                    let mut d = base;
                    d.level[3] = mode;
                    d.rel[2..].copy_from_slice(&inst);
                    draws.push((d, range));
                };
                match &mesh.geometry {
                    LevelGeometry::Strips { strip } => {
                        let start = strips.len() as u32;
                        for t in footprint::strip_to_triangles(strip).iter() {
                            strips.extend(t.iter().map(|&i| local(i)));
                        }
                        slot(MODE_STRIPS, [0, 0], start..strips.len() as u32);
                    }
                    LevelGeometry::Footprints { instances, edge } => {
                        let ranges = &self.footprints.as_ref().expect("built").2;
                        for i in instances {
                            let (a, b) = ranges[&i.shape];
                            let off = [(i.offset[0] - o[0]) as i32, (i.offset[1] - o[1]) as i32];
                            slot(MODE_FOOTPRINT, off, a..b);
                        }
                        // Blocks crossing the map edge: pulled like strips.
                        if !edge.is_empty() {
                            let start = strips.len() as u32;
                            for t in edge {
                                strips.extend(t.iter().map(|&i| local(i)));
                            }
                            slot(MODE_STRIPS, [0, 0], start..strips.len() as u32);
                        }
                    }
                }
            }
        } else if frame.mesh.vertices.len() == frame.positions.len() && self.gpu.api == Api::Vulkan
        {
            mesh = Self::mesh_vertices(frame)?;
            let origin = [
                i32_of(u.origin[0], "floating origin")?,
                i32_of(u.origin[1], "floating origin")?,
                0,
                0,
            ];
            Self::level_draws(frame, MODE_MESH, origin, &mut draws);
        } else {
            passthrough = Self::passed_through(frame);
            Self::level_draws(frame, MODE_PASSTHROUGH, [0; 4], &mut draws);
        }

        Ok(DrawList {
            draws,
            strips,
            mesh,
            passthrough,
        })
    }

    /// One draw of `mode` per run of the frame's triangles on one level.
    fn level_draws(
        frame: &Frame,
        mode: i32,
        origin: [i32; 4],
        draws: &mut Vec<(Draw, std::ops::Range<u32>)>,
    ) {
        for (l, t, end) in crate::lod::LodMesh::level_runs(&frame.mesh.levels) {
            let d = Draw {
                level: [l as i32, 1, 1, mode],
                origin,
                ..Default::default()
            };
            draws.push((d, 3 * t as u32..3 * end as u32));
        }
    }

    /// The frame's mesh as resident vertices: grid places, heights and
    /// morph from the LOD scheme, normals and level texel coordinates from
    /// the CPU vertex stage (view-independent both).
    fn mesh_vertices(frame: &Frame) -> Result<Vec<MeshVertex>> {
        let lay = &frame.layout;
        let k = lay.len();
        frame
            .mesh
            .vertices
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let a = &frame.attrs[i * k..(i + 1) * k];
                let mut m = MeshVertex {
                    grid: [
                        i32_of(v.col, "vertex column")?,
                        i32_of(v.row, "vertex row")?,
                    ],
                    offset: v.offset,
                    z: v.z,
                    zc: v.zc,
                    alpha: v.alpha,
                    ..Default::default()
                };
                if let Some(s) = lay.normal {
                    m.normal.copy_from_slice(&a[s..s + 3]);
                }
                if let Some(s) = lay.uv {
                    m.uv.copy_from_slice(&a[s..s + 2]);
                }
                Ok(m)
            })
            .collect()
    }

    /// The CPU vertex stage's clip positions and varyings.
    fn passed_through(frame: &Frame) -> Vec<PassVertex> {
        let u = &frame.uniforms;
        let lay = &frame.layout;
        let k = lay.len();
        (0..frame.positions.len())
            .map(|i| {
                let a = &frame.attrs[i * k..(i + 1) * k];
                let get = |dst: &mut [f32], src: Option<usize>| {
                    if let Some(s) = src {
                        dst.copy_from_slice(&a[s..s + dst.len()]);
                    }
                };
                let mut v = PassVertex {
                    clip: u.clip(frame.positions[i]),
                    ..Default::default()
                };
                get(&mut v.albedo, lay.albedo);
                get(&mut v.normal, lay.normal);
                get(&mut v.uv, lay.uv);
                get(std::slice::from_mut(&mut v.alpha), lay.alpha);
                get(std::slice::from_mut(&mut v.fog), lay.fog);
                get(&mut v.view, lay.view);
                get(&mut v.edge, lay.edge);
                v
            })
            .collect()
    }

    /// The uniforms every draw of `frame` shares.
    fn globals(
        frame: &Frame,
        clip: Option<&ClipDraw>,
        lm_atlas: &Atlas,
        nm_atlas: &Atlas,
    ) -> Result<Globals> {
        let u = &frame.uniforms;
        let (w, h) = (frame.width, frame.height);
        let fog_rate = crate::shade::fog::rate(frame.params.fog_density);
        let (lo, span) = frame.height_ramp;
        let p = &frame.params;
        let sun = p.sun_direction().map(|c| c as f32);
        let fc = p.fog_colour.unwrap_or(frame.background);
        let lm = frame.resources.lightmap.as_ref();
        let lm_levels = lm.map_or(0, |l| l.pyramid.levels.len());
        let mut gl = Globals {
            view_proj: u.view_proj,
            eye: [u.eye[0], u.eye[1], u.eye[2], 1.0],
            cell: [u.cell[0], u.cell[1], u.vertical_scale, fog_rate],
            ramp: [lo, span, p.ambient, p.specular_strength],
            sun: [sun[0], sun[1], sun[2], 0.0],
            fog_colour: [fc[0], fc[1], fc[2], 0.0],
            wire_colour: [p.wire_colour[0], p.wire_colour[1], p.wire_colour[2], 0.0],
            size: [w as f32, h as f32, 0.0, 0.0],
            ints: [
                clip.map_or(1, |c| c.clipmap.n() as i32),
                lm_levels as i32,
                lm.map_or(1, |l| l.scale as i32),
                p.specular_squarings as i32,
            ],
            levels: [uniforms::Level::default(); MAX_LEVELS],
        };
        for (l, level) in gl.levels.iter_mut().enumerate() {
            let info = frame.resources.levels.get(l).copied().flatten();
            let o = info.map_or([0, 0], |i| i.origin);
            let nm = frame.resources.normal_maps.get(l).and_then(|m| m.as_ref());
            let nmo = nm.map_or([0, 0], |m| m.origin);
            let nms = nm.map_or([0, 0], |m| m.size.map(|s| s as i32));
            let lml = lm.and_then(|m| m.pyramid.levels.get(l));
            let lmd = lml.map_or([0, 0], |p| [p.width as i32, p.height as i32]);
            let t = level_tint::albedo(l as u32);
            *level = uniforms::Level {
                origin: [
                    i32_of(o[0], "window origin")?,
                    i32_of(o[1], "window origin")?,
                    i32_of(nmo[0], "normal-map origin")?,
                    i32_of(nmo[1], "normal-map origin")?,
                ],
                nm: [nms[0], nms[1], nm_atlas.row(l), nm.is_some() as i32],
                lm: [lm_atlas.row(l), lmd[0], lmd[1], 0],
                tint: [t[0], t[1], t[2], 0.0],
            };
        }

        Ok(gl)
    }

    /// Draws `frame`; with `clip`, from the clipmap's toroidal textures.
    pub fn draw(&mut self, frame: &Frame, clip: Option<ClipDraw>) -> Result<Image> {
        let uploaded = self.gpu.uploaded();
        let (w, h) = (frame.width, frame.height);
        let DrawList {
            draws,
            strips,
            mesh,
            passthrough,
        } = self.draw_list(frame, clip.as_ref())?;
        let lm = frame.resources.lightmap.as_ref();
        let lm_atlas = Atlas::lightmap(&self.gpu, lm)?;
        let nm_atlas = Atlas::normal_maps(&self.gpu, &frame.resources.normal_maps)?;
        let gl = Self::globals(frame, clip.as_ref(), &lm_atlas, &nm_atlas)?;

        let globals = self.gpu.buffer_init(
            "globals",
            bytemuck::bytes_of(&gl),
            wgpu::BufferUsages::UNIFORM,
        );
        let mut draw_bytes = vec![0u8; draws.len().max(1) * DRAW_STRIDE as usize];
        for (i, (d, _)) in draws.iter().enumerate() {
            let b = bytemuck::bytes_of(d);
            let at = i * DRAW_STRIDE as usize;
            draw_bytes[at..at + b.len()].copy_from_slice(b);
        }
        let storage = wgpu::BufferUsages::STORAGE;
        let gpu = &self.gpu;
        let words: &[u32] = bytemuck::cast_slice(&draw_bytes);
        Resident::hold(
            gpu,
            &mut self.draw_slots,
            words,
            "draws",
            wgpu::BufferUsages::UNIFORM,
        )?;
        Resident::hold(gpu, &mut self.strips, &strips, "strips", storage)?;
        let words: &[u32] = bytemuck::cast_slice(&mesh);
        Resident::hold(gpu, &mut self.mesh, words, "mesh", storage)?;
        fn held(r: &Option<Resident>) -> &wgpu::Buffer {
            &r.as_ref().expect("held above").buffer
        }
        let (draw_buf, strip_buf, mesh_buf) =
            (held(&self.draw_slots), held(&self.strips), held(&self.mesh));
        let empty = self.gpu.buffer_init("empty", &[], storage);
        let pt_bytes = std::mem::size_of_val(passthrough.as_slice()) as u64;
        let limit = self.gpu.device.limits().max_storage_buffer_binding_size;
        if pt_bytes > limit {
            return Err(Error::value(
                "gpu",
                format!(
                    "passthrough: {pt_bytes} bytes exceed {}'s binding limit of {limit}",
                    self.gpu.adapter()
                ),
            ));
        }
        let pt_buf =
            self.gpu
                .buffer_init("passthrough", bytemuck::cast_slice(&passthrough), storage);
        let fp_buf = self.footprints.as_ref().map_or(&empty, |f| &f.1);
        let dev = &self.gpu.device;
        let dummy = ToroidTextures::empty(&self.gpu);
        let tt = if clip.is_some() {
            self.toroid.as_ref().expect("synced")
        } else {
            &dummy
        };
        let view = |t: &wgpu::Texture, dim| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(dim),
                ..Default::default()
            })
        };
        let a2 = wgpu::TextureViewDimension::D2Array;
        let d2 = wgpu::TextureViewDimension::D2;
        let (hv, gv) = (view(&tt.heights, a2), view(&tt.gradients, a2));
        let (lv, nv) = (view(&lm_atlas.texture, d2), view(&nm_atlas.texture, d2));
        let bg0 = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("globals"),
            layout: &self.layouts[0],
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: globals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&hv),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&gv),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&lv),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: wgpu::BindingResource::TextureView(&nv),
                },
            ],
        });
        let bg1 = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("draw"),
            layout: &self.layouts[1],
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: draw_buf,
                        offset: 0,
                        size: wgpu::BufferSize::new(DRAW_STRIDE),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: strip_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: fp_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: pt_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: mesh_buf.as_entire_binding(),
                },
            ],
        });

        let extent = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        let target = |format, label| {
            dev.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: extent,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let colour = target(wgpu::TextureFormat::Rgba8Unorm, "colour");
        let depth = target(wgpu::TextureFormat::Depth32Float, "depth");
        let (cv, dv) = (
            colour.create_view(&Default::default()),
            depth.create_view(&Default::default()),
        );
        // The clear colour is the CPU's 8-bit background, so conversion
        // rounding cannot differ.
        let bg = frame.background.map(|c| unorm8(c) as f64 / 255.0);
        let pipeline = self.pipeline(&frame.effects).clone();
        if self.gpu.timestamps && self.timer.is_none() {
            self.timer = Some(Self::timer(&self.gpu));
        }
        let dev = &self.gpu.device;
        let mut enc = dev.create_command_encoder(&Default::default());
        let mut draw_calls = 0;
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("terrain"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &cv,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: bg[0],
                            g: bg[1],
                            b: bg[2],
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &dv,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: self
                    .timer
                    .as_ref()
                    .map(|t| wgpu::RenderPassTimestampWrites {
                        query_set: &t.0,
                        beginning_of_pass_write_index: Some(0),
                        end_of_pass_write_index: Some(1),
                    }),
                ..Default::default()
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bg0, &[]);
            for (i, (_, range)) in draws.iter().enumerate() {
                if range.is_empty() {
                    continue;
                }
                pass.set_bind_group(1, &bg1, &[(i as u64 * DRAW_STRIDE) as u32]);
                pass.draw(range.clone(), 0..1);
                draw_calls += 1;
            }
        }
        if let Some((set, resolve, copy)) = &self.timer {
            enc.resolve_query_set(set, 0..2, resolve, 0);
            enc.copy_buffer_to_buffer(resolve, 0, copy, 0, 16);
        }
        // Counted before the read-back, which writes nothing.
        let upload_bytes = self.gpu.uploaded() - uploaded;
        let rgba = textures::read_back(&self.gpu, enc, &colour, &depth, w, h)?;
        let gpu_ms = match &self.timer {
            Some((_, _, copy)) => Some(self.pass_ms(copy)?),
            None => None,
        };
        self.costs = FrameCosts {
            upload_bytes,
            draw_calls,
            gpu_ms,
        };
        Ok(rgba)
    }

    /// The query set of two timestamps, the buffer they resolve into and
    /// the mappable copy read after the frame.
    fn timer(gpu: &Gpu) -> (wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer) {
        let d = &gpu.device;
        let set = d.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("pass time"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let buffer = |usage, label| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let resolve = buffer(U::QUERY_RESOLVE | U::COPY_SRC, "timestamps");
        let copy = buffer(U::MAP_READ | U::COPY_DST, "timestamps read");
        (set, resolve, copy)
    }

    /// The render pass's time (ms) from the two timestamps in `copy`, on
    /// the queue's tick period.
    fn pass_ms(&self, copy: &wgpu::Buffer) -> Result<f64> {
        let slice = copy.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| ());
        self.gpu
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::value("gpu", format!("wait for timestamps failed: {e}")))?;
        let ticks: [u64; 2] = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| Error::value("gpu", format!("timestamps unreadable: {e}")))?;
            let t: &[u64] = bytemuck::cast_slice(&view);
            [t[0], t[1]]
        };
        copy.unmap();
        let period = self.gpu.queue.get_timestamp_period() as f64;
        Ok(ticks[1].wrapping_sub(ticks[0]) as f64 * period / 1e6)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_changed_words_are_written() {
        let old = [
            1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20,
        ];
        // Nothing changed: nothing to write.
        assert!(changed_runs(&old, &old).is_empty());
        // One word, and two words far apart, are separate runs.
        let mut new = old;
        new[3] = 0;
        assert_eq!(changed_runs(&old, &new), vec![3..4]);
        new[18] = 0;
        assert_eq!(changed_runs(&old, &new), vec![3..4, 18..19]);
        // Changes closer than the gap are one write.
        let mut near = old;
        near[2] = 0;
        near[2 + RUN_GAP_WORDS - 1] = 0;
        assert_eq!(changed_runs(&old, &near), vec![2..2 + RUN_GAP_WORDS]);
        // Words past the old end are written; a shorter list writes nothing.
        assert_eq!(changed_runs(&old[..18], &old), vec![18..20]);
        assert!(changed_runs(&old, &old[..5]).is_empty());
        assert_eq!(changed_runs(&[], &old[..3]), vec![0..3]);
    }
}
