//! The pyramid built on demand, in square tiles around the viewer, as
//! Holkner wished ("begin traversing it immediately"): the first frame of a
//! 16384² terrain needs the tiles under its windows, not the whole map.
//!
//! - Level 0 comes from the procedural generator one tile at a time
//!   ([`Procedural::generate_rect`]), or is given whole (a loaded file).
//! - A tile of level l + 1 first makes sure of the level-l tiles its filter
//!   taps reach, then filters them with the eager build's own block code,
//!   so every sample has the eager pyramid's bits whatever order tiles are
//!   built in (`tests/pyramid.rs` checks this against `Pyramid::build`).
//! - Levels keep their full-size arrays, zero-filled by the allocator:
//!   pages no tile touched are never faulted in, so memory follows what was
//!   built, and every reader indexes a level as it would an eager one.
//! - Each update may build at most `budget` samples (all levels counted).
//!   What does not fit waits for later updates: a clipmap draws the finer
//!   levels that are ready and defers the coarser ones, the reverse of
//!   LH04's degradation, which drops fine levels when updates fall behind.

use super::downsample::{self, Block, Scratch};
use super::{Filter, Pyramid, PyramidLevel, RangeGrid, RANGE_TILE};
use crate::terrain::procedural::Procedural;
use crate::terrain::world::WorldMap;
use crate::terrain::Heightmap;
use rayon::prelude::*;
use serde::Serialize;

/// Side of a lazily built tile, in samples of its level: one range-grid
/// cell, so its bounds are whole once the tile is. Small, because a tile's
/// filter taps reach into the next finer level's neighbouring tiles, and
/// that ring of extra tiles, one tile wide, doubles in base texels at every
/// level down: with 64, one frame of n = 255 built about 3× its windows'
/// area at level 0; with 32, about 1.5×.
pub const TILE: usize = RANGE_TILE;

/// Where level 0 of a lazy pyramid comes from.
#[derive(Clone, Debug)]
pub enum LazyBase {
    /// Generated tile by tile.
    Procedural(Procedural),
    /// Already whole (a loaded file): only the coarser levels are lazy.
    Heightmap(Box<Heightmap>),
}

impl LazyBase {
    /// Level 0 for a scene's `[terrain]` table, and its world placement: a
    /// procedural terrain is not generated here, a file is loaded whole.
    pub fn for_terrain(
        spec: &crate::terrain::Spec,
        base_dir: &std::path::Path,
    ) -> crate::Result<(LazyBase, WorldMap)> {
        match &spec.procedural {
            Some(p) => {
                p.validate()
                    .map_err(|r| crate::Error::value("terrain.procedural", r))?;
                let cell = spec.cell_size.as_ref().map_or([1.0; 2], |c| c.pair());
                Ok((
                    LazyBase::Procedural(p.clone()),
                    WorldMap::for_terrain(spec, cell),
                ))
            }
            None => {
                let h = crate::terrain::load(spec, base_dir)?;
                let world = WorldMap::for_terrain(spec, h.cell_size);
                Ok((LazyBase::Heightmap(Box::new(h)), world))
            }
        }
    }
}

/// How far a lazy pyramid has got.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LazyStats {
    /// Tiles built so far, and in all, over every level.
    pub tiles_built: u64,
    /// (with `tiles_built`) Tiles in all.
    pub tiles_total: u64,
    /// Samples built so far, every level counted.
    pub samples_built: u64,
}

/// Which tiles of one level exist.
#[derive(Clone, Debug)]
pub(super) struct Tiles {
    /// Tile side in samples.
    pub side: usize,
    pub nx: usize,
    pub ny: usize,
    pub done: Vec<bool>,
}

