//! The height pyramid: level l is the terrain sampled every 2^l texels, with
//! sample j of level l+1 sitting exactly on sample 2j of level l (vertex-
//! centred), as geometry clipmaps need for coarse vertices to coincide with
//! even fine vertices.
//!
//! Filters (applied separably, level to level):
//! - `point`: takes every second sample (Brettell's "every g-th value").
//! - `box`: a width-2 box integrated over vertex samples, i.e. weights
//!   ¼, ½, ¼. It averages, so it lowers peaks and raises troughs.
//! - `sinc-blackman`: a half-band windowed sinc (Holkner), which keeps peaks
//!   and troughs closer to their true heights.
//!
//! No-data texels take no part in the weights; a coarse sample is no-data
//! where the fine sample under it is.

mod decoded;
pub(crate) mod downsample;
mod lazy;
pub mod subdivide;

use crate::terrain::Heightmap;
pub use decoded::{Built, TileSource};
use downsample::downsample;
pub use lazy::{LazyBase, LazyStats, TILE};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Downsampling filter for building pyramid levels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind", deny_unknown_fields)]
pub enum Filter {
    /// Every other sample: aliasing, kept as the baseline.
    Point,
    /// The mean of each 2×2 block.
    Box,
    /// `taps` is the odd kernel length (≥ 3).
    SincBlackman {
        /// Kernel length: odd, 3 to 63.
        taps: usize,
    },
}

impl Default for Filter {
    fn default() -> Self {
        Filter::SincBlackman { taps: 11 }
    }
}

impl Filter {
    /// Parses `point`, `box`, `sinc-blackman` or `sinc-blackman:N`.
    pub fn parse(s: &str) -> Result<Self, String> {
        match s {
            "point" => Ok(Filter::Point),
            "box" => Ok(Filter::Box),
            "sinc-blackman" => Ok(Filter::default()),
            _ => match s.strip_prefix("sinc-blackman:") {
                Some(n) => {
                    let taps = n.parse().map_err(|_| format!("bad tap count '{n}'"))?;
                    let f = Filter::SincBlackman { taps };
                    f.validate()?;
                    Ok(f)
                }
                None => Err(format!(
                    "unknown filter '{s}' (expected point, box or sinc-blackman[:taps])"
                )),
            },
        }
    }

    /// The name [`Filter::parse`] reads back: `point`, `box`,
    /// `sinc-blackman:N`.
    pub fn name(&self) -> String {
        match *self {
            Filter::Point => "point".into(),
            Filter::Box => "box".into(),
            Filter::SincBlackman { taps } => format!("sinc-blackman:{taps}"),
        }
    }

    /// Checks the settings; the message says what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        match *self {
            Filter::SincBlackman { taps } if taps < 3 || taps % 2 == 0 || taps > 63 => Err(
                format!("sinc-blackman taps must be odd and within 3..=63, got {taps}"),
            ),
            _ => Ok(()),
        }
    }

    /// Kernel weights for offsets -r..=r, summing to 1.
    pub fn kernel(&self) -> Vec<f64> {
        match *self {
            Filter::Point => vec![1.0],
            Filter::Box => vec![0.25, 0.5, 0.25],
            Filter::SincBlackman { taps } => {
                let r = (taps / 2) as f64;
                let n = taps as f64 - 1.0;
                let mut k: Vec<f64> = (0..taps)
                    .map(|i| {
                        let x = i as f64 - r;
                        let sinc = if x == 0.0 {
                            1.0
                        } else {
                            let a = std::f64::consts::PI * x / 2.0;
                            a.sin() / a
                        };
                        let t = 2.0 * std::f64::consts::PI * i as f64 / n;
                        let blackman = 0.42 - 0.5 * t.cos() + 0.08 * (2.0 * t).cos();
                        sinc * blackman
                    })
                    .collect();
                let s: f64 = k.iter().sum();
                k.iter_mut().for_each(|v| *v /= s);
                k
            }
        }
    }
}

