//! The fitted predictor: the lifting scheme's phases, each predicted by a
//! linear combination fitted to the tile.
//!
//! [`super::predict`]'s lifting weights are fixed: the four-point
//! interpolation along a row or a column, the coarse sample sharpened by a
//! quarter of its Laplacian. A map's best weights differ from place to
//! place (a smooth sea floor, a ridge crossing the grid, latitude
//! squeezing the columns of a geographic grid), so the fitted predictor
//! lets each tile choose them. Each sample's prediction is a base, the
//! mean of its two (or four) nearest known samples, plus `NF` features,
//! each a mean of known samples further out minus that base, weighted by
//! the tile's coefficients for the phase. Every feature is zero on a
//! plane, so whatever the weights the prediction follows any height
//! offset exactly.
//!
//! The encoder fits the weights by iteratively reweighted least squares to
//! the cost of a residual in bits, about log |r| (see [`fit`]), and writes
//! them, in 1/1024ths, at the head of the tile's side stream, phase by
//! phase (`docs/how-to/pack.md`). The decoder reads them and repeats the
//! arithmetic: f64 over f32 samples in a fixed order with no fused
//! operations, so encoder and decoder agree bit for bit on any machine.
//!
//! Like the lifting predictor's, a phase's predictions need no sample of
//! the phase itself, so they are straight loops over rows: each source
//! phase is copied once into a plane padded by repeating its edge samples,
//! and every feature is then a sum of shifted rows.

use super::predict::{coarse_window, Coarse, Planes};

/// Features a phase's prediction weighs.
pub(crate) const NF: usize = 4;
/// A coefficient's unit: 1/1024, exact in f64, so the decoder's weights
/// are the encoder's.
const ONE: f64 = 1024.0;
/// The largest |coefficient| in units of 1/1024 (32 in value): more than
/// any fit of these features takes, and a bound a forged tile cannot pass.
pub(crate) const MAX_COEF: i64 = 32767;
/// Samples of padding on each side of a source row: the widest reach is
/// phase 2's and 3's ±2 and the coarse window's ±2, plus one for a phase
/// of one column more than the one it feeds.
const PAD: usize = 3;
/// Rounds of reweighting in [`fit`]. On etopo5 at E = 0.5 m the pack
/// shrank by 0.7 % from 3 rounds to 8 (the first round is plain least
/// squares, which cliffs pull off the bulk of the samples).
const ROUNDS: usize = 8;

/// A phase's base predictions and features, one row-major array each, as
/// the encoder fits them.
#[derive(Default)]
pub(crate) struct Features {
    pub base: Vec<f64>,
    pub f: [Vec<f64>; NF],
}

/// What a tile's phases are predicted from, kept from phase to phase:
/// the source phases padded and the coarse window. [`Sources::phase`] is
/// called for phases 0, 1, 2 and 3 of a tile in that order, each after
/// the phase before it is reconstructed.
#[derive(Default)]
pub(crate) struct Sources {
    src: [Padded; 3],
    win: Padded,
}

/// A plane of f64 samples with `PAD` columns each side holding copies of
/// the edge samples; rows are clamped when read.
#[derive(Default)]
struct Padded {
    data: Vec<f64>,
    stride: usize,
    rows: usize,
}

impl Padded {
    /// Fills from `cols` × `rows` samples produced row by row by `row`.
    fn fill<'a>(&mut self, cols: usize, rows: usize, row: impl Fn(usize) -> &'a [f32]) {
        self.stride = cols + 2 * PAD;
        self.rows = rows;
        self.data.clear();
        if cols == 0 {
            return;
        }
        for j in 0..rows {
            let r = &row(j)[..cols];
            self.data.extend(std::iter::repeat_n(r[0] as f64, PAD));
            self.data.extend(r.iter().map(|&v| v as f64));
            self.data
                .extend(std::iter::repeat_n(r[cols - 1] as f64, PAD));
        }
    }

    /// `n` samples of row `j` (clamped) from column `i` (−PAD ≤ i).
    #[inline]
    fn at(&self, i: i64, j: i64, n: usize) -> &[f64] {
        let j = j.clamp(0, self.rows as i64 - 1) as usize;
        &self.data[j * self.stride + (i + PAD as i64) as usize..][..n]
    }
}

/// Rows `n` long, bounded once so the loops over them carry no checks.
#[inline(always)]
fn cut<const K: usize>(rows: [&[f64]; K], n: usize) -> [&[f64]; K] {
    rows.map(|r| &r[..n])
}

