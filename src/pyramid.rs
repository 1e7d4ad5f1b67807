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
}

impl Pyramid {
    /// Builds `count` levels (level 0 is the heightmap itself). Stops early
    /// only if a level would have fewer than 2 samples along an axis.
    pub fn build(map: &Heightmap, filter: Filter, count: usize) -> Self {
        let base = PyramidLevel {
            width: map.width(),
            height: map.height(),
            data: map.data().to_vec(),
            nodata: map.nodata_mask().to_vec(),
            min: 0.0,
            max: 0.0,
        };
        let mut levels = vec![with_range(base)];
        let kernel = filter.kernel();
        while levels.len() < count {
            let prev = levels.last().expect("level 0 exists");
            if prev.width < 3 || prev.height < 3 {
                break;
            }
            levels.push(with_range(downsample(prev, &kernel)));
        }
        Pyramid { filter, levels }
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

/// Filters along one axis and keeps every second sample. `get(i)` reads the
/// input line at a clamped index and returns (value, is_nodata).
fn filter_line(
    kernel: &[f64],
    len_out: usize,
    get: impl Fn(i64) -> (f32, bool),
) -> Vec<(f32, bool)> {
    let r = (kernel.len() / 2) as i64;
    (0..len_out)
        .map(|j| {
            let c = 2 * j as i64;
            let (centre, centre_nd) = get(c);
            let (mut acc, mut wsum) = (0.0f64, 0.0f64);
            for (k, &w) in kernel.iter().enumerate() {
                let (v, nd) = get(c + k as i64 - r);
                if !nd {
                    acc += w * v as f64;
                    wsum += w;
                }
            }
            let v = if wsum > 1e-6 {
                (acc / wsum) as f32
            } else {
                centre
            };
            (v, centre_nd)
        })
        .collect()
}

fn downsample(src: &PyramidLevel, kernel: &[f64]) -> PyramidLevel {
    let (w, h) = (src.width, src.height);
    let (w2, h2) = ((w - 1) / 2 + 1, (h - 1) / 2 + 1);
    let clamp = |i: i64, n: usize| i.clamp(0, n as i64 - 1) as usize;
    // Pass 1: rows (x direction), all rows kept.
    let rows: Vec<Vec<(f32, bool)>> = (0..h)
        .into_par_iter()
        .map(|y| {
            filter_line(kernel, w2, |x| {
                let i = y * w + clamp(x, w);
                (src.data[i], src.nodata[i])
            })
        })
        .collect();
    // Pass 2: columns (y direction), every second row kept.
    let cols: Vec<Vec<(f32, bool)>> = (0..w2)
        .into_par_iter()
        .map(|x| filter_line(kernel, h2, |y| rows[clamp(y, h)][x]))
        .collect();
    let mut data = vec![0f32; w2 * h2];
    let mut nodata = vec![false; w2 * h2];
    for (x, col) in cols.iter().enumerate() {
        for (y, &(v, nd)) in col.iter().enumerate() {
            data[y * w2 + x] = v;
            nodata[y * w2 + x] = nd;
        }
    }
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
}
