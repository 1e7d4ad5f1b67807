//! Detail finer than the data (LH04; GPU Gems 2 ch. 2): a level
//! finer than the map is the interpolatory subdivision of the level above
//! it plus Gaussian noise read from a small wrapped table.
//!
//! This is the synthesis stage's arithmetic: the noise table, the
//! subdivision, and the amplitude each finer level gets from the map's own
//! measured detail. A synthesised sample is f32 arithmetic in a fixed
//! order with no fused operations and none of the shapes lavapipe's shader
//! compiler rewrites (docs/reference/raster-rules.md), so a GPU pass can repeat it
//! bit for bit; the table comes from integer arithmetic only (no `exp`,
//! `ln` or `cos`, whose last bits differ between C libraries), so a
//! synthesised level is the same bits on any machine and any thread count.

pub use crate::pyramid::subdivide::{subdivide, subdivide_window};
use crate::pyramid::PyramidLevel;
use rayon::prelude::*;

pub mod source;

/// Side of the wrapped noise table.
pub const TABLE: usize = 64;

/// How much a level's table coordinates are stretched, as a fraction: by
/// 98/97, so that the texel a coordinate lands on slips by one every 97
/// texels and the table's period of 64 does not repeat on the terrain (GPU
/// Gems 2 scales its noise coordinates for the same reason). Integer
/// division, not a float product, so that x = 97 lands on 98 everywhere.
pub const STRETCH: [i64; 2] = [98, 97];

/// A wrapped table of standard Gaussian values made from a seed.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseTable {
    values: Vec<f32>,
}

/// SplitMix64: the next state and its output.
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl NoiseTable {
    /// The table for `seed`: each value the sum of twelve uniforms on
    /// [0, 1) less 6 (the Irwin–Hall approximation of a standard Gaussian,
    /// mean 0 and variance 1, tails cut at ±6), in exact-order f64 sums.
    pub fn new(seed: u64) -> NoiseTable {
        let mut state = seed;
        let values = (0..TABLE * TABLE)
            .map(|_| {
                let mut s = 0.0f64;
                for _ in 0..12 {
                    s += (splitmix(&mut state) >> 11) as f64 / (1u64 << 53) as f64;
                }
                (s - 6.0) as f32
            })
            .collect();
        NoiseTable { values }
    }

    /// The noise at texel (x, y) of the `k`-th synthesised level (k ≥ 1):
    /// the table read at stretched coordinates, offset per level so that
    /// the levels' noise is not the same pattern at different scales.
    pub fn at(&self, k: usize, x: i64, y: i64) -> f32 {
        let [u, v] = Self::cell(k, x, y);
        self.values[v * TABLE + u]
    }

    /// The table cell [`NoiseTable::at`] reads: each coordinate stretched
    /// by [`STRETCH`] (rounded down), offset by 17 k (x) or 51 k (y), and
    /// wrapped.
    pub fn cell(k: usize, x: i64, y: i64) -> [usize; 2] {
        let off = 17 * k as i64;
        let [a, b] = STRETCH;
        let wrap = |v: i64, o: i64| ((a * v).div_euclid(b) + o).rem_euclid(TABLE as i64) as usize;
        [wrap(x, off), wrap(y, 3 * off)]
    }

    /// Every value, row-major.
    pub fn values(&self) -> &[f32] {
        &self.values
    }
}

/// RMS of `fine` less the subdivision of `coarse` (its next coarser level)
/// over the samples where neither is no-data: how much detail the map adds
/// at its finest step, the amplitude its first synthesised level continues.
/// `None` when no sample counts.
pub fn detail_rms(fine: &PyramidLevel, coarse: &PyramidLevel) -> Option<f64> {
    let w = fine.width.min(2 * coarse.width - 1);
    let h = fine.height.min(2 * coarse.height - 1);
    detail_rms_window(fine, coarse, [0, 0, w, h])
}

