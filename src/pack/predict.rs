//! The predictions a tile's samples are coded against, phase by phase.
//!
//! A finer level's tile is coded as four phases, as a lifting scheme does:
//! the samples on the coarse grid (even column, even row), those between
//! two of them along a row (odd, even), along a column (even, odd), and
//! the centres (odd, odd). Each phase is predicted only from the coarser
//! level and from the phases before it, never from its own samples, so a
//! whole phase's predictions are computed before any of its residuals is
//! decoded: the arithmetic runs as straight loops over contiguous rows,
//! and only the entropy decoder is serial. That is why a tile is held as
//! four phase planes (each phase's samples, row-major) while it is coded.
//!
//! The arithmetic is f64 over f32 samples in a fixed order, with no fused
//! operations, so encoder and decoder, on any machine, compute the same
//! predictions and contexts bit for bit.

use crate::pyramid::{PyramidLevel, Rows};

/// The coarser level a tile is predicted from, read with clamped indices.
pub trait Coarse: Sync {
    /// Samples across the level.
    fn width(&self) -> usize;
    /// Row `j` clamped to the level's extent, whole.
    fn row(&self, j: i64) -> &[f32];
}

impl Coarse for PyramidLevel {
    fn width(&self) -> usize {
        self.width
    }
    fn row(&self, j: i64) -> &[f32] {
        let y = j.clamp(0, self.height as i64 - 1) as usize;
        &self.data[y * self.width..][..self.width]
    }
}

/// A band of the coarser level must hold every row the clamped indices
/// reach: [`super::codec::coarse_rows`] of the tiles it predicts.
impl Coarse for Rows<'_> {
    fn width(&self) -> usize {
        self.width
    }
    fn row(&self, j: i64) -> &[f32] {
        let y = j.clamp(0, self.height as i64 - 1) as usize;
        &self.data[self.index(0, y)..][..self.width]
    }
}

/// The four-point interpolation weights −1/16, 9/16, 9/16, −1/16 at the
/// midpoint between `v1` and `v2`, and the activity there: the step
/// between the two nearest samples plus half the steps beside them.
#[inline(always)]
fn four_point(v0: f64, v1: f64, v2: f64, v3: f64) -> (f64, f64) {
    let p = (-v0 + 9.0 * v1 + 9.0 * v2 - v3) / 16.0;
    let act = (v1 - v2).abs() + ((v0 - v1).abs() + (v2 - v3).abs()) / 2.0;
    (p, act)
}

/// How much of the coarse level's Laplacian a coarse-grid sample's
/// prediction adds back: the coarse sample is a low-pass of the fine
/// neighbourhood, and a quarter of the detail it lost returns this way
/// (0.5 and −0.25 coded larger on jacksboro and etopo5; see the commit).
const SHARPEN: f64 = 0.25;

/// A tile's samples split into its four phases (phase `px | py << 1`),
/// each row-major: phase (px, py) holds tile samples (2i + px, 2j + py).
#[derive(Default)]
pub(crate) struct Planes {
    /// Tile samples across and down.
    pub w: usize,
    pub h: usize,
    /// The phases' samples.
    pub planes: [Vec<f32>; 4],
}

impl Planes {
    pub fn new(w: usize, h: usize) -> Planes {
        let mut p = Planes::default();
        p.reset(w, h);
        p
    }

    /// Planes for a `w` × `h` tile, reusing these buffers. Every sample is
    /// written before it is read: each phase is predicted only from the
    /// phases before it.
    pub fn reset(&mut self, w: usize, h: usize) {
        (self.w, self.h) = (w, h);
        for ph in 0..4 {
            let [c, r] = self.dims(ph);
            self.planes[ph].resize(c * r, 0.0);
        }
    }

    /// Columns and rows of phase `ph`.
    #[inline]
    pub fn dims(&self, ph: usize) -> [usize; 2] {
        [
            (self.w - (ph & 1)).div_ceil(2),
            (self.h - (ph >> 1)).div_ceil(2),
        ]
    }

