//! GeoMipMapping (de Boer 2000; the ATLOD renderer): the map is cut into
//! blocks of 2^k + 1 vertices, and each block is drawn at one mip level (a
//! vertex every 2^L texels) picked by distance, linearly or exponentially
//! as ATLOD does, or by de Boer's screen-space error: level L is allowed
//! while its largest height error δ_L, seen from the block's distance d,
//! covers at most τ pixels (δ_L · k / d ≤ τ).
//!
//! Neighbouring blocks differ by at most one level. A block next to a
//! coarser one omits the odd vertices of that side: each 2×2 group of
//! cells that touches such a side is drawn as a fan around its centre that
//! skips them, which covers all 16 side permutations. Interior groups use
//! the clipmap's cell diagonal, so level 0 is exactly the brute-force mesh.
//!
//! With morph on, the odd vertices of a block blend toward the next level's
//! surface by the fraction of the block's continuous level (de Boer's
//! "trilinear" variant). On a shared side both blocks use the smaller
//! fraction, next to a finer block 0 (the finer one keeps those vertices),
//! so morphing opens no cracks.

use super::grid::{self, MinMax};
use super::{Lod, LodMesh, LodUpdate, LodVertex, View};
use crate::lod::LodScheme;
use crate::pyramid::{Pyramid, PyramidLevel};
use rayon::prelude::*;
use std::sync::Arc;

/// How a block's level is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mode {
    /// Level = d / distance.
    Linear {
        /// Metres per level step.
        distance: f64,
    },
    /// Level 1 from `distance`, each further level at twice the distance.
    Exponential {
        /// Metres to the first step.
        distance: f64,
    },
    /// The coarsest level whose error covers at most τ pixels.
    Error {
        /// Pixels of screen-space error allowed.
        tau: f64,
    },
}

/// GeoMipMapping's settings (de Boer 2000; ATLOD's renderer).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// Block side in cells (2^k; the block has 2^k + 1 vertices).
    pub cells: usize,
    /// How each block's level is chosen.
    pub mode: Mode,
    /// Whether a block's vertices morph towards the next level (no popping).
    pub morph: bool,
}

/// GeoMipMapping: square blocks, each at one pyramid level chosen per frame, with
/// neighbours' edges stitched so levels that differ by one leave no crack.
pub struct GeoMipMap {
    pyramid: Arc<Pyramid>,
    cfg: Config,
    /// Blocks across and down.
    blocks: [usize; 2],
    max_level: usize,
    bounds: MinMax,
    /// δ_L per block and level (running maximum, so coarser is never
    /// "better"), in height units.
    errors: Vec<Vec<f32>>,
    /// Current level and morph fraction per block.
    levels: Vec<u8>,
    fraction: Vec<f32>,
}

impl GeoMipMap {
    /// The scheme over `pyramid` with `cfg`'s blocks and level rule.
    pub fn new(pyramid: Arc<Pyramid>, cfg: Config) -> Self {
        let base = &pyramid.levels[0];
        let s = cfg.cells;
        let blocks = [
            (base.width - 1).max(1).div_ceil(s),
            (base.height - 1).max(1).div_ceil(s),
        ];
        let max_level = s.trailing_zeros() as usize;
        let errors = (0..blocks[0] * blocks[1])
            .into_par_iter()
            .map(|b| {
                let (c0, r0) = ((b % blocks[0] * s) as i64, (b / blocks[0] * s) as i64);
                let mut worst = 0.0f32;
                (0..=max_level)
                    .map(|l| {
                        worst = worst.max(level_error(base, c0, r0, s as i64, 1 << l));
                        worst
                    })
                    .collect()
            })
            .collect();
        let n = blocks[0] * blocks[1];
        GeoMipMap {
            bounds: MinMax::new(base),
            pyramid,
            cfg,
            blocks,
            max_level,
            errors,
            levels: vec![0; n],
            fraction: vec![0.0; n],
        }
    }

    /// The current level of every block (row-major), for tests.
    pub fn block_levels(&self) -> &[u8] {
        &self.levels
    }

    fn rect(&self, b: usize) -> [i64; 4] {
        let s = self.cfg.cells as i64;
        let (c0, r0) = (
            (b % self.blocks[0]) as i64 * s,
            (b / self.blocks[0]) as i64 * s,
        );
        [c0, r0, c0 + s, r0 + s]
    }

