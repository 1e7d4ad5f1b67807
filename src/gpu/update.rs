//! `[gpu] update = "gpu"`: the clipmap update of synthesised levels done
//! on the GPU (GPU Gems 2 ch. 2 moved the upsampling there). Each dirty
//! rectangle of a synthesised level's toroid is filled by a compute pass
//! from the next coarser level's toroid, coarse to fine, with the noise
//! table uploaded once; the CPU uploads nothing for those levels. The
//! shader (`shaders/update.wgsl`) repeats the CPU's synthesis and slope
//! arithmetic operation for operation, so lavapipe's toroids equal the
//! CPU's bit for bit (`check-gpu --frames N` compares them after every
//! update).

use super::textures::ToroidTextures;
use super::Gpu;
use crate::clipmap::toroid::TexRects;
use crate::clipmap::Clipmap;
use crate::synthesis::source::Continuation;
use crate::synthesis::{NoiseTable, STRETCH};
use crate::terrain::world::WorldMap;
use wgpu::util::DeviceExt;

const SHADER: &str = concat!(
    include_str!("shaders/wrap.wgsl"),
    include_str!("shaders/update.wgsl")
);

/// The shader's uniforms, one set per dirty rectangle.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Synth {
    dims: [i32; 4],
    grid: [i32; 4],
    origin: [i32; 4],
    rect_end: [i32; 4],
    scale: [f32; 4],
}

/// The compute pipeline and the noise table it reads.
pub struct UpdatePass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// The seed the table was made from, and the table.
    table: Option<(u64, wgpu::Buffer)>,
    /// A slope target for passes that write none.
    no_slopes: wgpu::Texture,
}

impl UpdatePass {
    /// Compiles the shader on `gpu`.
    pub fn new(gpu: &Gpu) -> Self {
        let d = &gpu.device;
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("update.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let cs = wgpu::ShaderStages::COMPUTE;
        let storage_tex = |binding, format| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: cs,
            ty: wgpu::BindingType::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                format,
                view_dimension: wgpu::TextureViewDimension::D2,
            },
            count: None,
        };
        let layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("update"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: cs,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: cs,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: cs,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage_tex(3, wgpu::TextureFormat::R32Float),
                storage_tex(4, wgpu::TextureFormat::Rg32Float),
            ],
        });
        let pl = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("update"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("update"),
            layout: Some(&pl),
            module: &module,
            entry_point: Some("update"),
            compilation_options: Default::default(),
            cache: None,
        });
        let no_slopes = super::textures::toroid_texture(
            gpu,
            [1, 1, 1],
            wgpu::TextureFormat::Rg32Float,
            "no slopes",
        );
        UpdatePass {
            pipeline,
            layout,
            table: None,
            no_slopes,
        }
    }

    /// Per clipmap level, whether the GPU makes it: the synthesised levels
    /// whose windows are [`UpdatePass::covered`] (the rest are uploaded).
    pub fn levels(cm: &Clipmap, slopes: bool) -> Vec<bool> {
        let k = cm.pyramid().finer_levels();
        (0..cm.levels().len())
            .map(|l| l < k && Self::covered(cm, l, slopes))
            .collect()
    }

    /// Whether level `l`'s whole window (one texel wider with slopes)
    /// reads only coarse samples inside level l + 1's window, so its
    /// toroid can be made from the coarser one's alone.
    pub fn covered(cm: &Clipmap, l: usize, slopes: bool) -> bool {
        let (levels, p) = (cm.levels(), cm.pyramid());
        if l + 1 >= levels.len() {
            return false;
        }
        let (Some(o), Some(oc)) = (levels[l].heights.origin(), levels[l + 1].heights.origin())
        else {
            return false;
        };
        let (n, g) = (cm.n(), slopes as i64);
        let (fine, coarse) = (&p.levels[l], &p.levels[l + 1]);
        let sizes = [[fine.width, coarse.width], [fine.height, coarse.height]];
        (0..2).all(|a| {
            let [fw, cw] = sizes[a].map(|v| v as i64);
            let lo = (o[a] - g).clamp(0, fw - 1) / 2 - 1;
            let hi = (o[a] + n - 1 + g).clamp(0, fw - 1) / 2 + 2;
            let (lo, hi) = (lo.clamp(0, cw - 1), hi.clamp(0, cw - 1));
            lo >= oc[a] && hi < oc[a] + n
        })
    }

    /// Fills each of `jobs` (a synthesised level and its dirty
    /// rectangles), coarsest first, on the GPU; returns the texels made.
    /// Every level must be [`UpdatePass::covered`].
    pub fn run(
        &mut self,
        gpu: &Gpu,
        tt: &ToroidTextures,
        cm: &Clipmap,
        world: &WorldMap,
        how: &Continuation,
        jobs: &[(usize, TexRects)],
    ) -> u64 {
        let d = &gpu.device;
        if self.table.as_ref().is_none_or(|t| t.0 != how.seed) {
            let t = NoiseTable::new(how.seed);
            let buf = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("noise table"),
                contents: bytemuck::cast_slice(t.values()),
                usage: wgpu::BufferUsages::STORAGE,
            });
            self.table = Some((how.seed, buf));
        }
        let table = &self.table.as_ref().expect("made above").1;
        let finer = cm.pyramid().finer_levels();
        let n = cm.n();
        let slopes = tt.has_gradients();
        let layer = |t: &wgpu::Texture, l: usize| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: l as u32,
                array_layer_count: Some(1),
                ..Default::default()
            })
        };
        let no_slopes = layer(&self.no_slopes, 0);
        let mut order: Vec<&(usize, TexRects)> = jobs.iter().collect();
        order.sort_by_key(|j| std::cmp::Reverse(j.0));
        let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("update"),
        });
        let mut made = 0;
        for &(l, ref rects) in order {
            let (fine, coarse) = (&cm.pyramid().levels[l], &cm.pyramid().levels[l + 1]);
            let o = cm.levels()[l].heights.origin().expect("covered");
            let k = finer - l;
            let [sx, sy] = crate::shade::normals::slope_scale(world, (1u64 << l) as f64);
            let (cv, fv) = (layer(&tt.heights, l + 1), layer(&tt.heights, l));
            let own;
            let gv = if slopes {
                own = layer(&tt.gradients, l);
                &own
            } else {
                &no_slopes
            };
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("update level"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            for r in rects {
                let u = Synth {
                    dims: [
                        fine.width as i32,
                        fine.height as i32,
                        coarse.width as i32,
                        coarse.height as i32,
                    ],
                    grid: [n as i32, k as i32, STRETCH[0] as i32, STRETCH[1] as i32],
                    origin: [o[0] as i32, o[1] as i32, r.x0 as i32, r.y0 as i32],
                    rect_end: [r.x1 as i32, r.y1 as i32, slopes as i32, 0],
                    scale: [how.amplitudes[k - 1] as f32, sx, sy, 0.0],
                };
                let ub = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("update uniforms"),
                    contents: bytemuck::bytes_of(&u),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
                let bg = d.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("update"),
                    layout: &self.layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: ub.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: wgpu::BindingResource::TextureView(&cv),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: table.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: wgpu::BindingResource::TextureView(&fv),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: wgpu::BindingResource::TextureView(gv),
                        },
                    ],
                });
                pass.set_bind_group(0, &bg, &[]);
                let (w, h) = ((r.x1 - r.x0) as u32, (r.y1 - r.y0) as u32);
                pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
                made += r.area() as u64;
            }
        }
        gpu.queue.submit([enc.finish()]);
        made
    }
}
