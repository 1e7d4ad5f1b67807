//! Where a view-dependent clipmap places its levels (`lod.centre = "view"`).
//!
//! A clipmap gives a point the level its distance from the centre calls
//! for, while the spacing a view needs at a point grows with the point's
//! distance from the eye times the tangent of half the field of view. The
//! 1° views ATLOD measured see terrain 700 texels away, which a clipmap
//! centred on the eye draws from a level whose texels cover tens of pixels
//! there. So each level is placed over the terrain that needs it instead.
//!
//! Rays through a grid of window positions find the terrain points the
//! view sees first. A point at distance d from the eye needs spacing at
//! most τ·d / (k·cell) base texels for its texels to cover at most τ
//! pixels (k = [`View::pixel_scale`]), so level `floor(log2)` of that or a
//! finer one. Level l's window should therefore hold every point that
//! needs level l or finer: it is centred on the middle of their bounding
//! box. A level no point needs has no want and stays on the eye's chain.
//! [`crate::clipmap::Clipmap::update_placed`] then places each level as
//! near its want as nesting allows.
//!
//! Rays march over the pyramid's range tiles and test heights texel by
//! texel only in tiles whose bound the ray dips under. A level not yet
//! decoded (a pack) reads as its range bound says, so the placement is
//! always made, from what is there, and the same for any thread count.

use super::View;
use crate::pyramid::Pyramid;
use glam::DVec3;
use rayon::prelude::*;

/// Window positions sampled across and down the image.
const RAYS: [usize; 2] = [17, 11];

/// Horizontal step, in texels, of the coarse march over range tiles (half
/// the pyramid's range tile, so that a step touches at most two across);
/// a step whose bound the ray dips under is tested texel by texel.
const COARSE: f64 = 16.0;

/// Per level (finest first, `levels` of them), the base-grid point a
/// view-dependent clipmap centres it on for `view` over `pyramid`, whose
/// texels should cover at most `tau` pixels; `None` for a level no
/// terrain the view sees needs (see the module).
pub fn wants(view: &View, pyramid: &Pyramid, levels: usize, tau: f64) -> Vec<Option<[f64; 2]>> {
    let eye = view.camera.eye;
    let size = view.viewport;
    let rays: Vec<(f64, f64)> = (0..RAYS[1])
        .flat_map(|j| (0..RAYS[0]).map(move |i| (i, j)))
        .map(|(i, j)| {
            let at = |k: usize, n: usize, px: u32| {
                (k as f64 / (n - 1) as f64 * px as f64).clamp(0.5, px as f64 - 0.5)
            };
            (at(i, RAYS[0], size[0]), at(j, RAYS[1], size[1]))
        })
        .collect();
    let hits: Vec<([f64; 2], f64)> = rays
        .par_iter()
        .filter_map(|&(wx, wy)| {
            let d = view.camera.ray_through(size, wx, wy);
            first_hit(view, pyramid, eye, d)
        })
        .collect();
    let per_texel = tau / (view.pixel_scale() * view.world.cell[0].max(view.world.cell[1]));
    place(&hits, per_texel, levels)
}

/// Level l's want: the middle of the bounding box of the hits that need
/// level l or finer, a hit at eye distance d needing spacing at most
/// `per_texel`·d base texels.
fn place(hits: &[([f64; 2], f64)], per_texel: f64, levels: usize) -> Vec<Option<[f64; 2]>> {
    // Per level, the bounding box (x0, y0, x1, y1) of the hits it must hold.
    let mut boxes: Vec<Option<[f64; 4]>> = vec![None; levels];
    for &(q, d) in hits {
        let spacing = per_texel * d;
        // The coarsest level whose spacing 2^l is at most the need (0 for
        // a need under one texel, or NaN).
        let l = if spacing >= 2.0 {
            (spacing.log2().floor() as usize).min(levels.saturating_sub(1))
        } else {
            0
        };
        for b in &mut boxes[l..] {
            let [x0, y0, x1, y1] = b.get_or_insert([q[0], q[1], q[0], q[1]]);
            (*x0, *y0, *x1, *y1) = (x0.min(q[0]), y0.min(q[1]), x1.max(q[0]), y1.max(q[1]));
        }
    }
    boxes
        .into_iter()
        .map(|b| b.map(|[x0, y0, x1, y1]| [0.5 * (x0 + x1), 0.5 * (y0 + y1)]))
        .collect()
}