    fn block_bounds(&self, b: usize) -> (f32, f32) {
        let k = self.cfg.cells.trailing_zeros() as usize;
        self.bounds
            .get(k, (b % self.blocks[0]) as i64, (b / self.blocks[0]) as i64)
    }

    /// Continuous level of block `b` seen from the view.
    fn lambda(&self, b: usize, view: &View) -> f64 {
        let [c0, r0, c1, r1] = self.rect(b);
        let (lo, hi) = self.block_bounds(b);
        let (a, z) = view.world.aabb(
            c0 as f64, r0 as f64, c1 as f64, r1 as f64, lo as f64, hi as f64,
        );
        let e = view.camera.eye;
        let d = (e.clamp(a, z) - e).length().max(1e-6);
        let top = self.max_level as f64;
        let l = match self.cfg.mode {
            Mode::Linear { distance } => d / distance,
            Mode::Exponential { distance } => {
                if d < distance {
                    d / distance
                } else {
                    (d / distance).log2() + 1.0
                }
            }
            Mode::Error { tau } => {
                // Distance from which level L is allowed: δ_L · k / τ.
                let k = view.pixel_scale() * view.world.vertical_scale / tau;
                let reach = |l: usize| self.errors[b][l] as f64 * k;
                let mut l = 0;
                while l < self.max_level && reach(l + 1) <= d {
                    l += 1;
                }
                if l == self.max_level {
                    top
                } else {
                    let (d0, d1) = (reach(l), reach(l + 1));
                    l as f64 + ((d - d0) / (d1 - d0)).clamp(0.0, 1.0).min(0.999_999)
                }
            }
        };
        l.clamp(0.0, top)
    }

    fn neighbour(&self, b: usize, side: usize) -> Option<usize> {
        let (i, j) = ((b % self.blocks[0]) as i64, (b / self.blocks[0]) as i64);
        let (i, j) = match side {
            0 => (i, j - 1),
            1 => (i + 1, j),
            2 => (i, j + 1),
            _ => (i - 1, j),
        };
        let inside = i >= 0 && j >= 0 && i < self.blocks[0] as i64 && j < self.blocks[1] as i64;
        inside.then(|| j as usize * self.blocks[0] + i as usize)
    }

    /// Morph fraction of the odd vertices on `side` of block `b` (None when
    /// the side is stitched to a coarser block and those vertices are gone).
    fn side_fraction(&self, b: usize, side: usize) -> Option<f32> {
        let (l, t) = (self.levels[b], self.fraction[b]);
        match self.neighbour(b, side) {
            None => Some(t),
            Some(n) if self.levels[n] > l => None,
            Some(n) if self.levels[n] == l => Some(t.min(self.fraction[n])),
            Some(_) => Some(0.0),
        }
    }