/// [`detail_rms`] over the samples `[x, y, w, h]` of `fine` alone (which
/// must lie in both levels), in the same order: a pack's detail measured
/// in the window decoded for it.
pub fn detail_rms_window(
    fine: &PyramidLevel,
    coarse: &PyramidLevel,
    rect: [usize; 4],
) -> Option<f64> {
    let [x0, y0, w, h] = rect;
    let (up, nd) = subdivide_window(coarse, rect);
    let (mut sum, mut count) = (0.0f64, 0u64);
    for y in 0..h {
        for x in 0..w {
            let (f, u) = ((y0 + y) * fine.width + x0 + x, y * w + x);
            if fine.nodata[f] || nd[u] {
                continue;
            }
            let d = fine.data[f] as f64 - up[u] as f64;
            sum += d * d;
            count += 1;
        }
    }
    (count > 0).then(|| (sum / count as f64).sqrt())
}

/// The amplitude of the `k`-th synthesised level (k ≥ 1) from the map's
/// finest detail `rms` and roughness `h`: rms · 2^(−h k), so each level
/// finer is rougher or smoother by the same factor as fractal terrain.
pub fn amplitude(rms: f64, h: f64, k: usize) -> f64 {
    let mut a = rms;
    let f = pow2(-h);
    for _ in 0..k {
        a *= f;
    }
    a
}

/// The largest roughness synthesis continues (and the study measures).
pub const MAX_ROUGHNESS: f64 = 2.0;

/// Checks a roughness exponent given by hand.
pub fn check_roughness(h: f64) -> Result<(), String> {
    if h.is_finite() && (0.0..=MAX_ROUGHNESS).contains(&h) {
        Ok(())
    } else {
        Err(format!("{h}: must be within 0..={MAX_ROUGHNESS}"))
    }
}

