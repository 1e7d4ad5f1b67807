//! Homogeneous clipping as Mesa's draw module does it (docs/reference/raster-rules.md
//! rule 6): with a depth attachment there is no guard band, so every
//! triangle that crosses the frustum is cut against the planes its vertices
//! fall outside of, in a fixed order, and the polygon is fanned from its
//! first vertex. Matching Mesa's choice of which end to interpolate from is
//! what keeps shared clipped edges bit-identical on both sides.

use super::setup::{Viewport, WinVertex};

/// Most varyings a vertex may carry.
pub const MAX_VARYINGS: usize = 16;

/// A vertex entering or made by the clipper.
#[derive(Clone, Copy, Debug)]
pub struct ClipVertex {
    pub clip: [f32; 4],
    /// Window position: valid for vertices inside all planes, and for every
    /// vertex the clipper emits.
    pub win: WinVertex,
    pub attrs: [f32; MAX_VARYINGS],
}

/// Outside bits, in Mesa's plane order: x > w, x + w < 0, y > w, y + w < 0,
/// z < 0, z > w.
#[inline]
pub fn outcode(c: [f32; 4]) -> u32 {
    let mut m = 0;
    for p in 0..6 {
        if distance(c, p) < 0.0 {
            m |= 1 << p;
        }
    }
    m
}

/// Signed distance to plane `p` (Mesa's dot product with the plane, whose
/// zero terms drop out exactly).
#[inline]
pub fn distance(c: [f32; 4], p: usize) -> f32 {
    match p {
        0 => -c[0] + c[3],
        1 => c[0] + c[3],
        2 => -c[1] + c[3],
        3 => c[1] + c[3],
        4 => c[2],
        _ => -c[2] + c[3],
    }
}

#[inline]
fn lerp(t: f32, out: f32, inn: f32) -> f32 {
    out + t * (inn - out)
}

/// The new vertex `out + t·(in − out)`; window coordinates without FMA and
/// screen-linear varyings with Mesa's screen-space t.
fn interp(
    t: f32,
    out: &ClipVertex,
    inn: &ClipVertex,
    n_attrs: usize,
    linear: &[bool],
    vp: &Viewport,
) -> ClipVertex {
    let clip = [0, 1, 2, 3].map(|k| lerp(t, out.clip[k], inn.clip[k]));
    let mut t_linear = t;
    for k in 0..2 {
        if inn.clip[k] != out.clip[k] {
            let ic = inn.clip[k] / inn.clip[3];
            let oc = out.clip[k] / out.clip[3];
            let dc = clip[k] / clip[3];
            t_linear = (dc - oc) / (ic - oc);
            break;
        }
    }
    let mut attrs = [0.0; MAX_VARYINGS];
    for j in 0..n_attrs {
        let tj = if linear[j] { t_linear } else { t };
        attrs[j] = lerp(tj, out.attrs[j], inn.attrs[j]);
    }
    ClipVertex {
        clip,
        win: vp.map_clipped(clip),
        attrs,
    }
}

/// Mesa's null-triangle test on window positions (zero 3-D cross product).
fn is_null(a: &WinVertex, b: &WinVertex, c: &WinVertex) -> bool {
    let (x1, y1, z1) = (b.x - a.x, b.y - a.y, b.z - a.z);
    let (x2, y2, z2) = (c.x - a.x, c.y - a.y, c.z - a.z);
    let vx = y1 * z2 - z1 * y2;
    let vy = x1 * z2 - z1 * x2;
    let vz = x1 * y2 - y1 * x2;
    vx * vx + vy * vy + vz * vz == 0.0
}

