//! The pyramid decoded from a pack tile by tile, as the clipmap's windows
//! reach them: LH04's incremental decompression.
//!
//! - Levels are full-size arrays that no page of is touched until a tile
//!   is decoded into it, kept on small pages, so memory follows what is
//!   decoded.
//! - A tile of level l is predicted from level l + 1 around it, so an
//!   update decodes coarse to fine: for each level's window, the missing
//!   tiles under it and, first, the coarser tiles those read, up to the
//!   pack's coarsest level.
//! - Each update decodes about `budget` samples. The coarsest drawn
//!   level's window is decoded whatever the budget, so there is always
//!   something to draw; a finer level whose window is not complete waits
//!   (is not drawn), with every level finer than it: LH04's graceful
//!   degradation, the reverse of the filtered lazy pyramid's.
//! - A few tiles an update are decoded ahead, in a ring a tile deep around
//!   each window, so crossing into new tiles mostly finds them decoded.
//! - Tiles more than a tile away from their level's window are evicted:
//!   marked missing, and the pages only they used given back
//!   ([`crate::terrain::huge::release`]), so a flight of any length over a
//!   map of any size holds a few tiles per level.
//! - A tile that fails to decode (a damaged pack) stays missing, and the
//!   pyramid keeps the first error for the session to report.

use super::lazy::Tiles;
use super::{Filter, Pyramid, PyramidLevel, RangeGrid, RANGE_TILE};
use crate::terrain::huge;
use rayon::prelude::*;
use std::collections::HashSet;
use std::path::Path;
use std::sync::Arc;

/// Levels that come decoded a tile at a time, each tile from the coarser
/// level around it (a pack).
pub trait TileSource: Send + Sync + std::fmt::Debug {
    /// The file the tiles come from, for errors.
    fn path(&self) -> &Path;
    /// Each level's width and height, finest first.
    fn sizes(&self) -> Vec<[usize; 2]>;
    /// Each level's least and greatest valid height, as decoded.
    fn ranges(&self) -> Vec<[f32; 2]>;
    /// Tile side in samples.
    fn tile(&self) -> usize;
    /// The samples of level l + 1 (inclusive `[x0, y0, x1, y1]`, clamped
    /// by the reader) that tile `t` of level `l` is predicted from; `None`
    /// on the coarsest level.
    fn reads(&self, l: usize, t: [usize; 2]) -> Option<[i64; 4]>;
    /// Tile `t` of level `l` (heights and no-data flags, row-major over the
    /// tile), with level l + 1 as `coarse` where [`TileSource::reads`]
    /// says. Errors name the level and the tile.
    fn decode(
        &self,
        l: usize,
        t: [usize; 2],
        coarse: &PyramidLevel,
    ) -> Result<(Vec<f32>, Vec<bool>), String>;
    /// Where every sample of level `l` is the four-point upsampling of
    /// level l + 1 plus a whole number of this f32 step (a pack coded with
    /// [`crate::pack::Predictor::Upsampled`]): the step, so that a GPU
    /// pass can rebuild the level from its residuals. `None` otherwise.
    fn residual_step(&self, _l: usize) -> Option<f32> {
        None
    }
}

/// The decoding part of a [`Pyramid`].
#[derive(Clone, Debug)]
pub(super) struct Decoded {
    src: Arc<dyn TileSource>,
    tiles: Vec<Tiles>,
    /// Decoded tiles per level, for eviction.
    resident: Vec<Vec<[usize; 2]>>,
    /// Samples one update may decode.
    budget: u64,
    /// Samples the decoding ahead may still spend, earned as the windows
    /// move ([`AHEAD_RATE`]).
    ahead_credit: u64,
    /// The windows of the last update, to measure how far they moved.
    last: Vec<[i64; 4]>,
    /// The first tile that failed to decode.
    error: Option<String>,
}

/// Tiles an update decodes ahead of the windows, all levels together,
/// finest first ([`Pyramid::decode_ahead`]): at 64 texels a frame,
/// diagonally, 255-texel windows of 128² tiles need about 3 new tiles a
/// frame over all levels, so 4 mostly keeps ahead while no frame decodes
/// more than 4 tiles for it (two per level, or a ring two tiles deep,
/// measured no better; docs/how-to/pack.md).
const AHEAD: usize = 4;
/// How many tiles deep the ring decoded ahead of each window is, which
/// eviction keeps.
const RING: i64 = 1;
/// Samples decoded ahead for each sample the windows newly cover. A window
/// n wide moving one texel along an axis uncovers n texels, and its ring's
/// leading edge then needs (n + 2 · tile) / tile new tiles every tile
/// texels, about 2.5 n samples a texel at n = 255 with 128² tiles; 4 keeps
/// ahead with room to spare. Decoding ahead at the rate the windows move
/// (at least a tile an update, at most [`AHEAD`]), instead of [`AHEAD`]
/// tiles whenever any are missing, keeps a slow viewer's frames from
/// decoding four tiles at once (1.9 % of a frame at one texel a frame,
/// against 0.25 % on average; docs/how-to/pack.md).
const AHEAD_RATE: u64 = 4;

/// What one call of [`Pyramid::build_around`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Built {
    /// The levels ready to draw: `0..k` for a filtered lazy pyramid (the
    /// coarser ones wait), `k..count` for a decoded one (the finer wait).
    pub ready: std::ops::Range<usize>,
    /// Samples built or decoded.
    pub samples: u64,
    /// Tiles built or decoded.
    pub tiles: u64,
    /// Tiles evicted.
    pub evicted: u64,
}

/// Level `l`, `size` samples, no page of which is touched until a tile is
/// decoded into it (kept on small pages, so memory follows what is
/// decoded), with `range` as its height bounds.
fn reserved(l: usize, [w, h]: [usize; 2], [lo, hi]: [f32; 2]) -> Result<PyramidLevel, String> {
    let n = w.saturating_mul(h);
    let no_room =
        || format!("level {l} of {w}×{h} samples: the address space for it cannot be reserved");
    let mut data = huge::try_zeroed::<f32>(n).ok_or_else(no_room)?;
    let mut nodata = huge::try_zeroed::<bool>(n).ok_or_else(no_room)?;
    huge::small_pages(&mut data);
    huge::small_pages(&mut nodata);
    Ok(PyramidLevel {
        width: w,
        height: h,
        data,
        nodata,
        min: lo,
        max: hi,
    })
}

