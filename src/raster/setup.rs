//! Viewport transform, 8-bit snap and triangle setup: integer edge functions
//! with the top-left rule and f32 attribute planes (docs/reference/raster-rules.md 1–5).
//!
//! Every expression here is written in the order the rules give, because a
//! different order (or a fused multiply-add where none is meant) changes bits.

/// A vertex in window space: y down, depth in [0, 1], and 1/w.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WinVertex {
    /// Column in pixels, from the left edge.
    pub x: f32,
    /// Row in pixels, from the top edge.
    pub y: f32,
    /// Depth in 0..=1.
    pub z: f32,
    /// 1/w of the clip-space vertex.
    pub oow: f32,
}

/// Window size as the viewport's half extents.
#[derive(Clone, Copy, Debug)]
pub struct Viewport {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    half_w: f32,
    half_h: f32,
}

impl Viewport {
    /// A `width` × `height` viewport at the origin, depth 0..1 (Vulkan's default).
    pub fn new(width: u32, height: u32) -> Self {
        Viewport {
            width,
            height,
            half_w: width as f32 * 0.5,
            half_h: height as f32 * 0.5,
        }
    }

    /// Rule 1: an unclipped vertex is mapped with a fused multiply-add; the
    /// negative viewport height that wgpu uses flips y.
    #[inline]
    pub fn map(&self, c: [f32; 4]) -> WinVertex {
        let oow = 1.0 / c[3];
        let (xd, yd, zd) = (c[0] * oow, c[1] * oow, c[2] * oow);
        WinVertex {
            x: xd.mul_add(self.half_w, self.half_w),
            y: yd.mul_add(-self.half_h, self.half_h),
            z: zd,
            oow,
        }
    }

    /// Rule 6: a vertex made by the clipper is mapped without FMA, as Mesa's
    /// clipper does in C: `clip * oow * scale + translate`.
    #[inline]
    pub fn map_clipped(&self, c: [f32; 4]) -> WinVertex {
        let oow = 1.0 / c[3];
        WinVertex {
            x: c[0] * oow * self.half_w + self.half_w,
            y: c[1] * oow * -self.half_h + self.half_h,
            z: c[2] * oow * 1.0 + 0.0,
            oow,
        }
    }
}

/// Rule 2: 8 subpixel bits, round half to even, with pixel centres at
/// multiples of 256 after the −0.5 shift.
#[inline]
pub fn snap(v: f32) -> i64 {
    ((v - 0.5) * 256.0).round_ties_even() as i64
}

/// A linear function of the pixel index: value = fma(dady, py, fma(dadx, px, a00)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Plane {
    /// Change per pixel to the right.
    pub dadx: f32,
    /// Change per pixel down.
    pub dady: f32,
    /// Value at pixel (0, 0).
    pub a00: f32,
}

impl Plane {
    /// The value at pixel (px, py), with the fused operations in the order the planes were set up for.
    #[inline(always)]
    pub fn eval(&self, px: f32, py: f32) -> f32 {
        self.dady.mul_add(py, self.dadx.mul_add(px, self.a00))
    }
}

/// The per-triangle constants of rule 5 that every attribute plane shares.
#[derive(Clone, Copy, Debug)]
pub struct PlaneSetup {
    x0: f32,
    y0: f32,
    dy01_ooa: f32,
    dy20_ooa: f32,
    dx01_ooa: f32,
    dx20_ooa: f32,
}

impl PlaneSetup {
    /// From the window positions before snapping (already in setup order).
    pub fn new(v: &[WinVertex; 3]) -> Self {
        let dx01 = v[0].x - v[1].x;
        let dy01 = v[0].y - v[1].y;
        let dx20 = v[2].x - v[0].x;
        let dy20 = v[2].y - v[0].y;
        let ooa = 1.0 / (dx01 * dy20 - dy01 * dx20);
        PlaneSetup {
            x0: v[0].x,
            y0: v[0].y,
            dy01_ooa: dy01 * ooa,
            dy20_ooa: dy20 * ooa,
            dx01_ooa: dx01 * ooa,
            dx20_ooa: dx20 * ooa,
        }
    }