impl Tiles {
    pub fn new(l: &PyramidLevel, done: bool, side: usize) -> Self {
        let (nx, ny) = (l.width.div_ceil(side), l.height.div_ceil(side));
        Tiles {
            side,
            nx,
            ny,
            done: vec![done; nx * ny],
        }
    }
    /// Tiles that hold level samples of `[x0, x1] × [y0, y1]` (clamped to
    /// the level), row by row.
    pub fn under(
        &self,
        l: &PyramidLevel,
        [x0, y0, x1, y1]: [i64; 4],
    ) -> impl Iterator<Item = [usize; 2]> {
        let side = self.side;
        let t = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize / side;
        let (i0, i1) = (t(x0.min(x1), l.width), t(x1.max(x0), l.width));
        let (j0, j1) = (t(y0.min(y1), l.height), t(y1.max(y0), l.height));
        (j0..=j1).flat_map(move |j| (i0..=i1).map(move |i| [i, j]))
    }
    /// The missing ones of [`Tiles::under`].
    pub fn missing<'a>(
        &'a self,
        l: &PyramidLevel,
        rect: [i64; 4],
    ) -> impl Iterator<Item = [usize; 2]> + 'a {
        self.under(l, rect)
            .filter(|&[i, j]| !self.done[j * self.nx + i])
    }
}

/// The lazy part of a [`Pyramid`].
#[derive(Clone, Debug)]
pub(super) struct Lazy {
    /// Level-0 generator; `None` when level 0 was given whole.
    source: Option<Procedural>,
    kernel: Vec<f64>,
    tiles: Vec<Tiles>,
    /// Samples one update may build.
    budget: u64,
}

/// A level no tile of which is built yet: zeroed arrays straight from the
/// allocator (no page touched), bounds that hold nothing.
fn unbuilt(width: usize, height: usize) -> PyramidLevel {
    PyramidLevel {
        width,
        height,
        data: vec![0.0; width * height],
        nodata: vec![false; width * height],
        min: f32::INFINITY,
        max: f32::NEG_INFINITY,
    }
}

/// Level samples of tile (i, j).
fn tile_block(l: &PyramidLevel, [i, j]: [usize; 2]) -> Block {
    Block {
        x0: i * TILE,
        y0: j * TILE,
        x1: ((i + 1) * TILE).min(l.width),
        y1: ((j + 1) * TILE).min(l.height),
    }
}

/// The level-(l − 1) samples that tile `t` of level `lv` (level l) reads
/// with a kernel of radius `r`.
fn inputs(lv: &PyramidLevel, t: [usize; 2], r: i64) -> [i64; 4] {
    let b = tile_block(lv, t);
    [
        2 * b.x0 as i64 - r,
        2 * b.y0 as i64 - r,
        2 * (b.x1 as i64 - 1) + r,
        2 * (b.y1 as i64 - 1) + r,
    ]
}

impl Pyramid {
    /// A pyramid of up to `count` levels that builds its tiles when
    /// [`Pyramid::build_around`] asks for them, about `budget` samples per
    /// call (less than one tile, [`TILE`]², more). Nothing but level 0 of a given heightmap is computed here.
    pub fn lazy(
        base: LazyBase,
        filter: Filter,
        count: usize,
        budget: u64,
    ) -> Result<Pyramid, String> {
        filter.validate()?;
        if budget == 0 {
            return Err("the lazy pyramid's budget must be at least 1 sample".into());
        }
        let (first, source, done) = match base {
            LazyBase::Procedural(p) => {
                p.validate()?;
                (unbuilt(p.width, p.height), Some(p), false)
            }
            LazyBase::Heightmap(h) => (PyramidLevel::of_heightmap(*h), None, true),
        };
        let mut levels = vec![first];
        while levels.len() < count.max(1) {
            let prev = levels.last().expect("level 0 exists");
            if !prev.can_halve() {
                break;
            }
            let (width, height) = downsample::halved(prev.width, prev.height);
            levels.push(unbuilt(width, height));
        }
        let tiles: Vec<Tiles> = levels
            .iter()
            .enumerate()
            .map(|(l, lv)| Tiles::new(lv, done && l == 0, TILE))
            .collect();
        let ranges = levels
            .iter()
            .enumerate()
            .map(|(l, lv)| match l == 0 && done {
                true => RangeGrid::new(lv),
                false => RangeGrid::empty(lv),
            })
            .collect();
        let tiles_total = tiles.iter().map(|t| (t.nx * t.ny) as u64).sum();
        let tiles_built = tiles
            .iter()
            .map(|t| t.done.iter().filter(|&&d| d).count() as u64)
            .sum();
        Ok(Pyramid {
            filter,
            levels,
            ranges,
            decoded: None,
            lazy: Some(Box::new(Lazy {
                source,
                kernel: filter.kernel(),
                tiles,
                budget,
            })),
            progress: Some(LazyStats {
                tiles_built,
                tiles_total,
                samples_built: 0,
            }),
            finer: 0,
        })
    }

