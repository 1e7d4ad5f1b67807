//! The CPU geometry-clipmap engine: L nested n×n grids around the viewer,
//! held in toroidal arrays, updated in L-shaped strips, meshed in one of two
//! index layouts, geomorphed in transition bands and culled to the frustum.

pub mod columns;
pub mod cull;
pub(crate) mod footprint;
pub(crate) mod level;
pub(crate) mod morph;
pub mod region;
pub mod toroid;

use crate::camera::Frustum;
use crate::error::{Error, Result};
use crate::pyramid::Pyramid;
use crate::terrain::world::WorldMap;
pub use footprint::{Footprints, Instance, ShapeId};
pub use level::ClipLevel;
pub use morph::MorphParams;
use rayon::prelude::*;
use region::{Rect, RegionParams};
use serde::Serialize;
use std::sync::Arc;
use toroid::TexRects;

crate::names::named! {
    /// Index layout used to mesh each level.
    #[derive(Default)]
    pub enum Layout ("layout") {
        /// Brettell / LH04: strips over the toroid, cropped to finite maps.
        #[default]
        Strips => "strips",
        /// GPU Gems 2: static footprints; full rings, blocks off the map
        /// culled.
        Footprints => "footprints",
    }
}

/// Side, in level texels, down to which a placed level's render
/// rectangles are cut for culling ([`cull::cull_blocks`]): small enough
/// that a 1° view's wedge is not drawn as its bounding rectangle, large
/// enough that a level's rectangles stay a few dozen.
const CULL_BLOCK: i64 = 16;

/// Clipmap settings.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipmapConfig {
    /// Grid size n = 2^k − 1 (15 ≤ n ≤ 4095).
    pub n: i64,
    /// Level count; `None` = the most the map allows.
    pub levels: Option<usize>,
    /// Strips over the toroid, or static footprints (LH04 / GPU Gems 2 ch. 2).
    pub layout: Layout,
    /// Transition width w in level texels; `None` = n/10 (capped at m − 3).
    pub transition: Option<f32>,
    /// Geomorphing on or off (off shows the cracks and pops it hides).
    pub morph: bool,
    /// At most this many texels rewritten per update, coarse levels first;
    /// levels that do not fit are deactivated for the frame (LH04's graceful
    /// degradation). The coarsest level is always updated.
    pub texel_budget: Option<u64>,
}

impl Default for ClipmapConfig {
    fn default() -> Self {
        ClipmapConfig {
            n: 63,
            levels: None,
            layout: Layout::Strips,
            transition: None,
            morph: true,
            texel_budget: None,
        }
    }
}

/// What one update did, per level (finest first).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct UpdateStats {
    /// Texels rewritten in each level.
    pub texels_per_level: Vec<u64>,
    /// The toroid rectangles rewritten in each level (what a GPU back end uploads).
    pub rects_per_level: Vec<TexRects>,
    /// Texels rewritten over all levels.
    pub texels_total: u64,
    /// Levels left stale (and inactive) because the budget ran out.
    pub levels_deferred: usize,
    /// Coarsest levels left out (inactive) because a lazy pyramid has not
    /// built their tiles yet.
    pub levels_unbuilt: usize,
    /// Finest levels left out (inactive) because a pyramid decoded from a
    /// pack has not decoded their windows within its budget yet.
    pub levels_waiting: usize,
    /// Pyramid samples a lazy pyramid built, or a pack decoded, for this
    /// update.
    pub pyramid_samples: u64,
    /// Pyramid tiles built or decoded for this update.
    pub pyramid_tiles: u64,
    /// Decoded tiles evicted by this update (they left their windows).
    pub tiles_evicted: u64,
    /// Source rows copied into column blocks ([`columns::BLOCK`] texels
    /// each) for east and west steps: a walk's cost in fresh source reads.
    pub column_rows_copied: u64,
}

/// A mesh vertex after the vertex stage: base-grid position and heights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshVertex {
    /// Base-grid column.
    pub x: i64,
    /// Base-grid row.
    pub y: i64,
    /// Own height, coarser-level height, morph weight and morphed height.
    pub z: f32,
    /// The coarser level's height here: what the vertex morphs towards.
    pub zc: f32,
    /// Morph weight: 0 inside the transition band, rising to 1 at the level's outer edge.
    pub alpha: f32,
    /// The height drawn: z + alpha · (zc − z).
    pub zm: f32,
}

