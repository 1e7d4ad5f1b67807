//! Tile binning: each set-up triangle is listed, in submission order, in
//! every tile its bounding box touches, so tiles can be rasterised in any
//! order (and in parallel) with the same result.

use super::Tri;

/// Tile side in pixels (llvmpipe's size).
pub const TILE: u32 = 64;

/// Tiles across and down for a target.
pub fn grid(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(TILE), height.div_ceil(TILE))
}

/// Triangle indices per tile, row-major over tiles, into `bins` (whose
/// lists are cleared first and keep their memory): `tris[i]` is listed as
/// `first + i`.
pub fn bin_into(bins: &mut Vec<Vec<u32>>, tris: &[Tri], first: u32, width: u32, height: u32) {
    let (tx, ty) = grid(width, height);
    bins.resize_with((tx * ty) as usize, Vec::new);
    bins.iter_mut().for_each(Vec::clear);
    for (i, t) in tris.iter().enumerate() {
        let i = first + i as u32;
        let [x0, y0, x1, y1] = t.bbox;
        for by in (y0 as u32 / TILE)..=(y1 as u32 / TILE) {
            for bx in (x0 as u32 / TILE)..=(x1 as u32 / TILE) {
                bins[(by * tx + bx) as usize].push(i);
            }
        }
    }
}
