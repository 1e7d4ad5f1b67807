//! `[gpu] update = "gpu"`: the clipmap update done on the GPU (GPU Gems 2
//! ch. 2 moved the upsampling there). Each dirty rectangle of a level's
//! toroid is filled by a compute pass from the next coarser level's
//! toroid, coarse to fine:
//!
//! - a synthesised level adds the noise table, uploaded once; the CPU
//!   uploads nothing for it;
//! - a level of a pack coded with `--predictor upsampled` adds its
//!   residuals, which the CPU uploads as 16-bit codes over the rectangle
//!   and a texel around it (for the slopes), with the rare height that no
//!   code reaches sent whole: LH04's and GPU Gems 2's division of labour,
//!   2 bytes a texel instead of 4 for the height and 8 for the slope.
//!
//! The shader (`shaders/update.wgsl`) repeats the CPU's subdivision,
//! synthesis, reconstruction and slope arithmetic operation for
//! operation, so lavapipe's toroids equal the CPU's bit for bit
//! (`check-gpu --frames N` compares them after every update).

use super::textures::ToroidTextures;
use super::Gpu;
use crate::clipmap::toroid::{TexRect, TexRects};
use crate::clipmap::Clipmap;
use crate::pyramid::PyramidLevel;
use crate::synthesis::source::Continuation;
use crate::synthesis::{NoiseTable, STRETCH};
use crate::terrain::world::WorldMap;

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
    res_box: [i32; 4],
    res: [i32; 4],
}

/// The residual of a code the shader reads as an escape.
const ESCAPE: i32 = -32768;

/// The words the shader reads for the residuals of `level` over `bx`
/// (first column, first row, columns, rows of level texels): every
/// sample's code q, the i16 with `p + f32(q) · step` equal to the CPU's
/// height, p the subdivision of `coarse` (the next coarser level), two
/// codes a word (the even sample in the low half); then, for each sample
/// no code reaches (a height the pack stored whole, a residual past
/// ±32767, or one not yet decoded), its index and its height's bits. A
/// pack level's heights are its decoded ones, so the codes are the pack's
/// residuals.
fn residual_words(
    level: &PyramidLevel,
    coarse: &PyramidLevel,
    step: f32,
    bx: [usize; 4],
) -> Vec<u32> {
    let [x0, y0, w, h] = bx;
    let (pred, _) = crate::pyramid::subdivide::subdivide_window(coarse, bx);
    let mut codes = Vec::with_capacity(w * h);
    let mut escapes = Vec::new();
    for (i, &p) in pred.iter().enumerate() {
        let v = level.data[(y0 + i / w) * level.width + x0 + i % w];
        let q = ((v as f64 - p as f64) / step as f64).round();
        let fits = q.abs() < 32767.5 && (p + q as f32 * step).to_bits() == v.to_bits();
        if fits {
            codes.push(q as i32);
        } else {
            codes.push(ESCAPE);
            escapes.extend([i as u32, v.to_bits()]);
        }
    }
    let mut words: Vec<u32> = codes
        .chunks(2)
        .map(|c| (c[0] as u16 as u32) | (c.get(1).map_or(0, |&q| q as u16 as u32) << 16))
        .collect();
    words.extend(escapes);
    words
}

/// The level texels toroid rectangle `r` of a level whose window starts at
/// `o` holds, `margin` wider on every side, clamped to the level's `size`:
/// first column, first row, columns, rows.
fn level_box(r: &TexRect, o: [i64; 2], n: i64, margin: i64, size: [usize; 2]) -> [usize; 4] {
    let span = |a: usize, b: usize, o: i64, last: usize| {
        // A toroid interval's level texels: one run, or two across the
        // window's seam, which the window's whole width then spans.
        let at = |t: usize| o + (t as i64 - o).rem_euclid(n);
        let (lo, hi) = (at(a), at(b - 1));
        let (lo, hi) = if lo <= hi { (lo, hi) } else { (o, o + n - 1) };
        let lo = (lo - margin).clamp(0, last as i64) as usize;
        let hi = (hi + margin).clamp(0, last as i64) as usize;
        (lo, hi - lo + 1)
    };
    let (x0, w) = span(r.x0, r.x1, o[0], size[0] - 1);
    let (y0, h) = span(r.y0, r.y1, o[1], size[1] - 1);
    [x0, y0, w, h]
}

