//! LOD schemes turn the terrain and a view into triangles. Every scheme sits
//! behind the one [`Lod`] trait and hands the frame builder the same thing, a
//! [`LodMesh`], so the back ends never see which scheme made it and the
//! metrics compare schemes on equal terms.

pub mod annulus;
pub(crate) mod brute_force;
pub mod cbt;
pub mod cdlod;
pub mod clipmap;
pub mod focus;
pub mod geomipmap;
mod grid;
pub mod roam;

use crate::camera::{Camera, Frustum};
use crate::clipmap::{Clipmap, ClipmapConfig, Layout};
use crate::error::{Error, Result};
use crate::pyramid::Pyramid;
use crate::terrain::world::WorldMap;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The scene's `[lod]`: the scheme and its settings (docs/reference/lod-schemes.md lists which
/// scheme reads which key). Without the table, the clipmap with its defaults.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// The scheme (default `clipmap`).
    #[serde(default = "default_scheme")]
    pub scheme: LodScheme,
    /// Clipmap grid size, 2^k − 1 in 15..=4095 (default 63).
    #[serde(default = "default_n")]
    pub n: i64,
    /// Clipmap level count; the most the map allows if absent.
    pub levels: Option<usize>,
    /// Clipmap mesh layout: strips (LH04, Brettell) or footprints (GPU Gems 2).
    #[serde(default)]
    pub layout: Layout,
    /// Clipmap transition width in level texels; n/10 if absent, at most m − 3.
    pub transition: Option<f32>,
    /// Clipmap texels one update may rewrite; levels beyond it stay stale (LH04's graceful degradation).
    pub texel_budget: Option<u64>,
    /// Where the clipmap's levels nest: "eye" (LH04) or "view" (the
    /// terrain the view sees; [`focus`]).
    pub centre: Option<String>,
    /// GeoMipMapping: block side in vertices, 2^k + 1.
    pub block: Option<usize>,
    /// GeoMipMapping level choice: "linear", "exponential" or "error".
    pub mode: Option<String>,
    /// GeoMipMapping distance modes: distance (metres) of the first step.
    pub distance: Option<f64>,
    /// Screen-space error threshold in pixels (GeoMipMapping "error" mode,
    /// ROAM, CBT).
    pub tau: Option<f64>,
    /// ROAM: triangle budget.
    pub max_triangles: Option<usize>,
    /// CDLOD: node side in cells (2^k).
    pub grid: Option<usize>,
    /// CDLOD: first range as a multiple of the finest node's diagonal.
    pub range: Option<f64>,
}

fn default_scheme() -> LodScheme {
    LodScheme::Clipmap
}

impl Default for Spec {
    fn default() -> Self {
        Spec {
            scheme: default_scheme(),
            n: default_n(),
            levels: None,
            layout: Layout::default(),
            transition: None,
            texel_budget: None,
            centre: None,
            block: None,
            mode: None,
            distance: None,
            tau: None,
            max_triangles: None,
            grid: None,
            range: None,
        }
    }
}
fn default_n() -> i64 {
    63
}

crate::names::named! {
    /// A level-of-detail scheme.
    pub enum LodScheme ("scheme") {
        /// Geometry clipmaps, this project.
        Clipmap => "clipmap",
        /// Every heightmap vertex: the accuracy reference.
        BruteForce => "brute-force",
        /// de Boer's GeoMipMapping.
        Geomipmap => "geomipmap",
        /// Duchaineau's ROAM.
        Roam => "roam",
        /// Strugar's CDLOD.
        Cdlod => "cdlod",
        /// A "draping" annulus.
        Annulus => "annulus",
        /// Dupuy's concurrent binary tree running longest-edge bisection.
        Cbt => "cbt",
    }
}

/// One vertex as the LOD scheme emits it: base-grid position, own height,
/// the coarser surface's height there and the morph weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodVertex {
    /// Base-grid column.
    pub col: i64,
    /// Base-grid row.
    pub row: i64,
    /// Sub-texel offset added to (col, row), in base texels. Zero for
    /// schemes on the grid; the annulus (unsnapped) and CDLOD (xy morph)
    /// place vertices between grid points.
    pub offset: [f32; 2],
    /// The vertex's own height (height units).
    pub z: f32,
    /// The coarser surface's height at the same place: the morph target.
    pub zc: f32,
    /// Morph weight in 0..=1: the height drawn is z + alpha · (zc − z).
    pub alpha: f32,
}