impl Sources {
    /// Phase `ph` of the tile whose first sample is (x0, y0) of its level,
    /// from the phases before it in `planes` and from `coarse`: calls
    /// `put(j, i, base, features)` for each of its samples (i, j) in
    /// row-major order. Each sample's base and features come from one
    /// expression, so the encoder that fits them and the decoder that
    /// only weighs them compute the same bits (and the decoder's loop
    /// holds them in registers).
    #[inline(always)]
    pub(crate) fn phase<C: Coarse + ?Sized>(
        &mut self,
        ph: usize,
        planes: &Planes,
        coarse: &C,
        (x0, y0): (usize, usize),
        mut put: impl FnMut(usize, usize, f64, [f64; NF]),
    ) {
        let [cols, rows] = planes.dims(ph);
        if ph == 0 {
            self.window(planes, coarse, (x0, y0));
        } else {
            // The phase before this one is whole now.
            let p = ph - 1;
            let [c, r] = planes.dims(p);
            self.src[p].fill(c, r, |j| &planes.planes[p][j * c..][..c]);
        }
        if cols * rows == 0 {
            return;
        }
        let n = cols;
        let Sources { src, win } = self;
        let [e, r1, c2] = &*src;
        for j in 0..rows {
            let jj = j as i64;
            // Coarse sample (i + di, j + dj) of a phase's sample (i, j).
            let c = |di: i64, dj: i64| win.at(di + 2, jj + dj + 2, n);
            let e = |di: i64, dj: i64| e.at(di, jj + dj, n);
            match ph {
                0 => {
                    let [m, l, r, u, d] = cut([c(0, 0), c(-1, 0), c(1, 0), c(0, -1), c(0, 1)], n);
                    let [ul, ur, dl, dr] = cut([c(-1, -1), c(1, -1), c(-1, 1), c(1, 1)], n);
                    let [l2, r2, u2, d2] = cut([c(-2, 0), c(2, 0), c(0, -2), c(0, 2)], n);
                    let k = cut(
                        [
                            c(-2, -1),
                            c(2, -1),
                            c(-2, 1),
                            c(2, 1),
                            c(-1, -2),
                            c(1, -2),
                            c(-1, 2),
                            c(1, 2),
                        ],
                        n,
                    );
                    for i in 0..n {
                        let m = m[i];
                        let f0 = (l[i] + r[i] + u[i] + d[i]) * 0.25 - m;
                        let f1 = (ul[i] + ur[i] + dl[i] + dr[i]) * 0.25 - m;
                        let f2 = (l2[i] + r2[i] + u2[i] + d2[i]) * 0.25 - m;
                        let f3 = (k[0][i]
                            + k[1][i]
                            + k[2][i]
                            + k[3][i]
                            + k[4][i]
                            + k[5][i]
                            + k[6][i]
                            + k[7][i])
                            * 0.125
                            - m;
                        put(j, i, m, [f0, f1, f2, f3]);
                    }
                }
                1 => {
                    // Sample (2i + 1, 2j): phase 0's (i, j) and (i + 1, j)
                    // beside it.
                    let [a, b, a3, b3] = cut([e(0, 0), e(1, 0), e(-1, 0), e(2, 0)], n);
                    let [ua, ub, da, db] = cut([e(0, -1), e(1, -1), e(0, 1), e(1, 1)], n);
                    let [ca, cb] = cut([c(0, 0), c(1, 0)], n);
                    let [cua, cub, cda, cdb] = cut([c(0, -1), c(1, -1), c(0, 1), c(1, 1)], n);
                    for i in 0..n {
                        let m = (a[i] + b[i]) * 0.5;
                        let f0 = (a3[i] + b3[i]) * 0.5 - m;
                        let f1 = (ua[i] + ub[i] + da[i] + db[i]) * 0.25 - m;
                        let f2 = (ca[i] + cb[i]) * 0.5 - m;
                        let f3 = (cua[i] + cub[i] + cda[i] + cdb[i]) * 0.25 - m;
                        put(j, i, m, [f0, f1, f2, f3]);
                    }
                }
                2 => {
                    // Sample (2i, 2j + 1): phase 0's (i, j) and (i, j + 1)
                    // above and below it, phase 1's (i − 1 …, j …)
                    // diagonally (a tile one sample across has no phase 1:
                    // the base's own rows stand in, a feature of about 0).
                    let [a, b, a3, b3, a5, b5] =
                        cut([e(0, 0), e(0, 1), e(0, -1), e(0, 2), e(0, -2), e(0, 3)], n);
                    let [ca, cb] = cut([c(0, 0), c(0, 1)], n);
                    let [ul, ur, dl, dr] = if planes.dims(1)[0] > 0 {
                        let r = |di: i64, dj: i64| r1.at(di, jj + dj, n);
                        cut([r(-1, 0), r(0, 0), r(-1, 1), r(0, 1)], n)
                    } else {
                        [a, a, b, b]
                    };
                    for i in 0..n {
                        let m = (a[i] + b[i]) * 0.5;
                        let f0 = (a3[i] + b3[i]) * 0.5 - m;
                        let f1 = (ul[i] + ur[i] + dl[i] + dr[i]) * 0.25 - m;
                        let f2 = (ca[i] + cb[i]) * 0.5 - m;
                        let f3 = (a5[i] + b5[i]) * 0.5 - m;
                        put(j, i, m, [f0, f1, f2, f3]);
                    }
                }
                _ => {
                    // Sample (2i + 1, 2j + 1): phase 1's (i, j) and
                    // (i, j + 1) above and below, phase 2's (i, j) and
                    // (i + 1, j) beside.
                    let r = |di: i64, dj: i64| r1.at(di, jj + dj, n);
                    let k = |di: i64, dj: i64| c2.at(di, jj + dj, n);
                    let [up, down, left, right] = cut([r(0, 0), r(0, 1), k(0, 0), k(1, 0)], n);
                    let [ul, ur, dl, dr] = cut([e(0, 0), e(1, 0), e(0, 1), e(1, 1)], n);
                    let [u3, d3, l3, r3] = cut([r(0, -1), r(0, 2), k(-1, 0), k(2, 0)], n);
                    let kn = cut(
                        [
                            r(-1, 0),
                            r(1, 0),
                            r(-1, 1),
                            r(1, 1),
                            k(0, -1),
                            k(1, -1),
                            k(0, 1),
                            k(1, 1),
                        ],
                        n,
                    );
                    for i in 0..n {
                        let v = (up[i] + down[i]) * 0.5;
                        let h = (left[i] + right[i]) * 0.5;
                        let m = (v + h) * 0.5;
                        let f0 = v - m;
                        let f1 = (ul[i] + ur[i] + dl[i] + dr[i]) * 0.25 - m;
                        let f2 = (u3[i] + d3[i] + l3[i] + r3[i]) * 0.25 - m;
                        let f3 = (kn[0][i]
                            + kn[1][i]
                            + kn[2][i]
                            + kn[3][i]
                            + kn[4][i]
                            + kn[5][i]
                            + kn[6][i]
                            + kn[7][i])
                            * 0.125
                            - m;
                        put(j, i, m, [f0, f1, f2, f3]);
                    }
                }
            }
        }
    }