/// One pyramid level: a vertex grid with spacing 2^l base texels.
#[derive(Clone, Debug)]
pub struct PyramidLevel {
    /// Vertices across.
    pub width: usize,
    /// Vertices down.
    pub height: usize,
    /// Heights, row-major (height units; no-data cells hold a filled value).
    pub data: Vec<f32>,
    /// Which vertices had no data in the source, row-major.
    pub nodata: Vec<bool>,
    /// Least height in the level.
    pub min: f32,
    /// Greatest height in the level.
    pub max: f32,
}

/// Rows `[y0, y0 + data.len() / width)` of a `width` × `height` level: the
/// whole level, or the band of it a streaming pack holds in memory while
/// the rest waits on disk. The downsampler and the pack codec read levels
/// through it, so both give the same bits from a band as from the whole.
#[derive(Clone, Copy, Debug)]
pub struct Rows<'a> {
    /// Samples across the level (and the band).
    pub width: usize,
    /// Samples down the whole level, which indices clamp to.
    pub height: usize,
    /// The level row the band's first row is.
    pub y0: usize,
    /// Heights of the band's rows, row-major.
    pub data: &'a [f32],
    /// Their no-data flags.
    pub nodata: &'a [bool],
}

impl Rows<'_> {
    /// One past the band's last level row.
    pub fn end(&self) -> usize {
        self.y0 + self.data.len() / self.width
    }
    /// Index into the band of level sample (x, y), which it must hold.
    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize {
        debug_assert!(
            (self.y0..self.end()).contains(&y),
            "row {y} outside the band"
        );
        (y - self.y0) * self.width + x
    }
}

impl PyramidLevel {
    /// Level 0 made of a heightmap's own arrays (moved, not copied), with
    /// its height range.
    fn of_heightmap(map: Heightmap) -> Self {
        let (width, height) = (map.width(), map.height());
        let (data, nodata) = map.into_parts();
        Self::from_parts(width, height, data, nodata)
    }

    /// A `width` × `height` level of `data` and `nodata`, its height range
    /// taken from them.
    pub fn from_parts(width: usize, height: usize, data: Vec<f32>, nodata: Vec<bool>) -> Self {
        with_range(PyramidLevel {
            width,
            height,
            data,
            nodata,
            min: 0.0,
            max: 0.0,
        })
    }

    /// [`PyramidLevel::from_parts`] where the least and greatest valid
    /// height are known already, `(lo, hi)` ((+∞, −∞) for none), as a
    /// decoder finds them tile by tile while the samples are in cache: a
    /// second pass over a whole level was a tenth of a pack's decode.
    pub(crate) fn from_parts_ranged(
        width: usize,
        height: usize,
        data: Vec<f32>,
        nodata: Vec<bool>,
        (lo, hi): (f32, f32),
    ) -> Self {
        // A level of only no-data still has the fill value everywhere.
        let (min, max) = if lo <= hi {
            (lo, hi)
        } else {
            (data[0], data[0])
        };
        PyramidLevel {
            width,
            height,
            data,
            nodata,
            min,
            max,
        }
    }

    /// A level of one sample: what a coarsest level, which nothing
    /// predicts, is given as its coarser one.
    pub fn single() -> Self {
        PyramidLevel {
            width: 1,
            height: 1,
            data: vec![0.0],
            nodata: vec![false],
            min: 0.0,
            max: 0.0,
        }
    }

