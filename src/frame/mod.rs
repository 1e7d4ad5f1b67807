//! The frame: everything a back end needs to draw one view, and nothing it
//! would have to decide itself. The LOD scheme's triangles, the vertex
//! uniforms, the per-vertex varyings the listed effects need, and the
//! effects' precomputed inputs. Both back ends consume the same `Frame`.

pub mod stats;
pub mod surface;
pub mod vertex;

use crate::camera::Camera;
use crate::error::Result;
use crate::lod::LodMesh;
use crate::pyramid::{Filter, Pyramid};
use crate::shade::normal_map::{NormalMap, Sources};
use crate::shade::shadows::Lightmap;
use crate::shade::{self, fog, normals, wireframe, Effects, Layout, Resources, ShadeParams};
use crate::terrain::world::WorldMap;
use rayon::prelude::*;
use stats::Passes;
use vertex::VertexUniforms;

/// Everything a back end needs to draw one image: the mesh after the vertex stage,
/// its varyings and the shading inputs. The CPU rasteriser and the wgpu back end draw
/// the same `Frame`, which is what makes their images comparable pixel for pixel.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Clear colour, linear RGB in 0..1.
    pub background: [f32; 3],
    /// Name of the LOD scheme that made the mesh.
    pub lod: String,
    /// The vertex stage's constants (floating origin, view-projection).
    pub uniforms: VertexUniforms,
    /// The LOD scheme's mesh for this view.
    pub mesh: LodMesh,
    /// The effects the scene lists; nothing else is computed.
    pub effects: Effects,
    /// The scene's shading constants.
    pub params: ShadeParams,
    /// Which varyings each vertex carries, and where (the effects decide).
    pub layout: Layout,
    /// Camera-relative position per vertex (the vertex stage's output).
    pub positions: Vec<[f32; 3]>,
    /// `layout.len()` varyings per vertex.
    pub attrs: Vec<f32>,
    /// Per-frame shading resources the effects need (normal map, lightmap).
    pub resources: Resources,
    /// Height-ramp low end and span (metres) of the albedo.
    pub height_ramp: (f32, f32),
}

/// What a frame is made from.
pub struct FrameInput<'a> {
    /// The pyramid the mesh samples.
    pub pyramid: &'a Pyramid,
    /// The pyramid's filter.
    pub filter: Filter,
    /// Grid-to-world placement.
    pub world: &'a WorldMap,
    /// The view.
    pub camera: &'a Camera,
    /// The LOD scheme's mesh.
    pub mesh: LodMesh,
    /// The scheme's name, for statistics.
    pub lod: &'a str,
    /// Image width and height in pixels.
    pub size: [u32; 2],
    /// Clear colour, linear RGB.
    pub background: [f32; 3],
    /// The effects to compute.
    pub effects: Effects,
    /// Shading constants.
    pub params: &'a ShadeParams,
}

impl Frame {
    /// Non-finite values among the vertex stage's positions and varyings.
    pub fn non_finite(&self) -> usize {
        let bad = |v: &f32| !v.is_finite();
        self.positions.iter().flatten().filter(|v| bad(v)).count()
            + self.attrs.iter().filter(|v| bad(v)).count()
    }

    /// Runs the vertex stage and the listed effects' precomputations, each
    /// as a timed pass.
    pub fn build(input: FrameInput, passes: &mut Passes) -> Result<Frame> {
        let FrameInput {
            pyramid,
            filter,
            world,
            camera,
            mesh,
            lod,
            size,
            background,
            effects,
            params,
        } = input;
        let uniforms = VertexUniforms::new(camera, world);
        let layout = Layout::new(&effects);
        let base = &pyramid.levels[0];
        let vs = world.vertical_scale as f32;
        let [lo, hi] = params.height_range.unwrap_or(pyramid.height_range());
        let (lo, hi) = (lo * vs, hi * vs);
        let span = if hi > lo { hi - lo } else { 1.0 };
        let mut frame = Frame {
            width: size[0],
            height: size[1],
            background,
            lod: lod.to_string(),
            uniforms,
            mesh,
            effects,
            params: params.clone(),
            layout,
            positions: Vec::new(),
            attrs: Vec::new(),
            resources: Resources::default(),
            height_ramp: (lo, span),
        };
        frame.vertex_stage(pyramid, world, passes);
        let mesh = &frame.mesh;

        let mut resources = Resources {
            levels: mesh.level_info.clone(),
            ..Default::default()
        };
        if effects.normal_map {
            resources.normal_maps = passes.time("normal-map", || {
                let drawn = &mesh.level_info;
                let src = Sources::new(&pyramid.levels, drawn.first().is_some_and(|d| d.is_some()));
                drawn
                    .iter()
                    .map(|d| {
                        d.map(|info| {
                            NormalMap::build(
                                &pyramid.levels,
                                &src,
                                info.level,
                                info.origin,
                                info.size,
                                world,
                            )
                        })
                    })
                    .collect()
            });
        }
        if effects.shadows {
            // One more than drawn, so the top level can blend toward it.
            let levels = mesh.level_info.len() + 1;
            resources.lightmap = Some(passes.time("lightmap", || {
                Lightmap::build(
                    base,
                    world,
                    params.sun_direction(),
                    params.shadow_epsilon,
                    params.lightmap_scale,
                    filter,
                    levels,
                )
            })?);
        }
        frame.resources = resources;
        Ok(frame)
    }

