//! Geomorphing in transition regions (Losasso & Hoppe 2004 §2.3; GPU Gems 2
//! ch. 2): each vertex blends its own height z toward z_c, the coarser level's
//! surface at the same point, with a weight α that is 0 inside the level and
//! 1 on its outer boundary, so levels meet without cracks and without popping.
//!
//! Everything here is f32 in a fixed operation order, with no fused
//! multiply-add, so a WGSL vertex shader can reproduce it bit for bit.

use super::toroid::Toroid;

/// Per-level morph constants (what a GPU would hold in a uniform).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MorphParams {
    /// Viewer position relative to the level's window origin, in level texels.
    pub viewer: [f32; 2],
    /// Half the window width, (n − 1) / 2.
    pub half: f32,
    /// Transition width w in level texels.
    pub width: f32,
    /// False on the coarsest level (nothing to morph toward) or with morph off.
    pub enabled: bool,
    /// Outer boundary of the active region, relative to the window origin in
    /// level texels (x0, y0, x1, y1), and which of its sides face a coarser
    /// level (map edges do not). Vertices there get α = 1 exactly.
    pub boundary: [i32; 4],
    /// Per side of `boundary`: whether a coarser level lies beyond it, so its vertices
    /// are stitched (snapped onto the coarser grid).
    pub stitched: [bool; 4],
}

impl MorphParams {
    /// α = max(αx, αy) with αx = clamp((|x − v′x| − (half − w − 1)) / w, 0, 1),
    /// raised to exactly 1 on stitched boundary sides. `x`, `y` are relative to
    /// the window origin.
    #[inline]
    pub fn alpha(&self, x: i32, y: i32) -> f32 {
        if !self.enabled {
            return 0.0;
        }
        let b = &self.boundary;
        let on_edge = (self.stitched[0] && x == b[0])
            || (self.stitched[1] && y == b[1])
            || (self.stitched[2] && x == b[2])
            || (self.stitched[3] && y == b[3]);
        if on_edge {
            return 1.0;
        }
        let t = self.half - self.width - 1.0;
        let ax = (((x as f32 - self.viewer[0]).abs() - t) / self.width).clamp(0.0, 1.0);
        let ay = (((y as f32 - self.viewer[1]).abs() - t) / self.width).clamp(0.0, 1.0);
        ax.max(ay)
    }

    /// Where vertex (x, y) (relative to the window origin) is drawn: an odd
    /// vertex on a stitched side moves onto its even neighbour below, so the
    /// level's outer edges are exactly the coarser level's edges. With α = 1
    /// there it already lies on that edge; collapsing it removes the
    /// T-junction outright. The zero-area triangles the literature uses
    /// instead get extrapolated attribute planes wherever snapping gives them
    /// a pixel, and the clipper keeps them. Triangles that collapse have two
    /// bit-identical vertices, which no rasteriser covers (collapsing to the
    /// lower neighbour never flips a triangle with the main diagonal).
    #[inline]
    pub fn stitch(&self, x: i32, y: i32) -> (i32, i32) {
        if !self.enabled {
            return (x, y);
        }
        let [x0, y0, x1, y1] = self.boundary;
        let s = &self.stitched;
        if ((s[1] && y == y0) || (s[3] && y == y1)) && (x - x0) & 1 == 1 {
            return (x - 1, y);
        }
        if ((s[0] && x == x0) || (s[2] && x == x1)) && (y - y0) & 1 == 1 {
            return (x, y - 1);
        }
        (x, y)
    }
}

/// z′ = (1 − α)·z + α·z_c, evaluated without FMA, then held within
/// [min(z, z_c), max(z, z_c)]: rounding alone can overshoot (z = z_c =
/// 10 000 gave 10 000.001 in `tests/stability.rs`). `max` then `min` is
/// WGSL's `clamp`, and never panics.
#[inline]
pub fn blend(z: f32, zc: f32, alpha: f32) -> f32 {
    let keep = 1.0 - alpha;
    let a = keep * z;
    let b = alpha * zc;
    (a + b).max(z.min(zc)).min(z.max(zc))
}