    /// The whole level as [`Rows`].
    pub fn rows(&self) -> Rows<'_> {
        Rows {
            width: self.width,
            height: self.height,
            y0: 0,
            data: &self.data,
            nodata: &self.nodata,
        }
    }

    /// Whether a coarser level can be made: it needs 2 samples per axis.
    fn can_halve(&self) -> bool {
        self.width >= 3 && self.height >= 3
    }

    /// Sample (x, y) of this level with coordinates clamped to its extent.
    #[inline]
    pub fn get_clamped(&self, x: i64, y: i64) -> f32 {
        let xc = x.clamp(0, self.width as i64 - 1) as usize;
        let yc = y.clamp(0, self.height as i64 - 1) as usize;
        self.data[yc * self.width + xc]
    }

    /// Starts fetching texels `[x0, x1)` of row `y` (clamped to the level
    /// like [`Self::copy_clamped`]) into the nearest cache, for a copy a
    /// frame later.
    pub fn prefetch_row(&self, x0: i64, x1: i64, y: i64) {
        if let Some(run) = self.prefetch_range(x0, x1, y) {
            prefetch_run(&self.data[run]);
        }
    }

    /// The samples [`Self::prefetch_row`] fetches: the smallest run of
    /// `data` that holds every sample `copy_clamped(x0, y, ..)` of
    /// `x1 − x0` samples reads; `None` for an empty run or level.
    fn prefetch_range(&self, x0: i64, x1: i64, y: i64) -> Option<std::ops::Range<usize>> {
        if self.width == 0 || self.height == 0 || x1 <= x0 {
            return None;
        }
        let w = self.width as i64;
        let (a, b) = (x0.clamp(0, w - 1) as usize, x1.clamp(1, w) as usize);
        let row = y.clamp(0, self.height as i64 - 1) as usize * self.width;
        Some(row + a..row + b)
    }

    /// Samples `(x0 + i, y)` into `out[i]`, coordinates clamped like
    /// [`PyramidLevel::get_clamped`]: one row lookup per run, and a copy
    /// where the run lies inside the level (the usual case for a clipmap
    /// update's rows and columns).
    #[inline]
    pub fn copy_clamped(&self, x0: i64, y: i64, out: &mut [f32]) {
        let w = self.width as i64;
        let yc = y.clamp(0, self.height as i64 - 1) as usize;
        let row = &self.data[yc * self.width..(yc + 1) * self.width];
        let x1 = x0 + out.len() as i64;
        if x0 >= 0 && x1 <= w {
            let src = &row[x0 as usize..x1 as usize];
            // A column's runs are a texel or two wide: a call to memcpy
            // would cost more than the copy.
            if out.len() <= 4 {
                out.iter_mut().zip(src).for_each(|(o, s)| *o = *s);
            } else {
                out.copy_from_slice(src);
            }
        } else {
            for (i, o) in out.iter_mut().enumerate() {
                *o = row[(x0 + i as i64).clamp(0, w - 1) as usize];
            }
        }
    }
}

