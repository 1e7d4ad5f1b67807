//! How plausible synthesised detail is: a map decimated 2× or 4× by its own
//! pyramid, synthesised back down to full resolution, against the real
//! map. Synthesis cannot recover the real terrain, only match its
//! statistics, so the study measures statistics: the variogram's slope
//! (twice the roughness exponent), the distribution of slopes (by the
//! Kolmogorov–Smirnov distance) and, for scale, the RMSE; each for the
//! synthesised surface and for the plain subdivision without noise.

use crate::error::{Error, Result};
use crate::pyramid::{Filter, Pyramid, PyramidLevel};
use crate::synthesis::{
    amplitude, check_roughness, detail_gain, detail_rms, finer_gain, roughness_between, synthesize,
    synthesize_with_gain, NoiseTable,
};
use crate::terrain::{window_of, Heightmap};
use serde::Serialize;

/// What to measure.
#[derive(Clone, Debug)]
pub struct Options {
    /// 2 or 4: how far the map is decimated before synthesis.
    pub factor: usize,
    /// Roughness H (amplitude × 2^−H a level); `None` measures it from the
    /// decimated map's two finest detail levels.
    pub roughness: Option<f64>,
    /// The noise table's seed.
    pub seed: u64,
    /// The pyramid's filter (the decimation).
    pub filter: Filter,
    /// Scale the noise by the decimated map's local detail
    /// ([`detail_gain`]) instead of one amplitude everywhere.
    pub local: bool,
}

/// Samples around each one that its local detail is measured over.
const LOCAL_RADIUS: usize = 2;

/// One surface against the real map.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Surface {
    /// Slope of log₂ variogram against log₂ lag over lags 1, 2, 4, 8.
    pub variogram_slope: f64,
    /// Its difference from the real map's, over the real map's.
    pub variogram_slope_error: f64,
    /// Kolmogorov–Smirnov distance between its slopes' distribution and
    /// the real map's.
    pub slope_ks: f64,
    /// RMS height difference from the real map.
    pub rmse: f64,
}

/// The study's figures.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// The compared region's samples across.
    pub width: usize,
    /// And down.
    pub height: usize,
    /// The decimation factor.
    pub factor: usize,
    /// The roughness used.
    pub roughness: f64,
    /// Whether it was measured from the decimated map.
    pub roughness_measured: bool,
    /// Whether the noise followed the map's local detail.
    pub local: bool,
    /// The noise amplitude of each synthesised level, coarse to fine.
    pub amplitudes: Vec<f64>,
    /// The real map's variogram slope.
    pub real_variogram_slope: f64,
    /// Subdivision plus noise.
    pub synthesised: Surface,
    /// Subdivision alone.
    pub subdivided: Surface,
}

/// The three surfaces, for pictures: the real map's region, the decimated
/// level, and the synthesised one (the last the real one's size).
pub struct Surfaces {
    /// The real map over the compared region.
    pub real: PyramidLevel,
    /// The pyramid level synthesis started from.
    pub decimated: PyramidLevel,
    /// Synthesised back to the real map's resolution.
    pub synthesised: PyramidLevel,
}

/// Runs the study on `map`.
pub fn run(map: &Heightmap, opts: &Options) -> Result<(Report, Surfaces)> {
    let k = match opts.factor {
        2 => 1,
        4 => 2,
        f => {
            return Err(Error::value(
                "synthesis.factor",
                format!("{f}: must be 2 or 4"),
            ))
        }
    };
    if let Some(h) = opts.roughness {
        check_roughness(h).map_err(|r| Error::value("synthesis.roughness", r))?;
    }
    let pyr = Pyramid::build(map, opts.filter, k + 3);
    if pyr.levels.len() < k + 3 {
        return Err(Error::value(
            "synthesis",
            format!(
                "a {}×{} map is too small to decimate {}× and measure its detail",
                map.width(),
                map.height(),
                opts.factor
            ),
        ));
    }
    let lv = &pyr.levels;
    let too_flat = || Error::value("synthesis", "the map has no detail to continue (flat)");
    let finest = detail_rms(&lv[k], &lv[k + 1]).ok_or_else(too_flat)?;
    let next = detail_rms(&lv[k + 1], &lv[k + 2]).ok_or_else(too_flat)?;
    let (roughness, measured) = match opts.roughness {
        Some(h) => (h, false),
        None => (roughness_between(finest, next).ok_or_else(too_flat)?, true),
    };
    let table = NoiseTable::new(opts.seed);
    let amplitudes: Vec<f64> = (1..=k).map(|j| amplitude(finest, roughness, j)).collect();
    let (mut synth, mut plain) = (lv[k].clone(), lv[k].clone());
    // The noise follows the decimated map's local detail, carried down to
    // each finer level by nearest sample.
    let mut gain = opts
        .local
        .then(|| detail_gain(&lv[k], &lv[k + 1], LOCAL_RADIUS));
    for (j, &a) in amplitudes.iter().enumerate() {
        let next = synthesize_with_gain(&synth, &table, j + 1, a, gain.as_deref());
        gain = gain.map(|g| finer_gain(&g, synth.width, &next));
        synth = next;
        plain = synthesize(&plain, &table, j + 1, 0.0);
    }
    let (w, h) = (synth.width.min(map.width()), synth.height.min(map.height()));
    let real = crop(&lv[0], w, h);
    let (synth, plain) = (crop(&synth, w, h), crop(&plain, w, h));
    let real_slope = variogram_slope(&real);
    let real_grad = gradients(&real, &real);
    let surface = |s: &PyramidLevel| {
        let slope = variogram_slope(s);
        Surface {
            variogram_slope: slope,
            variogram_slope_error: (slope - real_slope) / real_slope,
            slope_ks: ks(&real_grad, &gradients(s, &real)),
            rmse: rmse(&real, s),
        }
    };
    let report = Report {
        width: w,
        height: h,
        factor: opts.factor,
        roughness,
        roughness_measured: measured,
        local: opts.local,
        amplitudes,
        real_variogram_slope: real_slope,
        synthesised: surface(&synth),
        subdivided: surface(&plain),
    };
    let decimated = lv[k].clone();
    Ok((
        report,
        Surfaces {
            real,
            decimated,
            synthesised: synth,
        },
    ))
}

