//! Queries on the surface as rendered: `height_at` and `ray_hit` answer from
//! the very triangles a frame rasterised (its LOD, its morph, the diagonal
//! each cell was split along, and the f32 positions the vertex stage made),
//! so a collision or picking query agrees with the image. A bilinear lookup
//! in the heightmap does not: it bends where the mesh is flat
//! (`tests/stability.rs` measures by how much).
//!
//! Triangles are bucketed on a uniform xy grid; `ray_hit` walks that grid
//! along the ray (Amanatides & Woo) and stops at the first bucket whose
//! nearest hit lies inside it.

use crate::frame::Frame;
use crate::terrain::world::WorldMap;
use glam::DVec3;

/// A ray's first hit on the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter: hit = origin + t·dir.
    pub t: f64,
    /// World position of the hit.
    pub point: DVec3,
}

/// The rendered triangles of one frame, indexed for point and ray queries.
#[derive(Clone, Debug)]
pub struct Surface {
    /// World position that the triangle coordinates are relative to.
    origin: DVec3,
    tris: Vec<[DVec3; 3]>,
    /// Bucket grid: lower corner (relative), bucket side, counts per axis.
    lo: [f64; 2],
    side: f64,
    dims: [usize; 2],
    /// Bucket b holds `ids[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    ids: Vec<u32>,
}

impl Surface {
    /// Indexes `frame`'s triangles; `world` places its floating origin.
    /// Points the frame did not draw (outside the view, culled) have no
    /// height.
    pub fn new(frame: &Frame, world: &WorldMap) -> Surface {
        let o = frame.uniforms.origin;
        let origin = world.to_world(o[0] as f64, o[1] as f64, 0.0);
        let p = |i: usize| DVec3::from_array(frame.positions[i].map(|v| v as f64));
        let tris: Vec<[DVec3; 3]> = (0..frame.triangle_count())
            .map(|t| [p(3 * t), p(3 * t + 1), p(3 * t + 2)])
            .filter(|t| t.iter().all(|v| v.is_finite()))
            .collect();
        Surface::from_triangles(origin, tris)
    }

