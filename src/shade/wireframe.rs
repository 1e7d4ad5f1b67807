//! `wireframe`: darkens pixels within half a pixel of a triangle edge. The
//! distance is a screen-linear barycentric divided by the length of its
//! screen gradient, which the rasteriser's plane already holds.

use crate::raster::setup::Plane;

/// Half the line width in pixels.
pub const HALF_WIDTH: f32 = 0.5;

/// True if a pixel with screen-linear barycentrics `b` (planes `p`) lies on
/// an edge of its triangle.
#[inline]
pub fn on_edge(b: [f32; 3], p: [Plane; 3]) -> bool {
    (0..3).any(|k| {
        let g = (p[k].dadx * p[k].dadx + p[k].dady * p[k].dady).sqrt();
        g > 0.0 && b[k] < HALF_WIDTH * g
    })
}

/// Line colour mixed over the surface.
#[inline]
pub fn apply(c: [f32; 3], line: [f32; 3]) -> [f32; 3] {
    [
        c[0] * 0.2 + line[0] * 0.8,
        c[1] * 0.2 + line[1] * 0.8,
        c[2] * 0.2 + line[2] * 0.8,
    ]
}
