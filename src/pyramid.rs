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

use crate::heightmap::Heightmap;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Downsampling filter for building pyramid levels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind", deny_unknown_fields)]
pub enum Filter {
    Point,
    Box,
    /// `taps` is the odd kernel length (≥ 3).
    SincBlackman {
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
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
    pub nodata: Vec<bool>,
    pub min: f32,
    pub max: f32,
}

impl PyramidLevel {
    /// Sample (x, y) of this level with coordinates clamped to its extent.
    #[inline]
    pub fn get_clamped(&self, x: i64, y: i64) -> f32 {
        let xc = x.clamp(0, self.width as i64 - 1) as usize;
        let yc = y.clamp(0, self.height as i64 - 1) as usize;
        self.data[yc * self.width + xc]
    }
}

/// All levels, finest first.
#[derive(Clone, Debug)]
pub struct Pyramid {
    pub filter: Filter,
    pub levels: Vec<PyramidLevel>,
    /// Per level, height bounds of square tiles, for [`Pyramid::range_in`].
    ranges: Vec<RangeGrid>,
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
        let (tx, ty) = (l.width.div_ceil(RANGE_TILE), l.height.div_ceil(RANGE_TILE));
        let bounds = (0..ty)
            .into_par_iter()
            .flat_map_iter(|j| {
                let rows = j * RANGE_TILE..((j + 1) * RANGE_TILE).min(l.height);
                (0..tx).map(move |i| {
                    let cols = i * RANGE_TILE..((i + 1) * RANGE_TILE).min(l.width);
                    let mut b = [f32::INFINITY, f32::NEG_INFINITY];
                    for y in rows.clone() {
                        for &v in &l.data[y * l.width + cols.start..y * l.width + cols.end] {
                            b = [b[0].min(v), b[1].max(v)];
                        }
                    }
                    b
                })
            })
            .collect();
        RangeGrid {
            tiles_x: tx,
            bounds,
        }
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
        let (width, height) = (map.width(), map.height());
        let (data, nodata) = map.into_parts();
        let base = PyramidLevel {
            width,
            height,
            data,
            nodata,
            min: 0.0,
            max: 0.0,
        };
        let base = with_range(base);
        let mut p = Pyramid {
            filter,
            ranges: vec![RangeGrid::new(&base)],
            levels: vec![base],
        };
        p.extend_to(count);
        p
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
            if prev.width < 3 || prev.height < 3 {
                break;
            }
            let next = with_range(downsample(prev, &kernel));
            self.ranges.push(RangeGrid::new(&next));
            self.levels.push(next);
        }
    }
}