    /// The plane through values a0, a1, a2 at the three vertices.
    #[inline]
    pub fn plane(&self, a: [f32; 3]) -> Plane {
        let d10 = a[0] - a[1];
        let d20 = a[2] - a[0];
        let dadx = d10 * self.dy20_ooa - d20 * self.dy01_ooa;
        let dady = d20 * self.dx01_ooa - d10 * self.dx20_ooa;
        let a00 = a[0] - (dadx * (self.x0 - 0.5) + dady * (self.y0 - 0.5));
        Plane { dadx, dady, a00 }
    }
}

/// One edge function E(px, py) = a·px + b·py + c over pixel indices; a sample
/// is covered when E > 0 for all three edges (the top-left bias is in c).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Edge {
    /// Coefficient of px (1/256-pixel units).
    pub a: i64,
    /// Coefficient of py.
    pub b: i64,
    /// Constant term, top-left bias included.
    pub c: i64,
}

impl Edge {
    /// Edge from snapped point p to q of a triangle with positive `area`
    /// (rule 3), interior where the unbiased function is positive.
    pub fn new(p: [i64; 2], q: [i64; 2]) -> Self {
        let nx = q[1] - p[1];
        let ny = p[0] - q[0];
        // Rule 4: a sample exactly on the edge counts only on top and left
        // edges, i.e. when the inward normal points right, or straight down.
        let top_left = nx > 0 || (nx == 0 && ny > 0);
        Edge {
            a: 256 * nx,
            b: 256 * ny,
            c: -(nx * p[0]) - ny * p[1] + i64::from(top_left),
        }
    }
    /// E at pixel (px, py): positive inside.
    #[inline(always)]
    pub fn at(&self, px: i64, py: i64) -> i64 {
        self.a * px + self.b * py + self.c
    }
}

/// Rule 3 on snapped positions; zero means the triangle is dropped and a
/// negative value means it is reordered to (v0, v2, v1).
#[inline]
pub fn area(p: &[[i64; 2]; 3]) -> i64 {
    (p[0][0] - p[1][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[0][1] - p[1][1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snap_rounds_half_to_even() {
        // (x − 0.5)·256 = 0.5 → 0 and 1.5 → 2.
        assert_eq!(snap(0.5 + 0.5 / 256.0), 0);
        assert_eq!(snap(0.5 + 1.5 / 256.0), 2);
        assert_eq!(snap(0.5 + 2.5 / 256.0), 2);
        assert_eq!(snap(0.5 - 0.5 / 256.0), 0);
        assert_eq!(snap(0.5 - 1.5 / 256.0), -2);
        assert_eq!(snap(10.5), 2560);
    }

    #[test]
    fn plane_reproduces_vertex_values_at_centres() {
        // Vertices on pixel centres: the plane must give the vertex values.
        let v = [(0.5, 0.5), (8.5, 0.5), (0.5, 4.5)].map(|(x, y)| WinVertex {
            x,
            y,
            z: 0.0,
            oow: 1.0,
        });
        let p = PlaneSetup::new(&v).plane([1.0, 3.0, 5.0]);
        assert_eq!(p.eval(0.0, 0.0), 1.0);
        assert_eq!(p.eval(8.0, 0.0), 3.0);
        assert_eq!(p.eval(0.0, 4.0), 5.0);
    }

    /// Rule 1 against rule 6 on an input where fusing changes the f32
    /// result in both x and y (found by a search over x_ndc in (0, 1) at
    /// 1920×1080), so a mapping that drops the FMA, or a clipper mapping
    /// that adds one, fails.
    #[test]
    fn viewport_uses_fma() {
        let vp = Viewport::new(1920, 1080);
        let xd = 0.23757f32;
        let (fx, ux) = (xd.mul_add(960.0, 960.0), xd * 960.0 + 960.0);
        let (fy, uy) = (xd.mul_add(-540.0, 540.0), xd * -540.0 + 540.0);
        assert_ne!(fx.to_bits(), ux.to_bits(), "the input must tell them apart");
        assert_ne!(fy.to_bits(), uy.to_bits(), "the input must tell them apart");
        let v = vp.map([xd, xd, 0.5, 1.0]);
        assert_eq!((v.x.to_bits(), v.y.to_bits()), (fx.to_bits(), fy.to_bits()));
        assert_eq!(v.z, 0.5);
        let c = vp.map_clipped([xd, xd, 0.5, 1.0]);
        assert_eq!((c.x.to_bits(), c.y.to_bits()), (ux.to_bits(), uy.to_bits()));
    }
}