    /// Tile-local (x, y) of phase `ph`'s sample `i`.
    #[inline]
    pub fn xy(&self, ph: usize, i: usize) -> (usize, usize) {
        let cols = self.dims(ph)[0];
        (2 * (i % cols) + (ph & 1), 2 * (i / cols) + (ph >> 1))
    }

    /// The tile's samples, row-major.
    pub fn interleave(&self) -> Vec<f32> {
        let mut out = vec![0f32; self.w * self.h];
        self.interleave_into(&mut out, self.w, 0);
        out
    }

    /// The tile's samples into `out`, rows `stride` apart, the first at
    /// `x0`.
    ///
    /// A row at a time from its two phases, in pairs (a loop that
    /// vectorises to unpacks; four strided passes took three times as
    /// long: 8 % of a fast decode of jacksboro, now under 3 %).
    pub fn interleave_into(&self, out: &mut [f32], stride: usize, x0: usize) {
        let w = self.w;
        for y in 0..self.h {
            let (even, odd) = (2 * (y & 1), 2 * (y & 1) + 1);
            let [ce, _] = self.dims(even);
            let co = self.dims(odd)[0];
            let j = y / 2;
            let a = &self.planes[even][j * ce..][..ce];
            let b = &self.planes[odd][j * co..][..co];
            let row = &mut out[y * stride + x0..][..w];
            let (pairs, last) = row.split_at_mut(w / 2 * 2);
            for ((d, &a), &b) in pairs.chunks_exact_mut(2).zip(a).zip(b) {
                d[0] = a;
                d[1] = b;
            }
            // An odd width ends with an even column's sample.
            if let Some(d) = last.first_mut() {
                *d = a[ce - 1];
            }
        }
    }
}

/// Predicts every sample of phase `ph` (1 to 3) from the phases before it
/// in `planes`, or (phase 0) from `coarse`, the coarser level, for the
/// tile whose first sample is (x0, y0) of its level. Writes the
/// predictions and, with `ACT`, the activities (height units) of what
/// each was predicted from into `pred` and `act`, in the phase's order.
/// Only the ratio coder's contexts read activities: the fast coder's
/// decoder asks for none.
///
/// Every element is written, so the buffers are only resized, never
/// cleared (a memset of both a phase). The two together took a fast
/// decode of jacksboro from 1.83 to 1.65 ms.
pub(crate) fn phase<const ACT: bool, C: Coarse + ?Sized>(
    ph: usize,
    planes: &Planes,
    coarse: &C,
    (x0, y0): (usize, usize),
    pred: &mut Vec<f64>,
    act: &mut Vec<f64>,
) {
    let [cols, rows] = planes.dims(ph);
    pred.resize(cols * rows, 0.0);
    act.resize(cols * rows, 0.0);
    let out = pred
        .chunks_exact_mut(cols.max(1))
        .zip(act.chunks_exact_mut(cols.max(1)));
    let even = &planes.planes[0];
    let [ecols, erows] = planes.dims(0);
    // Rows of an even-row plane at j − 1, j, j + 1, j + 2, clamped to the
    // tile (the stencil stays inside it, so a tile decodes alone).
    let near = |j: usize| {
        let last = erows - 1;
        [j.saturating_sub(1), j, (j + 1).min(last), (j + 2).min(last)]
    };
    let mut line = Vec::new();
    match ph {
        0 => {
            // The coarser level's samples under the tile and one around
            // it, read once with clamped indices.
            let (cw, ch) = (cols + 2, rows + 2);
            let (ci, cj) = ((x0 / 2) as i64 - 1, (y0 / 2) as i64 - 1);
            let mut win = Vec::with_capacity(cw * ch);
            coarse_window(coarse, (ci, cj), (cw, ch), &mut win);
            for (j, (pred, act)) in out.enumerate() {
                let (u, m, d) = (&win[j * cw..], &win[(j + 1) * cw..], &win[(j + 2) * cw..]);
                for i in 0..cols {
                    let (l, c, r, u, d) = (m[i], m[i + 1], m[i + 2], u[i + 1], d[i + 1]);
                    if ACT {
                        act[i] = (r - l).abs() + (d - u).abs();
                    }
                    let lap = c - (r + l + d + u) / 4.0;
                    pred[i] = c + SHARPEN * lap;
                }
            }
        }
        1 => {
            for (j, (pred, act)) in out.enumerate() {
                along_row::<ACT>(&even[j * ecols..][..ecols], &mut line, pred, act);
            }
        }
        2 => {
            for (j, (pred, act)) in out.enumerate() {
                let r = near(j).map(|k| &even[k * ecols..][..ecols]);
                along_col::<ACT>(r, pred, act);
            }
        }
        _ => {
            // The centres: the mean of the row interpolation (over the
            // column phase's samples of the same row) and the column
            // interpolation (over the row phase's samples of the same
            // column).
            let (col_phase, row_phase) = (&planes.planes[2], &planes.planes[1]);
            let ccols = planes.dims(2)[0];
            let rcols = planes.dims(1)[0];
            let (mut p2, mut a2) = (vec![0f64; cols], vec![0f64; cols]);
            for (j, (pred, act)) in out.enumerate() {
                along_row::<ACT>(&col_phase[j * ccols..][..ccols], &mut line, pred, act);
                let r = near(j).map(|k| &row_phase[k * rcols..][..rcols]);
                along_col::<ACT>(r, &mut p2, &mut a2);
                for (p, b) in pred.iter_mut().zip(&p2) {
                    *p = (*p + b) / 2.0;
                }
                if ACT {
                    for (a, v) in act.iter_mut().zip(&a2) {
                        *a = (*a + v) / 2.0;
                    }
                }
            }
        }
    }
}