fn with_range(mut l: PyramidLevel) -> PyramidLevel {
    let (lo, hi) = l
        .data
        .par_iter()
        .zip(l.nodata.par_iter())
        .filter(|(_, &nd)| !nd)
        .map(|(&v, _)| (v, v))
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

/// Weighted sums of a line of output samples, Σ w·v and Σ w over the valid
/// taps, each in kernel order, in f64. Kept as two arrays so a tap is added
/// to several outputs per instruction.
struct Sums {
    sum: Vec<f64>,
    weight: Vec<f64>,
}

impl Sums {
    fn new(len: usize) -> Self {
        Sums {
            sum: vec![0.0; len],
            weight: vec![0.0; len],
        }
    }
    fn clear(&mut self) {
        self.sum.fill(0.0);
        self.weight.fill(0.0);
    }
    /// Adds tap weight `w` of samples `v` with validity `ok` (1 or 0) to
    /// every output. A no-data tap adds (w·0)·v = ±0 and w·0 = 0, which leave
    /// both sums bit for bit as skipping it would (heights are finite:
    /// no-data texels hold a fill value), and the loop needs no branch.
    #[inline(always)]
    fn add(&mut self, w: f64, v: &[f64], ok: &[f64]) {
        let n = self.sum.len();
        let (v, ok) = (&v[..n], &ok[..n]);
        for (((s, t), &v), &ok) in self.sum.iter_mut().zip(&mut self.weight).zip(v).zip(ok) {
            let w = w * ok;
            *s += w * v;
            *t += w;
        }
    }
    /// Output j normalised, or `centre` where no valid tap had weight.
    #[inline(always)]
    fn value(&self, j: usize, centre: f32) -> f32 {
        if self.weight[j] > 1e-6 {
            (self.sum[j] / self.weight[j]) as f32
        } else {
            centre
        }
    }
}

/// One line of samples as f64 values and 1/0 validity, extended by `r`
/// clamped copies at each end, and split into even and odd positions: tap k
/// of output j reads padded position 2j + k, which is element j + k/2 of
/// the even (k even) or odd (k odd) half, so every tap is a contiguous run.
fn padded_halves(r: usize, len: usize, get: impl Fn(usize) -> (f32, bool)) -> [[Vec<f64>; 2]; 2] {
    let n = len + 2 * r;
    let mut out: [[Vec<f64>; 2]; 2] = Default::default();
    for half in &mut out {
        for v in half.iter_mut() {
            v.reserve(n / 2 + 1);
        }
    }
    for i in 0..n {
        let (x, nd) = get((i as i64 - r as i64).clamp(0, len as i64 - 1) as usize);
        out[i % 2][0].push(x as f64);
        out[i % 2][1].push(if nd { 0.0 } else { 1.0 });
    }
    out
}

/// Output rows per task of [`downsample`]: each task filters the input
/// rows it needs along x itself (2·64 + taps − 1 of them), so no
/// full-size intermediate image is allocated; the rows shared with the
/// neighbouring tasks (taps − 1 of every 128) are filtered twice.
const ROWS_PER_TASK: usize = 64;

/// Pass 1 of [`downsample`] for input row `y`: filtered along x, every
/// second sample kept, into `out` (values, f32 held as f64) and `out_ok`
/// (1 valid, 0 no-data): the form pass 2 sums, converted once per row.
fn filter_row(
    src: &PyramidLevel,
    y: usize,
    kernel: &[f64],
    acc: &mut Sums,
    out: &mut [f64],
    out_ok: &mut [f64],
) {
    let w = src.width;
    let line = |x: usize| (src.data[y * w + x], src.nodata[y * w + x]);
    let halves = padded_halves(kernel.len() / 2, w, line);
    acc.clear();
    for (k, &wk) in kernel.iter().enumerate() {
        let [v, ok] = &halves[k % 2];
        acc.add(wk, &v[k / 2..], &ok[k / 2..]);
    }
    for (j, (o, o_ok)) in out.iter_mut().zip(out_ok.iter_mut()).enumerate() {
        let (centre, nd) = line(2 * j);
        *o = acc.value(j, centre) as f64;
        *o_ok = if nd { 0.0 } else { 1.0 };
    }
}

/// Filters and keeps every second sample, rows first, then columns. Each
/// output sample is the same sum in the same order as a per-sample loop
/// over the kernel; the loops go tap by tap over whole lines, so both
/// passes run 4 f64 lanes wide, and in parallel over bands of output rows.
fn downsample(src: &PyramidLevel, kernel: &[f64]) -> PyramidLevel {
    let (w, h) = (src.width, src.height);
    let (w2, h2) = ((w - 1) / 2 + 1, (h - 1) / 2 + 1);
    let r = kernel.len() / 2;
    let clamp = |i: i64| i.clamp(0, h as i64 - 1) as usize;
    let mut data = vec![0f32; w2 * h2];
    let mut nodata = vec![false; w2 * h2];
    let band = w2 * ROWS_PER_TASK;
    data.par_chunks_mut(band)
        .zip(nodata.par_chunks_mut(band))
        .enumerate()
        .for_each_init(
            || (Sums::new(w2), vec![], vec![]),
            |(acc, rows, rows_ok), (b, (out, out_nd))| {
                let j0 = b * ROWS_PER_TASK;
                let j1 = j0 + out.len() / w2;
                // Pass 1 for the input rows this band's taps reach.
                let ya = clamp(2 * j0 as i64 - r as i64);
                let yb = clamp(2 * (j1 as i64 - 1) + r as i64);
                rows.resize((yb - ya + 1) * w2, 0.0);
                rows_ok.resize((yb - ya + 1) * w2, 0.0);
                let pass1 = rows.chunks_exact_mut(w2).zip(rows_ok.chunks_exact_mut(w2));
                for (y, (row, row_ok)) in (ya..=yb).zip(pass1) {
                    filter_row(src, y, kernel, acc, row, row_ok);
                }
                // Pass 2: columns (y direction), every second row kept.
                let out_rows = out.chunks_exact_mut(w2).zip(out_nd.chunks_exact_mut(w2));
                for (j, (out, out_nd)) in (j0..j1).zip(out_rows) {
                    acc.clear();
                    for (k, &wk) in kernel.iter().enumerate() {
                        let at = (clamp(2 * j as i64 + k as i64 - r as i64) - ya) * w2;
                        acc.add(wk, &rows[at..at + w2], &rows_ok[at..at + w2]);
                    }
                    let c = (2 * j - ya) * w2;
                    let (centre, centre_ok) = (&rows[c..c + w2], &rows_ok[c..c + w2]);
                    for x in 0..w2 {
                        // Exact: the f64 holds an f32.
                        out[x] = acc.value(x, centre[x] as f32);
                        out_nd[x] = centre_ok[x] == 0.0;
                    }
                }
            },
        );
    PyramidLevel {
        width: w2,
        height: h2,
        data,
        nodata,
        min: 0.0,
        max: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// The definition: each output sample filters its input line one tap at
    /// a time, skipping no-data taps; first along x, then along y.
    fn reference(src: &PyramidLevel, kernel: &[f64]) -> (Vec<f32>, Vec<bool>) {
        let (w, h) = (src.width, src.height);
        let (w2, h2) = ((w - 1) / 2 + 1, (h - 1) / 2 + 1);
        let r = (kernel.len() / 2) as i64;
        let line = |len_out: usize, n: usize, get: &dyn Fn(usize) -> (f32, bool)| {
            (0..len_out)
                .map(|j| {
                    let c = 2 * j as i64;
                    let (mut acc, mut wsum) = (0.0f64, 0.0f64);
                    for (k, &wk) in kernel.iter().enumerate() {
                        let (v, nd) = get((c + k as i64 - r).clamp(0, n as i64 - 1) as usize);
                        if !nd {
                            acc += wk * v as f64;
                            wsum += wk;
                        }
                    }
                    let (centre, nd) = get(c as usize);
                    let v = if wsum > 1e-6 {
                        (acc / wsum) as f32
                    } else {
                        centre
                    };
                    (v, nd)
                })
                .collect::<Vec<_>>()
        };
        let rows: Vec<Vec<(f32, bool)>> = (0..h)
            .map(|y| line(w2, w, &|x| (src.data[y * w + x], src.nodata[y * w + x])))
            .collect();
        let mut out = (vec![0.0; w2 * h2], vec![false; w2 * h2]);
        for x in 0..w2 {
            let col = |y: usize| rows.get(y).expect("row")[x];
            for (y, (v, nd)) in line(h2, h, &col).into_iter().enumerate() {
                out.0[y * w2 + x] = v;
                out.1[y * w2 + x] = nd;
            }
        }
        out
    }

    proptest::proptest! {
        /// The row-wise, branch-free passes give the definition's bits, with
        /// no-data, odd and even sizes, and every filter.
        #[test]
        fn downsample_equals_the_per_sample_definition(
            w in 3usize..40, h in 3usize..300, seed in 0u64..1000, holes in 0u32..4,
            taps in proptest::sample::select(vec![3usize, 5, 11, 21]),
        ) {
            let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
            let mut next = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let data: Vec<f32> = (0..w * h).map(|_| (next() % 20_000) as f32 * 0.37 - 3000.0).collect();
            let nodata: Vec<bool> = (0..w * h).map(|_| next() % 8 < holes as u64).collect();
            let src = PyramidLevel { width: w, height: h, data, nodata, min: 0.0, max: 0.0 };
            for f in [Filter::Point, Filter::Box, Filter::SincBlackman { taps }] {
                let k = f.kernel();
                let got = downsample(&src, &k);
                let (data, nodata) = reference(&src, &k);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                proptest::prop_assert_eq!(bits(&got.data), bits(&data), "{:?}", f);
                proptest::prop_assert_eq!(&got.nodata, &nodata);
            }
        }
    }
}