/// The first `w` × `h` samples of `l`.
fn crop(l: &PyramidLevel, w: usize, h: usize) -> PyramidLevel {
    let data = window_of(&l.data, l.width, [0, 0, w, h]);
    let nodata = window_of(&l.nodata, l.width, [0, 0, w, h]);
    PyramidLevel::from_parts(w, h, data, nodata)
}

/// Least-squares slope of log₂ γ(h) against log₂ h for lags 1, 2, 4, 8,
/// γ(h) the mean squared height difference of sample pairs h apart along
/// rows and columns where neither is no-data.
pub fn variogram_slope(l: &PyramidLevel) -> f64 {
    let at = |x: usize, y: usize| {
        let i = y * l.width + x;
        (!l.nodata[i]).then(|| l.data[i] as f64)
    };
    let pts: Vec<(f64, f64)> = [1usize, 2, 4, 8]
        .iter()
        .filter_map(|&lag| {
            let (mut sum, mut n) = (0.0f64, 0u64);
            for y in 0..l.height {
                for x in 0..l.width {
                    let Some(z) = at(x, y) else { continue };
                    for (dx, dy) in [(lag, 0), (0, lag)] {
                        if x + dx < l.width && y + dy < l.height {
                            if let Some(v) = at(x + dx, y + dy) {
                                sum += (v - z) * (v - z);
                                n += 1;
                            }
                        }
                    }
                }
            }
            (n > 0 && sum > 0.0).then(|| ((lag as f64).log2(), (sum / n as f64).log2()))
        })
        .collect();
    let n = pts.len() as f64;
    if pts.len() < 2 {
        return 0.0;
    }
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    sxy / sxx
}

/// Central-difference slope magnitudes (height units per sample) of `l`
/// at the interior samples where it and `mask`, and their four neighbours,
/// hold data; sorted.
fn gradients(l: &PyramidLevel, mask: &PyramidLevel) -> Vec<f64> {
    let w = l.width;
    let ok = |i: usize| !l.nodata[i] && !mask.nodata[i];
    let mut g = Vec::new();
    for y in 1..l.height.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let i = y * w + x;
            if !(ok(i) && ok(i - 1) && ok(i + 1) && ok(i - w) && ok(i + w)) {
                continue;
            }
            let gx = (l.data[i + 1] as f64 - l.data[i - 1] as f64) / 2.0;
            let gy = (l.data[i + w] as f64 - l.data[i - w] as f64) / 2.0;
            g.push((gx * gx + gy * gy).sqrt());
        }
    }
    g.sort_by(f64::total_cmp);
    g
}

/// The Kolmogorov–Smirnov distance between two sorted samples: the largest
/// gap between their empirical distribution functions.
pub fn ks(a: &[f64], b: &[f64]) -> f64 {
    if a.is_empty() || b.is_empty() {
        return 1.0;
    }
    let (mut i, mut j, mut d) = (0usize, 0usize, 0f64);
    while i < a.len() && j < b.len() {
        let v = a[i].min(b[j]);
        while i < a.len() && a[i] <= v {
            i += 1;
        }
        while j < b.len() && b[j] <= v {
            j += 1;
        }
        d = d.max((i as f64 / a.len() as f64 - j as f64 / b.len() as f64).abs());
    }
    d
}

