//! The render stage: scene → heightmap → pyramid → LOD → frame → raster →
//! shade, every step a timed pass, and only the passes the scene's effects
//! need.

#[cfg(feature = "gpu")]
pub mod gpu;

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::frame::stats::{Pass, Passes};
use crate::frame::vertex::VertexUniforms;
use crate::frame::{Frame, FrameInput};
use crate::lod::LodMesh;
use crate::lod::LodVertex;
use crate::lod::{Lod, LodConfig, LodUpdate, View};
use crate::pack::reader::PackReader;
use crate::pyramid::Filter;
use crate::pyramid::{LazyBase, LazyStats, Pyramid};
use crate::raster::setup::Viewport;
use crate::raster::{self, Fate, Mesh, Options, Path, RasterStats, Target};
use crate::scene::Scene;
use crate::shade::{self, ShadeInputs};
use crate::shade::{Effects, ShadeParams};
use crate::terrain;
use crate::terrain::world::WorldMap;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;

crate::names::named! {
    /// Which back end draws a frame.
    pub enum Backend ("back end") {
        /// The CPU reference rasteriser.
        Cpu => "cpu",
        /// The wgpu back end.
        Gpu => "gpu",
    }
}

/// The image both back ends produce (it lives with the rasteriser, below
/// the GPU back end that also makes one).
pub use crate::raster::Image;

use crate::synthesis::source::Continuation;

/// Statistics of one render (the CLI's JSON keys).
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// `cpu` or `gpu`.
    pub backend: &'static str,
    /// The LOD scheme's name.
    pub lod: String,
    /// Triangles drawn.
    pub triangles: usize,
    /// Each timed pass in the order it ran; an effect not listed has no pass.
    pub passes: Vec<Pass>,
    /// Wall time of every pass (ms).
    pub ms_total: f64,
    /// Vertices the vertex stage made non-finite (the same as `non_finite.vertex`).
    pub non_finite_vertices: usize,
    /// Non-finite values seen per stage; every stability test requires 0.
    pub non_finite: NonFinite,
    /// Clipmap levels with triangles in the frame (0 for other schemes).
    pub levels_drawn: usize,
    /// What the rasteriser saw.
    pub raster: RasterStats,
    /// Rays traced for the lightmap (0 without `shadows`).
    pub lightmap_rays: usize,
    /// Normals computed: per vertex, plus normal-map texels.
    pub normals_computed: usize,
    /// With `pyramid.lazy`, or a pack decoded tile by tile: what the
    /// pyramid has built or decoded (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lazy: Option<LazyFrame>,
    /// The CPU raster and shading build that ran ([`crate::raster::Path::label`]:
    /// `scalar`, `portable` or `avx2+fma`); absent for the GPU back end.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub raster_path: Option<&'static str>,
    /// With `[terrain] synthesis`: how the synthesised levels continue the
    /// map (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub synthesis: Option<Continuation>,
}

/// A lazy pyramid after a frame.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct LazyFrame {
    /// Tiles and samples built so far.
    #[serde(flatten)]
    pub pyramid: LazyStats,
    /// Samples built (or decoded from a pack) for this frame.
    pub samples_this_frame: u64,
    /// Tiles built (or decoded) for this frame.
    pub tiles_this_frame: u64,
    /// Coarsest levels not drawn because their tiles are not built yet.
    pub levels_unbuilt: usize,
    /// Finest levels not drawn because a pack's tiles under them are not
    /// decoded yet (the decoding budget ran out).
    pub levels_waiting: usize,
    /// A pack only: decoded tiles held now, and evicted for this frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tiles_resident: Option<u64>,
    /// (with `tiles_resident`)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tiles_evicted: Option<u64>,
}

impl RenderStats {
    /// Total time of the passes named `names` (ms).
    pub fn pass_ms(&self, names: &[&str]) -> f64 {
        crate::frame::stats::pass_ms(&self.passes, names)
    }
}

/// Non-finite counts per pipeline stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct NonFinite {
    /// Vertex-stage positions and varyings.
    pub vertex: usize,
    /// Clip coordinates in, and vertices the clipper made.
    pub clip: usize,
    /// Set-up planes and covered depths.
    pub raster: usize,
}