/// One level's geometry for a frame, in the layout's own form.
#[derive(Clone, Debug, PartialEq)]
pub enum LevelGeometry {
    /// Strip indices into the level's toroid (vertex i = toroid texel i).
    Strips {
        /// One triangle strip; rows are joined by degenerate triangles.
        strip: Vec<u32>,
    },
    /// Placed static footprints.
    Footprints {
        /// The footprints placed for the frame (culled ones left out).
        instances: Vec<Instance>,
        /// In-map triangles (toroid indices) of blocks that cross the
        /// usable map's edge: drawn like strips, so nothing is drawn
        /// beyond the map (no shelf of edge heights, no curtains).
        edge: Vec<[u32; 3]>,
    },
}

/// One level's share of a frame's clipmap mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelMesh {
    /// The level, 0 the finest.
    pub level: usize,
    /// Its triangles, in the layout's form.
    pub geometry: LevelGeometry,
}

/// The engine.
#[derive(Clone, Debug)]
pub struct Clipmap {
    cfg: ClipmapConfig,
    n: i64,
    pyramid: Arc<Pyramid>,
    params: RegionParams,
    levels: Vec<ClipLevel>,
    footprints: Arc<Footprints>,
    viewer: [f64; 2],
    /// Per level, the centre [`Clipmap::update_placed`] was given (empty
    /// for a clipmap centred on the viewer).
    wants: Vec<Option<[f64; 2]>>,
    /// The last update's statistics and this frame's regions, kept so an
    /// update reuses their memory instead of allocating every frame.
    stats: UpdateStats,
    regions: Vec<region::LevelRegions>,
}

impl Clipmap {
    /// Validates the settings against the map and allocates the levels.
    pub fn new(pyramid: Arc<Pyramid>, cfg: ClipmapConfig) -> Result<Self> {
        region::check_n(cfg.n).map_err(|r| Error::value("lod.n", r))?;
        let base = &pyramid.levels[0];
        let max = region::max_levels(base.width, base.height, cfg.n);
        let count = cfg.levels.unwrap_or(max);
        if count == 0 || count > max {
            return Err(Error::value(
                "lod.levels",
                format!(
                    "{count} levels requested, but a {}×{} map with n = {} allows 1..={max}",
                    base.width, base.height, cfg.n
                ),
            ));
        }
        if pyramid.levels.len() < count {
            return Err(Error::value(
                "lod.levels",
                format!(
                    "pyramid has {} levels, {count} needed",
                    pyramid.levels.len()
                ),
            ));
        }
        let m = region::block_size(cfg.n) as f32;
        let w = cfg.transition.unwrap_or((cfg.n as f32 / 10.0).min(m - 3.0));
        if !(w > 0.0 && w <= m - 3.0) {
            return Err(Error::value(
                "lod.transition",
                format!(
                    "transition width must be in (0, {}] for n = {} so the band never reaches a level's inner edge, got {w}",
                    m - 3.0,
                    cfg.n
                ),
            ));
        }
        let map = match cfg.layout {
            Layout::Strips => Some(region::map_bounds(base.width, base.height, count)),
            Layout::Footprints => None,
        };
        let params = RegionParams {
            n: cfg.n,
            levels: count,
            map,
        };
        let regions = region::compute(&params, [0.0, 0.0]);
        let levels: Vec<ClipLevel> = (0..count)
            .map(|l| {
                let mut lv = ClipLevel::new(l, cfg.n as usize, regions[l]);
                lv.morph.width = w;
                lv
            })
            .collect();
        Ok(Clipmap {
            n: cfg.n,
            footprints: Arc::new(Footprints::new(cfg.n)),
            cfg,
            pyramid,
            params,
            levels,
            viewer: [f64::NAN; 2],
            wants: Vec::new(),
            stats: UpdateStats::default(),
            regions,
        })
    }