    /// Indexes triangles given relative to `origin`.
    pub fn from_triangles(origin: DVec3, tris: Vec<[DVec3; 3]>) -> Surface {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for v in tris.iter().flatten() {
            lo = [lo[0].min(v.x), lo[1].min(v.y)];
            hi = [hi[0].max(v.x), hi[1].max(v.y)];
        }
        if tris.is_empty() {
            lo = [0.0; 2];
            hi = [0.0; 2];
        }
        // About two triangles per bucket, at most 2048 buckets a side.
        let (w, h) = ((hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9));
        let side = (w * h / (tris.len().max(1) as f64 / 2.0))
            .sqrt()
            .max(w.max(h) / 2048.0);
        let dims = [
            ((w / side).ceil() as usize).clamp(1, 2048),
            ((h / side).ceil() as usize).clamp(1, 2048),
        ];
        let mut s = Surface {
            origin,
            tris,
            lo,
            side,
            dims,
            starts: vec![],
            ids: vec![],
        };
        let mut counts = vec![0u32; dims[0] * dims[1] + 1];
        let spans: Vec<[usize; 4]> = s.tris.iter().map(|t| s.span(t)).collect();
        for &[x0, y0, x1, y1] in &spans {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    counts[y * dims[0] + x + 1] += 1;
                }
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let mut fill = counts.clone();
        let mut ids = vec![0u32; *counts.last().expect("non-empty") as usize];
        for (t, &[x0, y0, x1, y1]) in spans.iter().enumerate() {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let b = y * dims[0] + x;
                    ids[fill[b] as usize] = t as u32;
                    fill[b] += 1;
                }
            }
        }
        s.starts = counts;
        s.ids = ids;
        s
    }

    /// Number of indexed triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    fn bucket_of(&self, x: f64, y: f64) -> [usize; 2] {
        let c = |v: f64, lo: f64, n: usize| {
            (((v - lo) / self.side).floor().max(0.0) as usize).min(n - 1)
        };
        [
            c(x, self.lo[0], self.dims[0]),
            c(y, self.lo[1], self.dims[1]),
        ]
    }

    fn span(&self, t: &[DVec3; 3]) -> [usize; 4] {
        let (x0, x1) = (
            t[0].x.min(t[1].x).min(t[2].x),
            t[0].x.max(t[1].x).max(t[2].x),
        );
        let (y0, y1) = (
            t[0].y.min(t[1].y).min(t[2].y),
            t[0].y.max(t[1].y).max(t[2].y),
        );
        let a = self.bucket_of(x0, y0);
        let b = self.bucket_of(x1, y1);
        [a[0], a[1], b[0], b[1]]
    }

    fn bucket(&self, b: [usize; 2]) -> &[u32] {
        let i = b[1] * self.dims[0] + b[0];
        &self.ids[self.starts[i] as usize..self.starts[i + 1] as usize]
    }

    /// Height of the rendered surface at world (x, y), or None where the
    /// frame drew nothing. On a shared edge either triangle answers (they
    /// agree); where triangles overlap (the annulus) the highest does.
    pub fn height_at(&self, x: f64, y: f64) -> Option<f64> {
        let (px, py) = (x - self.origin.x, y - self.origin.y);
        let mut best: Option<f64> = None;
        for &id in self.bucket(self.bucket_of(px, py)) {
            let [a, b, c] = self.tris[id as usize];
            let d = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
            if d == 0.0 {
                continue;
            }
            // Barycentric weights, inclusive of edges up to rounding.
            let wb = ((px - a.x) * (c.y - a.y) - (py - a.y) * (c.x - a.x)) / d;
            let wc = ((b.x - a.x) * (py - a.y) - (b.y - a.y) * (px - a.x)) / d;
            let wa = 1.0 - wb - wc;
            let eps = -1e-9;
            if wa >= eps && wb >= eps && wc >= eps {
                let z = wa * a.z + wb * b.z + wc * c.z;
                best = Some(best.map_or(z, |h| h.max(z)));
            }
        }
        best.map(|z| z + self.origin.z)
    }

    /// The first hit of the ray origin + t·dir (t > 0) on the rendered
    /// surface, or None.
    pub fn ray_hit(&self, origin: DVec3, dir: DVec3) -> Option<Hit> {
        if self.tris.is_empty() || !origin.is_finite() || !dir.is_finite() || dir == DVec3::ZERO {
            return None;
        }
        let o = origin - self.origin;
        // The part of the ray over the grid's xy box.
        let hi = [
            self.lo[0] + self.side * self.dims[0] as f64,
            self.lo[1] + self.side * self.dims[1] as f64,
        ];
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for (k, (&l, &h)) in self.lo.iter().zip(&hi).enumerate() {
            let (ok, dk) = (o[k], dir[k]);
            if dk == 0.0 {
                if ok < l || ok > h {
                    return None;
                }
            } else {
                let (a, b) = ((l - ok) / dk, (h - ok) / dk);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        if t0 > t1 {
            return None;
        }
        let start = o + dir * t0;
        let mut cell = self.bucket_of(start.x, start.y);
        let step = [0, 1].map(|k| if dir[k] > 0.0 { 1i64 } else { -1 });
        let next_t = |cell: [usize; 2], k: usize| -> f64 {
            if dir[k] == 0.0 {
                return f64::INFINITY;
            }
            let edge =
                self.lo[k] + self.side * (cell[k] as f64 + if dir[k] > 0.0 { 1.0 } else { 0.0 });
            (edge - o[k]) / dir[k]
        };
        let mut best: Option<f64> = None;
        loop {
            for &id in self.bucket(cell) {
                if let Some(t) = intersect(o, dir, &self.tris[id as usize]) {
                    if t > 0.0 && best.is_none_or(|b| t < b) {
                        best = Some(t);
                    }
                }
            }
            let (tx, ty) = (next_t(cell, 0), next_t(cell, 1));
            let exit = tx.min(ty);
            if best.is_some_and(|b| b <= exit) || exit > t1 {
                break;
            }
            let k = if tx < ty { 0 } else { 1 };
            let n = cell[k] as i64 + step[k];
            if n < 0 || n >= self.dims[k] as i64 {
                break;
            }
            cell[k] = n as usize;
        }
        best.map(|t| Hit {
            t,
            point: origin + dir * t,
        })
    }
}

/// Möller–Trumbore in f64; both faces count (a ray from below hits too).
fn intersect(o: DVec3, d: DVec3, t: &[DVec3; 3]) -> Option<f64> {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - t[0];
    let u = s.dot(p) * inv;
    let eps = 1e-12;
    if !(-eps..=1.0 + eps).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < -eps || u + v > 1.0 + eps {
        return None;
    }
    Some(e2.dot(q) * inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles over the unit square split along (0,0)–(1,1), with
    /// heights 0 at (0,0), 1 at (1,0), 0 at (1,1) and 0 at (0,1): not planar,
    /// so the diagonal decides the height at the centre.
    fn square(origin: DVec3) -> Surface {
        let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        Surface::from_triangles(
            origin,
            vec![
                [v(0.0, 0.0, 0.0), v(1.0, 0.0, 1.0), v(1.0, 1.0, 0.0)],
                [v(0.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(0.0, 1.0, 0.0)],
            ],
        )
    }

    #[test]
    fn height_follows_the_drawn_diagonal() {
        let s = square(DVec3::new(100.0, 200.0, 5.0));
        // On the diagonal both triangles give 0 (+ origin z); bilinear
        // would give 0.25.
        assert_eq!(s.height_at(100.5, 200.5), Some(5.0));
        assert_eq!(s.height_at(100.75, 200.25), Some(5.5));
        assert_eq!(s.height_at(100.25, 200.75), Some(5.0));
        assert_eq!(s.height_at(99.0, 200.5), None);
    }

    #[test]
    fn rays_hit_the_nearest_triangle() {
        let s = square(DVec3::ZERO);
        let h = s
            .ray_hit(DVec3::new(0.75, 0.25, 10.0), DVec3::new(0.0, 0.0, -1.0))
            .unwrap();
        assert!((h.t - 9.5).abs() < 1e-12, "{h:?}");
        // A slanted ray from outside the grid's box passes over the flat
        // half and meets z = x − y at x = 2/3.
        let h = s
            .ray_hit(DVec3::new(-1.0, 0.5, 1.0), DVec3::new(1.0, 0.0, -0.5))
            .unwrap();
        let want = DVec3::new(2.0 / 3.0, 0.5, 1.0 / 6.0);
        assert!((h.point - want).length() < 1e-12, "{h:?}");
        assert!(s
            .ray_hit(DVec3::new(0.5, 0.5, 1.0), DVec3::new(0.0, 0.0, 1.0))
            .is_none());
        assert!(s
            .ray_hit(DVec3::new(5.0, 5.0, 1.0), DVec3::new(1.0, 0.0, 0.0))
            .is_none());
    }
}