/// The four-point interpolations down the columns of rows `r` (the even
/// rows j − 1 ..= j + 2, clamped), at their midpoints between j and j + 1.
/// Appends the coarse samples (ci + i, cj + j) for i < `cw`, j < `ch`,
/// each clamped to the level, to `win` as f64 rows. Columns inside the
/// level are read as a straight slice (a loop that vectorises); only those
/// past its edges are clamped.
pub(crate) fn coarse_window<C: Coarse + ?Sized>(
    coarse: &C,
    (ci, cj): (i64, i64),
    (cw, ch): (usize, usize),
    win: &mut Vec<f64>,
) {
    let last = coarse.width() as i64 - 1;
    let inside = ci.max(0)..(ci + cw as i64).min(last + 1);
    for j in 0..ch as i64 {
        let row = coarse.row(cj + j);
        let at = |i: i64| row[i.clamp(0, last) as usize] as f64;
        win.extend((ci..inside.start).map(at));
        if inside.start < inside.end {
            let mid = &row[inside.start as usize..inside.end as usize];
            win.extend(mid.iter().map(|&v| v as f64));
        }
        win.extend((inside.end.max(inside.start)..ci + cw as i64).map(at));
    }
}

#[inline]
fn along_col<const ACT: bool>(r: [&[f32]; 4], pred: &mut [f64], act: &mut [f64]) {
    let n = pred.len();
    let (r0, r1, r2, r3) = (&r[0][..n], &r[1][..n], &r[2][..n], &r[3][..n]);
    for i in 0..n {
        let (p, a) = four_point(r0[i] as f64, r1[i] as f64, r2[i] as f64, r3[i] as f64);
        pred[i] = p;
        if ACT {
            act[i] = a;
        }
    }
}