    /// True when every sample of every level exists (never for a decoded
    /// pyramid, which evicts what its windows leave).
    pub fn is_complete(&self) -> bool {
        self.lazy.is_none() && self.decoded.is_none()
    }

    /// Progress of a lazy or decoded pyramid, also once complete (`None`
    /// for one built eagerly).
    pub fn lazy_stats(&self) -> Option<LazyStats> {
        self.progress
    }

    /// Builds (or, from a pack, decodes) what level l needs at level texels
    /// `windows[l]` (inclusive `[x0, y0, x1, y1]`, clamped to the level),
    /// within this call's budget, and says which levels are ready (all of
    /// them for a whole pyramid). A filtered lazy pyramid builds finest
    /// first, level 0's window whatever the budget; a decoded one coarse to
    /// fine (`pyramid::decoded`).
    pub fn build_around(&mut self, windows: &[[i64; 4]]) -> super::Built {
        if self.decoded.is_some() {
            return self.decode_around(windows);
        }
        let Some(z) = &self.lazy else {
            return super::Built {
                ready: 0..windows.len().min(self.levels.len()),
                ..Default::default()
            };
        };
        let mut budget = z.budget;
        let before = self.progress.unwrap_or_default();
        let mut ready = 0;
        for (l, &w) in windows.iter().enumerate().take(self.levels.len()) {
            let mut unlimited = u64::MAX;
            let b = if l == 0 { &mut unlimited } else { &mut budget };
            if !self.ensure(l, w, b) {
                break;
            }
            ready = l + 1;
        }
        let after = self.progress.unwrap_or_default();
        self.finish_if_complete();
        super::Built {
            ready: 0..ready,
            samples: after.samples_built - before.samples_built,
            tiles: after.tiles_built - before.tiles_built,
            evicted: 0,
        }
    }

    /// Builds the missing tiles of level `l` over `rect`, and first what
    /// they read, while `budget` (samples) lasts. It plans top-down (the
    /// missing tiles of each finer level that the coarser ones' taps reach)
    /// and builds bottom-up, one parallel batch per level, so a frame's
    /// tiles are built in a few large batches. A batch takes tiles while
    /// budget is left, so any budget makes progress and a call overruns it
    /// by less than one tile. True when all of level `l`'s tiles exist.
    fn ensure(&mut self, l: usize, rect: [i64; 4], budget: &mut u64) -> bool {
        let Some(z) = &self.lazy else { return true };
        let r = (z.kernel.len() / 2) as i64;
        let mut plan = vec![Vec::new(); l + 1];
        plan[l] = z.tiles[l].missing(&self.levels[l], rect).collect();
        if plan[l].is_empty() {
            return true;
        }
        for k in (1..=l).rev() {
            let (tiles, level) = (&z.tiles[k - 1], &self.levels[k - 1]);
            let mut wanted = vec![false; tiles.done.len()];
            let mut below = Vec::new();
            for &t in &plan[k] {
                for u in tiles.missing(level, inputs(&self.levels[k], t, r)) {
                    let i = u[1] * tiles.nx + u[0];
                    if !wanted[i] {
                        wanted[i] = true;
                        below.push(u);
                    }
                }
            }
            plan[k - 1] = below;
        }
        for (k, want) in plan.iter().enumerate() {
            if *budget == 0 {
                return false;
            }
            let z = self.lazy.as_ref().expect("lazy pyramid");
            let mut batch = Vec::with_capacity(want.len());
            for &t in want {
                if *budget == 0 {
                    break;
                }
                let ready = k == 0 || {
                    let (tiles, level) = (&z.tiles[k - 1], &self.levels[k - 1]);
                    tiles
                        .missing(level, inputs(&self.levels[k], t, r))
                        .next()
                        .is_none()
                };
                if ready {
                    *budget = budget.saturating_sub(tile_block(&self.levels[k], t).len() as u64);
                    batch.push(t);
                }
            }
            self.build_tiles(k, &batch);
        }
        let z = self.lazy.as_ref().expect("lazy pyramid");
        z.tiles[l].missing(&self.levels[l], rect).next().is_none()
    }