/// Render settings that are not part of the scene.
#[derive(Clone, Copy, Debug)]
pub struct RenderOptions {
    /// The CPU rasteriser's path (scalar, portable or AVX2 + FMA; the same bits).
    pub path: Path,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            path: Path::from_env(),
        }
    }
}

/// Rasterises `frame`'s triangles at the given clip positions (one per
/// frame vertex) with the frame's varyings.
pub fn rasterise_frame(frame: &Frame, clip: &[[f32; 4]], path: raster::Path) -> raster::Raster {
    let mut target = Target::new(
        frame.width,
        frame.height,
        &frame.layout.linear,
        Options { path },
    );
    let mut tris = Vec::new();
    draw_clipped(frame, clip, &mut tris, &mut target);
    target.finish()
}

/// Draws `frame`'s triangles at `clip` into `target`; `tris` is the
/// triangles' vertex indices, kept from batch to batch.
fn draw_clipped(frame: &Frame, clip: &[[f32; 4]], tris: &mut Vec<[u32; 3]>, target: &mut Target) {
    tris.clear();
    tris.extend((0..frame.triangle_count() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]));
    target.draw(&Mesh {
        clip,
        attrs: &frame.attrs,
        linear: &frame.layout.linear,
        triangles: tris,
        flat: &frame.mesh.levels,
    });
}

/// The memory one batch of a frame needs between the vertex stage and the
/// rasteriser, kept for the next batch.
#[derive(Default)]
struct BatchBuffers {
    clip: Vec<[f32; 4]>,
    tris: Vec<[u32; 3]>,
    fates: Vec<Fate>,
}

/// The vertex stage's clip positions of `frame`, then its triangles, into
/// `target`.
fn draw_frame(frame: &Frame, buffers: &mut BatchBuffers, target: &mut Target) {
    let u = &frame.uniforms;
    frame
        .positions
        .par_iter()
        .map(|&p| u.clip(p))
        .collect_into_vec(&mut buffers.clip);
    draw_clipped(frame, &buffers.clip, &mut buffers.tris, target);
}

/// The vertex stage's clip positions, then [`rasterise_frame`]: the raster
/// [`draw`] shades, for callers that need its triangles (the tie band of
/// `check-gpu`).
pub fn raster(frame: &Frame, path: raster::Path) -> raster::Raster {
    let mut target = Target::new(
        frame.width,
        frame.height,
        &frame.layout.linear,
        Options { path },
    );
    draw_frame(frame, &mut BatchBuffers::default(), &mut target);
    target.finish()
}

/// Rasterises and shades a frame on the CPU.
pub fn draw(frame: &Frame, opts: &RenderOptions, passes: &mut Passes) -> (Image, RasterStats) {
    let r = passes.time("raster", || raster(frame, opts.path));
    shade_pass(frame, r, opts, passes, None)
}

/// Shades the raster of `frame` (pass "shade").
/// The raster's buffers but the depth go back to `recycle`, if given.
fn shade_pass(
    frame: &Frame,
    mut r: raster::Raster,
    opts: &RenderOptions,
    passes: &mut Passes,
    recycle: Option<&mut Target>,
) -> (Image, RasterStats) {
    let rgba = passes.time("shade", || {
        let inputs = ShadeInputs {
            effects: &frame.effects,
            params: &frame.params,
            layout: &frame.layout,
            resources: &frame.resources,
            background: frame.background,
            sun: frame.params.sun_direction().map(|c| c as f32),
        };
        shade::shade(&inputs, &r, opts.path)
    });
    let image = Image {
        width: frame.width,
        height: frame.height,
        rgba,
        depth: std::mem::take(&mut r.depth),
    };
    let stats = std::mem::take(&mut r.stats);
    if let Some(t) = recycle {
        t.recycle(r);
    }
    (image, stats)
}

/// The buffers a CPU render fills, kept by its session for the next
/// render: a survey's views and a flight's frames then reuse the memory of
/// the first instead of having the kernel map and zero it again each time.
#[derive(Default)]
struct Kept {
    mesh: LodMesh,
    positions: Vec<[f32; 3]>,
    attrs: Vec<f32>,
    buffers: BatchBuffers,
    target: Option<Target>,
}

