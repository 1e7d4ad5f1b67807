//! LH04's interpolatory subdivision: the level finer than a given one
//! whose even samples are its samples and whose others are four-point
//! interpolations of them. Synthesis adds noise to it
//! ([`crate::synthesis`]), and a pack coded with
//! [`crate::pack::Predictor::Upsampled`] codes residuals against it, so
//! that a GPU pass can rebuild a level from the coarser one by repeating
//! it (`src/gpu/shaders/update.wgsl`). The arithmetic is f32 in a fixed
//! order with no fused operations and none of the shapes lavapipe's
//! shader compiler rewrites (docs/reference/raster-rules.md).

use super::PyramidLevel;
use rayon::prelude::*;

/// Samples from which a window's rows are made in parallel.
const PARALLEL_SAMPLES: usize = 1 << 16;

/// The four-point interpolation (−1/16, 9/16, 9/16, −1/16) at the midpoint
/// of `v1` and `v2`: LH04's subdivision, the pack's predictor.
#[inline]
fn four_point(v0: f32, v1: f32, v2: f32, v3: f32) -> f32 {
    // 9 (v1 + v2), not 9 v1 + 9 v2: lavapipe factors the second into the
    // first, so only this shape is the same bits on both sides.
    (9.0 * (v1 + v2) - (v0 + v3)) / 16.0
}

/// The interpolatory subdivision of `coarse`: a level of 2w − 1 × 2h − 1
/// samples whose even samples are the coarse ones, the samples between two
/// of them along a row or a column their four-point interpolation, and the
/// centres the mean of the row and column interpolations there (indices
/// clamped at the edges). A sample is no-data where any coarse sample its
/// stencil reads is. Returns the heights and the no-data flags.
pub fn subdivide(coarse: &PyramidLevel) -> (Vec<f32>, Vec<bool>) {
    subdivide_window(coarse, [0, 0, 2 * coarse.width - 1, 2 * coarse.height - 1])
}

/// The samples `[x, y, w, h]` of [`subdivide`]'s level: the same bits as
/// the whole level's, whichever window they are computed in, so a level
/// made tile by tile equals the level made whole. `coarse` need hold only
/// the samples the window's stencils read (coarse columns x/2 − 1 to
/// (x + w − 1)/2 + 2, and rows likewise, clamped to the level).
pub fn subdivide_window(
    coarse: &PyramidLevel,
    [x0, y0, w, h]: [usize; 4],
) -> (Vec<f32>, Vec<bool>) {
    let (cw, ch) = (coarse.width, coarse.height);
    let c = |i: i64, j: i64| {
        let (i, j) = (
            i.clamp(0, cw as i64 - 1) as usize,
            j.clamp(0, ch as i64 - 1) as usize,
        );
        (coarse.data[j * cw + i], coarse.nodata[j * cw + i])
    };
    // The four-point stencil along a row (dx = 1) or a column through
    // coarse (i, j) and the next one.
    let line = |i: i64, j: i64, dx: i64, dy: i64| {
        let (a, na) = c(i - dx, j - dy);
        let (b, nb) = c(i, j);
        let (e, ne) = c(i + dx, j + dy);
        let (f, nf) = c(i + 2 * dx, j + 2 * dy);
        (four_point(a, b, e, f), na || nb || ne || nf)
    };
    // The coarse cells the window lies in, and the midpoints each centre
    // reads, computed once: row midpoints (between (i, j) and (i + 1, j))
    // for rows j − 1 to j + 2, column midpoints for columns i − 1 to i + 2.
    let (i0, j0) = ((x0 / 2) as i64, (y0 / 2) as i64);
    let (i1, j1) = (((x0 + w - 1) / 2) as i64, ((y0 + h - 1) / 2) as i64);
    let ni = (i1 - i0 + 1) as usize;
    let row_mid: Vec<(f32, bool)> = (j0 - 1..=j1 + 2)
        .flat_map(|j| (i0..=i1).map(move |i| (i, j)))
        .map(|(i, j)| line(i, j, 1, 0))
        .collect();
    let col_mid: Vec<(f32, bool)> = (j0..=j1)
        .flat_map(|j| (i0 - 1..=i1 + 2).map(move |i| (i, j)))
        .map(|(i, j)| line(i, j, 0, 1))
        .collect();
    let rm = |i: i64, j: i64| row_mid[(j - j0 + 1) as usize * ni + (i - i0) as usize];
    let cm = |i: i64, j: i64| col_mid[(j - j0) as usize * (ni + 3) + (i - i0 + 1) as usize];
    let mut data = vec![0f32; w * h];
    let mut nodata = vec![false; w * h];
    let fill = |(r, (row, nd)): (usize, (&mut [f32], &mut [bool]))| {
        let y = y0 + r;
        let j = (y / 2) as i64;
        for (o, (out, out_nd)) in row.iter_mut().zip(nd.iter_mut()).enumerate() {
            let x = x0 + o;
            let i = (x / 2) as i64;
            let (v, n) = match (x % 2, y % 2) {
                (0, 0) => c(i, j),
                (1, 0) => rm(i, j),
                (0, _) => cm(i, j),
                _ => {
                    // The row interpolation through the four column
                    // midpoints beside the centre, and the column one
                    // through the four row midpoints above and below.
                    let r = [-1, 0, 1, 2].map(|t| cm(i + t, j));
                    let q = [-1, 0, 1, 2].map(|t| rm(i, j + t));
                    let a = four_point(r[0].0, r[1].0, r[2].0, r[3].0);
                    let b = four_point(q[0].0, q[1].0, q[2].0, q[3].0);
                    let n = r.iter().chain(&q).any(|v| v.1);
                    ((a + b) * 0.5, n)
                }
            };
            *out = v;
            *out_nd = n;
        }
    };
    // Rows in parallel only where there are enough of them to pay for it
    // (a pack tile's prediction is one small window among many decoded
    // at once); the bits are the same either way.
    let side = w.max(1);
    if w * h >= PARALLEL_SAMPLES {
        data.par_chunks_mut(side)
            .zip(nodata.par_chunks_mut(side))
            .enumerate()
            .for_each(fill);
    } else {
        data.chunks_mut(side)
            .zip(nodata.chunks_mut(side))
            .enumerate()
            .for_each(fill);
    }
    (data, nodata)
}