/// Asks the processor to start loading the cache lines under `run`. A hint
/// only: no value changes, and it does nothing off x86-64.
fn prefetch_run(run: &[f32]) {
    // One touch per 64-byte line, and the last texel for a line the stride
    // steps over.
    let last = run.len().saturating_sub(1);
    for i in (0..run.len())
        .step_by(16)
        .chain((!run.is_empty()).then_some(last))
    {
        let p = run[i..].as_ptr() as *const i8;
        #[cfg(target_arch = "x86_64")]
        // SAFETY: SSE is part of x86-64, and a prefetch neither reads the
        // value nor faults.
        unsafe {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>(p);
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = p;
    }
}

/// All levels, finest first.
#[derive(Clone, Debug)]
pub struct Pyramid {
    /// The filter each coarser level was made with.
    pub filter: Filter,
    /// The levels, finest first (a lazy pyramid's coarse ones grow as tiles are built).
    pub levels: Vec<PyramidLevel>,
    /// Per level, height bounds of square tiles, for [`Pyramid::range_in`].
    ranges: Vec<RangeGrid>,
    /// For a pyramid built on demand: which tiles exist and how to make the
    /// rest (`None` once every level is complete).
    lazy: Option<Box<lazy::Lazy>>,
    /// For a pyramid decoded from a pack as windows reach its tiles.
    decoded: Option<Box<decoded::Decoded>>,
    /// A lazy pyramid's progress, kept after it completes.
    progress: Option<LazyStats>,
    /// Levels before the map's own, finer than its data
    /// ([`Pyramid::with_finer`]): level `finer` is the map's finest.
    finer: usize,
}

/// Side of the tiles whose height bounds [`RangeGrid`] keeps.
const RANGE_TILE: usize = 32;

/// Min and max height per [`RANGE_TILE`]² tile of a level (every sample,
/// no-data fill values included, so the bounds hold for whatever a clipmap
/// reads from the level).
#[derive(Clone, Debug)]
struct RangeGrid {
    tiles_x: usize,
    bounds: Vec<[f32; 2]>,
}

impl RangeGrid {
    fn new(l: &PyramidLevel) -> Self {
        let mut g = Self::empty(l);
        let tx = g.tiles_x;
        g.bounds
            .par_iter_mut()
            .enumerate()
            .for_each(|(t, b)| *b = Self::tile_bounds(l, t % tx, t / tx));
        g
    }
    /// Bounds that hold nothing yet (min +∞, max −∞), for a lazy level.
    fn empty(l: &PyramidLevel) -> Self {
        let (tx, ty) = (l.width.div_ceil(RANGE_TILE), l.height.div_ceil(RANGE_TILE));
        RangeGrid {
            tiles_x: tx,
            bounds: vec![[f32::INFINITY, f32::NEG_INFINITY]; tx * ty],
        }
    }
    /// Min and max of range tile (i, j) of `l`.
    fn tile_bounds(l: &PyramidLevel, i: usize, j: usize) -> [f32; 2] {
        let rows = j * RANGE_TILE..((j + 1) * RANGE_TILE).min(l.height);
        let cols = i * RANGE_TILE..((i + 1) * RANGE_TILE).min(l.width);
        let mut b = [f32::INFINITY, f32::NEG_INFINITY];
        for y in rows {
            let (lo, hi) = extremes(&l.data[y * l.width + cols.start..y * l.width + cols.end]);
            b = [b[0].min(lo), b[1].max(hi)];
        }
        b
    }
}

impl Pyramid {
    /// Builds `count` levels (level 0 is the heightmap itself). Stops early
    /// only if a level would have fewer than 2 samples along an axis.
    pub fn build(map: &Heightmap, filter: Filter, count: usize) -> Self {
        Self::from_heightmap(map.clone(), filter, count)
    }

    /// [`Pyramid::build`] taking the heightmap as level 0 instead of copying
    /// it: for a 16384² map that saves 1.3 GB and the time to fault it in.
    pub fn from_heightmap(map: Heightmap, filter: Filter, count: usize) -> Self {
        let base = PyramidLevel::of_heightmap(map);
        let mut p = Pyramid {
            filter,
            ranges: vec![RangeGrid::new(&base)],
            levels: vec![base],
            lazy: None,
            decoded: None,
            progress: None,
            finer: 0,
        };
        p.extend_to(count);
        p
    }

    /// A pyramid of levels made elsewhere (decoded from a pack), finest
    /// first, each the vertex-centred half of the one before.
    pub fn from_levels(levels: Vec<PyramidLevel>, filter: Filter) -> Self {
        Pyramid {
            filter,
            ranges: levels.iter().map(RangeGrid::new).collect(),
            levels,
            lazy: None,
            decoded: None,
            progress: None,
            finer: 0,
        }
    }

    /// Levels finer than the map's data, before its own
    /// ([`Pyramid::with_finer`]); level `finer_levels()` is the map's
    /// finest.
    pub fn finer_levels(&self) -> usize {
        self.finer
    }

    /// The least and greatest height of the map's own finest level: the
    /// range a height ramp spans, the same whether or not finer levels
    /// are synthesised and however they are made (their own bounds,
    /// conservative until they are whole, are not).
    pub fn height_range(&self) -> [f32; 2] {
        let l = &self.levels[self.finer];
        [l.min, l.max]
    }

    /// Bounds on the heights that level `l` gives, edge-clamped, at level
    /// texels [x0, x1] × [y0, y1]. They come from the tiles the rectangle
    /// touches, so their cost depends on the rectangle, not on the map: a
    /// clipmap's culling stays independent of the terrain's size.
    pub fn range_in(&self, l: usize, [x0, y0, x1, y1]: [i64; 4]) -> (f32, f32) {
        let lv = &self.levels[l];
        let g = &self.ranges[l];
        let tile = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize / RANGE_TILE;
        let (i0, i1) = (tile(x0, lv.width), tile(x1, lv.width));
        let (j0, j1) = (tile(y0, lv.height), tile(y1, lv.height));
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for j in j0.min(j1)..=j1.max(j0) {
            for b in &g.bounds[j * g.tiles_x + i0.min(i1)..=j * g.tiles_x + i1.max(i0)] {
                lo = lo.min(b[0]);
                hi = hi.max(b[1]);
            }
        }
        (lo, hi)
    }

    /// Adds coarser levels until there are `count` (or a level would have
    /// fewer than 2 samples along an axis).
    fn extend_to(&mut self, count: usize) {
        let kernel = self.filter.kernel();
        while self.levels.len() < count {
            let prev = self.levels.last().expect("level 0 exists");
            if !prev.can_halve() {
                break;
            }
            let next = with_range(downsample(prev, &kernel));
            self.ranges.push(RangeGrid::new(&next));
            self.levels.push(next);
        }
    }
}

/// `l` with its `min` and `max` set from its valid samples (the fill value
/// where it has none).
pub(crate) fn with_range(mut l: PyramidLevel) -> PyramidLevel {
    const CHUNK: usize = 1 << 14;
    let (lo, hi) = l
        .data
        .par_chunks(CHUNK)
        .zip(l.nodata.par_chunks(CHUNK))
        .map(|(d, n)| range_of(d, n))
        .reduce(
            || (f32::INFINITY, f32::NEG_INFINITY),
            |a, b| (a.0.min(b.0), a.1.max(b.1)),
        );
    // A level of only no-data still has the fill value everywhere.
    let (lo, hi) = if lo <= hi {
        (lo, hi)
    } else {
        (l.data[0], l.data[0])
    };
    l.min = lo;
    l.max = hi;
    l
}

/// The least and greatest of `data` where `nodata` is false, (+∞, −∞)
/// when there are none.
pub(crate) fn range_of(data: &[f32], nodata: &[bool]) -> (f32, f32) {
    if nodata.iter().fold(false, |a, &b| a | b) {
        return data
            .iter()
            .zip(nodata)
            .filter(|(_, &nd)| !nd)
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (&v, _)| {
                (lo.min(v), hi.max(v))
            });
    }
    extremes(data)
}