/// Triangles per batch for a scheme whose mesh comes in batches (brute
/// force): with its vertex stage, clip positions and set-up triangles,
/// about 0.4 GB, whatever the size of the map.
pub const BATCH_TRIANGLES: usize = 1 << 20;

/// What the batches of one frame drew, summed: the statistics a frame
/// drawn whole reads from its one mesh.
#[derive(Clone, Copy, Debug, Default)]
pub struct Drawn {
    /// Triangles.
    pub triangles: usize,
    /// Vertices (three per triangle).
    pub vertices: usize,
    /// Non-finite values of the vertex stage.
    pub non_finite: usize,
}

impl Drawn {
    /// What `frame`'s mesh holds.
    pub fn of(frame: &Frame) -> Drawn {
        Drawn {
            triangles: frame.triangle_count(),
            vertices: frame.positions.len(),
            non_finite: frame.non_finite(),
        }
    }
}

/// Leaves out of `mesh` the triangles that cannot reach a pixel
/// ([`raster::fate`]), counting them in `target` as drawing them would,
/// before the vertex stage computes their varyings. Brute force of a large
/// map in a small image is mostly triangles smaller than a pixel, which
/// cover no pixel centre; their varyings and normals were most of its
/// time. The positions are computed as the vertex stage computes them, so
/// the triangles kept and the image are the same.
fn cull(
    mesh: &mut LodMesh,
    u: &VertexUniforms,
    vp: &Viewport,
    buffers: &mut BatchBuffers,
    target: &mut Target,
    path: Path,
) {
    const CHUNK: usize = 4096;
    let fates = &mut buffers.fates;
    fates.clear();
    fates.resize(mesh.triangle_count(), Fate::Draw);
    let fast = path.uses_avx2_fma();
    fates
        .par_chunks_mut(CHUNK)
        .zip(mesh.vertices.par_chunks(3 * CHUNK))
        .for_each(|(f, v)| fates_of(fast, v, u, vp, f));
    let (mut rejected, mut nothing, mut kept) = (0, 0, 0);
    for (t, f) in fates.iter().enumerate() {
        match f {
            Fate::Draw => {
                mesh.vertices.copy_within(3 * t..3 * t + 3, 3 * kept);
                mesh.levels[kept] = mesh.levels[t];
                kept += 1;
            }
            Fate::Rejected => rejected += 1,
            Fate::Nothing => nothing += 1,
        }
    }
    mesh.vertices.truncate(3 * kept);
    mesh.levels.truncate(kept);
    target.left_out(rejected, nothing);
}

#[inline(always)]
fn fates_in(v: &[LodVertex], u: &VertexUniforms, vp: &Viewport, out: &mut [Fate]) {
    for (t, f) in v.chunks_exact(3).zip(out) {
        let c = [0, 1, 2].map(|j| u.clip(u.position(&t[j])));
        *f = raster::fate(c, vp);
    }
}

crate::cpu::avx2_fma_twin! {
    /// [`raster::fate`] of each triangle of `v`, in the AVX2 + FMA build
    /// when `fast` (the same bits: the viewport's multiply-add is fused in
    /// both).
    fn fates_of(v: &[LodVertex], u: &VertexUniforms, vp: &Viewport, out: &mut [Fate]) => fates_in
}

/// A scene's terrain, loaded once, and its LOD scheme, kept across frames
/// so a camera path updates it incrementally.
pub struct Session {
    /// Grid-to-world placement of the terrain.
    pub world: WorldMap,
    /// The pyramid's filter.
    pub filter: Filter,
    /// The LOD scheme, kept across frames.
    pub lod: Box<dyn Lod>,
    /// What the last frame's LOD update changed.
    pub last_update: LodUpdate,
    /// With `[terrain] synthesis`: how its levels continue the map.
    pub synthesis: Option<Continuation>,
    /// `[gpu] update`: who fills the GPU back end's toroids.
    pub gpu_update: crate::scene::GpuUpdate,
    /// Triangles per batch where the scheme meshes in batches (brute
    /// force); [`BATCH_TRIANGLES`] unless set. The image does not depend
    /// on it, only the memory a render holds.
    pub batch_triangles: usize,
    /// The memory of the last CPU render, for the next one.
    kept: Kept,
    effects: Effects,
    params: ShadeParams,
    size: [u32; 2],
    background: [f32; 3],
}