    /// The coarse window: coarse samples (x0/2 − 2 …, y0/2 − 2 …), each
    /// clamped to the level, so that window (i + 2, j + 2) is the coarse
    /// sample at a phase's sample (i, j); it reaches two samples past the
    /// tile's coarse grid each way, as `codec::coarse_rows` provides.
    fn window<C: Coarse + ?Sized>(
        &mut self,
        planes: &Planes,
        coarse: &C,
        (x0, y0): (usize, usize),
    ) {
        let [ecols, erows] = planes.dims(0);
        // Read PAD columns wider each side, so that window column i is
        // `win.data` column i + PAD as `Padded::at` reads it (the extra
        // columns, clamped coarse samples too, are never read).
        let (ci, cj) = ((x0 / 2) as i64 - 2 - PAD as i64, (y0 / 2) as i64 - 2);
        let (wc, wr) = (ecols + 4 + 2 * PAD, erows + 4);
        self.win.data.clear();
        coarse_window(coarse, (ci, cj), (wc, wr), &mut self.win.data);
        (self.win.stride, self.win.rows) = (wc, wr);
    }
}

/// The features of every sample of phase `ph` (see [`Sources::phase`]),
/// row-major, for fitting.
pub(crate) fn features<C: Coarse + ?Sized>(
    sources: &mut Sources,
    ph: usize,
    planes: &Planes,
    coarse: &C,
    at: (usize, usize),
    out: &mut Features,
) {
    out.base.clear();
    for f in &mut out.f {
        f.clear();
    }
    sources.phase(ph, planes, coarse, at, |_, _, m, f| {
        out.base.push(m);
        for (o, f) in out.f.iter_mut().zip(f) {
            o.push(f);
        }
    });
}

/// One sample's prediction: its base plus the features weighted by `w`,
/// summed in feature order.
#[inline(always)]
fn combine(m: f64, f: [f64; NF], w: &[f64; NF]) -> f64 {
    m + w[0] * f[0] + w[1] * f[1] + w[2] * f[2] + w[3] * f[3]
}

/// Each sample's prediction from `x` and `coef` (1/1024ths).
pub(crate) fn predict(x: &Features, coef: &[i64; NF], pred: &mut Vec<f64>) {
    let w = coef.map(|c| c as f64 / ONE);
    let n = x.base.len();
    pred.clear();
    let [f0, f1, f2, f3] = [&x.f[0][..n], &x.f[1][..n], &x.f[2][..n], &x.f[3][..n]];
    pred.extend((0..n).map(|i| combine(x.base[i], [f0[i], f1[i], f2[i], f3[i]], &w)));
}

