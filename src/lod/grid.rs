//! Helpers the grid-based schemes share: clamped base-map vertices, cells
//! split on the clipmap's diagonal, and a min/max tree for bounding boxes.
//!
//! Schemes whose blocks do not tile a map exactly (GeoMipMapping, ROAM,
//! CDLOD on a 403×344 DEM) lay their blocks over a larger virtual grid and
//! clamp vertex positions to the map. Clamping is the same function on both
//! sides of every shared edge, so a watertight mesh stays watertight: the
//! triangles beyond the edge only collapse onto it.

use super::{LodMesh, LodVertex, View};
use crate::camera::Frustum;
use crate::clipmap::cull::{classify, Class};
use crate::pyramid::PyramidLevel;
use crate::terrain::world::WorldMap;

/// The base-map vertex at (col, row), clamped onto the map.
#[inline]
pub fn vertex(base: &PyramidLevel, col: i64, row: i64) -> LodVertex {
    let c = col.clamp(0, base.width as i64 - 1);
    let r = row.clamp(0, base.height as i64 - 1);
    LodVertex::on_grid(c, r, base.data[r as usize * base.width + c as usize])
}

/// Bilinear height at a fractional base-grid point, texels addressed by
/// floor (the texel a point falls in is the one at its floor, so the
/// interpolation weights stay in [0, 1) for negative offsets too).
pub fn bilinear(level: &PyramidLevel, x: f64, y: f64) -> f32 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
    let (c, r) = (x0 as i64, y0 as i64);
    let z00 = level.get_clamped(c, r);
    let z10 = level.get_clamped(c + 1, r);
    let z01 = level.get_clamped(c, r + 1);
    let z11 = level.get_clamped(c + 1, r + 1);
    let top = z00 + (z10 - z00) * fx;
    let bottom = z01 + (z11 - z01) * fx;
    top + (bottom - top) * fy
}

/// Two triangles of the quad a(x0,y0) b(x1,y0) c(x1,y1) d(x0,y1), split on
/// the a–c diagonal like the clipmap and brute force.
#[inline]
pub fn push_quad(out: &mut LodMesh, a: LodVertex, b: LodVertex, c: LodVertex, d: LodVertex) {
    out.push([a, b, c]);
    out.push([a, c, d]);
}

/// Height bounds of aligned power-of-two blocks of cells: level k holds,
/// for block (i, j), the min and max over vertices
/// [i·2^k, (i+1)·2^k] × [j·2^k, (j+1)·2^k] clamped to the map.
pub struct MinMax {
    levels: Vec<Bounds>,
}

/// One level of [`MinMax`]: blocks across, down, and (min, max) per block.
type Bounds = (usize, usize, Vec<(f32, f32)>);