pub use crate::lod::clipmap::ClipFrame;

impl Session {
    /// The terrain pyramid, as the LOD scheme has built it so far.
    pub fn pyramid(&self) -> &Pyramid {
        self.lod.pyramid()
    }

    /// Loads the heightmap and builds the pyramid (timed passes "terrain",
    /// "pyramid"). With `pyramid.lazy`, a procedural terrain is not
    /// generated and nothing is filtered here: the clipmap's updates build
    /// the tiles they need. Each stage builds itself from its part of the
    /// scene; errors come back naming the scene and the field.
    pub fn new(scene: &Scene, passes: &mut Passes) -> Result<Session> {
        Self::build(scene, None, passes).map_err(|e| scene.named(e))
    }

    /// The heightmap a session of `scene` would load whole (None for a
    /// pack or a lazy pyramid, which are read as the view needs them):
    /// loaded once, it can be given to [`Session::with_map`] for each of
    /// several sessions of the same terrain, as a survey of several
    /// schemes makes.
    pub fn load_map(scene: &Scene) -> Result<Option<terrain::Heightmap>> {
        let pack = crate::pack::file::pack_path(&scene.terrain, &scene.base_dir);
        if pack.is_some() || scene.pyramid.lazy {
            return Ok(None);
        }
        terrain::load(&scene.terrain, &scene.base_dir)
            .map(Some)
            .map_err(|e| scene.named(e))
    }

    /// [`Session::new`], with `map` (from [`Session::load_map`] of a scene
    /// with the same terrain) in place of loading the terrain again; its
    /// own pyramid is built from it, with the levels its scheme needs.
    pub fn with_map(
        scene: &Scene,
        map: Option<&terrain::Heightmap>,
        passes: &mut Passes,
    ) -> Result<Session> {
        Self::build(scene, map, passes).map_err(|e| scene.named(e))
    }