impl LodVertex {
    /// An unmorphed vertex on the grid.
    #[inline]
    pub fn on_grid(col: i64, row: i64, z: f32) -> Self {
        LodVertex {
            col,
            row,
            offset: [0.0; 2],
            z,
            zc: z,
            alpha: 0.0,
        }
    }
}

/// Per-level constants the effects need (texture addressing).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelInfo {
    /// The level, 0 the finest.
    pub level: usize,
    /// Window origin in level texels.
    pub origin: [i64; 2],
    /// Window size in level texels (n for a clipmap level).
    pub size: [usize; 2],
    /// Whether this level morphs toward the next.
    pub morph: bool,
}

/// Unshared triangles (three vertices each) with a level per triangle.
#[derive(Clone, Debug, Default)]
pub struct LodMesh {
    /// Three vertices per triangle, unshared.
    pub vertices: Vec<LodVertex>,
    /// The level of each triangle (for per-level resources and `level-tint`).
    pub levels: Vec<u32>,
    /// Indexed by level number; levels not drawn may be absent (`None`).
    pub level_info: Vec<Option<LevelInfo>>,
}

impl LodMesh {
    /// Triangles in the mesh.
    pub fn triangle_count(&self) -> usize {
        self.levels.len()
    }

    /// An empty mesh whose triangles all use the base level's resources
    /// (normals, lightmap) over the whole `w`×`h` map: what every scheme
    /// but the clipmap draws with.
    pub fn base_level(w: usize, h: usize) -> Self {
        LodMesh {
            level_info: vec![Some(LevelInfo {
                level: 0,
                origin: [0, 0],
                size: [w, h],
                morph: false,
            })],
            ..Default::default()
        }
    }

    /// Appends the triangles `emit` makes for each item, made in parallel
    /// and appended in item order (so the mesh is the same for any thread
    /// count).
    pub fn append_parallel<T: Sync>(
        &mut self,
        items: &[T],
        emit: impl Fn(&T, &mut LodMesh) + Sync,
    ) {
        use rayon::prelude::*;
        let parts: Vec<LodMesh> = items
            .par_iter()
            .map(|it| {
                let mut m = LodMesh::default();
                emit(it, &mut m);
                m
            })
            .collect();
        for p in parts {
            self.vertices.extend(p.vertices);
            self.levels.extend(p.levels);
        }
    }

    /// The runs of consecutive triangles on one level, in draw order:
    /// (level, first triangle, end). Back ends that draw per level (the
    /// GPU's passthrough, the exported glTF's primitives) keep the
    /// triangles' order, which decides depth ties.
    pub fn level_runs(levels: &[u32]) -> Vec<(u32, usize, usize)> {
        let mut out = vec![];
        let mut t = 0;
        while t < levels.len() {
            let l = levels[t];
            let end = (t..levels.len())
                .find(|&j| levels[j] != l)
                .unwrap_or(levels.len());
            out.push((l, t, end));
            t = end;
        }
        out
    }

    /// Appends one triangle on the base level.
    #[inline]
    pub fn push(&mut self, t: [LodVertex; 3]) {
        self.vertices.extend(t);
        self.levels.push(0);
    }
}

/// What a scheme sees of the view.
pub struct View<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// Its frustum, for culling.
    pub frustum: &'a Frustum,
    /// Grid-to-world placement.
    pub world: &'a WorldMap,
    /// Image size in pixels (screen-space error thresholds need it).
    pub viewport: [u32; 2],
}

impl<'a> View<'a> {
    /// The view of `camera` (whose frustum is `frustum`) over `world` in an
    /// image of `viewport` pixels.
    pub fn new(
        camera: &'a Camera,
        frustum: &'a Frustum,
        world: &'a WorldMap,
        viewport: [u32; 2],
    ) -> Self {
        View {
            camera,
            frustum,
            world,
            viewport,
        }
    }

    /// Pixels per unit of (size ÷ distance) at the image centre: a world
    /// length e at distance d covers about `e · k / d` pixels.
    pub fn pixel_scale(&self) -> f64 {
        self.viewport[1] as f64 / (2.0 * (0.5 * self.camera.fov_y_deg.to_radians()).tan())
    }
}

/// What one update changed, for `fly` and the statistics.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct LodUpdate {
    /// Heightmap texels rewritten into the scheme's own storage (clipmap).
    pub texels_updated: u64,
    /// Structural changes: splits + merges (ROAM), blocks whose level
    /// changed (GeoMipMapping), nodes selected (CDLOD).
    pub changes: u64,
}