/// Phase `ph`'s predictions under `coef` (1/1024ths): the same bits as
/// [`features`] then [`predict`], without holding the features.
pub(crate) fn predict_phase<C: Coarse + ?Sized>(
    sources: &mut Sources,
    ph: usize,
    planes: &Planes,
    coarse: &C,
    at: (usize, usize),
    coef: &[i64; NF],
    pred: &mut Vec<f64>,
) {
    let w = coef.map(|c| c as f64 / ONE);
    let [cols, rows] = planes.dims(ph);
    pred.resize(cols * rows, 0.0);
    sources.phase(ph, planes, coarse, at, |j, i, m, f| {
        pred[j * cols + i] = combine(m, f, &w);
    });
}

/// The coefficients (1/1024ths) that predict `target` from `x` at about the
/// fewest bits. A residual r costs about log2(|r| + u) bits for a
/// quantisation step u (`unit` of the prediction), whose least-squares
/// surrogate at r is weight 1 / ((|r| ∨ u)(|r| + u)): each round solves
/// the weighted normal equations and reweighs by the new residuals. A
/// sample whose target is not finite (no-data is coded raw, whatever its
/// prediction) is left out.
pub(crate) fn fit(x: &Features, target: &[f64], unit: impl Fn(f64) -> f64) -> [i64; NF] {
    let n = x.base.len();
    let mut weight = vec![1.0; n];
    let mut coef = [0.0; NF];
    let mut pred = Vec::new();
    for _ in 0..ROUNDS {
        let mut a = [[0.0f64; NF]; NF];
        let mut b = [0.0f64; NF];
        for i in 0..n {
            let y = target[i] - x.base[i];
            let f = [x.f[0][i], x.f[1][i], x.f[2][i], x.f[3][i]];
            if !(y.is_finite() && f.iter().all(|v| v.is_finite())) {
                continue;
            }
            let wt = weight[i];
            for r in 0..NF {
                b[r] += wt * f[r] * y;
                for c in 0..NF {
                    a[r][c] += wt * f[r] * f[c];
                }
            }
        }
        coef = solve(a, b);
        let q = quantise(coef);
        predict(x, &q, &mut pred);
        for i in 0..n {
            let r = (target[i] - pred[i]).abs();
            let u = unit(pred[i]);
            weight[i] = 1.0 / (r.max(u) * (r + u));
        }
    }
    quantise(coef)
}

fn quantise(coef: [f64; NF]) -> [i64; NF] {
    coef.map(|c| {
        let q = (c * ONE).round();
        if q.is_finite() {
            q.clamp(-(MAX_COEF as f64), MAX_COEF as f64) as i64
        } else {
            0
        }
    })
}

/// Solves a x = b by Gaussian elimination, with a relative ridge of 10^−9
/// on the diagonal so that a feature that is zero over the tile (a flat
/// tile, a phase one sample wide) gets weight 0. All zeros where the
/// system is singular.
fn solve(mut a: [[f64; NF]; NF], mut b: [f64; NF]) -> [f64; NF] {
    let scale = (0..NF).map(|k| a[k][k]).fold(0.0, f64::max);
    if !(scale > 0.0 && scale.is_finite()) {
        return [0.0; NF];
    }
    for (k, row) in a.iter_mut().enumerate() {
        row[k] += 1e-9 * scale;
    }
    for k in 0..NF {
        let piv = a[k][k];
        let pivot_row = a[k];
        for r in k + 1..NF {
            let f = a[r][k] / piv;
            for (v, p) in a[r][k..].iter_mut().zip(&pivot_row[k..]) {
                *v -= f * p;
            }
            b[r] -= f * b[k];
        }
    }
    let mut x = [0.0; NF];
    for k in (0..NF).rev() {
        let s: f64 = (k + 1..NF).map(|c| a[k][c] * x[c]).sum();
        x[k] = (b[k] - s) / a[k][k];
    }
    if x.iter().all(|v| v.is_finite()) {
        x
    } else {
        [0.0; NF]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fit_recovers_the_weights_that_made_the_target() {
        let n = 500;
        let mut x = Features {
            base: (0..n).map(|i| (i as f64 * 0.37).sin() * 100.0).collect(),
            ..Features::default()
        };
        for (k, f) in x.f.iter_mut().enumerate() {
            *f = (0..n)
                .map(|i| ((i * (k + 2)) as f64 * 0.91).cos() * (k + 1) as f64)
                .collect();
        }
        let truth = [-128i64, 300, 0, 77];
        let mut target = Vec::new();
        predict(&x, &truth, &mut target);
        assert_eq!(fit(&x, &target, |_| 1.0), truth);
        // A flat tile: every feature zero, so every weight 0.
        for f in &mut x.f {
            f.fill(0.0);
        }
        assert_eq!(fit(&x, &x.base.clone(), |_| 1.0), [0; NF]);
    }
}