    fn build(
        scene: &Scene,
        map: Option<&terrain::Heightmap>,
        passes: &mut Passes,
    ) -> Result<Session> {
        let mut filter = scene.pyramid.filter;
        let effects = Effects::from_list(&scene.effects).map_err(|r| Error::value("effects", r))?;
        let cfg = LodConfig::from_spec(&scene.lod, effects.morph)?;
        let pack = crate::pack::file::pack_path(&scene.terrain, &scene.base_dir);
        // A pack under a clipmap that reads only its windows is decoded
        // tile by tile as the windows reach them (LH04); other schemes and
        // the effects that read the whole map get it decoded whole.
        let incremental = scene.lod.scheme == crate::lod::LodScheme::Clipmap
            && !effects.shadows
            && !effects.normal_map;
        // Synthesised levels come before the map's own: the map needs as
        // many fewer, but at least the three its detail and roughness are
        // measured over.
        let finer = scene.terrain.synthesis.map_or(0, |s| s.levels);
        let base_levels = |w: usize, h: usize| {
            let fine = |v: usize| ((v - 1) << finer) + 1;
            let count = cfg.pyramid_levels(fine(w), fine(h));
            if finer > 0 {
                count.saturating_sub(finer).max(3)
            } else {
                count
            }
        };
        let (pyramid, world) = if let Some(path) = pack {
            if scene.pyramid.lazy {
                return Err(Error::value(
                    "pyramid.lazy",
                    "a pack is already decoded tile by tile as the clipmap needs it; remove lazy",
                ));
            }
            if incremental {
                let reader = passes.time("terrain", || PackReader::open(&path))?;
                let h = reader.header();
                let made_with = Filter::parse(&h.filter).map_err(|r| Error::file(&path, r))?;
                let world = WorldMap::for_terrain(
                    &scene.terrain,
                    crate::pack::file::cell_size(&scene.terrain, h),
                );
                filter = made_with;
                let p = Pyramid::decoded(Arc::new(reader), made_with, scene.pyramid.budget)
                    .map_err(|r| Error::file(&path, r))?;
                (p, world)
            } else {
                let crate::pack::file::PackTerrain {
                    mut levels,
                    cell_size,
                    filter: made_with,
                } = passes.time("terrain", || {
                    crate::pack::file::read_terrain(&scene.terrain, &path)
                })?;
                let count = base_levels(levels[0].width, levels[0].height);
                levels.truncate(count.max(1));
                let world = WorldMap::for_terrain(&scene.terrain, cell_size);
                // The pack's levels were made with its own filter.
                filter = made_with;
                (Pyramid::from_levels(levels, made_with), world)
            }
        } else if scene.pyramid.lazy {
            let (base, world) = passes.time("terrain", || {
                LazyBase::for_terrain(&scene.terrain, &scene.base_dir)
            })?;
            let [w, h] = match &base {
                LazyBase::Procedural(p) => [p.width, p.height],
                LazyBase::Heightmap(h) => [h.width(), h.height()],
            };
            let count = base_levels(w, h);
            let p = Pyramid::lazy(base, filter, count, scene.pyramid.budget)
                .map_err(|r| Error::value("pyramid", r))?;
            (p, world)
        } else {
            let h = match map {
                Some(m) => passes.time("terrain", || m.clone()),
                None => {
                    passes.time("terrain", || terrain::load(&scene.terrain, &scene.base_dir))?
                }
            };
            let world = WorldMap::for_terrain(&scene.terrain, h.cell_size);
            let count = base_levels(h.width(), h.height());
            let p = passes.time("pyramid", || Pyramid::from_heightmap(h, filter, count));
            (p, world)
        };
        let mut continuation = None;
        let (pyramid, world) = match &scene.terrain.synthesis {
            None => (pyramid, world),
            Some(spec) => {
                let path = match &scene.terrain.file {
                    Some(f) => scene.base_dir.join(f),
                    None => "procedural terrain".into(),
                };
                let budget = scene.pyramid.budget;
                let (p, world, how) = passes
                    .time("synthesis", || {
                        crate::synthesis::source::apply(
                            pyramid,
                            world,
                            spec,
                            &path,
                            budget,
                            !incremental,
                        )
                    })
                    .map_err(|r| Error::value("terrain.synthesis", r))?;
                continuation = Some(how);
                (p, world)
            }
        };
        // The scheme holds the only reference, so a lazy pyramid grows in
        // place.
        let lod = cfg.build(Arc::new(pyramid))?;
        Ok(Session {
            world,
            filter,
            lod,
            last_update: LodUpdate::default(),
            batch_triangles: BATCH_TRIANGLES,
            kept: Kept::default(),
            synthesis: continuation,
            gpu_update: scene.gpu.update,
            effects,
            params: scene.shading.clone(),
            size: [scene.image.width, scene.image.height],
            background: scene.image.background,
        })
    }

    /// Moves the LOD scheme to `camera` (timed pass "lod") without meshing
    /// or drawing: what `diagram` shows. [`Session::frame`] does this first.
    pub fn update(&mut self, camera: &Camera, passes: &mut Passes) -> &LodUpdate {
        let frustum = camera.frustum();
        let view = View::new(camera, &frustum, &self.world, self.size);
        let lod = &mut self.lod;
        self.last_update = passes.time("lod", || lod.update(&view));
        &self.last_update
    }

    /// The frame for `camera` (timed passes "lod", "mesh" and the frame's
    /// own), and for a clipmap the level meshes it was made from.
    pub fn frame(
        &mut self,
        camera: &Camera,
        passes: &mut Passes,
    ) -> Result<(Frame, Option<ClipFrame>)> {
        self.update(camera, passes);
        if let Some(e) = self.pyramid().decode_error() {
            return Err(e);
        }
        let frustum = camera.frustum();
        let view = View::new(camera, &frustum, &self.world, self.size);
        let mesh = passes.time("mesh", || self.lod.mesh(&view));
        let clip = self.lod.take_clip_frame();
        Ok((self.build_frame(camera, mesh, passes)?, clip))
    }

    /// The frame of `mesh`, seen from `camera`.
    fn build_frame(&self, camera: &Camera, mesh: LodMesh, passes: &mut Passes) -> Result<Frame> {
        Frame::build(
            FrameInput {
                pyramid: self.lod.pyramid(),
                filter: self.filter,
                world: &self.world,
                camera,
                mesh,
                lod: self.lod.name(),
                size: self.size,
                background: self.background,
                effects: self.effects,
                params: &self.params,
            },
            passes,
        )
    }
}