/// A terrain LOD scheme: state kept across frames (`update`) and the
/// triangles for a view (`mesh`). The two are separate timed passes, so
/// the trade-off report can split LOD cost into update and mesh generation.
pub trait Lod: Send {
    /// Which scheme this is.
    fn scheme(&self) -> LodScheme;
    /// The scheme's name.
    fn name(&self) -> &'static str {
        self.scheme().name()
    }
    /// Moves the scheme's state to the view.
    fn update(&mut self, view: &View) -> LodUpdate;
    /// The triangles for the view, culled to its frustum.
    fn mesh(&mut self, view: &View) -> LodMesh;
    /// The same triangles in consecutive batches, in draw order, for a
    /// back end that draws as they come: `cursor` starts at 0 and says
    /// where the next batch begins; `out` is replaced by a batch of about
    /// `max` triangles (its memory kept), and the answer is whether more
    /// follow. A scheme whose mesh is small gives it whole, in one batch;
    /// brute force, whose mesh grows with the map, gives rows of blocks.
    fn mesh_batch(
        &mut self,
        view: &View,
        cursor: &mut usize,
        max: usize,
        out: &mut LodMesh,
    ) -> bool {
        let _ = (cursor, max);
        *out = self.mesh(view);
        false
    }
    /// The terrain the scheme draws from (the frame reads normals and
    /// bounds from it; a lazy one grows as the scheme updates).
    fn pyramid(&self) -> &Pyramid;
    /// The clipmap, for a back end that draws from its own toroidal copy.
    fn clipmap(&self) -> Option<&Clipmap> {
        None
    }
    /// The clipmap's level meshes and update from the last `mesh`/`update`.
    fn take_clip_frame(&mut self) -> Option<clipmap::ClipFrame> {
        None
    }
}

/// A scheme and its settings, as a scene names them.
#[derive(Clone, Debug, PartialEq)]
pub enum LodConfig {
    /// Geometry clipmaps (LH04), nested around the eye or the view.
    Clipmap(ClipmapConfig, clipmap::Centre),
    /// Every base-grid cell: the reference the others are measured against.
    BruteForce,
    /// GeoMipMapping blocks.
    GeoMipMap(geomipmap::Config),
    /// ROAM's split and merge queues.
    Roam(roam::Config),
    /// A draping annulus of fixed rings around the viewer.
    Annulus(annulus::Config),
    /// CDLOD's quadtree with per-vertex morphing.
    Cdlod(cdlod::Config),
    /// Longest-edge bisection in a concurrent binary tree.
    Cbt(cbt::Config),
}