/// Clips one triangle whose vertices' outcodes OR to `mask` (non-zero, and
/// not all outside one plane) and appends the fan triangles to `out`.
/// Returns how many vertices it made with a non-finite clip or window
/// coordinate (their fan triangles are dropped; the stability tests require
/// the count to be 0).
pub fn clip_triangle(
    tri: [&ClipVertex; 3],
    mut mask: u32,
    n_attrs: usize,
    linear: &[bool],
    vp: &Viewport,
    out: &mut Vec<[ClipVertex; 3]>,
) -> usize {
    // At most 3 + 6 vertices survive six planes; Mesa's bound is 25.
    let mut poly: Vec<ClipVertex> = tri.iter().map(|v| **v).collect();
    let mut next: Vec<ClipVertex> = Vec::with_capacity(12);
    while mask != 0 && poly.len() >= 3 {
        let p = mask.trailing_zeros() as usize;
        mask &= !(1 << p);
        next.clear();
        let n = poly.len();
        let mut prev = poly[0];
        let mut dp_prev = distance(prev.clip, p);
        if !dp_prev.is_finite() {
            return poly.len();
        }
        for i in 1..=n {
            let vert = poly[i % n];
            let dp = distance(vert.clip, p);
            if !dp.is_finite() {
                return poly.len();
            }
            let different = if dp_prev >= 0.0 {
                next.push(prev);
                dp < 0.0
            } else {
                // NaN was rejected above, so this is Mesa's !(dp < 0).
                dp >= 0.0
            };
            if different {
                // Mesa 22.3 interpolates from the end nearer the plane, with
                // t measured from that end (its precision fix).
                let denom = dp - dp_prev;
                let v = if dp < 0.0 {
                    if -dp < dp_prev {
                        interp(dp / denom, &vert, &prev, n_attrs, linear, vp)
                    } else {
                        interp(-dp_prev / denom, &prev, &vert, n_attrs, linear, vp)
                    }
                } else if -dp_prev < dp {
                    interp(-dp_prev / denom, &prev, &vert, n_attrs, linear, vp)
                } else {
                    interp(dp / denom, &vert, &prev, n_attrs, linear, vp)
                };
                next.push(v);
            }
            prev = vert;
            dp_prev = dp;
        }
        std::mem::swap(&mut poly, &mut next);
    }
    if poly.len() < 3 {
        return 0;
    }
    let finite = |v: &ClipVertex| {
        v.clip.iter().all(|c| c.is_finite()) && v.win.x.is_finite() && v.win.y.is_finite()
    };
    let bad = poly.iter().filter(|v| !finite(v)).count();
    if bad > 0 {
        return bad;
    }
    // Fan from the first vertex, skipping null triangles the way Mesa's
    // emit_poly does.
    let (mut last_null, mut any_real) = (false, false);
    for i in 2..poly.len() {
        let t = [poly[0], poly[i - 1], poly[i]];
        let null = is_null(&t[0].win, &t[1].win, &t[2].win);
        if null && (any_real || last_null) {
            last_null = null;
            continue;
        }
        last_null = null;
        any_real |= !null;
        out.push(t);
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each plane's outside bit, alone, for a vertex just beyond it; a
    /// vertex exactly on a plane is inside (Mesa tests `< 0`).
    #[test]
    fn outcodes_name_the_planes_in_mesas_order() {
        let beyond = [
            [1.5, 0.0, 0.5, 1.0],
            [-1.5, 0.0, 0.5, 1.0],
            [0.0, 1.5, 0.5, 1.0],
            [0.0, -1.5, 0.5, 1.0],
            [0.0, 0.0, -0.5, 1.0],
            [0.0, 0.0, 1.5, 1.0],
        ];
        for (p, c) in beyond.iter().enumerate() {
            assert_eq!(outcode(*c), 1 << p, "plane {p}: {c:?}");
        }
        for on in [
            [1.0, 1.0, 1.0, 1.0],
            [-1.0, -1.0, 0.0, 1.0],
            [0.0, 0.0, 0.5, 1.0],
        ] {
            assert_eq!(outcode(on), 0, "{on:?} lies on or inside every plane");
        }
    }

    /// Mesa's null test is a zero 3-D cross product of the window
    /// positions: collinear points (off the origin, with every difference
    /// non-zero) are null, a real triangle is not, whichever component of
    /// its normal is the one that is non-zero.
    #[test]
    fn null_triangles_are_collinear_in_3d() {
        let v = |x: f32, y: f32, z: f32| WinVertex { x, y, z, oow: 1.0 };
        let (a, b, c) = (v(1.0, 1.0, 1.0), v(2.0, 3.0, 4.0), v(3.0, 5.0, 7.0));
        assert!(is_null(&a, &b, &c));
        assert!(is_null(&a, &a, &b));
        for d in [v(3.0, 5.0, 7.5), v(3.0, 5.5, 7.0), v(3.5, 5.0, 7.0)] {
            assert!(!is_null(&a, &b, &d), "{:?}", (d.x, d.y, d.z));
        }
    }

    fn cv(c: [f32; 4], vp: &Viewport) -> ClipVertex {
        ClipVertex {
            clip: c,
            win: vp.map(c),
            attrs: [0.0; MAX_VARYINGS],
        }
    }

    #[test]
    fn near_plane_cut_makes_a_quad() {
        let vp = Viewport::new(100, 100);
        let a = cv([0.0, 0.0, 0.5, 1.0], &vp);
        let b = cv([0.5, 0.0, 0.5, 1.0], &vp);
        let c = cv([0.0, 0.5, -0.5, 1.0], &vp);
        let mask = outcode(a.clip) | outcode(b.clip) | outcode(c.clip);
        assert_eq!(mask, 1 << 4);
        let mut out = vec![];
        clip_triangle([&a, &b, &c], mask, 0, &[], &vp, &mut out);
        assert_eq!(out.len(), 2);
        for t in &out {
            for v in t {
                assert!(v.clip[2] >= 0.0, "{:?}", v.clip);
            }
        }
    }

    #[test]
    fn shared_clipped_edge_gives_identical_vertices() {
        // Two triangles share the edge p–q, which crosses x = w; each walks
        // it in the opposite direction.
        let vp = Viewport::new(64, 48);
        let p = cv([0.3, 0.2, 0.4, 1.0], &vp);
        let q = cv([1.7, -0.3, 0.6, 1.1], &vp);
        let r = cv([0.1, -0.9, 0.5, 1.0], &vp);
        let s = cv([1.9, 0.8, 0.3, 1.2], &vp);
        let (mut o1, mut o2) = (vec![], vec![]);
        let m = |a: &ClipVertex, b: &ClipVertex, c: &ClipVertex| {
            outcode(a.clip) | outcode(b.clip) | outcode(c.clip)
        };
        clip_triangle([&p, &q, &r], m(&p, &q, &r), 0, &[], &vp, &mut o1);
        clip_triangle([&q, &p, &s], m(&q, &p, &s), 0, &[], &vp, &mut o2);
        let originals: Vec<[u32; 4]> = [&p, &q, &r, &s]
            .iter()
            .map(|v| v.clip.map(f32::to_bits))
            .collect();
        let made = |o: &Vec<[ClipVertex; 3]>| -> Vec<[u32; 4]> {
            o.iter()
                .flatten()
                .map(|v| v.clip.map(f32::to_bits))
                .filter(|b| !originals.contains(b))
                .collect()
        };
        let (a, b) = (made(&o1), made(&o2));
        assert!(a.iter().any(|v| b.contains(v)), "{a:?} vs {b:?}");
    }
}