/// The coarser level's surface height at fine vertex (x, y) (fine-level world
/// texels): the coarse sample itself on even-even vertices, the midpoint of
/// the two coarse neighbours on edge midpoints, and the midpoint of the main
/// diagonal (the one every mesh here uses) at cell centres.
#[inline]
pub fn coarse_height(coarse: &Toroid<f32>, x: i64, y: i64) -> f32 {
    coarse_sample(x, y, |a, b| coarse.get(a, b), |p, q| (p + q) * 0.5)
}

/// The main-diagonal convention for any coarse quantity (heights, slopes,
/// upsampled maps): `get` reads coarse texel (x, y) and `mid` averages two.
#[inline]
pub fn coarse_sample<T>(x: i64, y: i64, get: impl Fn(i64, i64) -> T, mid: impl Fn(T, T) -> T) -> T {
    let (hx, hy) = (x.div_euclid(2), y.div_euclid(2));
    match (x.rem_euclid(2), y.rem_euclid(2)) {
        (0, 0) => get(hx, hy),
        (1, 0) => mid(get(hx, hy), get(hx + 1, hy)),
        (0, _) => mid(get(hx, hy), get(hx, hy + 1)),
        _ => mid(get(hx, hy), get(hx + 1, hy + 1)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(viewer: [f32; 2]) -> MorphParams {
        MorphParams {
            viewer,
            half: 31.0,
            width: 6.3,
            enabled: true,
            boundary: [0, 0, 62, 62],
            stitched: [true; 4],
        }
    }

    #[test]
    fn zero_inside_one_on_boundary() {
        let p = params([31.0, 31.0]);
        assert_eq!(p.alpha(31, 31), 0.0);
        assert_eq!(p.alpha(20, 40), 0.0);
        for i in 0..=62 {
            assert_eq!(p.alpha(0, i), 1.0);
            assert_eq!(p.alpha(i, 62), 1.0);
        }
    }

    /// α is 1 on each stitched side by itself, whatever the ramp gives
    /// there: with the boundary well inside the ramp's reach (a region cut
    /// short of the window), only the stitched sides are raised to 1.
    #[test]
    fn each_stitched_side_alone_is_raised_to_one() {
        let mut p = params([31.0, 31.0]);
        p.boundary = [10, 12, 50, 52];
        // The ramp alone gives 0 at these boundary midpoints.
        let mids = [(10, 31), (31, 12), (50, 31), (31, 52)];
        p.stitched = [false; 4];
        for (x, y) in mids {
            assert_eq!(p.alpha(x, y), 0.0, "({x}, {y})");
        }
        for side in 0..4 {
            p.stitched = [false; 4];
            p.stitched[side] = true;
            for (k, &(x, y)) in mids.iter().enumerate() {
                let want = if k == side { 1.0 } else { 0.0 };
                assert_eq!(p.alpha(x, y), want, "side {side}: ({x}, {y})");
            }
        }
    }

    #[test]
    fn blend_endpoints_are_exact() {
        assert_eq!(blend(3.7, -2.25, 1.0), -2.25);
        assert_eq!(blend(3.7, -2.25, 0.0), 3.7);
    }

    #[test]
    fn stitch_moves_odd_vertices_of_stitched_sides_only() {
        let mut p = params([31.0, 31.0]);
        p.boundary = [2, 4, 12, 14];
        p.stitched = [true, true, false, true];
        // Bottom (y = 4) and top (y = 14): odd offsets from x0 = 2 move down.
        assert_eq!(p.stitch(3, 4), (2, 4));
        assert_eq!(p.stitch(11, 14), (10, 14));
        assert_eq!(p.stitch(4, 4), (4, 4));
        // Left (x = 2): odd offsets from y0 = 4 move down; right is a map edge.
        assert_eq!(p.stitch(2, 7), (2, 6));
        assert_eq!(p.stitch(12, 7), (12, 7));
        // Interior and corners stay.
        assert_eq!(p.stitch(5, 7), (5, 7));
        assert_eq!(p.stitch(2, 4), (2, 4));
        p.enabled = false;
        assert_eq!(p.stitch(3, 4), (3, 4));
    }
}