impl LodConfig {
    /// The scheme and settings a scene's `[lod]` table asks for, checked;
    /// `morph` is whether the scene lists geomorphing. Errors name the
    /// field (`lod.tau`, …); the caller adds the scene's name.
    pub fn from_spec(l: &Spec, morph: bool) -> Result<LodConfig> {
        let pow2 = |field: &str, v: usize, lo: usize, hi: usize| -> Result<usize> {
            if v.is_power_of_two() && (lo..=hi).contains(&v) {
                Ok(v)
            } else {
                Err(Error::value(
                    field,
                    format!("must be a power of two in {lo}..={hi}, got {v}"),
                ))
            }
        };
        let positive = |field: &str, v: Option<f64>, default: f64| -> Result<f64> {
            match v {
                None => Ok(default),
                Some(x) if x.is_finite() && x > 0.0 => Ok(x),
                Some(x) => Err(Error::value(
                    field,
                    format!("must be finite and > 0, got {x}"),
                )),
            }
        };
        Ok(match l.scheme {
            LodScheme::Clipmap => LodConfig::Clipmap(
                ClipmapConfig {
                    n: l.n,
                    levels: l.levels,
                    layout: l.layout,
                    transition: l.transition,
                    morph,
                    texel_budget: l.texel_budget,
                },
                match l.centre.as_deref().unwrap_or("eye") {
                    "eye" => clipmap::Centre::Eye,
                    // The footprints' trims fix where each level sits in
                    // the coarser one.
                    "view" if l.layout == Layout::Footprints => {
                        return Err(Error::value(
                            "lod.centre",
                            "\"view\" places each level on its own, which needs lod.layout = \"strips\"",
                        ))
                    }
                    "view" => clipmap::Centre::View {
                        tau: positive("lod.tau", l.tau, 1.0)?,
                    },
                    c => {
                        return Err(Error::value(
                            "lod.centre",
                            format!("unknown centre '{c}' (available: eye, view)"),
                        ))
                    }
                },
            ),
            LodScheme::BruteForce => LodConfig::BruteForce,
            LodScheme::Geomipmap => {
                let block = l.block.unwrap_or(33);
                let cells = block
                    .checked_sub(1)
                    .filter(|c| c.is_power_of_two() && (4..=256).contains(c))
                    .ok_or_else(|| {
                        Error::value(
                            "lod.block",
                            format!("must be 2^k + 1 vertices with 5 <= block <= 257, got {block}"),
                        )
                    })?;
                let distance = positive("lod.distance", l.distance, 500.0)?;
                let mode = match l.mode.as_deref().unwrap_or("error") {
                    "linear" => geomipmap::Mode::Linear { distance },
                    "exponential" => geomipmap::Mode::Exponential { distance },
                    "error" => geomipmap::Mode::Error {
                        tau: positive("lod.tau", l.tau, 2.0)?,
                    },
                    m => {
                        return Err(Error::value(
                            "lod.mode",
                            format!("unknown mode '{m}' (available: linear, exponential, error)"),
                        ))
                    }
                };
                LodConfig::GeoMipMap(geomipmap::Config { cells, mode, morph })
            }
            LodScheme::Roam => LodConfig::Roam(roam::Config {
                tau: positive("lod.tau", l.tau, 2.0)?,
                max_triangles: match l.max_triangles {
                    Some(0) => return Err(Error::value("lod.max_triangles", "must be > 0")),
                    Some(m) => m,
                    None => 1 << 20,
                },
            }),
            LodScheme::Cbt => LodConfig::Cbt(cbt::Config {
                tau: positive("lod.tau", l.tau, 2.0)?,
                morph,
            }),
            LodScheme::Annulus => LodConfig::Annulus(annulus::Config {
                n: l.n,
                rings: l.levels.unwrap_or(6).clamp(1, 24),
            }),
            LodScheme::Cdlod => LodConfig::Cdlod(cdlod::Config {
                grid: pow2("lod.grid", l.grid.unwrap_or(32), 4, 256)?,
                range: match positive("lod.range", l.range, 2.0)? {
                    r if r >= 1.0 => r,
                    r => return Err(Error::value("lod.range", format!("must be >= 1, got {r}"))),
                },
                morph,
            }),
        })
    }

    /// The scheme's name (as scenes and the CLI spell it).
    pub fn scheme(&self) -> LodScheme {
        match self {
            LodConfig::Clipmap(..) => LodScheme::Clipmap,
            LodConfig::BruteForce => LodScheme::BruteForce,
            LodConfig::GeoMipMap(_) => LodScheme::Geomipmap,
            LodConfig::Roam(_) => LodScheme::Roam,
            LodConfig::Annulus(_) => LodScheme::Annulus,
            LodConfig::Cdlod(_) => LodScheme::Cdlod,
            LodConfig::Cbt(_) => LodScheme::Cbt,
        }
    }

    /// The scheme's name.
    pub fn name(&self) -> &'static str {
        self.scheme().name()
    }

    /// Pyramid levels the scheme reads (level 1 always exists where the map
    /// allows, for the lightmap's and normal map's blends).
    pub fn pyramid_levels(&self, w: usize, h: usize) -> usize {
        match self {
            LodConfig::Clipmap(c, _) => c
                .levels
                .unwrap_or_else(|| crate::clipmap::region::max_levels(w, h, c.n))
                .max(1),
            LodConfig::Annulus(c) => c.rings.max(2),
            _ => 2,
        }
    }

    /// The scheme over `pyramid`.
    pub fn build(&self, pyramid: Arc<Pyramid>) -> Result<Box<dyn Lod>> {
        Ok(match self {
            LodConfig::Clipmap(c, centre) => Box::new(
                clipmap::ClipmapLod::new(Clipmap::new(pyramid, c.clone())?).centred(*centre),
            ),
            LodConfig::BruteForce => Box::new(brute_force::BruteForce::new(pyramid)),
            LodConfig::GeoMipMap(c) => Box::new(geomipmap::GeoMipMap::new(pyramid, *c)),
            LodConfig::Roam(c) => Box::new(roam::Roam::new(pyramid, *c)),
            LodConfig::Annulus(c) => Box::new(annulus::Annulus::new(pyramid, *c)),
            LodConfig::Cdlod(c) => Box::new(cdlod::Cdlod::new(pyramid, *c)),
            LodConfig::Cbt(c) => Box::new(cbt::Cbt::new(pyramid, *c)),
        })
    }
}