/// Two tile sources as one pyramid's: `finer`'s levels first, then
/// `coarser`'s, or, with none, levels that were whole already (which are
/// never asked for).
#[derive(Debug)]
struct Stacked {
    finer: Arc<dyn TileSource>,
    coarser: Option<Arc<dyn TileSource>>,
    /// Levels `finer` gives.
    k: usize,
    /// Every level's size and range, finest first.
    sizes: Vec<[usize; 2]>,
    ranges: Vec<[f32; 2]>,
}

impl TileSource for Stacked {
    fn path(&self) -> &Path {
        self.coarser.as_ref().unwrap_or(&self.finer).path()
    }
    fn sizes(&self) -> Vec<[usize; 2]> {
        self.sizes.clone()
    }
    fn ranges(&self) -> Vec<[f32; 2]> {
        self.ranges.clone()
    }
    fn tile(&self) -> usize {
        self.finer.tile()
    }
    fn reads(&self, l: usize, t: [usize; 2]) -> Option<[i64; 4]> {
        match &self.coarser {
            _ if l < self.k => self.finer.reads(l, t),
            Some(c) => c.reads(l - self.k, t),
            None => None,
        }
    }
    fn decode(
        &self,
        l: usize,
        t: [usize; 2],
        coarse: &PyramidLevel,
    ) -> Result<(Vec<f32>, Vec<bool>), String> {
        match &self.coarser {
            _ if l < self.k => self.finer.decode(l, t, coarse),
            Some(c) => c.decode(l - self.k, t, coarse),
            None => Err(format!("level {l} is whole and has no tiles to decode")),
        }
    }
    fn residual_step(&self, l: usize) -> Option<f32> {
        match &self.coarser {
            _ if l < self.k => self.finer.residual_step(l),
            Some(c) => c.residual_step(l - self.k),
            None => None,
        }
    }
}

impl Pyramid {
    /// A pyramid of every level of `src`, decoded as
    /// [`Pyramid::build_around`] asks, about `budget` samples per call.
    pub fn decoded(
        src: Arc<dyn TileSource>,
        filter: Filter,
        budget: u64,
    ) -> Result<Pyramid, String> {
        if budget == 0 {
            return Err("the decoding budget must be at least 1 sample".into());
        }
        let (sizes, ranges) = (src.sizes(), src.ranges());
        if sizes.is_empty() || sizes.len() != ranges.len() {
            return Err("a pack of no level".into());
        }
        let levels: Vec<PyramidLevel> = sizes
            .iter()
            .zip(&ranges)
            .enumerate()
            .map(|(l, (&size, &range))| reserved(l, size, range))
            .collect::<Result<_, String>>()?;
        let side = src.tile();
        let tiles: Vec<Tiles> = levels.iter().map(|l| Tiles::new(l, false, side)).collect();
        let tiles_total = tiles.iter().map(|t| (t.nx * t.ny) as u64).sum();
        Ok(Pyramid {
            filter,
            ranges: levels.iter().map(RangeGrid::empty).collect(),
            levels,
            lazy: None,
            decoded: Some(Box::new(Decoded {
                src,
                resident: vec![Vec::new(); tiles.len()],
                tiles,
                budget,
                ahead_credit: 0,
                last: Vec::new(),
                error: None,
            })),
            progress: Some(super::LazyStats {
                tiles_built: 0,
                tiles_total,
                samples_built: 0,
            }),
            finer: 0,
        })
    }

    /// [`TileSource::residual_step`] of level `l`, for a pyramid decoded
    /// from tiles.
    pub fn residual_step(&self, l: usize) -> Option<f32> {
        self.decoded.as_ref()?.src.residual_step(l)
    }

    /// The first tile a decoded pyramid failed to decode, as an error that
    /// names the pack, the level and the tile.
    pub fn decode_error(&self) -> Option<crate::Error> {
        let d = self.decoded.as_ref()?;
        let e = d.error.as_ref()?;
        Some(crate::Error::file(d.src.path(), e.clone()))
    }

    /// This pyramid with `finer`'s levels before its own, each finer level
    /// made a tile at a time from the next coarser one, as
    /// [`Pyramid::build_around`] asks, within `budget` samples a call (a
    /// decoded pyramid keeps its own budget): LH04's levels finer than the
    /// data. The pyramid's own levels stay as they are, whole or decoded
    /// from a pack; a lazily filtered one, whose coarser levels wait on its
    /// finer ones, cannot be refined.
    pub fn with_finer(self, finer: Arc<dyn TileSource>, budget: u64) -> Result<Pyramid, String> {
        if self.lazy.is_some() {
            return Err("a pyramid filtered lazily cannot take finer levels".into());
        }
        let (fs, fr) = (finer.sizes(), finer.ranges());
        let k = fs.len();
        if k == 0 || fr.len() != k {
            return Err("no finer level to add".into());
        }
        // Each finer level's vertices the coarser one's and the midpoints
        // between them, down to this pyramid's finest level.
        let mut sizes = fs.clone();
        sizes.extend(self.levels.iter().map(|l| [l.width, l.height]));
        if let Some(w) = sizes[..=k]
            .windows(2)
            .find(|w| w[0] != [2 * w[1][0] - 1, 2 * w[1][1] - 1])
        {
            return Err(format!(
                "a finer level of {}×{} samples cannot lie over one of {}×{}",
                w[0][0], w[0][1], w[1][0], w[1][1]
            ));
        }
        let side = finer.tile();
        let Pyramid {
            filter,
            levels,
            ranges,
            decoded,
            progress,
            finer: had,
            ..
        } = self;
        let (coarser, tiles, resident, budget, progress) = match decoded {
            Some(d) => {
                if d.src.tile() != side {
                    return Err(format!(
                        "finer tiles of {side}² cannot stack on a pack's of {}²",
                        d.src.tile()
                    ));
                }
                (Some(d.src), d.tiles, d.resident, d.budget, progress)
            }
            None => {
                if budget == 0 {
                    return Err("the budget must be at least 1 sample".into());
                }
                let tiles = levels.iter().map(|l| Tiles::new(l, true, side)).collect();
                (None, tiles, vec![Vec::new(); levels.len()], budget, None)
            }
        };
        let mut all: Vec<PyramidLevel> = fs
            .iter()
            .zip(&fr)
            .enumerate()
            .map(|(l, (&size, &range))| reserved(l, size, range))
            .collect::<Result<_, String>>()?;
        let mut all_tiles: Vec<Tiles> = all.iter().map(|l| Tiles::new(l, false, side)).collect();
        let added: u64 = all_tiles.iter().map(|t| (t.nx * t.ny) as u64).sum();
        let mut all_ranges: Vec<RangeGrid> = all.iter().map(RangeGrid::empty).collect();
        all_ranges.extend(ranges);
        all_tiles.extend(tiles);
        let mut all_resident = vec![Vec::new(); k];
        all_resident.extend(resident);
        let mut range_list = fr;
        range_list.extend(levels.iter().map(|l| [l.min, l.max]));
        all.extend(levels);
        let mut progress = progress.unwrap_or_default();
        progress.tiles_total += added;
        Ok(Pyramid {
            filter,
            levels: all,
            ranges: all_ranges,
            lazy: None,
            decoded: Some(Box::new(Decoded {
                src: Arc::new(Stacked {
                    finer,
                    coarser,
                    k,
                    sizes,
                    ranges: range_list,
                }),
                tiles: all_tiles,
                resident: all_resident,
                budget,
                ahead_credit: 0,
                last: Vec::new(),
                error: None,
            })),
            progress: Some(progress),
            finer: had + k,
        })
    }

