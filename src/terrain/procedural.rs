//! Seeded procedural terrain: fBm of gradient noise with ridged upper octaves,
//! so the embedded default scene has peaks, valleys and cliffs without a file.
//! Each texel is a pure function of (seed, x, y), so the result is identical
//! for any thread count.

use super::Heightmap;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Parameters of the generator.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Procedural {
    /// Seed: the same map on every machine and thread count.
    pub seed: u64,
    /// Samples across.
    pub width: usize,
    /// Samples down.
    pub height: usize,
    /// Wavelength of the first octave in texels.
    #[serde(default = "default_wavelength")]
    pub wavelength: f64,
    /// Octaves of noise summed (fBm).
    #[serde(default = "default_octaves")]
    pub octaves: u32,
    /// Peak-to-trough amplitude in metres, before `vertical_scale`.
    #[serde(default = "default_amplitude")]
    pub amplitude: f64,
}

fn default_wavelength() -> f64 {
    256.0
}
fn default_octaves() -> u32 {
    8
}
fn default_amplitude() -> f64 {
    600.0
}

impl Procedural {
    /// A generator with default shape parameters.
    pub fn new(seed: u64, width: usize, height: usize) -> Self {
        Procedural {
            seed,
            width,
            height,
            wavelength: default_wavelength(),
            octaves: default_octaves(),
            amplitude: default_amplitude(),
        }
    }

    /// Height at texel (x, y) in metres.
    pub fn sample(&self, x: f64, y: f64) -> f64 {
        self.sample_with(x, y, |o, cx, cy| gradient(self.octave_seed(o), cx, cy))
    }

    fn octave_seed(&self, o: u32) -> u64 {
        self.seed.wrapping_add(o as u64 * 0x9E37)
    }

    /// Octave frequencies, doubling from 1 / wavelength (the same f64 values
    /// for every caller).
    fn frequencies(&self) -> impl Iterator<Item = f64> {
        std::iter::successors(Some(1.0 / self.wavelength), |f| Some(f * 2.0))
            .take(self.octaves as usize)
    }

    /// [`Procedural::sample`] with the lattice gradients (cos, sin) of octave o
    /// at (cx, cy) from `grad`, so `generate` can look them up instead of
    /// recomputing them for every texel.
    #[inline(always)]
    fn sample_with(&self, x: f64, y: f64, grad: impl Fn(u32, i64, i64) -> (f64, f64)) -> f64 {
        let mut sum = 0.0;
        let mut amp = 0.5;
        for (o, freq) in (0..self.octaves).zip(self.frequencies()) {
            let n = gradient_noise(x * freq, y * freq, |cx, cy| grad(o, cx, cy));
            // Lower octaves shape the land; upper octaves are ridged for crests.
            let v = if o < 2 { n } else { 0.5 - n.abs() };
            sum += amp * v;
            amp *= 0.5;
        }
        sum * self.amplitude
    }

    /// Checks the parameters `generate` and lazy generation rely on.
    pub fn validate(&self) -> Result<(), String> {
        super::check_dimensions(self.width as u64, self.height as u64)?;
        self.validate_shape()
    }

    /// Checks the parameters other than the size (which a generator by
    /// rows limits per side only).
    pub fn validate_shape(&self) -> Result<(), String> {
        if !(self.wavelength.is_finite() && self.wavelength > 0.0) {
            return Err("procedural wavelength must be positive".into());
        }
        if self.octaves == 0 || self.octaves > 24 {
            return Err("procedural octaves must be within 1..=24".into());
        }
        if !self.amplitude.is_finite() {
            return Err("procedural amplitude must be finite".into());
        }
        Ok(())
    }

    /// Generates the heightmap (cell size 1 m; the scene scales it), in
    /// parallel bands of `BAND` rows.
    pub fn generate(&self) -> Result<Heightmap, String> {
        self.validate()?;
        let mut values = crate::terrain::huge::filled(self.width * self.height, 0f32);
        values
            .par_chunks_mut(self.width * BAND)
            .enumerate()
            .for_each(|(b, band)| {
                let y0 = b * BAND;
                self.fill_rect([0, y0, self.width, y0 + band.len() / self.width], band);
            });
        Heightmap::from_values(
            self.width,
            self.height,
            values,
            None,
            [1.0, 1.0],
            "procedural",
        )
    }

    /// Heights of texels `[x0, x1) × [y0, y1)`, row-major: a tile of the map
    /// without generating the rest (the lazy pyramid's level 0), with the
    /// bits `generate` gives there.
    pub fn generate_rect(&self, rect: [usize; 4]) -> Vec<f32> {
        let mut values = vec![0f32; (rect[2] - rect[0]) * (rect[3] - rect[1])];
        self.fill_rect(rect, &mut values);
        values
    }

    /// Texels of `rect` into `out` (row-major). Per octave it first looks
    /// up the gradients of the lattice points the rectangle spans: a 32²
    /// tile needs about 0.5 (cos, sin) pairs per texel, and a band of 16
    /// full rows fewer still, where sampling each texel alone needs 32.
    fn fill_rect(&self, rect: [usize; 4], out: &mut [f32]) {
        // In the AVX2 + FMA build `floor` is one instruction instead of a
        // libm call (16 per texel). Rust never fuses a multiply and an add
        // on its own, so the bits are the portable ones
        // (`generate_equals_sample_bit_for_bit` compares with `sample`).
        fill_rect_in(true, self, rect, out)
    }