/// Builds the scene's frame (everything before rasterisation).
pub fn build_frame(scene: &Scene, passes: &mut Passes) -> Result<Frame> {
    let mut session = Session::new(scene, passes)?;
    Ok(session.frame(&scene.camera(), passes)?.0)
}

/// Statistics of a render from its frame, image-independent parts.
pub fn stats(
    frame: &Frame,
    drawn: Drawn,
    backend: &'static str,
    raster: RasterStats,
    passes: Passes,
) -> RenderStats {
    let normals_computed = frame.layout.normal.map_or(0, |_| drawn.vertices)
        + frame
            .resources
            .normal_maps
            .iter()
            .flatten()
            .map(|m| m.data.len())
            .sum::<usize>();
    RenderStats {
        width: frame.width,
        height: frame.height,
        backend,
        lod: frame.lod.clone(),
        triangles: drawn.triangles,
        ms_total: passes.total_ms(),
        passes: passes.0,
        non_finite_vertices: raster.non_finite_vertices,
        non_finite: NonFinite {
            vertex: drawn.non_finite,
            clip: raster.non_finite_vertices + raster.non_finite_clipped,
            raster: raster.non_finite_planes + raster.non_finite_depth,
        },
        levels_drawn: frame.mesh.level_info.iter().flatten().count(),
        raster,
        lightmap_rays: frame.resources.lightmap.as_ref().map_or(0, |l| l.rays),
        normals_computed,
        lazy: None,
        raster_path: None,
        synthesis: None,
    }
}

/// Renders a scene on the CPU.
pub fn render(scene: &Scene, opts: &RenderOptions) -> Result<(Image, RenderStats)> {
    let mut passes = Passes::default();
    let mut session = Session::new(scene, &mut passes)?;
    session.render(&scene.camera(), opts, passes)
}

impl Session {
    /// Renders `camera`'s view on the CPU; the stats include `passes` so
    /// far (terrain loading, for a one-off render). A scheme that meshes
    /// in batches ([`Lod::mesh_batch`]) is drawn batch by batch into one
    /// target, which holds only the triangles pixels still show: the same
    /// image as the whole mesh drawn at once, in memory that does not grow
    /// with the map.
    pub fn render(
        &mut self,
        camera: &Camera,
        opts: &RenderOptions,
        mut passes: Passes,
    ) -> Result<(Image, RenderStats)> {
        self.update(camera, &mut passes);
        if let Some(e) = self.pyramid().decode_error() {
            return Err(e);
        }
        let frustum = camera.frustum();
        let view = View::new(camera, &frustum, &self.world, self.size);
        let Kept {
            mut mesh,
            positions,
            attrs,
            mut buffers,
            target,
        } = std::mem::take(&mut self.kept);
        let mut cursor = 0;
        let batch = self.batch_triangles.max(1);
        let mut more = passes.time("mesh", || {
            self.lod.mesh_batch(&view, &mut cursor, batch, &mut mesh)
        });
        let clip = self.lod.take_clip_frame();
        // The frame is made for the view's levels, then given the kept
        // buffers and the first batch.
        let levels = LodMesh {
            level_info: mesh.level_info.clone(),
            ..Default::default()
        };
        let mut frame = self.build_frame(camera, levels, &mut passes)?;
        frame.positions = positions;
        frame.attrs = attrs;
        let opts_raster = Options { path: opts.path };
        let linear = &frame.layout.linear;
        let mut target = match target {
            Some(mut t) => {
                t.reset(frame.width, frame.height, linear, opts_raster);
                t
            }
            None => Target::new(frame.width, frame.height, linear, opts_raster),
        };
        let vp = Viewport::new(frame.width, frame.height);
        let mut drawn = Drawn::default();
        let mut first = Some(mesh);
        loop {
            let mut these = Passes::default();
            let mut mesh = match first.take() {
                Some(m) => m,
                None if more => {
                    let mut m = std::mem::take(&mut frame.mesh);
                    more = these.time("mesh", || {
                        self.lod.mesh_batch(&view, &mut cursor, batch, &mut m)
                    });
                    m
                }
                None => break,
            };
            drawn.triangles += mesh.triangle_count();
            let (u, path) = (&frame.uniforms, opts.path);
            these.time("cull", || {
                cull(&mut mesh, u, &vp, &mut buffers, &mut target, path)
            });
            passes.add(these);
            frame.next_batch(mesh, self.lod.pyramid(), &self.world, &mut passes);
            let d = Drawn::of(&frame);
            drawn.vertices += d.vertices;
            drawn.non_finite += d.non_finite;
            let mut these = Passes::default();
            these.time("raster", || {
                draw_frame(&frame, &mut buffers, &mut target);
                if more {
                    target.compact();
                }
            });
            passes.add(these);
        }
        let mut last = Passes::default();
        let r = last.time("raster", || target.finish());
        passes.add(last);
        let (image, raster) = shade_pass(&frame, r, opts, &mut passes, Some(&mut target));
        let mut s = stats(&frame, drawn, Backend::Cpu.name(), raster, passes);
        self.kept = Kept {
            mesh: frame.mesh,
            positions: frame.positions,
            attrs: frame.attrs,
            buffers,
            target: Some(target),
        };
        s.lazy = self.lazy_frame(clip.as_ref());
        s.raster_path = Some(opts.path.label());
        s.synthesis = self.synthesis.clone();
        Ok((image, s))
    }