    fn emit(&self, b: usize, out: &mut LodMesh) {
        let base = &self.pyramid.levels[0];
        let [c0, r0, ..] = self.rect(b);
        let g = 1i64 << self.levels[b];
        let m = self.cfg.cells as i64 / g;
        let sides = [0, 1, 2, 3].map(|s| self.side_fraction(b, s));
        let t = if self.cfg.morph {
            self.fraction[b]
        } else {
            0.0
        };
        // Vertex (i, j) of the block's level grid, morphed when odd.
        let v = |i: i64, j: i64| -> LodVertex {
            let at = |i: i64, j: i64| grid::vertex(base, c0 + i * g, r0 + j * g);
            let mut v = at(i, j);
            let (oi, oj) = (i % 2 == 1, j % 2 == 1);
            if !self.cfg.morph || !(oi || oj) {
                return v;
            }
            let side = if j == 0 {
                Some(0)
            } else if i == m {
                Some(1)
            } else if j == m {
                Some(2)
            } else if i == 0 {
                Some(3)
            } else {
                None
            };
            v.alpha = match side {
                Some(s) => sides[s].unwrap_or(1.0),
                None => t,
            };
            let (a, c) = match (oi, oj) {
                (true, false) => (at(i - 1, j), at(i + 1, j)),
                (false, true) => (at(i, j - 1), at(i, j + 1)),
                _ => (at(i - 1, j - 1), at(i + 1, j + 1)),
            };
            v.zc = 0.5 * (a.z + c.z);
            v
        };
        if m == 1 {
            grid::push_quad(out, v(0, 0), v(1, 0), v(1, 1), v(0, 1));
            return;
        }
        for gj in (0..m).step_by(2) {
            for gi in (0..m).step_by(2) {
                // Sides of the block this 2×2 group touches that are stitched.
                let touches = [gj == 0, gi + 2 == m, gj + 2 == m, gi == 0];
                let stitched = |s: usize| touches[s] && sides[s].is_none();
                if !(0..4).any(stitched) {
                    for (i, j) in [(gi, gj), (gi + 1, gj), (gi, gj + 1), (gi + 1, gj + 1)] {
                        grid::push_quad(out, v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
                    }
                    continue;
                }
                // Fan around the centre over the ring of 8, skipping the
                // odd vertices of stitched sides.
                let ring = [
                    (0, 0, None),
                    (1, 0, Some(0)),
                    (2, 0, None),
                    (2, 1, Some(1)),
                    (2, 2, None),
                    (1, 2, Some(2)),
                    (0, 2, None),
                    (0, 1, Some(3)),
                ];
                let kept: Vec<LodVertex> = ring
                    .iter()
                    .filter(|(_, _, s)| !s.is_some_and(stitched))
                    .map(|&(i, j, _)| v(gi + i, gj + j))
                    .collect();
                let centre = v(gi + 1, gj + 1);
                for k in 0..kept.len() {
                    out.push([centre, kept[k], kept[(k + 1) % kept.len()]]);
                }
            }
        }
    }
}

/// Largest |z − z_L| over block vertices, where z_L is the surface of the
/// level with vertex spacing `g` (cells split on the a–c diagonal).
fn level_error(base: &PyramidLevel, c0: i64, r0: i64, s: i64, g: i64) -> f32 {
    if g == 1 {
        return 0.0;
    }
    let z = |c: i64, r: i64| base.get_clamped(c, r);
    let mut worst = 0.0f32;
    for y in 0..=s {
        for x in 0..=s {
            let (cx, cy) = ((x / g).min(s / g - 1), (y / g).min(s / g - 1));
            let (fx, fy) = (
                (x - cx * g) as f32 / g as f32,
                (y - cy * g) as f32 / g as f32,
            );
            let (x0, y0) = (c0 + cx * g, r0 + cy * g);
            let (a, b, c, d) = (z(x0, y0), z(x0 + g, y0), z(x0 + g, y0 + g), z(x0, y0 + g));
            let zl = if fx >= fy {
                a + (b - a) * fx + (c - b) * fy
            } else {
                a + (d - a) * fy + (c - d) * fx
            };
            worst = worst.max((z(c0 + x, r0 + y) - zl).abs());
        }
    }
    worst
}

impl Lod for GeoMipMap {
    fn scheme(&self) -> LodScheme {
        LodScheme::Geomipmap
    }
    fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    fn update(&mut self, view: &View) -> LodUpdate {
        let n = self.levels.len();
        let lambdas: Vec<f64> = (0..n).map(|b| self.lambda(b, view)).collect();
        let mut levels: Vec<u8> = lambdas.iter().map(|l| l.floor() as u8).collect();
        let mut fraction: Vec<f32> = lambdas
            .iter()
            .zip(&levels)
            .map(|(l, &f)| (l - f as f64) as f32)
            .collect();
        // Neighbours differ by at most one level: lower blocks until no
        // block is more than one above a neighbour. A lowered block shows
        // the next level fully morphed, the shape it wanted.
        let mut changed = true;
        while changed {
            changed = false;
            for b in 0..n {
                for side in 0..4 {
                    if let Some(nb) = self.neighbour(b, side) {
                        if levels[b] > levels[nb] + 1 {
                            levels[b] = levels[nb] + 1;
                            fraction[b] = 1.0;
                            changed = true;
                        }
                    }
                }
            }
        }
        let changes = levels
            .iter()
            .zip(&self.levels)
            .filter(|(a, b)| a != b)
            .count();
        self.levels = levels;
        self.fraction = fraction;
        LodUpdate {
            texels_updated: 0,
            changes: changes as u64,
        }
    }

    fn mesh(&mut self, view: &View) -> LodMesh {
        let base = &self.pyramid.levels[0];
        let visible: Vec<usize> = (0..self.levels.len())
            .filter(|&b| {
                grid::visible(
                    base,
                    view.frustum,
                    view.world,
                    self.rect(b),
                    self.block_bounds(b),
                )
            })
            .collect();
        let mut out = LodMesh::base_level(base.width, base.height);
        out.append_parallel(&visible, |&b, m| self.emit(b, m));
        out
    }
}