    /// The configuration it was built with.
    pub fn config(&self) -> &ClipmapConfig {
        &self.cfg
    }
    /// The grid size n of every level.
    pub fn n(&self) -> i64 {
        self.n
    }
    /// The levels, finest first.
    pub fn levels(&self) -> &[ClipLevel] {
        &self.levels
    }
    /// The pyramid the levels are filled from.
    pub fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }
    /// The footprint meshes shared by every level (footprints layout).
    pub fn footprints(&self) -> &Footprints {
        &self.footprints
    }
    /// The region parameters (m, margins) derived from n.
    pub fn region_params(&self) -> &RegionParams {
        &self.params
    }
    /// The viewer (base-grid units) of the last update.
    pub fn viewer(&self) -> [f64; 2] {
        self.viewer
    }
    /// Usable map bounds (strips layout) in base vertices.
    pub fn map_bounds(&self) -> Option<Rect> {
        self.params.map
    }

    /// The usable map in level-`l` texels (the same rectangle on every
    /// level, on grid lines of all of them). The footprint layout draws
    /// only what lies inside it.
    pub fn level_bounds(&self, l: usize) -> Rect {
        let b = &self.pyramid.levels[0];
        let m = region::map_bounds(b.width, b.height, self.levels.len());
        Rect::new(m.x0 >> l, m.y0 >> l, m.x1 >> l, m.y1 >> l)
    }

    /// Marks every level stale, so the next update rebuilds all texels (after
    /// the terrain under the clipmap changed, or to time a full rebuild).
    pub fn invalidate(&mut self) {
        self.levels.iter_mut().for_each(|l| {
            l.heights.invalidate();
            l.columns.clear();
        });
    }

    /// Moves every level to the viewer at base-grid position `viewer`,
    /// rewriting only newly exposed texels, coarse levels first. Allocates
    /// nothing once the first update has sized its lists (with an eager
    /// pyramid), so a one-texel step costs about the texels it writes.
    pub fn update(&mut self, viewer: [f64; 2]) -> &UpdateStats {
        self.wants.clear();
        self.update_levels(viewer)
    }

    /// [`Clipmap::update`] with level l centred on `wants[l]` where it
    /// gives a point (base-grid units), as near as nesting allows
    /// ([`region::placed_into`]): a view-dependent clipmap's placement.
    /// The coarsest level keeps the viewer's window, and each level's morph
    /// is centred on its own window.
    pub fn update_placed(&mut self, viewer: [f64; 2], wants: &[Option<[f64; 2]>]) -> &UpdateStats {
        self.wants.clear();
        self.wants.extend_from_slice(wants);
        if self.wants.is_empty() {
            // No want at all still places (every level on the viewer's chain).
            self.wants.push(None);
        }
        self.update_levels(viewer)
    }

    /// The regions of every level for `viewer` (and the wants, if placed).
    fn regions_into(
        &self,
        p: &RegionParams,
        viewer: [f64; 2],
        out: &mut Vec<region::LevelRegions>,
    ) {
        if self.wants.is_empty() {
            region::compute_into(p, viewer, out);
        } else {
            let width = self.levels.first().map_or(1.0, |l| l.morph.width);
            region::placed_into(p, viewer, width, &self.wants, out);
        }
    }

    fn update_levels(&mut self, viewer: [f64; 2]) -> &UpdateStats {
        let count = self.levels.len();
        let placed = !self.wants.is_empty();
        let viewer = if viewer[0].is_finite() && viewer[1].is_finite() {
            viewer
        } else {
            [0.0, 0.0]
        };
        let previous = std::mem::replace(&mut self.viewer, viewer);
        // While level 0's origin stays put (a still viewer, every other
        // frame of a one-texel walk) and every level holds its window, the
        // regions and toroids are already right: only the morph viewer moves.
        // The last frame's regions are `region::compute`'s own (none was
        // cut back for a budget or an unbuilt level).
        let pristine = self.stats.levels_deferred == 0
            && self.stats.levels_unbuilt == 0
            && self.stats.levels_waiting == 0
            && self.regions.len() == count;
        let settled = pristine
            && !placed
            && self.pyramid.is_complete()
            && self.regions[0].origin == region::level0_origin(&self.params, viewer)
            && self
                .levels
                .iter()
                .zip(&self.regions)
                .all(|(lv, r)| lv.heights.origin() == Some(r.origin));
        let mut regions = std::mem::take(&mut self.regions);
        let mut stats = std::mem::take(&mut self.stats);
        if stats.texels_per_level.len() == count && stats.rects_per_level.len() == count {
            // Only the levels the last update wrote (at most a few after a
            // step) hold anything to clear.
            let last = stats
                .texels_per_level
                .iter_mut()
                .zip(&mut stats.rects_per_level);
            for (t, r) in last.filter(|(t, _)| **t != 0) {
                (*t, *r) = (0, TexRects::default());
            }
        } else {
            stats.texels_per_level.clear();
            stats.texels_per_level.resize(count, 0);
            stats.rects_per_level.clear();
            stats.rects_per_level.resize(count, TexRects::default());
        }
        stats.texels_total = 0;
        stats.levels_deferred = 0;
        stats.levels_unbuilt = 0;
        stats.levels_waiting = 0;
        stats.pyramid_samples = 0;
        stats.pyramid_tiles = 0;
        stats.tiles_evicted = 0;
        stats.column_rows_copied = 0;
        if !settled {
            if pristine && !placed {
                region::update_into(&self.params, viewer, &mut regions);
            } else {
                self.regions_into(&self.params, viewer, &mut regions);
            }
            self.move_levels(viewer, &mut regions, &mut stats);
        }
        let clamped = region::clamp_viewer(self.params.map.as_ref(), viewer);
        // 2^-l: exact, so the product has the bits of a division by 2^l.
        let mut scale = 1.0f64;
        for l in 0..count {
            let lv = &mut self.levels[l];
            // Read from the local list: reading back the fields just stored
            // stalls on store forwarding. Only the origin on a settled frame:
            // copying the whole regions cost more than the rest of its loop.
            let o = regions[l].origin;
            lv.morph.viewer = if placed {
                // A placed level's window is centred on itself.
                [lv.morph.half; 2]
            } else {
                [
                    (clamped[0] * scale - o[0] as f64) as f32,
                    (clamped[1] * scale - o[1] as f64) as f32,
                ]
            };
            scale *= 0.5;
            if settled {
                // Regions, and so the rest of the morph constants, as before.
                continue;
            }
            let r = regions[l];
            lv.regions = r;
            lv.morph.enabled = self.cfg.morph
                && l + 1 < count
                && regions.get(l + 1).is_some_and(|r| r.active.is_some());
            if let Some(a) = r.active {
                let b = footprint::to_level(&a, l);
                lv.morph.boundary = [
                    (b[0] - o[0]) as i32,
                    (b[1] - o[1]) as i32,
                    (b[2] - o[0]) as i32,
                    (b[3] - o[1]) as i32,
                ];
                lv.morph.stitched = r.map_sides.map(|s| !s);
            }
        }
        self.regions = regions;
        self.stats = stats;
        if !placed {
            self.prefetch_ahead(previous, viewer);
        }
        &self.stats
    }

    /// Starts loading the source rows the next update will copy if the
    /// viewer repeats its last vertical step, so that copy finds them in
    /// cache. (Column blocks are not prefetched: it made east walks
    /// slower; `docs/explanation/performance.md` has the figures.) Only for small steps and a complete pyramid (a lazy one may
    /// not have built them). A hint: no value changes.
    fn prefetch_ahead(&self, previous: [f64; 2], viewer: [f64; 2]) {
        let d = [viewer[0] - previous[0], viewer[1] - previous[1]];
        let small = d.iter().all(|c| c.abs() <= 8.0) && d != [0.0, 0.0];
        if !small || !self.pyramid.is_complete() {
            return;
        }
        let (n, m) = (self.n, region::block_size(self.n));
        let next = [viewer[0] + d[0], viewer[1] + d[1]];
        let mut o = region::level0_origin(&self.params, next);
        for (lv, src) in self.levels.iter().zip(&self.pyramid.levels) {
            let Some(cur) = lv.heights.origin() else {
                break;
            };
            if o == cur {
                // Coarser origins follow from this one: they stay put too.
                break;
            }
            let rows = if o[1] > cur[1] {
                cur[1] + n..o[1] + n
            } else {
                o[1]..cur[1]
            };
            for y in rows {
                src.prefetch_row(o[0], o[0] + n, y);
            }
            o = region::coarser_origin(o, m);
        }
    }

    /// Moves every ready level's toroid to its window in `regions` (the
    /// viewer's), coarse first, within the texel budget; a lazy pyramid's
    /// unbuilt levels and the levels past the budget are made inactive.
    fn move_levels(
        &mut self,
        viewer: [f64; 2],
        regions: &mut [region::LevelRegions],
        stats: &mut UpdateStats,
    ) {
        let count = self.levels.len();
        let ready = self.build_pyramid(regions, stats);
        let complete = self.pyramid.is_complete();
        if ready.end < count {
            // The ready levels are drawn as a clipmap of their own: the
            // coarsest of them is cropped only by the map.
            let params = RegionParams {
                levels: ready.end,
                ..self.params
            };
            let mut own = Vec::with_capacity(params.levels);
            self.regions_into(&params, viewer, &mut own);
            regions[..ready.end].copy_from_slice(&own);
            regions[ready.end..]
                .iter_mut()
                .for_each(|r| r.active = None);
            stats.levels_unbuilt = count - ready.end;
        }
        // Finer levels a pack has not decoded yet wait, as levels past the
        // texel budget do.
        regions[..ready.start]
            .iter_mut()
            .for_each(|r| r.active = None);
        stats.levels_waiting = ready.start;
        let mut budget = self.cfg.texel_budget.unwrap_or(u64::MAX);
        let mut deferred_from = None;
        for l in ready.clone().rev() {
            let lv = &mut self.levels[l];
            let origin = regions[l].origin;
            if lv.heights.origin() == Some(origin) {
                continue;
            }
            // Moved (or first filled), so never empty.
            let rects = toroid::update_rects(lv.heights.origin(), origin, self.n as usize);
            let needed: u64 = rects.iter().map(|r| r.area() as u64).sum();
            if needed > budget && l + 1 < ready.end {
                deferred_from = Some(l);
                break;
            }
            budget = budget.saturating_sub(needed);
            let src = &self.pyramid.levels[l];
            let tall = |r: &&toroid::TexRect| {
                r.x1 - r.x0 <= toroid::NARROW && r.y1 - r.y0 > toroid::NARROW
            };
            // Only a finished pyramid: a lazy one's columns beyond the
            // window may not be built yet. A finished one never changes,
            // so a step without a column (a level moving only vertically
            // this frame, as coarse levels of a diagonal walk do every
            // other step) keeps its block for the next one.
            if !complete {
                lv.columns.clear();
            } else if let Some(r) = rects.iter().find(tall) {
                let x = toroid::Toroid::<f32>::world_of(r.x0, origin[0], self.n as usize);
                stats.column_rows_copied +=
                    lv.columns.ensure(src, x, origin[1], origin[1] + self.n);
            }
            stats.texels_per_level[l] = needed;
            stats.texels_total += needed;
            stats.rects_per_level[l] = rects;
        }
        if let Some(d) = deferred_from {
            for r in regions.iter_mut().take(d + 1) {
                r.active = None;
            }
            stats.levels_deferred = d + 1;
        }
        // The writes, once planned. Each level's toroid is its own, so a
        // large update (after a jump) writes all levels in one parallel
        // pass: one fork for the frame, not one per level, each of which
        // had to wake the pool again. A step's few hundred texels stay on
        // this thread.
        let (pyramid, plan, regions) = (&self.pyramid, &stats.rects_per_level, &*regions);
        let write = |(l, lv): (usize, &mut ClipLevel)| {
            let rects = &plan[l];
            if !rects.is_empty() {
                let src = columns::LevelSource {
                    level: &pyramid.levels[l],
                    cache: &lv.columns,
                };
                lv.heights.move_from(regions[l].origin, rects, &src);
            }
        };
        if stats.texels_total >= toroid::PARALLEL_TEXELS as u64 {
            self.levels.par_iter_mut().enumerate().for_each(write);
        } else {
            self.levels.iter_mut().enumerate().for_each(write);
        }
    }

    /// For a lazy pyramid, builds the tiles under each level's window (one
    /// texel wider, for normals and height bounds) within the pyramid's
    /// budget, or decodes them from a pack; returns the levels ready. The
    /// pyramid is shared copy-on-write: a clipmap that was cloned builds
    /// its own.
    fn build_pyramid(
        &mut self,
        regions: &[region::LevelRegions],
        stats: &mut UpdateStats,
    ) -> std::ops::Range<usize> {
        if self.pyramid.is_complete() {
            return 0..self.levels.len();
        }
        let n = self.n;
        let windows: Vec<[i64; 4]> = regions
            .iter()
            .map(|r| {
                [
                    r.origin[0] - 1,
                    r.origin[1] - 1,
                    r.origin[0] + n,
                    r.origin[1] + n,
                ]
            })
            .collect();
        let built = Arc::make_mut(&mut self.pyramid).build_around(&windows);
        stats.pyramid_samples = built.samples;
        stats.pyramid_tiles = built.tiles;
        stats.tiles_evicted = built.evicted;
        built.ready
    }

    /// The vertex stage for level `l` at level texel (x, y): stitching
    /// ([`morph::MorphParams::stitch`]), height fetch, coarser height, α and
    /// the morphed height.
    #[inline]
    pub fn vertex(&self, l: usize, x: i64, y: i64) -> MeshVertex {
        let lv = &self.levels[l];
        let o = lv.regions.origin;
        let (sx, sy) = lv.morph.stitch((x - o[0]) as i32, (y - o[1]) as i32);
        let (x, y) = (o[0] + sx as i64, o[1] + sy as i64);
        let z = lv.heights.get(x, y);
        let alpha = lv.morph.alpha(sx, sy);
        let zc = if lv.morph.enabled {
            morph::coarse_height(&self.levels[l + 1].heights, x, y)
        } else {
            z
        };
        let g = 1i64 << l;
        MeshVertex {
            x: x * g,
            y: y * g,
            z,
            zc,
            alpha,
            zm: morph::blend(z, zc, alpha),
        }
    }

    /// Height range a level's morphed vertices can take: the samples of its
    /// window (one texel wider, for stitching) and of the window of the level
    /// it morphs toward, which holds it. Taken from the windows rather than
    /// whole levels, so culling does not depend on the terrain's size.
    pub fn height_range(&self, l: usize) -> (f32, f32) {
        let window = |l: usize| {
            let o = self.levels[l].regions.origin;
            [o[0] - 1, o[1] - 1, o[0] + self.n, o[1] + self.n]
        };
        self.morphed_range(l, window(l), || window(l + 1))
    }

    /// Bounds on level l's morphed heights over level texels `own`, whose
    /// coarser samples lie in level l + 1's texels `coarser()` (asked only
    /// where the level morphs, so never past the coarsest).
    fn morphed_range(
        &self,
        l: usize,
        own: [i64; 4],
        coarser: impl FnOnce() -> [i64; 4],
    ) -> (f32, f32) {
        let (mut lo, mut hi) = self.pyramid.range_in(l, own);
        if self.levels[l].morph.enabled {
            let (a, b) = self.pyramid.range_in(l + 1, coarser());
            lo = lo.min(a);
            hi = hi.max(b);
        }
        (lo, hi)
    }

    /// Builds this frame's meshes, culled and cropped to `frustum` if given.
    pub fn meshes(&self, frustum: Option<(&Frustum, &WorldMap)>) -> Vec<LevelMesh> {
        let count = self.levels.len();
        (0..count)
            .filter(|&l| self.levels[l].is_active())
            .map(|l| {
                let geometry = match self.cfg.layout {
                    Layout::Strips => self.strip_geometry(l, frustum),
                    Layout::Footprints => self.footprint_geometry(l, frustum),
                };
                LevelMesh { level: l, geometry }
            })
            .collect()
    }

    fn strip_geometry(&self, l: usize, frustum: Option<(&Frustum, &WorldMap)>) -> LevelGeometry {
        let lv = &self.levels[l];
        let regions: Vec<_> = self.levels.iter().map(|lv| lv.regions).collect();
        let (zlo, zhi) = self.height_range(l);
        let g = lv.spacing();
        let level_rects = region::render_rects(&regions, l)
            .into_iter()
            .map(|r| footprint::to_level(&r, l));
        let rects: Vec<[i64; 4]> = match frustum {
            None => level_rects.collect(),
            // A placed level is culled in blocks, each with the height
            // bounds of its own reach (and of the coarser level it morphs
            // toward, as `height_range` takes them).
            Some((f, w)) if !self.wants.is_empty() => {
                let range = |at: [i64; 4]| {
                    self.morphed_range(l, at, || {
                        [at[0] >> 1, at[1] >> 1, (at[2] + 1) >> 1, (at[3] + 1) >> 1]
                    })
                };
                let mut out = Vec::new();
                for r in level_rects {
                    cull::cull_blocks(f, w, r, g, CULL_BLOCK, &range, &mut out);
                }
                out
            }
            Some((f, w)) => level_rects
                .filter_map(|r| cull::cull_rect(f, w, r, g, zlo, zhi))
                .collect(),
        };
        LevelGeometry::Strips {
            strip: footprint::strip_indices(&lv.heights, &rects),
        }
    }

    fn footprint_geometry(
        &self,
        l: usize,
        frustum: Option<(&Frustum, &WorldMap)>,
    ) -> LevelGeometry {
        let lv = &self.levels[l];
        let finer = l
            .checked_sub(1)
            .filter(|&f| self.levels[f].is_active())
            .map(|f| self.levels[f].regions.origin);
        let mut instances = self.footprints.instances(lv.regions.origin, finer);
        if let Some((f, w)) = frustum {
            let (zlo, zhi) = self.height_range(l);
            let g = lv.spacing() as f64;
            let base = &self.pyramid.levels[0];
            let map = [(base.width - 1) as f64, (base.height - 1) as f64];
            instances.retain(|i| {
                let s = self.footprints.shape(i.shape);
                let (mut x0, mut y0, mut x1, mut y1) = (i32::MAX, i32::MAX, i32::MIN, i32::MIN);
                for v in &s.vertices {
                    x0 = x0.min(v[0]);
                    y0 = y0.min(v[1]);
                    x1 = x1.max(v[0]);
                    y1 = y1.max(v[1]);
                }
                let r = cull::stitch_reach([
                    i.offset[0] + x0 as i64,
                    i.offset[1] + y0 as i64,
                    i.offset[0] + x1 as i64,
                    i.offset[1] + y1 as i64,
                ])
                .map(|v| v as f64 * g);
                let off_map = r[2] < 0.0 || r[3] < 0.0 || r[0] > map[0] || r[1] > map[1];
                let (lo, hi) = w.aabb(r[0], r[1], r[2], r[3], zlo as f64, zhi as f64);
                !off_map && cull::classify(f, lo, hi) != cull::Class::Outside
            });
        }
        // Blocks crossing the map edge: their in-map triangles only. The
        // bounds lie on grid lines of every level, so a cell is wholly in
        // or out.
        let b = self.level_bounds(l);
        let n = self.n;
        let inside = |x: i64, y: i64| x >= b.x0 && x <= b.x1 && y >= b.y0 && y <= b.y1;
        let mut edge = Vec::new();
        instances.retain(|i| {
            let s = self.footprints.shape(i.shape);
            let at = |v: [i32; 2]| (i.offset[0] + v[0] as i64, i.offset[1] + v[1] as i64);
            if s.vertices.iter().all(|&v| inside(at(v).0, at(v).1)) {
                return true;
            }
            for t in &s.triangles {
                let p = t.map(|k| at(s.vertices[k as usize]));
                if p.iter().all(|&(x, y)| inside(x, y)) {
                    edge.push(p.map(|(x, y)| (y.rem_euclid(n) * n + x.rem_euclid(n)) as u32));
                }
            }
            false
        });
        LevelGeometry::Footprints { instances, edge }
    }

    /// Expands a level mesh into triangles of morphed vertices, for the
    /// rasteriser and for tests.
    pub fn triangles(&self, mesh: &LevelMesh) -> Vec<[MeshVertex; 3]> {
        let l = mesh.level;
        let lv = &self.levels[l];
        let s = self.n as usize;
        let o = lv.regions.origin;
        let at = |i: u32| {
            let (tx, ty) = (i as usize % s, i as usize / s);
            self.vertex(
                l,
                toroid::Toroid::<f32>::world_of(tx, o[0], s),
                toroid::Toroid::<f32>::world_of(ty, o[1], s),
            )
        };
        let mut tris: Vec<[MeshVertex; 3]> = match &mesh.geometry {
            LevelGeometry::Strips { strip } => footprint::strip_to_triangles(strip)
                .into_iter()
                .map(|t| t.map(at))
                .collect(),
            LevelGeometry::Footprints { instances, edge } => instances
                .iter()
                .flat_map(|i| {
                    let shape = self.footprints.shape(i.shape);
                    shape.triangles.iter().map(move |t| {
                        t.map(|k| {
                            let v = shape.vertices[k as usize];
                            self.vertex(l, i.offset[0] + v[0] as i64, i.offset[1] + v[1] as i64)
                        })
                    })
                })
                .chain(edge.iter().map(|t| t.map(at)))
                .collect(),
        };
        // Triangles that stitching collapsed cover nothing anywhere.
        tris.retain(|t| {
            let same = |a: &MeshVertex, b: &MeshVertex| a.x == b.x && a.y == b.y;
            !(same(&t[0], &t[1]) || same(&t[1], &t[2]) || same(&t[2], &t[0]))
        });
        tris
    }
}
