//! Coverage and depth for one tile: the scalar path, one pixel at a time.
//! `simd.rs` holds the fast path; both decide coverage with the same integer
//! edge functions and evaluate the same FMA depth plane per pixel, so their
//! bits agree.

use super::Tri;

/// Row stride of a tile buffer.
pub const STRIDE: usize = super::bin::TILE as usize;

/// A tile's depth and triangle-id buffers.
pub struct TileBuf {
    pub depth: Vec<f32>,
    pub prim: Vec<u32>,
}

impl TileBuf {
    pub fn new() -> Self {
        let n = STRIDE * super::bin::TILE as usize;
        TileBuf {
            depth: vec![1.0; n],
            prim: vec![super::NONE; n],
        }
    }
}

impl Default for TileBuf {
    fn default() -> Self {
        Self::new()
    }
}

/// The pixel span of triangle `t` inside the tile at (tx0, ty0):
/// inclusive x and y ranges, or None.
#[inline]
pub fn span(t: &Tri, tx0: i64, ty0: i64) -> Option<[i64; 4]> {
    let tile = super::bin::TILE as i64;
    let x0 = (t.bbox[0] as i64).max(tx0);
    let y0 = (t.bbox[1] as i64).max(ty0);
    let x1 = (t.bbox[2] as i64).min(tx0 + tile - 1);
    let y1 = (t.bbox[3] as i64).min(ty0 + tile - 1);
    (x0 <= x1 && y0 <= y1).then_some([x0, y0, x1, y1])
}

/// Scalar rasterisation of triangle `id` into the tile.
pub fn draw(t: &Tri, id: u32, tx0: i64, ty0: i64, buf: &mut TileBuf) {
    let Some([x0, y0, x1, y1]) = span(t, tx0, ty0) else {
        return;
    };
    let [e0, e1, e2] = &t.edges;
    for py in y0..=y1 {
        let row = (py - ty0) as usize * STRIDE;
        let mut e = [e0.at(x0, py), e1.at(x0, py), e2.at(x0, py)];
        let pyf = py as f32;
        for px in x0..=x1 {
            if e[0] > 0 && e[1] > 0 && e[2] > 0 {
                let z = t.z.eval(px as f32, pyf);
                let i = row + (px - tx0) as usize;
                if z < buf.depth[i] {
                    buf.depth[i] = z;
                    buf.prim[i] = id;
                }
            }
            e[0] += e0.a;
            e[1] += e1.a;
            e[2] += e2.a;
        }
    }
}