    /// Replaces the mesh by the next batch of the same view (the same
    /// levels, so the shading resources stay) and runs the vertex stage on
    /// it, adding its time to the passes already listed. The vertex
    /// buffers keep their memory from batch to batch.
    pub fn next_batch(
        &mut self,
        mesh: LodMesh,
        pyramid: &Pyramid,
        world: &WorldMap,
        passes: &mut Passes,
    ) {
        debug_assert_eq!(mesh.level_info, self.resources.levels, "one view's batches");
        self.mesh = mesh;
        let mut these = Passes::default();
        self.vertex_stage(pyramid, world, &mut these);
        passes.add(these);
    }

    /// The vertex stage (pass "vertex") and, with lighting, the vertex
    /// normals (pass "normals") of the mesh, into the frame's buffers.
    fn vertex_stage(&mut self, pyramid: &Pyramid, world: &WorldMap, passes: &mut Passes) {
        let Frame {
            uniforms,
            mesh,
            layout,
            positions,
            attrs,
            params,
            height_ramp: (lo, span),
            ..
        } = self;
        let (lo, span, k) = (*lo, *span, layout.len());
        let size = [self.width, self.height];
        let fog_rate = fog::rate(params.fog_density);
        passes.time("vertex", || {
            mesh.vertices
                .par_iter()
                .map(|v| uniforms.position(v))
                .collect_into_vec(positions);
            attrs.clear();
            attrs.resize(positions.len() * k, 0.0);
            if k > 0 {
                attrs.par_chunks_mut(k).enumerate().for_each(|(i, a)| {
                    let v = &mesh.vertices[i];
                    let p = positions[i];
                    let l = mesh.levels[i / 3] as usize;
                    if let Some(o) = layout.albedo {
                        a[o..o + 3].copy_from_slice(&shade::height_albedo((p[2] - lo) / span));
                    }
                    if let (Some(o), Some(info)) = (layout.uv, mesh.level_info[l]) {
                        let g = 1i64 << l;
                        a[o] = (v.col.div_euclid(g) - info.origin[0]) as f32;
                        a[o + 1] = (v.row.div_euclid(g) - info.origin[1]) as f32;
                    }
                    if let Some(o) = layout.alpha {
                        a[o] = v.alpha;
                    }
                    let e = uniforms.eye;
                    let view = [p[0] - e[0], p[1] - e[1], p[2] - e[2]];
                    if let Some(o) = layout.fog {
                        let d = shade::vec3::dot(view, view).sqrt();
                        a[o] = fog::factor(fog_rate, d);
                    }
                    if let Some(o) = layout.view {
                        a[o..o + 3].copy_from_slice(&view);
                    }
                    if let Some(o) = layout.bary {
                        a[o..o + 3].fill(0.0);
                        a[o + i % 3] = 1.0;
                    }
                });
            }
            if let Some(o) = layout.edge {
                attrs.par_chunks_mut(3 * k).enumerate().for_each(|(t, a)| {
                    let c = [0, 1, 2].map(|j| uniforms.clip(positions[3 * t + j]));
                    let th = wireframe::thresholds(c, size);
                    for j in 0..3 {
                        a[j * k + o..j * k + o + 3].copy_from_slice(&th);
                    }
                });
            }
        });

        if let Some(o) = layout.normal {
            passes.time("normals", || {
                attrs.par_chunks_mut(k).enumerate().for_each(|(i, a)| {
                    let v = &mesh.vertices[i];
                    let l = mesh.levels[i / 3] as usize;
                    let g = 1i64 << l;
                    let morph = mesh.level_info[l].is_some_and(|m| m.morph);
                    let alpha = if morph { v.alpha } else { 0.0 };
                    let n = normals::vertex_normal(
                        &pyramid.levels,
                        l,
                        v.col.div_euclid(g),
                        v.row.div_euclid(g),
                        alpha,
                        world,
                    );
                    a[o..o + 3].copy_from_slice(&n);
                });
            });
        }
    }

    /// Triangles in the mesh.
    pub fn triangle_count(&self) -> usize {
        self.mesh.triangle_count()
    }
}