    /// Rasterises and shades `frame` on the CPU as [`draw`] does, in the
    /// buffers this session keeps from image to image: for a caller that
    /// draws frames of its own one after another (a survey's schemes,
    /// `bench`), whose buffers would otherwise be mapped and zeroed by the
    /// kernel again for each.
    pub fn draw(
        &mut self,
        frame: &Frame,
        opts: &RenderOptions,
        passes: &mut Passes,
    ) -> (Image, RasterStats) {
        let mut kept = std::mem::take(&mut self.kept);
        let linear = &frame.layout.linear;
        let o = Options { path: opts.path };
        let target = match &mut kept.target {
            Some(t) => {
                t.reset(frame.width, frame.height, linear, o);
                t
            }
            none => none.insert(Target::new(frame.width, frame.height, linear, o)),
        };
        let r = passes.time("raster", || {
            draw_frame(frame, &mut kept.buffers, target);
            target.finish()
        });
        let out = shade_pass(frame, r, opts, passes, Some(target));
        self.kept = kept;
        out
    }

    /// The lazy pyramid's state after the frame `clip` was updated for.
    pub fn lazy_frame(&self, clip: Option<&ClipFrame>) -> Option<LazyFrame> {
        let update = clip.map(|c| &c.update);
        let resident = self.pyramid().tiles_resident();
        self.pyramid().lazy_stats().map(|pyramid| LazyFrame {
            pyramid,
            samples_this_frame: update.map_or(0, |u| u.pyramid_samples),
            tiles_this_frame: update.map_or(0, |u| u.pyramid_tiles),
            levels_unbuilt: update.map_or(0, |u| u.levels_unbuilt),
            levels_waiting: update.map_or(0, |u| u.levels_waiting),
            tiles_resident: resident,
            tiles_evicted: resident.map(|_| update.map_or(0, |u| u.tiles_evicted)),
        })
    }

    /// The surface `camera`'s frame draws, for `height_at` and `ray_hit`
    /// (it updates the LOD for that camera, as a render would).
    pub fn surface(&mut self, camera: &Camera) -> Result<crate::frame::surface::Surface> {
        let (frame, _) = self.frame(camera, &mut Passes::default())?;
        Ok(crate::frame::surface::Surface::new(&frame, &self.world))
    }

    /// Height of the base map at world point (x, y), nearest sample, in
    /// world units (for placing cameras above the terrain).
    pub fn ground(&self, x: f64, y: f64) -> f64 {
        let g = self.world.to_grid(glam::DVec3::new(x, y, 0.0));
        let z = self.pyramid().levels[0].get_clamped(g[0].round() as i64, g[1].round() as i64);
        z as f64 * self.world.vertical_scale
    }

    /// World extent of the map: (min corner, max corner) with the heights'
    /// range as z.
    pub fn extent(&self) -> (glam::DVec3, glam::DVec3) {
        let b = &self.pyramid().levels[0];
        self.world.aabb(
            0.0,
            0.0,
            (b.width - 1) as f64,
            (b.height - 1) as f64,
            b.min as f64,
            b.max as f64,
        )
    }
}