/// The least and greatest of `data` ((+∞, −∞) for none; NaN skipped, as
/// `f32::min` skips it). Eight independent running
/// extremes, so the loop vectorises instead of being one serial chain of
/// comparisons (that chain was an eighth of a pack's decode time).
pub(crate) fn extremes(data: &[f32]) -> (f32, f32) {
    const LANES: usize = 8;
    let mut lo = [f32::INFINITY; LANES];
    let mut hi = [f32::NEG_INFINITY; LANES];
    let chunks = data.chunks_exact(LANES);
    let rest = chunks.remainder();
    for d in chunks {
        for k in 0..LANES {
            lo[k] = lo[k].min(d[k]);
            hi[k] = hi[k].max(d[k]);
        }
    }
    for &v in rest {
        lo[0] = lo[0].min(v);
        hi[0] = hi[0].max(v);
    }
    (
        lo.iter().fold(f32::INFINITY, |a, &b| a.min(b)),
        hi.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The range skips no-data and NaN, holds for lengths that are not a
    /// multiple of the lanes, and is (+∞, −∞) for nothing.
    #[test]
    fn range_of_skips_no_data_at_any_length() {
        let data: Vec<f32> = (0..37).map(|i| i as f32 - 10.0).collect();
        let mut nodata = vec![false; 37];
        nodata[0] = true; // −10
        nodata[36] = true; // 26, in the remainder
        assert_eq!(range_of(&data, &nodata), (-9.0, 25.0));
        let mut nan = data.clone();
        nan[5] = f32::NAN;
        assert_eq!(range_of(&nan, &nodata), (-9.0, 25.0));
        assert_eq!(
            range_of(&data[..3], &[true; 3]),
            (f32::INFINITY, f32::NEG_INFINITY)
        );
        assert_eq!(range_of(&data[..20], &[false; 20]), (-10.0, 9.0));
    }

    /// Prefetch hints clamp like copies: for any range, on or off the level,
    /// inverted or empty, the run fetched is exactly the hull of the samples
    /// the same copy reads, and fetching changes nothing.
    #[test]
    fn prefetch_fetches_what_the_copy_reads() {
        let data: Vec<f32> = (0..40 * 30).map(|i| i as f32).collect();
        let lv = PyramidLevel {
            width: 40,
            height: 30,
            data: data.clone(),
            nodata: vec![false; 40 * 30],
            min: 0.0,
            max: 0.0,
        };
        for (x0, x1) in [
            (0, 40),
            (-100, -50),
            (35, 90),
            (60, 70),
            (20, 10),
            (5, 5),
            (-3, 3),
            (0, 1),
            (39, 40),
            (-1, 41),
        ] {
            for y in [-5, 0, 29, 30, 400] {
                let got = lv.prefetch_range(x0, x1, y);
                let want = (x1 > x0).then(|| {
                    // The values are their own indices.
                    let mut out = vec![0.0; (x1 - x0) as usize];
                    lv.copy_clamped(x0, y, &mut out);
                    let lo = out.iter().copied().fold(f32::INFINITY, f32::min) as usize;
                    let hi = out.iter().copied().fold(0.0, f32::max) as usize;
                    lo..hi + 1
                });
                assert_eq!(got, want, "x {x0}..{x1}, y {y}");
                lv.prefetch_row(x0, x1, y);
            }
        }
        prefetch_run(&[]);
        assert_eq!(lv.data, data);
        let empty = PyramidLevel {
            width: 0,
            height: 0,
            data: vec![],
            nodata: vec![],
            min: 0.0,
            max: 0.0,
        };
        assert_eq!(empty.prefetch_range(0, 5, 0), None);
        empty.prefetch_row(0, 5, 0);
    }

    fn bump(sigma: f64) -> Heightmap {
        let n = 65;
        let v = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f64 - 32.0, (i / n) as f64 - 32.0);
                (100.0 * (-(x * x + y * y) / (2.0 * sigma * sigma)).exp()) as f32
            })
            .collect();
        Heightmap::from_values(n, n, v, None, [1.0, 1.0], "t").unwrap()
    }

    #[test]
    fn level_sizes_are_vertex_centred() {
        let h =
            Heightmap::from_values(403, 344, vec![1.0; 403 * 344], None, [1.0, 1.0], "t").unwrap();
        let p = Pyramid::build(&h, Filter::Box, 4);
        let dims: Vec<_> = p.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(dims, vec![(403, 344), (202, 172), (101, 86), (51, 43)]);
    }

    #[test]
    fn point_filter_samples_every_2_to_the_l() {
        let h = bump(4.0);
        let p = Pyramid::build(&h, Filter::Point, 3);
        for y in 0..p.levels[2].height {
            for x in 0..p.levels[2].width {
                assert_eq!(
                    p.levels[2].data[y * p.levels[2].width + x],
                    h.get(4 * x, 4 * y)
                );
            }
        }
    }

    #[test]
    fn kernels_sum_to_one() {
        for f in [
            Filter::Point,
            Filter::Box,
            Filter::SincBlackman { taps: 11 },
        ] {
            let s: f64 = f.kernel().iter().sum();
            assert!((s - 1.0).abs() < 1e-12);
        }
    }
}