/// The compute pipeline and the noise table it reads.
pub struct UpdatePass {
    /// The first pass (the box's samples) and the second (the toroid's).
    fill: wgpu::ComputePipeline,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// The seed the table was made from, and the table.
    table: Option<(u64, wgpu::Buffer)>,
    /// A slope target for passes that write none.
    no_slopes: wgpu::Texture,
    /// A buffer for the binding a pass does not read (the table or the
    /// residuals).
    unused: wgpu::Buffer,
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
        let storage_buf = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: cs,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
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
                storage_buf(2, true),
                storage_tex(3, wgpu::TextureFormat::R32Float),
                storage_tex(4, wgpu::TextureFormat::Rg32Float),
                storage_buf(5, true),
                storage_buf(6, false),
            ],
        });
        let pl = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("update"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let entry = |name| {
            d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(name),
                layout: Some(&pl),
                module: &module,
                entry_point: Some(name),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let (fill, pipeline) = (entry("fill"), entry("update"));
        let no_slopes = super::textures::toroid_texture(
            gpu,
            [1, 1, 1],
            wgpu::TextureFormat::Rg32Float,
            "no slopes",
        );
        let unused = gpu.buffer_init("unused", &[0; 4], wgpu::BufferUsages::STORAGE);
        UpdatePass {
            fill,
            pipeline,
            layout,
            table: None,
            no_slopes,
            unused,
        }
    }

    /// Per clipmap level, whether the GPU makes it: the synthesised levels
    /// (with `synthesis`, how they are made) and the levels a pack holds
    /// as residuals against the upsampled coarser level, whose windows are
    /// [`UpdatePass::covered`] (the rest are uploaded).
    pub fn levels(cm: &Clipmap, slopes: bool, synthesis: bool) -> Vec<bool> {
        let (k, p) = (cm.pyramid().finer_levels(), cm.pyramid());
        (0..cm.levels().len())
            .map(|l| {
                let made = if l < k {
                    synthesis
                } else {
                    p.residual_step(l).is_some()
                };
                made && Self::covered(cm, l, slopes)
            })
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
        let (fine, coarse) = (&p.levels[l], &p.levels[l + 1]);
        let sizes = [[fine.width, coarse.width], [fine.height, coarse.height]];
        window_reads_inside(
            o,
            oc,
            cm.n(),
            slopes as i64,
            sizes.map(|s| s.map(|v| v as i64)),
        )
    }

    /// Fills each of `jobs` (a level [`UpdatePass::levels`] names and its
    /// dirty rectangles), coarsest first, on the GPU, synthesised levels
    /// as `how` says; returns the texels made and the bytes of residuals
    /// uploaded. Every level must be [`UpdatePass::covered`].
    pub fn run(
        &mut self,
        gpu: &Gpu,
        tt: &ToroidTextures,
        cm: &Clipmap,
        world: &WorldMap,
        how: Option<&Continuation>,
        jobs: &[(usize, TexRects)],
    ) -> (u64, u64) {
        let d = &gpu.device;
        if let Some(how) = how {
            if self.table.as_ref().is_none_or(|t| t.0 != how.seed) {
                let t = NoiseTable::new(how.seed);
                let buf = gpu.buffer_init(
                    "noise table",
                    bytemuck::cast_slice(t.values()),
                    wgpu::BufferUsages::STORAGE,
                );
                self.table = Some((how.seed, buf));
            }
        }
        let table = self.table.as_ref().map_or(&self.unused, |t| &t.1);
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
        let (mut made, mut sent) = (0, 0);
        for &(l, ref rects) in order {
            let (fine, coarse) = (&cm.pyramid().levels[l], &cm.pyramid().levels[l + 1]);
            let o = cm.levels()[l].heights.origin().expect("covered");
            // The synthesised level's depth below the map (0 for a pack's).
            let k = finer.saturating_sub(l);
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
            // A synthesised level's amplitude, or a pack level's step.
            let (amp, step) = match (l < finer, how) {
                (true, Some(how)) => (how.amplitudes[k - 1] as f32, None),
                _ => {
                    let s = cm.pyramid().residual_step(l).expect("a residual level");
                    (s, Some(s))
                }
            };
            for r in rects {
                let bx = level_box(r, o, n, slopes as i64, [fine.width, fine.height]);
                let res_box = bx.map(|v| v as i32);
                let (res, residuals) = match step {
                    None => ([0; 4], None),
                    Some(s) => {
                        let words = residual_words(fine, coarse, s, bx);
                        let escapes = words.len() - (bx[2] * bx[3]).div_ceil(2);
                        sent += 4 * words.len() as u64;
                        let buf = gpu.buffer_init(
                            "residuals",
                            bytemuck::cast_slice(&words),
                            wgpu::BufferUsages::STORAGE,
                        );
                        ([1, (escapes / 2) as i32, 0, 0], Some(buf))
                    }
                };
                let scratch = d.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("update box"),
                    size: 4 * (bx[2] * bx[3]) as u64,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                });
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
                    scale: [amp, sx, sy, 0.0],
                    res_box,
                    res,
                };
                let ub = gpu.buffer_init(
                    "update uniforms",
                    bytemuck::bytes_of(&u),
                    wgpu::BufferUsages::UNIFORM,
                );
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
                        wgpu::BindGroupEntry {
                            binding: 5,
                            resource: residuals
                                .as_ref()
                                .unwrap_or(&self.unused)
                                .as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 6,
                            resource: scratch.as_entire_binding(),
                        },
                    ],
                });
                pass.set_bind_group(0, &bg, &[]);
                // The box's samples, then (a dispatch later, so after
                // they are all written) the toroid's texels from them.
                pass.set_pipeline(&self.fill);
                pass.dispatch_workgroups((bx[2] as u32).div_ceil(8), (bx[3] as u32).div_ceil(8), 1);
                pass.set_pipeline(&self.pipeline);
                let (w, h) = ((r.x1 - r.x0) as u32, (r.y1 - r.y0) as u32);
                pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
                made += r.area() as u64;
            }
        }
        gpu.queue.submit([enc.finish()]);
        (made, sent)
    }
}