    /// Every level whole: a decoded pyramid's tiles all decoded (coarse
    /// first) and its levels made ordinary ones, with their own height
    /// ranges, for the schemes and effects that read whole levels. Errors
    /// name the pack, the level and the tile.
    pub fn whole(mut self) -> crate::Result<Pyramid> {
        if self.decoded.is_none() {
            return Ok(self);
        }
        for l in (0..self.levels.len()).rev() {
            let lv = &self.levels[l];
            let all = [0, 0, lv.width as i64 - 1, lv.height as i64 - 1];
            self.decode_window(l, all)?;
        }
        let levels = std::mem::take(&mut self.levels)
            .into_iter()
            .map(|l| PyramidLevel::from_parts(l.width, l.height, l.data, l.nodata))
            .collect();
        let mut p = Pyramid::from_levels(levels, self.filter);
        p.finer = self.finer;
        Ok(p)
    }

    /// The side of the tiles a decoded pyramid makes its levels in.
    pub fn tile_side(&self) -> Option<usize> {
        self.decoded.as_ref().map(|d| d.src.tile())
    }

    /// Tiles a decoded pyramid holds now, every level counted.
    pub fn tiles_resident(&self) -> Option<u64> {
        Some(self.tiles_resident_per_level()?.iter().sum())
    }

    /// [`Pyramid::tiles_resident`] level by level, finest first, so a
    /// bound can be held on each level rather than on a total that one
    /// level's growth can hide in.
    pub fn tiles_resident_per_level(&self) -> Option<Vec<u64>> {
        let d = self.decoded.as_ref()?;
        Some(d.resident.iter().map(|r| r.len() as u64).collect())
    }

    /// [`Pyramid::build_around`] for a decoded pyramid.
    pub(super) fn decode_around(&mut self, windows: &[[i64; 4]]) -> Built {
        let before = self.progress.unwrap_or_default();
        let top = self.levels.len() - 1;
        let count = windows.len().min(self.levels.len());
        let mut budget = self.decoded.as_ref().map_or(0, |d| d.budget);
        let mut first = count;
        for k in (0..count).rev() {
            // The coarsest drawn level whatever the budget.
            let unlimited = k + 1 == count;
            let plan = self.plan(k, windows[k], top);
            self.decode_plan(k, &plan, &mut budget, unlimited, usize::MAX);
            let d = self.decoded.as_ref().expect("decoded pyramid");
            if d.tiles[k]
                .missing(&self.levels[k], windows[k])
                .next()
                .is_some()
            {
                break;
            }
            first = k;
        }
        self.decode_ahead(&windows[first..count], first, &mut budget);
        // The levels coarser than the drawn ones keep what lies under the
        // coarsest window, halved level by level: what the drawn levels'
        // tiles are predicted from.
        let mut keep = windows[..count].to_vec();
        while let Some(&[x0, y0, x1, y1]) = keep.last().filter(|_| keep.len() <= top) {
            keep.push([
                x0.div_euclid(2),
                y0.div_euclid(2),
                x1.div_euclid(2) + 1,
                y1.div_euclid(2) + 1,
            ]);
        }
        let evicted = self.evict(&keep);
        let after = self.progress.unwrap_or_default();
        Built {
            ready: first..count,
            samples: after.samples_built - before.samples_built,
            tiles: after.tiles_built - before.tiles_built,
            evicted,
        }
    }