    #[inline(always)]
    fn fill_rect_portable(&self, [x0, y0, x1, y1]: [usize; 4], out: &mut [f32]) {
        let tables: Vec<Lattice> = (0..self.octaves)
            .zip(self.frequencies())
            .map(|(o, f)| {
                // The lattice cells of the first and last texels; the noise
                // also reads the next lattice line after each.
                let cell = |v: usize| (v as f64 * f).floor() as i64;
                let (cx, cy) = (cell(x0), cell(y0));
                let nx = (cell(x1 - 1) - cx + 2) as usize;
                let ny = (cell(y1 - 1) - cy + 2) as usize;
                let seed = self.octave_seed(o);
                let t = (0..ny as i64)
                    .flat_map(|j| (0..nx as i64).map(move |i| gradient(seed, cx + i, cy + j)))
                    .collect();
                ([cx, cy], nx, t)
            })
            .collect();
        let grad = |o: u32, cx: i64, cy: i64| {
            let ([cx0, cy0], nx, t) = &tables[o as usize];
            t[(cy - cy0) as usize * nx + (cx - cx0) as usize]
        };
        for (y, row) in (y0..y1).zip(out.chunks_exact_mut(x1 - x0)) {
            for (x, v) in (x0..x1).zip(row.iter_mut()) {
                *v = self.sample_with(x as f64, y as f64, grad) as f32;
            }
        }
    }
}

crate::cpu::avx2_fma_twin! {
    fn fill_rect_in(p: &Procedural, rect: [usize; 4], out: &mut [f32]) => Procedural::fill_rect_portable
}

/// Rows per task of [`Procedural::generate`].
const BAND: usize = 16;

/// Per octave: the first lattice column and row, the lattice columns per
/// row, and the (cos, sin) gradients of the lattice points a rectangle of
/// texels reads.
type Lattice = ([i64; 2], usize, Vec<(f64, f64)>);

fn hash(seed: u64, x: i64, y: i64) -> u64 {
    let mut h = seed ^ (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    h ^= (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    h = h.wrapping_mul(0xC4CE_B9FE_1A85_EC53);
    h ^ (h >> 33)
}

/// The unit gradient (cos a, sin a) at lattice point (cx, cy).
fn gradient(seed: u64, cx: i64, cy: i64) -> (f64, f64) {
    let a = (hash(seed, cx, cy) >> 11) as f64 * (std::f64::consts::TAU / (1u64 << 53) as f64);
    (a.cos(), a.sin())
}

/// Perlin-style gradient noise in about [-0.7, 0.7], with the lattice
/// gradients from `g`.
#[inline(always)]
fn gradient_noise(x: f64, y: f64, g: impl Fn(i64, i64) -> (f64, f64)) -> f64 {
    let (xi, yi) = (x.floor(), y.floor());
    let (fx, fy) = (x - xi, y - yi);
    let (xi, yi) = (xi as i64, yi as i64);
    let grad = |cx: i64, cy: i64, dx: f64, dy: f64| {
        let (c, s) = g(cx, cy);
        c * dx + s * dy
    };
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (u, v) = (fade(fx), fade(fy));
    let n00 = grad(xi, yi, fx, fy);
    let n10 = grad(xi + 1, yi, fx - 1.0, fy);
    let n01 = grad(xi, yi + 1, fx, fy - 1.0);
    let n11 = grad(xi + 1, yi + 1, fx - 1.0, fy - 1.0);
    let a = n00 + u * (n10 - n00);
    let b = n01 + u * (n11 - n01);
    a + v * (b - a)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn seeded_and_deterministic() {
        let a = Procedural::new(7, 65, 33).generate().unwrap();
        let b = Procedural::new(7, 65, 33).generate().unwrap();
        let c = Procedural::new(8, 65, 33).generate().unwrap();
        assert_eq!(a.data(), b.data());
        assert_ne!(a.data(), c.data());
        let (lo, hi) = a.min_max();
        assert!(hi - lo > 10.0, "terrain has relief: {lo}..{hi}");
    }

    /// The row tables of `generate` give exactly `sample`'s heights, with
    /// wavelengths that put lattice lines on and between texels.
    #[test]
    fn generate_equals_sample_bit_for_bit() {
        for (wl, oct) in [(256.0, 8), (3.7, 5), (1.0, 3), (0.3, 2), (1000.0, 12)] {
            let p = Procedural {
                wavelength: wl,
                octaves: oct,
                ..Procedural::new(11, 67, 41)
            };
            let m = p.generate().unwrap();
            for y in 0..41 {
                for x in 0..67 {
                    let want = p.sample(x as f64, y as f64) as f32;
                    assert_eq!(m.get(x, y).to_bits(), want.to_bits(), "{wl} ({x}, {y})");
                }
            }
            for rect in [
                [0, 0, 67, 41],
                [13, 7, 14, 8],
                [30, 20, 67, 41],
                [1, 0, 5, 41],
            ] {
                let v = p.generate_rect(rect);
                let w = rect[2] - rect[0];
                for (i, got) in v.iter().enumerate() {
                    let (x, y) = (rect[0] + i % w, rect[1] + i / w);
                    assert_eq!(
                        got.to_bits(),
                        m.get(x, y).to_bits(),
                        "{wl} {rect:?} ({x}, {y})"
                    );
                }
            }
        }
    }
}