/// Where the ray from `eye` along unit `d` first meets the terrain of
/// level 0, as a base-grid point and its distance from the eye; `None`
/// if it leaves the map (or the far plane) first.
fn first_hit(view: &View, pyramid: &Pyramid, eye: DVec3, d: DVec3) -> Option<([f64; 2], f64)> {
    let w = view.world;
    let base = &pyramid.levels[0];
    let (gw, gh) = (base.width as f64 - 1.0, base.height as f64 - 1.0);
    let g0 = w.to_grid(eye);
    // Grid units and world height per unit of ray length.
    let dg = [d.x / w.cell[0], -d.y / w.cell[1]];
    let vs = w.vertical_scale;
    // The part of the ray over the map: a slab test per axis.
    let (mut t0, mut t1) = (view.camera.near, view.camera.far);
    for (o, v, hi) in [(g0[0], dg[0], gw), (g0[1], dg[1], gh)] {
        if v.abs() < 1e-12 {
            if o < 0.0 || o > hi {
                return None;
            }
        } else {
            let (a, b) = ((0.0 - o) / v, (hi - o) / v);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    if t0.is_nan() || t1.is_nan() || t0 > t1 {
        return None;
    }
    let at = |t: f64| [g0[0] + dg[0] * t, g0[1] + dg[1] * t];
    let z = |t: f64| eye.z + d.z * t;
    let across = dg[0].abs().max(dg[1].abs());
    // Steps are counted, not summed, so that a step too small to move t
    // still ends. A ray that barely moves across the grid is tested in 64.
    let texels = across * (t1 - t0);
    let coarse_steps = if texels < 1.0 {
        1
    } else {
        (texels / COARSE).ceil() as usize
    };
    for i in 0..coarse_steps {
        let f = |k: f64| t0 + (t1 - t0) * (k / coarse_steps as f64);
        let (t, te) = (f(i as f64), f(i as f64 + 1.0));
        let (a, b) = (at(t), at(te));
        let rect = [
            a[0].min(b[0]).floor() as i64 - 1,
            a[1].min(b[1]).floor() as i64 - 1,
            a[0].max(b[0]).ceil() as i64 + 1,
            a[1].max(b[1]).ceil() as i64 + 1,
        ];
        let (_, hi) = pyramid.range_in(0, rect);
        if z(t).min(z(te)) <= hi as f64 * vs {
            let fine_steps = if texels < 1.0 {
                64
            } else {
                ((across * (te - t)).ceil() as usize).clamp(1, 64)
            };
            for k in 0..=fine_steps {
                let s = t + (te - t) * (k as f64 / fine_steps as f64);
                let g = at(s);
                if z(s) <= super::grid::bilinear(base, g[0], g[1]) as f64 * vs {
                    return Some((g, s));
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_level_holds_the_hits_that_need_it_or_a_finer_one() {
        // Needs 0.5, 3 and 40 texels: levels 0, 1 and 5.
        let hits = [
            ([10.0, 0.0], 0.5),
            ([30.0, 20.0], 3.0),
            ([500.0, 100.0], 40.0),
        ];
        let w = place(&hits, 1.0, 7);
        assert_eq!(w[0], Some([10.0, 0.0]));
        assert_eq!(w[1], Some([20.0, 10.0]));
        assert_eq!(w[4], Some([20.0, 10.0]));
        assert_eq!(w[5], Some([255.0, 50.0]));
        assert_eq!(w[6], Some([255.0, 50.0]));
        // A need past the coarsest level counts for the coarsest.
        assert_eq!(
            place(&[([8.0, 8.0], 1e6)], 1.0, 3),
            [None, None, Some([8.0, 8.0])]
        );
        assert_eq!(place(&[], 1.0, 2), [None, None]);
    }
}