/// Whether a fine window at `o` (`n` texels a side, grown by `g` for
/// slopes), on a level `sizes[a][0]` texels along axis a, reads only
/// coarse samples (the four-point stencil: j − 1 ..= j + 2 of the halved
/// index, clamped to the coarser level of `sizes[a][1]`) inside the
/// coarse window at `oc`.
fn window_reads_inside(o: [i64; 2], oc: [i64; 2], n: i64, g: i64, sizes: [[i64; 2]; 2]) -> bool {
    (0..2).all(|a| {
        let [fw, cw] = sizes[a];
        let lo = (o[a] - g).clamp(0, fw - 1) / 2 - 1;
        let hi = (o[a] + n - 1 + g).clamp(0, fw - 1) / 2 + 2;
        let (lo, hi) = (lo.clamp(0, cw - 1), hi.clamp(0, cw - 1));
        lo >= oc[a] && hi < oc[a] + n
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// n = 15 on a 100-texel level over a 50-texel one: a window at 20
    /// reads coarse 9 ..= 19 (one more each side with slopes).
    #[test]
    fn a_window_is_covered_only_where_the_coarser_window_holds_its_reads() {
        let sizes = [[100, 50]; 2];
        let at = |o: i64, oc: i64, g: i64| window_reads_inside([o, 20], [oc, 5], 15, g, sizes);
        // The coarse window 5 ..= 19 holds 9 ..= 19 exactly; 4 ..= 18
        // (one texel off) misses 19, 10 ..= 24 misses 9.
        assert!(at(20, 5, 0));
        assert!(!at(20, 4, 0));
        assert!(!at(20, 10, 0));
        // A window at 21 reads coarse 9 ..= 19; with slopes (20 ..= 36)
        // 9 ..= 20, which the coarse window 5 ..= 19 no longer holds.
        assert!(at(21, 5, 0));
        assert!(!at(21, 5, 1));
        assert!(at(21, 6, 1));
        // Along the other axis too.
        assert!(!window_reads_inside([20, 20], [5, 4], 15, 0, sizes));
        // At the map's edge the reads are clamped to the level: a window
        // hanging 5 texels off the west edge reads coarse 0 ..= 6, which a
        // coarse window at 0 holds and one at 1 does not.
        assert!(window_reads_inside([-5, 20], [0, 5], 15, 0, sizes));
        assert!(!window_reads_inside([-5, 20], [1, 5], 15, 0, sizes));
        // And the east edge: fine 90 ..= 104 clamps to 99, coarse 44 ..= 49.
        assert!(window_reads_inside([90, 20], [35, 5], 15, 0, sizes));
        assert!(!window_reads_inside([90, 20], [34, 5], 15, 0, sizes));
    }

    /// What the shader reads at box sample `i`: its code's sum, or its
    /// escape's bits found by a binary search.
    fn read(words: &[u32], count: usize, i: usize, p: f32, step: f32) -> f32 {
        let q = (words[i / 2] >> (16 * (i % 2))) as u16 as i16;
        if q != ESCAPE as i16 {
            return p + q as f32 * step;
        }
        let esc: Vec<[u32; 2]> = words[count.div_ceil(2)..]
            .chunks(2)
            .map(|c| [c[0], c[1]])
            .collect();
        assert!(esc.windows(2).all(|w| w[0][0] < w[1][0]), "sorted");
        let k = esc.partition_point(|e| e[0] as usize <= i) - 1;
        assert_eq!(esc[k][0] as usize, i);
        f32::from_bits(esc[k][1])
    }

    #[test]
    fn residual_words_give_back_every_height_of_the_box() {
        let coarse = PyramidLevel::from_parts(
            5,
            5,
            (0..25)
                .map(|i| ((i * 37) % 11) as f32 * 3.25 - 9.0)
                .collect(),
            vec![false; 25],
        );
        let step = 0.6f32;
        let (p, _) = crate::pyramid::subdivide::subdivide(&coarse);
        let mut data: Vec<f32> = p
            .iter()
            .enumerate()
            .map(|(i, &p)| p + ((i % 7) as f32 - 3.0) * step)
            .collect();
        // One height off the grid, one residual past an i16, one below.
        data[9 * 2 + 3] = 1.234_567;
        data[9 * 3 + 4] = p[9 * 3 + 4] + 40_000.0 * step;
        data[9 * 4 + 6] = p[9 * 4 + 6] - 32_767.0 * step;
        let level = PyramidLevel::from_parts(9, 9, data.clone(), vec![false; 81]);
        let bx = [2, 1, 5, 4];
        let words = residual_words(&level, &coarse, step, bx);
        let count = bx[2] * bx[3];
        assert_eq!(words.len(), count.div_ceil(2) + 2 * 2, "two escapes");
        for i in 0..count {
            let (x, y) = (bx[0] + i % bx[2], bx[1] + i / bx[2]);
            let got = read(&words, count, i, p[y * 9 + x], step);
            assert_eq!(got.to_bits(), data[y * 9 + x].to_bits(), "({x}, {y})");
        }
    }

    #[test]
    fn a_level_box_covers_the_rectangles_texels_and_their_margin() {
        let rect = |x0, x1, y0, y1| TexRect { x0, y0, x1, y1 };
        // Window at level (10, 3), n = 8: toroid column t holds level
        // 10 + (t − 10) mod 8.
        let (o, size) = ([10, 3], [40, 40]);
        // Columns 4..6 hold 12..=13; rows 0..8 the whole window, 3..=10.
        assert_eq!(level_box(&rect(4, 6, 0, 8), o, 8, 0, size), [12, 3, 2, 8]);
        assert_eq!(level_box(&rect(4, 6, 0, 8), o, 8, 1, size), [11, 2, 4, 10]);
        // Columns 1..4 hold 17, 10 and 11: across the seam, the whole window.
        assert_eq!(level_box(&rect(1, 4, 3, 4), o, 8, 0, size), [10, 3, 8, 1]);
        // Clamped to the level.
        assert_eq!(
            level_box(&rect(0, 8, 0, 8), [0, 4], 8, 1, [8, 12]),
            [0, 3, 8, 9]
        );
    }
}