    /// Decodes every tile of level `l` under `rect` (inclusive, level
    /// texels), and first the coarser tiles they are predicted from,
    /// whatever the budget: a window read out of a pack of any size.
    /// Errors name the pack, the level and the tile.
    pub fn decode_window(&mut self, l: usize, rect: [i64; 4]) -> crate::Result<()> {
        let top = self.levels.len() - 1;
        if self.decoded.is_none() || l > top {
            return Ok(());
        }
        let plan = self.plan(l, rect, top);
        for (j, want) in plan.iter().enumerate().rev() {
            self.decode_tiles(l + j, want);
        }
        match self.decode_error() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Decodes up to [`AHEAD`] missing tiles within [`RING`] tiles of the
    /// drawn levels' windows (`windows[i]` is level `first + i`'s), finest
    /// level first, from what the budget left: the tiles the next frames
    /// will reach, so that crossing into a new row or column of tiles
    /// finds them decoded instead of decoding them all in that frame. The
    /// same ring is what eviction keeps.
    fn decode_ahead(&mut self, windows: &[[i64; 4]], first: usize, budget: &mut u64) {
        let top = self.levels.len() - 1;
        let d = self.decoded.as_mut().expect("decoded pyramid");
        let side = d.src.tile() as u64;
        let g = RING * side as i64;
        // What the windows newly cover earns decoding ahead, at most
        // AHEAD tiles' worth (so a jump does not bank a burst).
        let moved = uncovered(&d.last, windows, first);
        d.last = vec![[0, 0, -1, -1]; first];
        d.last.extend_from_slice(windows);
        // At least a tile an update, so a still viewer's ring fills too.
        let (tile, cap) = (side * side, AHEAD as u64 * side * side);
        let earned = AHEAD_RATE.saturating_mul(moved).max(tile);
        d.ahead_credit = d.ahead_credit.saturating_add(earned).min(cap);
        let mut left = (d.ahead_credit / tile) as usize;
        let mut any = false;
        for (i, &[x0, y0, x1, y1]) in windows.iter().enumerate() {
            if left == 0 {
                break;
            }
            let k = first + i;
            let plan = self.plan(k, [x0 - g, y0 - g, x1 + g, y1 + g], top);
            let before = *budget;
            let taken = self.decode_plan(k, &plan, budget, false, left);
            left -= taken;
            let spent = (taken as u64 * tile).max(before - *budget);
            any |= taken > 0;
            let d = self.decoded.as_mut().expect("decoded pyramid");
            d.ahead_credit = d.ahead_credit.saturating_sub(spent);
        }
        // With the rings whole, credit is not banked: it would come out as
        // a burst of tiles when they next need some. (Nothing taken means
        // a tile or more was on offer: the credit is at least a tile.)
        if !any {
            let d = self.decoded.as_mut().expect("decoded pyramid");
            d.ahead_credit = 0;
        }
    }

    /// Decodes `plan` ([`Pyramid::plan`] of level `k`) coarse first: each
    /// tile whose coarser reads exist, while `budget` samples last (or
    /// whatever the budget, if `unlimited`), at most `limit` tiles; returns
    /// how many it took.
    fn decode_plan(
        &mut self,
        k: usize,
        plan: &[Vec<[usize; 2]>],
        budget: &mut u64,
        unlimited: bool,
        mut limit: usize,
    ) -> usize {
        let top = self.levels.len() - 1;
        let mut taken = 0;
        for (j, want) in plan.iter().enumerate().rev() {
            let d = self.decoded.as_ref().expect("decoded pyramid");
            let mut batch = Vec::with_capacity(want.len().min(limit));
            for &t in want {
                if limit == 0 || !unlimited && *budget == 0 {
                    break;
                }
                let ready = match d.src.reads(k + j, t) {
                    Some(r) if k + j < top => d.tiles[k + j + 1]
                        .missing(&self.levels[k + j + 1], r)
                        .next()
                        .is_none(),
                    _ => true,
                };
                if ready {
                    *budget = budget.saturating_sub(self.tile_samples(k + j, t));
                    batch.push(t);
                    limit -= 1;
                }
            }
            taken += batch.len();
            self.decode_tiles(k + j, &batch);
        }
        taken
    }

    /// Samples of tile `t` of level `l`.
    fn tile_samples(&self, l: usize, [i, j]: [usize; 2]) -> u64 {
        let side = self.decoded.as_ref().map_or(1, |d| d.src.tile());
        let lv = &self.levels[l];
        let w = ((i + 1) * side).min(lv.width) - i * side;
        let h = ((j + 1) * side).min(lv.height) - j * side;
        (w * h) as u64
    }

    /// The missing tiles level `k`'s window `rect` needs, per level from
    /// `k` (index 0) to `top`: those under the window, then the coarser
    /// ones each of those reads.
    fn plan(&self, k: usize, rect: [i64; 4], top: usize) -> Vec<Vec<[usize; 2]>> {
        let d = self.decoded.as_ref().expect("decoded pyramid");
        let mut plan = vec![d.tiles[k]
            .missing(&self.levels[k], rect)
            .collect::<Vec<_>>()];
        for j in k..top {
            let below = plan.last().expect("one level planned");
            if below.is_empty() {
                break;
            }
            let mut seen = HashSet::new();
            let mut next = Vec::new();
            for &t in below {
                let Some(r) = d.src.reads(j, t) else { continue };
                for u in d.tiles[j + 1].missing(&self.levels[j + 1], r) {
                    if seen.insert(u) {
                        next.push(u);
                    }
                }
            }
            plan.push(next);
        }
        plan
    }

    /// Decodes tiles `ts` of level `l` (what they read exists) in
    /// parallel, then writes them into the level and its range grid.
    fn decode_tiles(&mut self, l: usize, ts: &[[usize; 2]]) {
        if ts.is_empty() {
            return;
        }
        let Pyramid {
            levels,
            ranges,
            decoded,
            progress,
            ..
        } = self;
        let d = decoded.as_mut().expect("decoded pyramid");
        let progress = progress.as_mut().expect("decoded pyramid");
        let (fine, coarse) = levels.split_at_mut(l + 1);
        let dst = &mut fine[l];
        let empty = PyramidLevel::single();
        let c = coarse.first().unwrap_or(&empty);
        let src = &d.src;
        let made: Vec<_> = ts.par_iter().map(|&t| src.decode(l, t, c)).collect();
        let side = d.src.tile();
        let w = dst.width;
        for (&t, result) in ts.iter().zip(made) {
            let (v, nd) = match result {
                Ok(tile) => tile,
                Err(e) => {
                    d.error.get_or_insert(e);
                    continue;
                }
            };
            let (x0, y0) = (t[0] * side, t[1] * side);
            let (x1, y1) = ((x0 + side).min(w), (y0 + side).min(dst.height));
            let tw = x1 - x0;
            for (y, (row, row_nd)) in (y0..y1).zip(v.chunks_exact(tw).zip(nd.chunks_exact(tw))) {
                dst.data[y * w + x0..y * w + x1].copy_from_slice(row);
                dst.nodata[y * w + x0..y * w + x1].copy_from_slice(row_nd);
            }
            // Range tiles the tile overlaps take the union of their parts,
            // so they are whole once every part has been decoded (a part
            // evicted and decoded again gives the same bounds).
            let g = &mut ranges[l];
            for j in y0 / RANGE_TILE..y1.div_ceil(RANGE_TILE) {
                for i in x0 / RANGE_TILE..x1.div_ceil(RANGE_TILE) {
                    let (ya, yb) = ((j * RANGE_TILE).max(y0), ((j + 1) * RANGE_TILE).min(y1));
                    let (xa, xb) = ((i * RANGE_TILE).max(x0), ((i + 1) * RANGE_TILE).min(x1));
                    let b = &mut g.bounds[j * g.tiles_x + i];
                    for y in ya..yb {
                        let (lo, hi) = super::extremes(&dst.data[y * w + xa..y * w + xb]);
                        *b = [b[0].min(lo), b[1].max(hi)];
                    }
                }
            }
            let tiles = &mut d.tiles[l];
            tiles.done[t[1] * tiles.nx + t[0]] = true;
            d.resident[l].push(t);
            progress.tiles_built += 1;
            progress.samples_built += ((x1 - x0) * (y1 - y0)) as u64;
        }
    }

    /// Evicts the tiles of each level that lie more than [`RING`] tiles
    /// from its window in `windows`, giving back the pages only they used;
    /// returns how many.
    fn evict(&mut self, windows: &[[i64; 4]]) -> u64 {
        let Pyramid {
            levels, decoded, ..
        } = self;
        let d = decoded.as_mut().expect("decoded pyramid");
        let side = d.src.tile();
        let mut evicted = 0;
        for (l, &[x0, y0, x1, y1]) in windows.iter().enumerate() {
            let (g, r) = (side as i64, RING * side as i64);
            let keep = |[i, j]: [usize; 2]| {
                let (a, b) = (i as i64 * g, j as i64 * g);
                a + g > x0 - r && a <= x1 + r && b + g > y0 - r && b <= y1 + r
            };
            let (resident, tiles) = (&mut d.resident[l], &mut d.tiles[l]);
            let mut gone = Vec::new();
            resident.retain(|&t| {
                let k = keep(t);
                if !k {
                    gone.push(t);
                }
                k
            });
            if gone.is_empty() {
                continue;
            }
            for &[i, j] in &gone {
                tiles.done[j * tiles.nx + i] = false;
            }
            evicted += gone.len() as u64;
            release_runs(&mut levels[l], tiles, &gone);
        }
        evicted
    }
}

/// Texels of `windows` (level `first + i`'s is `windows[i]`; inclusive
/// rectangles) outside the same levels' windows in `last`: what the
/// windows newly cover. A level with no last window counts whole.
fn uncovered(last: &[[i64; 4]], windows: &[[i64; 4]], first: usize) -> u64 {
    let area = |[x0, y0, x1, y1]: [i64; 4]| ((x1 - x0 + 1).max(0) * (y1 - y0 + 1).max(0)) as u64;
    windows
        .iter()
        .enumerate()
        .map(|(i, &w)| match last.get(first + i) {
            // The overlap of an empty last window (a level not drawn) is
            // empty too, so it takes nothing off.
            Some(&[a0, b0, a1, b1]) => {
                let both = [w[0].max(a0), w[1].max(b0), w[2].min(a1), w[3].min(b1)];
                area(w) - area(both)
            }
            None => area(w),
        })
        .sum()
}

/// Gives back the pages of the runs of missing tiles that hold the tiles
/// `gone` (just evicted), row by row: a page is shared by the tiles beside
/// each other in a row, so only a run of missing ones frees any.
fn release_runs(lv: &mut PyramidLevel, tiles: &Tiles, gone: &[[usize; 2]]) {
    let side = tiles.side;
    let mut runs: Vec<(usize, usize, usize)> = gone
        .iter()
        .map(|&[i, j]| {
            let row = &tiles.done[j * tiles.nx..(j + 1) * tiles.nx];
            let a = row[..i].iter().rposition(|&d| d).map_or(0, |p| p + 1);
            let b = row[i..].iter().position(|&d| d).map_or(tiles.nx, |p| i + p);
            (j, a, b)
        })
        .collect();
    runs.sort_unstable();
    runs.dedup();
    let (w, h) = (lv.width, lv.height);
    let empty = |j: usize| {
        tiles.done[j * tiles.nx..(j + 1) * tiles.nx]
            .iter()
            .all(|&d| !d)
    };
    for (j, a, b) in runs {
        if (a, b) == (0, tiles.nx) {
            // A whole row of tiles is one contiguous span: released as
            // one, with the empty rows of tiles beside it, so the pages
            // that straddle one sample row's end and the next one's start
            // go back too (row by row, each such page is partly outside
            // every row's slice, and a flight's leftovers grew with the
            // rows of tiles it had passed over).
            let top = if j > 0 && empty(j - 1) { j - 1 } else { j };
            let bottom = if j + 1 < tiles.ny && empty(j + 1) {
                j + 2
            } else {
                j + 1
            };
            let span = top * side * w..(bottom * side).min(h) * w;
            huge::release(&mut lv.data[span.clone()]);
            huge::release(&mut lv.nodata[span]);
            continue;
        }
        let (x0, x1) = (a * side, (b * side).min(w));
        for y in j * side..((j + 1) * side).min(h) {
            huge::release(&mut lv.data[y * w + x0..y * w + x1]);
            huge::release(&mut lv.nodata[y * w + x0..y * w + x1]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tiles of one height each, of whatever sizes a test names. With
    /// `reads`, each tile reads the coarser level as a four-point
    /// upsampling does (its footprint halved, a texel more on each side),
    /// on every level, the coarsest too, as a careless source might; with
    /// `fail`, that tile of that level fails to decode. With `sloped`,
    /// sample (x, y) is 1 + x + 1000 y instead of 1, so every range tile
    /// has bounds of its own (and no sample is zero), and no-data where
    /// x + y is even (so no-data flags given back show too). Tiles are `side`² (0 for 32).
    #[derive(Debug, Default)]
    struct Fake {
        sizes: Vec<[usize; 2]>,
        ranges: Vec<[f32; 2]>,
        reads: bool,
        fail: Option<(usize, [usize; 2])>,
        sloped: bool,
        side: usize,
    }

    impl TileSource for Fake {
        fn path(&self) -> &Path {
            Path::new("fake.tcz")
        }
        fn sizes(&self) -> Vec<[usize; 2]> {
            self.sizes.clone()
        }
        fn ranges(&self) -> Vec<[f32; 2]> {
            self.ranges.clone()
        }
        fn tile(&self) -> usize {
            if self.side == 0 {
                32
            } else {
                self.side
            }
        }
        fn reads(&self, _: usize, [i, j]: [usize; 2]) -> Option<[i64; 4]> {
            let (x, y) = (i as i64 * 16, j as i64 * 16);
            self.reads.then_some([x - 1, y - 1, x + 16, y + 16])
        }
        fn decode(
            &self,
            l: usize,
            t: [usize; 2],
            _: &PyramidLevel,
        ) -> Result<(Vec<f32>, Vec<bool>), String> {
            if self.fail == Some((l, t)) {
                return Err(format!("level {l} tile {t:?}: damaged"));
            }
            let (side, [w, h]) = (self.tile(), self.sizes[l]);
            let (x0, y0) = (t[0] * side, t[1] * side);
            let (xs, ys) = (x0..(x0 + side).min(w), y0..(y0 + side).min(h));
            let at: Vec<[usize; 2]> = ys.flat_map(|y| xs.clone().map(move |x| [x, y])).collect();
            let v = at.iter().map(|&[x, y]| match self.sloped {
                true => (1 + x + 1000 * y) as f32,
                false => 1.0,
            });
            let nd = at.iter().map(|&[x, y]| self.sloped && (x + y) % 2 == 0);
            Ok((v.collect(), nd.collect()))
        }
    }

    fn fake(sizes: &[[usize; 2]], ranges: usize) -> Arc<dyn TileSource> {
        Arc::new(Fake {
            sizes: sizes.to_vec(),
            ranges: vec![[0.0, 1.0]; ranges],
            ..Fake::default()
        })
    }

    /// A one-level [`Fake`] of `size`, `sloped`, in `side`² tiles (0 for
    /// 32), its range the samples' own: 1 at (0, 0) to w + 1000 (h − 1)
    /// at the far corner.
    fn sloped([w, h]: [usize; 2], side: usize) -> Arc<dyn TileSource> {
        Arc::new(Fake {
            sizes: vec![[w, h]],
            ranges: vec![[1.0, (w + 1000 * (h - 1)) as f32]],
            sloped: true,
            side,
            ..Fake::default()
        })
    }

    /// Levels of `sizes` whose tiles read the coarser level (and fail to
    /// decode at `fail`), with an ample budget.
    fn reading(sizes: &[[usize; 2]], fail: Option<(usize, [usize; 2])>) -> Pyramid {
        let src = Arc::new(Fake {
            sizes: sizes.to_vec(),
            ranges: vec![[0.0, 1.0]; sizes.len()],
            reads: true,
            fail,
            ..Fake::default()
        });
        Pyramid::decoded(src, Filter::default(), 1 << 20).unwrap()
    }

    /// A source of no level, or whose sizes and ranges disagree, is an
    /// error, as a pyramid and as finer levels; a good one counts every
    /// tile of every level (65² in 32² tiles is 3 × 3), and the tiles it
    /// holds as it decodes them.
    #[test]
    fn sources_of_no_level_or_mismatched_lists_are_errors() {
        let f = Filter::default();
        for (sizes, ranges) in [(vec![], 0), (vec![[65, 65]], 0), (vec![[65, 65]], 2)] {
            assert!(Pyramid::decoded(fake(&sizes, ranges), f, 1).is_err());
            let base = Pyramid::decoded(fake(&[[33, 33]], 1), f, 1).unwrap();
            assert!(base.with_finer(fake(&sizes, ranges), 1).is_err());
        }
        let mut p = Pyramid::decoded(fake(&[[65, 65], [33, 17]], 2), f, 1).unwrap();
        assert_eq!(p.lazy_stats().unwrap().tiles_total, 9 + 2);
        // Decoding counts what it holds, level by level.
        assert_eq!(p.tiles_resident(), Some(0));
        p.decode_window(1, [0, 0, 32, 16]).unwrap();
        assert_eq!(p.tiles_resident(), Some(2));
        assert_eq!(p.tiles_resident_per_level(), Some(vec![0, 2]));
        let whole = p.whole().unwrap();
        assert!(whole
            .levels
            .iter()
            .all(|l| l.data.iter().all(|&v| v == 1.0)));
        // Finer levels add their tiles to the count: 3 × 3 over 2 × 2.
        let base = Pyramid::decoded(fake(&[[33, 33]], 1), f, 1).unwrap();
        let stacked = base.with_finer(fake(&[[65, 65]], 1), 1).unwrap();
        assert_eq!(stacked.lazy_stats().unwrap().tiles_total, 4 + 9);
        assert!(Pyramid::decoded(fake(&[[65, 65]], 1), f, 0).is_err());
    }

    /// The coarsest drawn level's window is decoded whatever the budget (a
    /// budget of 1 sample), finer levels wait, and a frame reports the
    /// samples it decoded itself, not the session's; a whole pyramid has
    /// no window to decode.
    #[test]
    fn the_coarsest_window_is_decoded_whatever_the_budget() {
        let f = Filter::default();
        let mut p = Pyramid::decoded(fake(&[[65, 65], [33, 17]], 2), f, 1).unwrap();
        let first = p.build_around(&[[0, 0, 64, 64], [0, 0, 32, 16]]);
        assert_eq!(first.ready.end, 2);
        assert!(
            first.ready.contains(&1) && !first.ready.contains(&0),
            "{:?}",
            first.ready
        );
        assert_eq!(p.tiles_resident_per_level().unwrap()[1], 2);
        let before = p.lazy_stats().unwrap().samples_built;
        assert_eq!(first.samples, before);
        assert!(before >= 33 * 17, "{before}");
        let second = p.build_around(&[[0, 0, 64, 64], [0, 0, 32, 16]]);
        assert_eq!(
            second.samples,
            p.lazy_stats().unwrap().samples_built - before
        );
        let mut whole = Pyramid::from_levels(vec![PyramidLevel::single()], f);
        assert!(whole.decode_window(0, [0, 0, 0, 0]).is_ok());
    }

    /// A level past the top is no window at all: nothing decoded, no
    /// error.
    #[test]
    fn a_level_past_the_top_decodes_nothing() {
        let mut p = Pyramid::decoded(fake(&[[65, 65]], 1), Filter::default(), 1).unwrap();
        assert!(p.decode_window(1, [0, 0, 64, 64]).is_ok());
        assert_eq!(p.tiles_resident(), Some(0));
        assert!(p.decode_window(0, [0, 0, 64, 64]).is_ok());
        assert_eq!(p.tiles_resident(), Some(9));
    }

    /// Eviction keeps, on each level coarser than the drawn ones, the
    /// tiles under the coarsest window halved level by level, the texel
    /// past its end included, and a ring of one tile around them: level
    /// 0's [64, 127] is level 1's [32, 64], and with the ring of 32 texels
    /// its tiles 0 to 3 a side (16 of 25). Without the texel past the end
    /// it would keep 9.
    #[test]
    fn coarser_levels_keep_what_the_coarsest_window_covers_halved() {
        let f = Filter::default();
        let mut p = Pyramid::decoded(fake(&[[257, 257], [129, 129], [65, 65]], 3), f, 1).unwrap();
        p.decode_window(1, [0, 0, 128, 128]).unwrap();
        p.decode_window(2, [0, 0, 64, 64]).unwrap();
        assert_eq!(p.tiles_resident_per_level(), Some(vec![0, 25, 9]));
        let built = p.build_around(&[[64, 64, 127, 127]]);
        let r = p.tiles_resident_per_level().unwrap();
        assert_eq!(r[1..], [16, 9], "{r:?}");
        assert_eq!(built.evicted, 25 - 16);
    }

    /// A tile's samples, edge tiles cut to the level: 65 × 33 in 32²
    /// tiles is 3 × 2 tiles, the last column 1 wide, the last row 1 high.
    #[test]
    fn edge_tiles_count_only_the_levels_samples() {
        let p = Pyramid::decoded(fake(&[[65, 33]], 1), Filter::default(), 1).unwrap();
        let n = |t| p.tile_samples(0, t);
        assert_eq!(
            [n([0, 0]), n([1, 0]), n([2, 0]), n([1, 1]), n([2, 1])],
            [1024, 1024, 32, 32, 1]
        );
    }

    /// Reads are clamped to the coarser level they name, and a source that
    /// names reads on its coarsest level is not followed past it: every
    /// tile of 128², 64² and 32² levels decodes once. The last tile of each
    /// row reads a texel past the coarser level's edge, which clamped to
    /// the finer level would name a tile the coarser one does not have.
    #[test]
    fn reads_are_clamped_to_their_level_and_stop_at_the_top() {
        let sizes = [[128, 128], [64, 64], [32, 32]];
        let mut p = reading(&sizes, None);
        let built = p.build_around(&[[0, 0, 127, 127], [0, 0, 63, 63]]);
        assert_eq!(built.ready, 0..2);
        assert_eq!(built.tiles, 16 + 4 + 1);
        assert_eq!(p.tiles_resident_per_level(), Some(vec![16, 4, 1]));
        let mut q = reading(&sizes, None);
        q.decode_window(0, [0, 0, 127, 127]).unwrap();
        assert_eq!(q.tiles_resident_per_level(), Some(vec![16, 4, 1]));
        assert!(p.decode_error().is_none() && q.decode_error().is_none());
    }

    /// A tile whose coarser tile failed to decode waits instead of being
    /// predicted from the hole: level 2's one tile fails, so none of level
    /// 1's four is decoded, nothing is ready, and the error names the tile.
    #[test]
    fn a_tile_whose_coarser_tile_failed_waits() {
        let mut p = reading(&[[128, 128], [64, 64], [32, 32]], Some((2, [0, 0])));
        let built = p.build_around(&[[0, 0, 127, 127], [0, 0, 63, 63]]);
        assert!(built.ready.is_empty(), "{:?}", built.ready);
        assert_eq!(p.tiles_resident_per_level(), Some(vec![0, 0, 0]));
        let e = p.decode_error().expect("the failed tile").to_string();
        assert!(
            e.contains("fake.tcz") && e.contains("level 2 tile [0, 0]"),
            "{e}"
        );
    }

    /// Decoding ahead, tile by tile, on one 256² level of 32² tiles with an
    /// ample budget (tiles decoded per update, the drawn window's first):
    ///
    /// 1. The corner window [0, 31]² covers one tile and newly covers 1,024
    ///    texels, which earns the cap of 4 tiles; its ring holds 3 more, so
    ///    1 + 3 are decoded and a tile's credit is left.
    /// 2. One texel right, the window newly covers 32 texels, which earns
    ///    the least, a tile; with the tile left over, both new ring tiles
    ///    of column 2 are decoded.
    /// 3. Standing still with the ring whole earns a tile an update that is
    ///    not banked, so creeping right a texel an update decodes one tile
    ///    (not a burst of the 4 a bank would hold) when the ring reaches
    ///    column 3 (the window's right end at 64), and the other the
    ///    update after.
    #[test]
    fn decoding_ahead_spends_what_the_windows_earn() {
        let mut p = reading(&[[256, 256]], None);
        let mut tiles = Vec::new();
        for x in [0, 1, 1, 1, 1, 1] {
            tiles.push(p.build_around(&[[x, 0, x + 31, 31]]).tiles);
        }
        assert_eq!(tiles, [4, 2, 0, 0, 0, 0]);
        assert_eq!(p.tiles_resident(), Some(6));
        let creep: Vec<u64> = (2..=34)
            .map(|x| p.build_around(&[[x, 0, x + 31, 31]]).tiles)
            .collect();
        let mut want = vec![0; 33];
        want[31] = 1; // x = 33: the window's end at 64 puts column 3 in the ring.
        want[32] = 1;
        assert_eq!(creep, want);
        assert_eq!(p.tiles_resident_per_level(), Some(vec![8]));
    }

    /// The height bounds a level's range tiles get as its tiles are
    /// decoded are the bounds of the whole level: with 48² pack tiles over
    /// 32² range tiles, a pack tile covers parts of several range tiles
    /// and a range tile gathers parts of several pack tiles, every row and
    /// column of them cut at a different place.
    #[test]
    fn range_bounds_gathered_tile_by_tile_are_the_levels() {
        let src = sloped([130, 100], 48);
        let mut p = Pyramid::decoded(src, Filter::default(), 1).unwrap();
        p.decode_window(0, [0, 0, 129, 99]).unwrap();
        assert_eq!(p.tiles_resident(), Some(3 * 3));
        assert_eq!(p.levels[0].data[99 * 130 + 129], 99_130.0);
        let whole = RangeGrid::new(&p.levels[0]);
        assert_eq!(p.ranges[0].tiles_x, whole.tiles_x);
        assert_eq!(p.ranges[0].bounds, whole.bounds);
        assert_eq!(p.lazy_stats().unwrap().samples_built, 130 * 100);
    }

    /// Eviction keeps a tile exactly when it lies within a tile of the
    /// window: of a 512² level of 32² tiles, all decoded, the window on
    /// tile (5, 5) keeps tiles 4 to 6 a side (a tile ending where the ring
    /// starts goes). Evicted tiles whose whole row of tiles went read as
    /// zero (their pages were given back, on Linux), and the next window decodes
    /// each evicted tile again, and only those.
    #[test]
    fn eviction_keeps_the_ring_and_evicted_tiles_decode_again() {
        let src = sloped([512, 512], 0);
        let mut p = Pyramid::decoded(src, Filter::default(), 1).unwrap();
        p.decode_window(0, [0, 0, 511, 511]).unwrap();
        let whole = p.levels[0].data.to_vec();
        let built = p.build_around(&[[160, 160, 191, 191]]);
        assert_eq!(built.evicted, 256 - 9);
        let d = p.decoded.as_ref().unwrap();
        let mut kept = d.resident[0].clone();
        kept.sort_unstable();
        let ring: Vec<[usize; 2]> = (4..7).flat_map(|i| (4..7).map(move |j| [i, j])).collect();
        assert_eq!(kept, ring);
        // Tile rows 0 to 3 went whole: every page inside them (the level
        // need not start on a page, so a page's worth is left at each end).
        let gone = &p.levels[0].data[1024..4 * 32 * 512 - 1024];
        assert!(!cfg!(target_os = "linux") || gone.iter().all(|&v| v == 0.0));
        let before = p.lazy_stats().unwrap().samples_built;
        p.decode_window(0, [0, 0, 511, 511]).unwrap();
        let again = p.lazy_stats().unwrap().samples_built - before;
        assert_eq!(again, (256 - 9) * 32 * 32);
        assert!(
            p.levels[0].data[..] == whole[..],
            "a tile did not come back"
        );
    }

    /// A move of [`evicts`]: decode the whole level or tile (i, j), or
    /// draw the window on tile (i, j).
    enum Move {
        All,
        Tile(i64, i64),
        On(i64, i64),
    }

    /// Makes `moves` on a 4096 × 2048 level of `side`² tiles whose samples
    /// are all non-zero and checks, after each, what eviction gave back,
    /// as its pages read zero (Linux):
    ///
    /// - no sample of a kept tile reads zero;
    /// - in a row of tiles partly missing, each run of missing tiles has
    ///   every page inside each of its sample rows given back;
    /// - rows of tiles missing whole, side by side, have every page inside
    ///   their span given back, the pages across their borders included.
    fn evicts(side: usize, moves: &[Move]) {
        let (w, h) = (4096usize, 2048usize);
        let src = sloped([w, h], side);
        let mut p = Pyramid::decoded(src, Filter::default(), 1).unwrap();
        // Whole pages inside samples `r` of an array at `base` of `size`
        // bytes a sample, as sample indices.
        let inner = |base: usize, size: usize, r: std::ops::Range<usize>| {
            let a = (base + size * r.start).next_multiple_of(4096);
            let b = (base + size * r.end) / 4096 * 4096;
            match b > a {
                true => (a - base) / size..(b - base) / size,
                false => 0..0,
            }
        };
        let check = |p: &Pyramid, step: usize| {
            let t = &p.decoded.as_ref().unwrap().tiles[0];
            let (data, nodata) = (&p.levels[0].data, &p.levels[0].nodata);
            let done = |i: usize, j: usize| t.done[j * t.nx + i];
            let empty = |j: usize| (0..t.nx).all(|i| !done(i, j));
            for y in 0..h {
                for i in (0..t.nx).filter(|&i| done(i, y / side)) {
                    let xs = i * side..(i + 1) * side;
                    let lost = data[y * w..][xs.clone()].contains(&0.0)
                        || xs.clone().any(|x| nodata[y * w + x] != ((x + y) % 2 == 0));
                    assert!(
                        !lost,
                        "{side}² tiles, move {step}: kept tile {i} lost row {y}"
                    );
                }
            }
            let zero = |r: std::ops::Range<usize>, what: String| {
                let d = inner(data.as_ptr() as usize, 4, r.clone());
                let n = inner(nodata.as_ptr() as usize, 1, r);
                let kept = data[d].iter().any(|&v| v != 0.0) || nodata[n].contains(&true);
                assert!(!kept, "{side}² tiles, move {step}: {what} kept pages");
            };
            let mut j = 0;
            while j < t.ny {
                if empty(j) {
                    let top = j;
                    while j < t.ny && empty(j) {
                        j += 1;
                    }
                    zero(
                        top * side * w..j * side * w,
                        format!("tile rows {top}..{j}"),
                    );
                    continue;
                }
                let mut i = 0;
                while i < t.nx {
                    if done(i, j) {
                        i += 1;
                        continue;
                    }
                    let a = i;
                    while i < t.nx && !done(i, j) {
                        i += 1;
                    }
                    for y in j * side..(j + 1) * side {
                        zero(
                            y * w + a * side..y * w + i * side,
                            format!("row {y}, tiles {a}..{i}"),
                        );
                    }
                }
                j += 1;
            }
        };
        let s = side as i64;
        for (step, m) in moves.iter().enumerate() {
            match *m {
                Move::All => p.decode_window(0, [0, 0, 4095, 2047]).unwrap(),
                Move::Tile(i, j) => {
                    let rect = [i * s, j * s, i * s + s - 1, j * s + s - 1];
                    p.decode_window(0, rect).unwrap();
                }
                Move::On(i, j) => {
                    p.build_around(&[[i * s, j * s, i * s + s - 1, j * s + s - 1]]);
                }
            }
            check(&p, step);
        }
    }

    /// Eviction gives back the pages only missing tiles use ([`evicts`]).
    /// With 512² tiles (8 × 4): tile rows empty partly (runs of 4 and 1
    /// tiles), wholly, beside a row emptied before (below it, then above
    /// it). With 1024² tiles (4 × 2), whose rows are two pages wide: a run
    /// starting after a kept tile and one ending before one, where a run
    /// a tile too long or too short would give back a kept tile's page or
    /// keep a missing one's.
    #[test]
    fn eviction_gives_back_the_pages_only_missing_tiles_use() {
        if !cfg!(target_os = "linux") {
            return;
        }
        use Move::*;
        // (5, 1) keeps tile rows 0 to 2 (tiles 4 to 6), so row 3 goes whole;
        // (5, 0) then empties row 2 beside it; (5, 3) empties rows 0 and 1;
        // (5, 8) keeps nothing, so rows 2 and 3 go beside them; (5, -1)
        // keeps only row 0, which (5, 8) then empties above rows gone.
        let (a, b) = (On(5, 8), On(5, -1));
        evicts(
            512,
            &[All, On(5, 1), On(5, 0), All, On(5, 3), a, All, b, On(5, 8)],
        );
        // (0, 0) keeps tiles 0 and 1: runs [2, 4); (3, 0) keeps 2 and 3:
        // runs [0, 2).
        evicts(1024, &[All, On(0, 0), All, On(3, 0), On(9, 9)]);
        // A run whose columns hold a kept tile in the row above: (2, 0) is
        // kept, (0, 1) goes, and its run is [0, 3) of row 1 (a run takes in
        // the missing tiles beside it, up to the window's tile); tile 2's
        // part of a sample row holds part of a page wherever the level
        // starts in its page.
        evicts(1024, &[Tile(2, 0), Tile(0, 1), On(3, 1)]);
    }

    /// What a window newly covers: none when it stays, a strip when it
    /// moves, the whole window when the level had none (or was not drawn).
    #[test]
    fn uncovered_counts_what_the_windows_newly_cover() {
        let w = [10, 20, 19, 29]; // 10 × 10, inclusive
        assert_eq!(uncovered(&[w], &[w], 0), 0);
        assert_eq!(uncovered(&[w], &[[11, 20, 20, 29]], 0), 10);
        assert_eq!(uncovered(&[w], &[[12, 21, 21, 30]], 0), 100 - 8 * 9);
        assert_eq!(uncovered(&[w], &[[40, 20, 49, 29]], 0), 100);
        assert_eq!(uncovered(&[], &[w], 0), 100);
        assert_eq!(uncovered(&[[0, 0, -1, -1]], &[w], 0), 100);
        // Level 1's window against level 1's last one.
        assert_eq!(uncovered(&[[0, 0, -1, -1], w], &[w], 1), 0);
    }
}
