//! `wireframe`: darkens pixels within half a pixel of a triangle edge.
//!
//! A pixel's distance to edge k, in pixels, is its screen-linear barycentric
//! b_k times the triangle's height over that edge, h_k = |2A| / |e_k|. The
//! per-triangle threshold 0.5 / h_k is computed once per triangle from the
//! three clip positions ([`thresholds`]) and carried as a constant
//! screen-linear varying, which interpolates to itself exactly. A GPU vertex
//! shader that sees its whole triangle repeats the same operations; the
//! rasteriser's own plane gradients are not visible to a fragment shader.

/// Half the line width in pixels.
pub const HALF_WIDTH: f32 = 0.5;

/// Per-edge barycentric thresholds of a triangle with clip positions `c` on
/// a `size` target. Edge k is the one opposite vertex k. Window positions
/// use no FMA (the shader's `edge_thresholds` repeats this order).
pub fn thresholds(c: [[f32; 4]; 3], size: [u32; 2]) -> [f32; 3] {
    let hw = size[0] as f32 * 0.5;
    let hh = size[1] as f32 * 0.5;
    let win = |p: [f32; 4]| {
        let ow = 1.0 / p[3];
        [(p[0] * ow) * hw + hw, hh - (p[1] * ow) * hh]
    };
    let [p0, p1, p2] = c.map(win);
    let a2 = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1]);
    let aa = a2.abs();
    let len = |a: [f32; 2], b: [f32; 2]| {
        let dx = b[0] - a[0];
        let dy = b[1] - a[1];
        (dx * dx + dy * dy).sqrt()
    };
    [len(p1, p2), len(p2, p0), len(p0, p1)].map(|l| (HALF_WIDTH * l) / aa)
}

/// True if a pixel with screen-linear barycentrics `b` lies on an edge of a
/// triangle with thresholds `t`.
#[inline(always)]
pub fn on_edge(b: [f32; 3], t: [f32; 3]) -> bool {
    b[0] < t[0] || b[1] < t[1] || b[2] < t[2]
}

/// Line colour mixed over the surface.
#[inline(always)]
pub fn apply(c: [f32; 3], line: [f32; 3]) -> [f32; 3] {
    [
        c[0] * 0.2 + line[0] * 0.8,
        c[1] * 0.2 + line[1] * 0.8,
        c[2] * 0.2 + line[2] * 0.8,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_are_half_a_pixel_over_the_height() {
        // A right triangle with 10 px legs on a 20×20 target (w = 1).
        let to_clip = |x: f32, y: f32| [x / 10.0 - 1.0, 1.0 - y / 10.0, 0.5, 1.0];
        let c = [to_clip(0.0, 0.0), to_clip(10.0, 0.0), to_clip(0.0, 10.0)];
        let t = thresholds(c, [20, 20]);
        // Heights: over the hypotenuse 10/√2, over each leg 10.
        assert!((t[0] - 0.5 / (10.0 / 2f32.sqrt())).abs() < 1e-6, "{t:?}");
        assert!(
            (t[1] - 0.05).abs() < 1e-6 && (t[2] - 0.05).abs() < 1e-6,
            "{t:?}"
        );
        assert!(on_edge([0.9, 0.06, 0.04], t) && !on_edge([0.5, 0.25, 0.25], t));
    }
}