impl MinMax {
    pub fn new(base: &PyramidLevel) -> Self {
        let (w, h) = (base.width.max(2) - 1, base.height.max(2) - 1);
        let z = |c: usize, r: usize| {
            base.data[r.min(base.height - 1) * base.width + c.min(base.width - 1)]
        };
        let cells: Vec<(f32, f32)> = (0..w * h)
            .map(|i| {
                let (c, r) = (i % w, i / w);
                let q = [z(c, r), z(c + 1, r), z(c, r + 1), z(c + 1, r + 1)];
                let lo = q.iter().fold(f32::INFINITY, |a, &b| a.min(b));
                let hi = q.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
                (lo, hi)
            })
            .collect();
        let mut levels = vec![(w, h, cells)];
        while {
            let (w, h, _) = levels.last().expect("level 0");
            *w > 1 || *h > 1
        } {
            let (pw, ph, prev) = levels.last().expect("level");
            let (w, h) = (pw.div_ceil(2), ph.div_ceil(2));
            let mut next = vec![(f32::INFINITY, f32::NEG_INFINITY); w * h];
            for (i, n) in next.iter_mut().enumerate() {
                let (c, r) = (i % w, i / w);
                for (dc, dr) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (x, y) = (2 * c + dc, 2 * r + dr);
                    if x < *pw && y < *ph {
                        let (lo, hi) = prev[y * pw + x];
                        n.0 = n.0.min(lo);
                        n.1 = n.1.max(hi);
                    }
                }
            }
            levels.push((w, h, next));
        }
        MinMax { levels }
    }

    /// Bounds of block (i, j) at level k; blocks beyond the map take the
    /// bounds of the nearest block (their vertices clamp onto it).
    pub fn get(&self, k: usize, i: i64, j: i64) -> (f32, f32) {
        let (w, h, d) = &self.levels[k.min(self.levels.len() - 1)];
        let c = i.clamp(0, *w as i64 - 1) as usize;
        let r = j.clamp(0, *h as i64 - 1) as usize;
        d[r * w + c]
    }

    /// Bounds over cell rectangle [c0, c1) × [r0, r1) (any alignment).
    pub fn range(&self, c0: i64, r0: i64, c1: i64, r1: i64) -> (f32, f32) {
        let mut k = 0;
        while k + 1 < self.levels.len() && (1i64 << (k + 1)) <= (c1 - c0).min(r1 - r0).max(1) {
            k += 1;
        }
        let s = 1i64 << k;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for j in r0.div_euclid(s)..=(r1 - 1).div_euclid(s) {
            for i in c0.div_euclid(s)..=(c1 - 1).div_euclid(s) {
                let (a, b) = self.get(k, i, j);
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        (lo, hi)
    }
}

/// Whether the cell rectangle [c0, c1] × [r0, r1] over heights [lo, hi]
/// can be seen (clamped to the map first).
pub fn visible(
    base: &PyramidLevel,
    frustum: &Frustum,
    world: &WorldMap,
    rect: [i64; 4],
    (lo, hi): (f32, f32),
) -> bool {
    let (mw, mh) = (base.width as i64 - 1, base.height as i64 - 1);
    let [c0, r0, c1, r1] = [
        rect[0].clamp(0, mw),
        rect[1].clamp(0, mh),
        rect[2].clamp(0, mw),
        rect[3].clamp(0, mh),
    ];
    let (a, b) = world.aabb(
        c0 as f64, r0 as f64, c1 as f64, r1 as f64, lo as f64, hi as f64,
    );
    classify(frustum, a, b) != Class::Outside
}

/// Bounding-disc radius of a bintree triangle as a multiple of half its
/// hypotenuse, centred on the hypotenuse's midpoint: at least 1/(√2 − 1)
/// makes each child's disc lie inside its parent's, so the distance below
/// never shrinks down the tree.
pub const NEST: f64 = 2.5;

/// The screen-space error in pixels of a right-isosceles bintree triangle
/// `v` (apex, left, right; base-grid corners) whose nested height error is
/// `e` (height units) and whose heights lie in `bounds`: `e` projected at
/// the distance from the eye to the triangle's bounding disc and height
/// range, 0 outside the frustum. A child's disc, heights and box lie
/// inside its parent's, so with a nested `e` the value never grows down
/// the tree: what lets ROAM and the CBT merge what they split.
pub fn screen_error(
    base: &PyramidLevel,
    view: &View,
    e: f64,
    v: [[i64; 2]; 3],
    bounds: (f32, f32),
) -> f64 {
    if e <= 0.0 {
        return 0.0;
    }
    let w = view.world;
    let [_, l, r] = v;
    let m = [(l[0] + r[0]) as f64 * 0.5, (l[1] + r[1]) as f64 * 0.5];
    let half = (((l[0] - r[0]).pow(2) + (l[1] - r[1]).pow(2)) as f64).sqrt() * 0.5;
    let radius = NEST * half * w.cell[0].max(w.cell[1]);
    let eye = view.camera.eye;
    let c = w.to_world(m[0], m[1], 0.0);
    let dh = ((eye.x - c.x).hypot(eye.y - c.y) - radius).max(0.0);
    let (zl, zh) = (
        bounds.0 as f64 * w.vertical_scale,
        bounds.1 as f64 * w.vertical_scale,
    );
    let dz = (zl - eye.z).max(eye.z - zh).max(0.0);
    let d = dh.hypot(dz).max(1e-3);
    if !visible(base, view.frustum, w, bounding_box(v), bounds) {
        return 0.0;
    }
    e * w.vertical_scale * view.pixel_scale() / d
}

/// The box [x0, y0, x1, y1] of a triangle's corners.
pub fn bounding_box(v: [[i64; 2]; 3]) -> [i64; 4] {
    let xs = v.map(|p| p[0]);
    let ys = v.map(|p| p[1]);
    [
        xs.into_iter().min().unwrap_or(0),
        ys.into_iter().min().unwrap_or(0),
        xs.into_iter().max().unwrap_or(0),
        ys.into_iter().max().unwrap_or(0),
    ]
}
