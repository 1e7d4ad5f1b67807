//! The render stage: scene → heightmap → pyramid → LOD → frame → raster →
//! shade, every step a timed pass, and only the passes the scene's effects
//! need.

use crate::error::{Error, Result};
use crate::frame::{Frame, FrameInput};
use crate::lod::{self, LodMesh};
use crate::pyramid::Pyramid;
use crate::raster::{self, Mesh, Options, Path, RasterStats};
use crate::scene::{LodScheme, Scene};
use crate::shade::{self, ShadeInputs};
use crate::stats::{Pass, Passes};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;

/// A rendered image with its depth buffer.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// RGBA8, row-major, top row first.
    pub rgba: Vec<u8>,
    /// Depth32Float as the rasteriser left it (1.0 where nothing drew).
    pub depth: Vec<f32>,
}

impl Image {
    /// PNG bytes of the colour image.
    pub fn png(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(
                &self.rgba,
                self.width,
                self.height,
                image::ExtendedColorType::Rgba8,
            )
            .map_err(|e| Error::value("png", e.to_string()))?;
        Ok(out)
    }
}

use image::ImageEncoder;

/// Statistics of one render (the CLI's JSON keys).
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    pub width: u32,
    pub height: u32,
    pub backend: &'static str,
    pub lod: String,
    pub triangles: usize,
    pub passes: Vec<Pass>,
    pub ms_total: f64,
    pub non_finite_vertices: usize,
    pub levels_drawn: usize,
    pub raster: RasterStats,
    /// Rays traced for the lightmap (0 without `shadows`).
    pub lightmap_rays: usize,
    /// Normals computed: per vertex, plus normal-map texels.
    pub normals_computed: usize,
}

/// Render settings that are not part of the scene.
#[derive(Clone, Copy, Debug)]
pub struct RenderOptions {
    pub path: Path,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            path: Path::from_env(),
        }
    }
}

/// Rasterises and shades a frame on the CPU.
pub fn draw(frame: &Frame, opts: &RenderOptions, passes: &mut Passes) -> (Image, RasterStats) {
    let r = passes.time("raster", || {
        let u = &frame.uniforms;
        let clip: Vec<[f32; 4]> = frame.positions.par_iter().map(|&p| u.clip(p)).collect();
        let tris: Vec<[u32; 3]> = (0..frame.triangle_count() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        let mesh = Mesh {
            clip: &clip,
            attrs: &frame.attrs,
            linear: &frame.layout.linear,
            triangles: &tris,
            flat: &frame.mesh.levels,
        };
        raster::rasterise(
            &mesh,
            frame.width,
            frame.height,
            &Options { path: opts.path },
        )
    });
    let rgba = passes.time("shade", || {
        let inputs = ShadeInputs {
            effects: &frame.effects,
            params: &frame.params,
            layout: &frame.layout,
            resources: &frame.resources,
            background: frame.background,
            sun: frame.params.sun_direction().map(|c| c as f32),
        };
        shade::shade(&inputs, &r)
    });
    let image = Image {
        width: frame.width,
        height: frame.height,
        rgba,
        depth: r.depth,
    };
    (image, r.stats)
}

/// Builds the scene's frame (everything before rasterisation).
pub fn build_frame(scene: &Scene, passes: &mut Passes) -> Result<Frame> {
    let h = passes.time("terrain", || scene.heightmap())?;
    let world = scene.world(&h);
    let camera = scene.camera();
    let frustum = camera.frustum();
    let filter = scene.filter()?;
    let scheme = scene.lod_scheme()?;
    let (pyramid, mesh): (Arc<Pyramid>, LodMesh) = match scheme {
        LodScheme::Clipmap => {
            let cfg = scene.clipmap_config();
            let count = scene.clipmap_levels(&h);
            let pyramid = Arc::new(passes.time("pyramid", || Pyramid::build(&h, filter, count)));
            let mesh = passes.time("lod", || -> Result<LodMesh> {
                let mut cm = scene.new_clipmap(pyramid.clone(), cfg)?;
                cm.update(world.to_grid(camera.eye));
                Ok(lod::clipmap_mesh(&cm, &frustum, &world))
            })?;
            (pyramid, mesh)
        }
        LodScheme::BruteForce => {
            // Level 1 only feeds the lightmap's and normal map's blends.
            let pyramid = Arc::new(passes.time("pyramid", || Pyramid::build(&h, filter, 1)));
            let mesh = passes.time("lod", || {
                lod::brute_force::mesh(&pyramid.levels[0], &frustum, &world)
            });
            (pyramid, mesh)
        }
    };
    drop(h);
    let params = scene.shading.clone();
    Frame::build(
        FrameInput {
            pyramid: &pyramid,
            filter,
            world: &world,
            camera: &camera,
            mesh,
            lod: scheme.name(),
            size: [scene.image.width, scene.image.height],
            background: scene.image.background,
            effects: scene.effects()?,
            params: &params,
        },
        passes,
    )
}

/// Renders a scene on the CPU.
pub fn render(scene: &Scene, opts: &RenderOptions) -> Result<(Image, RenderStats)> {
    let mut passes = Passes::default();
    let frame = build_frame(scene, &mut passes)?;
    let (image, raster) = draw(&frame, opts, &mut passes);
    let normals_computed = frame.layout.normal.map_or(0, |_| frame.positions.len())
        + frame
            .resources
            .normal_maps
            .iter()
            .flatten()
            .map(|m| m.data.len())
            .sum::<usize>();
    let stats = RenderStats {
        width: image.width,
        height: image.height,
        backend: "cpu",
        lod: frame.lod.clone(),
        triangles: frame.triangle_count(),
        ms_total: passes.total_ms(),
        passes: passes.0,
        non_finite_vertices: raster.non_finite_vertices,
        levels_drawn: frame.mesh.level_info.iter().flatten().count(),
        raster,
        lightmap_rays: frame.resources.lightmap.as_ref().map_or(0, |l| l.rays),
        normals_computed,
    };
    Ok((image, stats))
}