/// RMS of `a` − `b` where neither is no-data.
fn rmse(a: &PyramidLevel, b: &PyramidLevel) -> f64 {
    let (mut s, mut n) = (0.0f64, 0u64);
    for i in 0..a.data.len() {
        if !a.nodata[i] && !b.nodata[i] {
            let d = a.data[i] as f64 - b.data[i] as f64;
            s += d * d;
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// The `q` quantile of `l`'s slope magnitudes (height units per sample).
pub fn slope_percentile(l: &PyramidLevel, q: f64) -> f64 {
    let g = gradients(l, l);
    if g.is_empty() {
        return 0.0;
    }
    g[((g.len() - 1) as f64 * q.clamp(0.0, 1.0)) as usize]
}

/// The three surfaces side by side as hillshades, for `synthesis -o`: a
/// title over them (`title`, the map's name) and a label over each panel
/// (real, decimated F×, synthesised), so the picture reads on its own. The
/// real map's 95th-percentile slope shades at 45°, so maps of any relief
/// and cell size show their forms.
pub fn comparison_png(s: &Surfaces, factor: usize, title: &str) -> Result<Vec<u8>> {
    use crate::studies::report::text::{self, Anchor};
    let e = 1.0 / slope_percentile(&s.real, 0.95).max(1e-9);
    let panels = [
        (hillshade(&s.real, e, 1), "real".to_string()),
        (
            hillshade(&s.decimated, e / factor as f64, factor),
            format!("decimated {factor}×"),
        ),
        (
            hillshade(&s.synthesised, e, 1),
            format!("synthesised back down ({factor}×)"),
        ),
    ];
    let (gap, head) = (4usize, 56usize);
    let (pw, ph) = (s.real.width, s.real.height);
    let width = 3 * pw + 2 * gap;
    let mut pm = tiny_skia::Pixmap::new(width as u32, (ph + head) as u32)
        .ok_or_else(|| Error::value("synthesis -o", format!("a {width} × {ph} picture")))?;
    pm.fill(tiny_skia::Color::WHITE);
    let data = pm.data_mut();
    for (k, ((w, _, px), _)) in panels.iter().enumerate() {
        let n = pw.min(*w);
        for y in 0..ph {
            for x in 0..n {
                let g = px[y * w + x];
                let o = ((y + head) * width + k * (pw + gap) + x) * 4;
                data[o..o + 4].copy_from_slice(&[g, g, g, 255]);
            }
        }
    }
    let ink = [30, 30, 30];
    text::draw(
        &mut pm,
        (width as f32 / 2.0, 20.0),
        title,
        13.0,
        Anchor::Middle,
        false,
        ink,
    );
    for (k, (_, label)) in panels.iter().enumerate() {
        let x = (k * (pw + gap) + pw / 2) as f32;
        text::draw(&mut pm, (x, 46.0), label, 10.0, Anchor::Middle, false, ink);
    }
    pm.encode_png()
        .map_err(|e| Error::value("synthesis -o", e.to_string()))
}

/// Grey hillshade of `l` (light from the north-west, 45° up; `exaggerate`
/// scales heights over the sample spacing), `scale` pixels a sample.
pub fn hillshade(l: &PyramidLevel, exaggerate: f64, scale: usize) -> (usize, usize, Vec<u8>) {
    let (w, h) = (l.width, l.height);
    let at = |x: i64, y: i64| {
        l.data[(y.clamp(0, h as i64 - 1) as usize) * w + x.clamp(0, w as i64 - 1) as usize] as f64
    };
    let light = glam::DVec3::new(-1.0, -1.0, 2f64.sqrt()).normalize();
    let (ow, oh) = (w * scale, h * scale);
    let mut out = vec![0u8; ow * oh];
    for y in 0..h {
        for x in 0..w {
            let (xi, yi) = (x as i64, y as i64);
            let gx = (at(xi + 1, yi) - at(xi - 1, yi)) / 2.0 * exaggerate;
            let gy = (at(xi, yi + 1) - at(xi, yi - 1)) / 2.0 * exaggerate;
            let n = glam::DVec3::new(-gx, -gy, 1.0).normalize();
            let v = if l.nodata[y * w + x] {
                0
            } else {
                (n.dot(light).max(0.0) * 255.0).round() as u8
            };
            for sy in 0..scale {
                out[(y * scale + sy) * ow + x * scale..][..scale].fill(v);
            }
        }
    }
    (ow, oh, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// KS distance: 0 for equal samples, 1 for disjoint ones, and the gap
    /// of the distribution functions between.
    #[test]
    fn ks_distance_is_the_largest_gap() {
        assert_eq!(ks(&[1.0, 2.0, 3.0], &[1.0, 2.0, 3.0]), 0.0);
        assert_eq!(ks(&[1.0, 2.0], &[3.0, 4.0]), 1.0);
        assert_eq!(ks(&[1.0, 2.0, 3.0, 4.0], &[3.0, 4.0]), 0.5);
    }

    /// A variogram of a surface whose squared differences grow as lag²
    /// (a plane) has slope 2.
    #[test]
    fn a_plane_has_variogram_slope_two() {
        let (w, h) = (40, 30);
        let data = (0..w * h).map(|i| (i % w + i / w) as f32).collect();
        let l = PyramidLevel::from_parts(w, h, data, vec![false; w * h]);
        assert!((variogram_slope(&l) - 2.0).abs() < 1e-12);
    }
}