/// The roughness exponent a map's detail shows between its finest step
/// (`finest`, [`detail_rms`] of levels 0 and 1) and the next (`next`,
/// levels 1 and 2): H with 2^H = next / finest, as fractal terrain's
/// detail shrinks by 2^−H per halving of the step, within
/// 0..=[`MAX_ROUGHNESS`], to the nearest 1/1024 (found by bisection on
/// `pow2` rather than by `log2`, so every machine agrees). `None` when
/// either has no detail.
pub fn roughness_between(finest: f64, next: f64) -> Option<f64> {
    if !(finest > 0.0 && next > 0.0 && finest.is_finite() && next.is_finite()) {
        return None;
    }
    let ratio = next / finest;
    let top = (MAX_ROUGHNESS * 1024.0) as i64;
    let at = |q: i64| pow2(q as f64 / 1024.0);
    if ratio <= 1.0 {
        return Some(0.0);
    }
    if ratio >= at(top) {
        return Some(MAX_ROUGHNESS);
    }
    // at(lo) <= ratio < at(hi).
    let (mut lo, mut hi) = (0i64, top);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if at(mid) <= ratio {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    // The nearer of the two in ratio terms (log distance).
    let q = if ratio / at(lo) <= at(hi) / ratio {
        lo
    } else {
        hi
    };
    Some(q as f64 / 1024.0)
}

/// 2^x for the roughness factor, from integer powers and square roots (both
/// correctly rounded) so every machine agrees: x is taken to 1/1024.
fn pow2(x: f64) -> f64 {
    let q = (x * 1024.0).round() as i64;
    let (whole, frac) = (q.div_euclid(1024), q.rem_euclid(1024));
    let mut v = 1.0f64;
    let mut root = 2.0f64;
    // frac / 1024 in binary: 2^(1/2), 2^(1/4), ..., 2^(1/1024).
    for bit in (0..10).rev() {
        root = root.sqrt();
        if frac >> bit & 1 == 1 {
            v *= root;
        }
    }
    let mut p = 1.0f64;
    for _ in 0..whole.unsigned_abs() {
        p *= 2.0;
    }
    if whole < 0 {
        v / p
    } else {
        v * p
    }
}

/// How much detail `fine` has around each of its samples against the
/// subdivision of `coarse` (its next coarser level), over the level's
/// whole: the square root of the mean squared detail within `radius`
/// samples, over that of the whole level (1 where the level has none).
/// Noise scaled by it is loud where the map is rough and quiet where it is
/// smooth, instead of one amplitude everywhere.
pub fn detail_gain(fine: &PyramidLevel, coarse: &PyramidLevel, radius: usize) -> Vec<f64> {
    let (up, nd) = subdivide(coarse);
    let (w, h, uw) = (fine.width, fine.height, 2 * coarse.width - 1);
    let uh = 2 * coarse.height - 1;
    // Squared detail and whether it counts, then box sums by rows and columns.
    let mut sq = vec![0f64; w * h];
    let mut n = vec![0f64; w * h];
    for y in 0..h.min(uh) {
        for x in 0..w.min(uw) {
            let (f, u) = (y * w + x, y * uw + x);
            if !(fine.nodata[f] || nd[u]) {
                let d = fine.data[f] as f64 - up[u] as f64;
                sq[f] = d * d;
                n[f] = 1.0;
            }
        }
    }
    let total = sq.iter().sum::<f64>() / n.iter().sum::<f64>().max(1.0);
    let boxed = |v: &[f64]| {
        let r = radius as i64;
        let mut rows = vec![0f64; w * h];
        for y in 0..h {
            for x in 0..w {
                let (a, b) = ((x as i64 - r).max(0) as usize, (x + radius).min(w - 1));
                rows[y * w + x] = v[y * w + a..=y * w + b].iter().sum();
            }
        }
        let mut out = vec![0f64; w * h];
        for y in 0..h {
            let (a, b) = ((y as i64 - r).max(0) as usize, (y + radius).min(h - 1));
            for x in 0..w {
                out[y * w + x] = (a..=b).map(|j| rows[j * w + x]).sum();
            }
        }
        out
    };
    let (s, c) = (boxed(&sq), boxed(&n));
    s.iter()
        .zip(&c)
        .map(|(&s, &c)| {
            if total > 0.0 && c > 0.0 {
                (s / c / total).sqrt()
            } else {
                1.0
            }
        })
        .collect()
}

/// `gain` (one value per sample of a `coarse_width`-wide level) carried
/// down to the `fine` level synthesised from it, by nearest sample.
pub fn finer_gain(gain: &[f64], coarse_width: usize, fine: &PyramidLevel) -> Vec<f64> {
    let w = fine.width;
    (0..w * fine.height)
        .map(|i| gain[(i / w / 2) * coarse_width + (i % w) / 2])
        .collect()
}

/// The `k`-th synthesised level (k ≥ 1) from the level above it: its
/// subdivision plus `amp` times the table's noise, as f32; no-data where the
/// subdivision is.
pub fn synthesize(coarse: &PyramidLevel, table: &NoiseTable, k: usize, amp: f64) -> PyramidLevel {
    synthesize_with_gain(coarse, table, k, amp, None)
}

/// [`synthesize`] with the noise at each fine sample also scaled by
/// `gain` at the coarse sample it lies in (one value per coarse sample,
/// [`detail_gain`]).
pub fn synthesize_with_gain(
    coarse: &PyramidLevel,
    table: &NoiseTable,
    k: usize,
    amp: f64,
    gain: Option<&[f64]>,
) -> PyramidLevel {
    let (w, h) = (2 * coarse.width - 1, 2 * coarse.height - 1);
    let (data, nodata) = synthesize_window(coarse, table, k, amp, gain, [0, 0, w, h]);
    PyramidLevel::from_parts(w, h, data, nodata)
}

/// The samples `[x, y, w, h]` of [`synthesize_with_gain`]'s level, the
/// same bits as the whole level's (what [`subdivide_window`] says `coarse`
/// must hold): heights and no-data flags, row-major over the window.
pub fn synthesize_window(
    coarse: &PyramidLevel,
    table: &NoiseTable,
    k: usize,
    amp: f64,
    gain: Option<&[f64]>,
    rect: [usize; 4],
) -> (Vec<f32>, Vec<bool>) {
    let [x0, y0, w, _] = rect;
    let (mut data, nodata) = subdivide_window(coarse, rect);
    let cw = coarse.width;
    let a = amp as f32;
    data.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(r, row)| {
            let y = y0 + r;
            for (o, d) in row.iter_mut().enumerate() {
                let x = x0 + o;
                // The amplitude is f32 before it meets the noise, as a
                // shader receives it.
                let a = gain.map_or(a, |g| (amp * g[(y / 2) * cw + x / 2]) as f32);
                *d += a * table.at(k, x as i64, y as i64);
            }
        });
    (data, nodata)
}

#[cfg(test)]
mod tests;