    /// Computes tiles `ts` of level `l` (their inputs exist) in parallel,
    /// then writes them into the level, its bounds and its range grid.
    fn build_tiles(&mut self, l: usize, ts: &[[usize; 2]]) {
        let Pyramid {
            levels,
            ranges,
            lazy,
            progress,
            ..
        } = self;
        let progress = progress.as_mut().expect("lazy pyramid");
        let z = lazy.as_mut().expect("lazy pyramid");
        let (below, rest) = levels.split_at_mut(l);
        let dst = &mut rest[0];
        let blocks: Vec<Block> = ts.iter().map(|&t| tile_block(dst, t)).collect();
        let (source, kernel) = (&z.source, &z.kernel);
        let made: Vec<(Vec<f32>, Vec<bool>)> = blocks
            .par_iter()
            .map_init(Scratch::default, |s, &b| match (l, source) {
                (0, Some(p)) => (
                    p.generate_rect([b.x0, b.y0, b.x1, b.y1]),
                    vec![false; b.len()],
                ),
                (0, None) => unreachable!("a given level 0 has every tile"),
                _ => {
                    let (mut v, mut nd) = (vec![0.0; b.len()], vec![false; b.len()]);
                    downsample::block(below[l - 1].rows(), kernel, b, s, &mut v, &mut nd);
                    (v, nd)
                }
            })
            .collect();
        let w = dst.width;
        for (&t, (b, (v, nd))) in ts.iter().zip(blocks.iter().zip(made)) {
            for (y, (row, row_nd)) in
                (b.y0..b.y1).zip(v.chunks_exact(b.width()).zip(nd.chunks_exact(b.width())))
            {
                dst.data[y * w + b.x0..y * w + b.x1].copy_from_slice(row);
                dst.nodata[y * w + b.x0..y * w + b.x1].copy_from_slice(row_nd);
                for (&h, &bad) in row.iter().zip(row_nd) {
                    if !bad {
                        dst.min = dst.min.min(h);
                        dst.max = dst.max.max(h);
                    }
                }
            }
            let g = &mut ranges[l];
            for j in b.y0 / RANGE_TILE..b.y1.div_ceil(RANGE_TILE) {
                for i in b.x0 / RANGE_TILE..b.x1.div_ceil(RANGE_TILE) {
                    g.bounds[j * g.tiles_x + i] = RangeGrid::tile_bounds(dst, i, j);
                }
            }
            let tiles = &mut z.tiles[l];
            tiles.done[t[1] * tiles.nx + t[0]] = true;
            progress.tiles_built += 1;
            progress.samples_built += b.len() as u64;
        }
    }

    /// Drops the lazy state once every tile exists, so the pyramid is an
    /// ordinary one; a level of only no-data gets the eager build's bounds.
    fn finish_if_complete(&mut self) {
        // A lazy pyramid builds each tile once, so its count of tiles
        // built says when it is whole.
        let whole = self
            .progress
            .is_some_and(|p| p.tiles_built == p.tiles_total);
        if self.lazy.is_some() && whole {
            self.lazy = None;
            for l in &mut self.levels {
                if l.min > l.max {
                    (l.min, l.max) = (l.data[0], l.data[0]);
                }
            }
        }
    }
}