/// The four-point interpolations at the midpoints of `e`, a line's
/// samples at even positions, clamped to its ends: midpoint m reads
/// e[m − 1 ..= m + 2], so `line` holds `e` as f64 with one copy of its
/// first sample before it and two of its last after.
#[inline]
fn along_row<const ACT: bool>(e: &[f32], line: &mut Vec<f64>, pred: &mut [f64], act: &mut [f64]) {
    let (first, last) = (e[0] as f64, e[e.len() - 1] as f64);
    line.clear();
    line.push(first);
    line.extend(e.iter().map(|&v| v as f64));
    line.extend([last, last]);
    let n = pred.len();
    let (v0, v1, v2, v3) = (
        &line[..n],
        &line[1..n + 1],
        &line[2..n + 2],
        &line[3..n + 3],
    );
    for i in 0..n {
        let (p, a) = four_point(v0[i], v1[i], v2[i], v3[i]);
        pred[i] = p;
        if ACT {
            act[i] = a;
        }
    }
}

/// The predictions of a tile of [`super::codec::Quant::Upsampled`]'s
/// levels: every sample is the four-point upsampling of `coarse` (LH04's
/// tensor prediction, the bits of [`crate::pyramid::subdivide`]), for the
/// `w` × `h` tile whose first sample is (x0, y0) of its level. Writes, in
/// row-major order, the predictions, the activities of the coarse samples
/// each was interpolated from, and each sample's phase (`x & 1 | (y & 1)
/// << 1`), which with the activity picks its context.
pub(crate) fn upsampled<C: Coarse + ?Sized>(
    coarse: &C,
    (x0, y0, w, h): (usize, usize, usize, usize),
    pred: &mut Vec<f64>,
    act: &mut Vec<f64>,
    phase: &mut Vec<u8>,
) {
    // The coarse samples the tile's stencils read, one before and two
    // after, with the level's clamping done here: inside this crop the
    // subdivision reads no sample past its edges, so it clamps nothing
    // and gives the bits of the whole level's subdivision.
    let (ci0, cj0) = ((x0 / 2) as i64 - 1, (y0 / 2) as i64 - 1);
    let (cw, ch) = ((x0 + w - 1) / 2 + 4 - x0 / 2, (y0 + h - 1) / 2 + 4 - y0 / 2);
    let last = coarse.width() as i64 - 1;
    let mut data = Vec::with_capacity(cw * ch);
    for j in 0..ch as i64 {
        let row = coarse.row(cj0 + j);
        data.extend((0..cw as i64).map(|i| row[(ci0 + i).clamp(0, last) as usize]));
    }
    let crop = crate::pyramid::PyramidLevel {
        width: cw,
        height: ch,
        nodata: vec![false; data.len()],
        data,
        min: 0.0,
        max: 0.0,
    };
    // Tile origins are even, so (2, 2) of the crop's subdivision is the
    // tile's first sample with the same parity.
    let (up, _) = crate::pyramid::subdivide::subdivide_window(&crop, [2, 2, w, h]);
    pred.clear();
    pred.extend(up.iter().map(|&v| v as f64));
    // Activity: the steps between the coarse samples around each one, as
    // the lifting predictor's phases measure them.
    let c = |i: usize, j: usize| crop.data[j * cw + i] as f64;
    act.clear();
    phase.clear();
    for y in 0..h {
        // The coarse cell: (i, j) of the crop is coarse (x / 2, y / 2).
        let j = y / 2 + 1;
        for x in 0..w {
            let i = x / 2 + 1;
            let ph = (x & 1) | (y & 1) << 1;
            let row = || four_point(c(i - 1, j), c(i, j), c(i + 1, j), c(i + 2, j)).1;
            let col = || four_point(c(i, j - 1), c(i, j), c(i, j + 1), c(i, j + 2)).1;
            act.push(match ph {
                0 => (c(i + 1, j) - c(i - 1, j)).abs() + (c(i, j + 1) - c(i, j - 1)).abs(),
                1 => row(),
                2 => col(),
                _ => (row() + col()) / 2.0,
            });
            phase.push(ph as u8);
        }
    }
}
