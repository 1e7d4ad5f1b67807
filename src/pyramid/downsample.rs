//! One pyramid level from the next finer one: filtered separably (rows, then
//! columns) and every second sample kept. The work is done in rectangular
//! blocks of output samples, so the eager build (bands of whole rows) and
//! the lazy one (tiles around the viewer) run the same code and give the
//! same bits: each output sample is the same sum, in the same order, as a
//! per-sample loop over the kernel.

use super::{PyramidLevel, Rows};
use rayon::prelude::*;

/// Weighted sums of a line of output samples, Σ w·v and Σ w over the valid
/// taps, each in kernel order, in f64. Kept as two arrays so a tap is added
/// to several outputs per instruction.
#[derive(Default)]
struct Sums {
    sum: Vec<f64>,
    weight: Vec<f64>,
}

impl Sums {
    /// Zeroes the sums for a line of `len` outputs.
    fn clear(&mut self, len: usize) {
        self.sum.clear();
        self.sum.resize(len, 0.0);
        self.weight.clear();
        self.weight.resize(len, 0.0);
    }
    /// Adds tap weight `w` of samples `v` with validity `ok` (1 or 0) to
    /// every output. A no-data tap adds (w·0)·v = ±0 and w·0 = 0, which leave
    /// both sums bit for bit as skipping it would (heights are finite:
    /// no-data texels hold a fill value), and the loop needs no branch.
    #[inline(always)]
    fn add(&mut self, w: f64, v: &[f64], ok: &[f64]) {
        let n = self.sum.len();
        let (v, ok) = (&v[..n], &ok[..n]);
        for (((s, t), &v), &ok) in self.sum.iter_mut().zip(&mut self.weight).zip(v).zip(ok) {
            let w = w * ok;
            *s += w * v;
            *t += w;
        }
    }
    /// Output j normalised, or `centre` where no valid tap had weight.
    #[inline(always)]
    fn value(&self, j: usize, centre: f32) -> f32 {
        if self.weight[j] > 1e-6 {
            (self.sum[j] / self.weight[j]) as f32
        } else {
            centre
        }
    }
}

/// Reusable buffers of one worker: the sums and the pass-1 rows of a block.
#[derive(Default)]
pub(crate) struct Scratch {
    acc: Sums,
    rows: Vec<f64>,
    rows_ok: Vec<f64>,
}

/// Output samples `[x0, x1) × [y0, y1)` of the level below `src`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Block {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl Block {
    pub fn width(&self) -> usize {
        self.x1 - self.x0
    }
    pub fn len(&self) -> usize {
        self.width() * (self.y1 - self.y0)
    }
}

/// Size of the level made from a `w`×`h` one (vertex-centred halving).
pub(crate) fn halved(w: usize, h: usize) -> (usize, usize) {
    ((w - 1) / 2 + 1, (h - 1) / 2 + 1)
}

/// Input positions `start − r ..` of one line, clamped to `[0, len)` and
/// split into even and odd positions: tap k of output j reads padded
/// position 2j + k, which is element j + k/2 of the even (k even) or odd
/// (k odd) half, so every tap is a contiguous run. Values are f64 and
/// validity 1/0, the form [`Sums::add`] takes.
fn padded_halves(
    r: usize,
    start: usize,
    outputs: usize,
    len: usize,
    get: impl Fn(usize) -> (f32, bool),
) -> [[Vec<f64>; 2]; 2] {
    let n = 2 * outputs + 2 * r;
    let mut out: [[Vec<f64>; 2]; 2] = Default::default();
    for half in &mut out {
        for v in half.iter_mut() {
            v.reserve(n / 2 + 1);
        }
    }
    for i in 0..n {
        let at = (start as i64 + i as i64 - r as i64).clamp(0, len as i64 - 1) as usize;
        let (x, nd) = get(at);
        out[i % 2][0].push(x as f64);
        out[i % 2][1].push(if nd { 0.0 } else { 1.0 });
    }
    out
}

/// Pass 1 for input row `y`, output columns `[x0, x0 + out.len())`: filtered
/// along x, every second sample kept, into `out` (values, f32 held as f64)
/// and `out_ok` (1 valid, 0 no-data): the form pass 2 sums.
fn filter_row(
    src: Rows,
    y: usize,
    x0: usize,
    kernel: &[f64],
    acc: &mut Sums,
    out: &mut [f64],
    out_ok: &mut [f64],
) {
    let w = src.width;
    let row = src.index(0, y);
    let line = |x: usize| (src.data[row + x], src.nodata[row + x]);
    let halves = padded_halves(kernel.len() / 2, 2 * x0, out.len(), w, line);
    acc.clear(out.len());
    for (k, &wk) in kernel.iter().enumerate() {
        let [v, ok] = &halves[k % 2];
        acc.add(wk, &v[k / 2..], &ok[k / 2..]);
    }
    for (j, (o, o_ok)) in out.iter_mut().zip(out_ok.iter_mut()).enumerate() {
        let (centre, nd) = line(2 * (x0 + j));
        *o = acc.value(j, centre) as f64;
        *o_ok = if nd { 0.0 } else { 1.0 };
    }
}

/// Filters block `b` of the level below `src` into `out` / `out_nd` (row-
/// major, `b.width()` per row). Pass 1 filters the input rows the block's
/// taps reach ([`input_rows`]: `src` must hold them), over its columns
/// only; pass 2 filters those along y.
pub(crate) fn block(
    src: Rows,
    kernel: &[f64],
    b: Block,
    s: &mut Scratch,
    out: &mut [f32],
    out_nd: &mut [bool],
) {
    let h = src.height;
    let bw = b.width();
    let r = kernel.len() / 2;
    let clamp = |i: i64| i.clamp(0, h as i64 - 1) as usize;
    let (ya, yb) = {
        let rows = input_rows(h, r, b.y0, b.y1);
        (rows.start, rows.end - 1)
    };
    s.rows.resize((yb - ya + 1) * bw, 0.0);
    s.rows_ok.resize((yb - ya + 1) * bw, 0.0);
    let pass1 = s
        .rows
        .chunks_exact_mut(bw)
        .zip(s.rows_ok.chunks_exact_mut(bw));
    for (y, (row, row_ok)) in (ya..=yb).zip(pass1) {
        filter_row(src, y, b.x0, kernel, &mut s.acc, row, row_ok);
    }
    let (rows, rows_ok) = (&s.rows, &s.rows_ok);
    let out_rows = out.chunks_exact_mut(bw).zip(out_nd.chunks_exact_mut(bw));
    for (j, (out, out_nd)) in (b.y0..b.y1).zip(out_rows) {
        s.acc.clear(bw);
        for (k, &wk) in kernel.iter().enumerate() {
            let at = (clamp(2 * j as i64 + k as i64 - r as i64) - ya) * bw;
            s.acc.add(wk, &rows[at..at + bw], &rows_ok[at..at + bw]);
        }
        let c = (2 * j - ya) * bw;
        let (centre, centre_ok) = (&rows[c..c + bw], &rows_ok[c..c + bw]);
        for x in 0..bw {
            // Exact: the f64 holds an f32.
            out[x] = s.acc.value(x, centre[x] as f32);
            out_nd[x] = centre_ok[x] == 0.0;
        }
    }
}

/// The input rows that output rows `[y0, y1)` of the level below a level
/// of `h` rows read through a kernel of radius `r`.
pub(crate) fn input_rows(h: usize, r: usize, y0: usize, y1: usize) -> std::ops::Range<usize> {
    let clamp = |i: i64| i.clamp(0, h as i64 - 1) as usize;
    clamp(2 * y0 as i64 - r as i64)..clamp(2 * (y1 as i64 - 1) + r as i64) + 1
}

/// Output rows per task of [`downsample`]: each task filters the input
/// rows it needs along x itself (2·64 + taps − 1 of them), so no
/// full-size intermediate image is allocated; the rows shared with the
/// neighbouring tasks (taps − 1 of every 128) are filtered twice.
const ROWS_PER_TASK: usize = 64;

/// The whole next level, in parallel bands of whole output rows; both
/// passes run 4 f64 lanes wide.
pub(super) fn downsample(src: &PyramidLevel, kernel: &[f64]) -> PyramidLevel {
    let (w2, h2) = halved(src.width, src.height);
    let mut data = crate::terrain::huge::filled(w2 * h2, 0f32);
    let mut nodata = crate::terrain::huge::filled(w2 * h2, false);
    let band = w2 * ROWS_PER_TASK;
    data.par_chunks_mut(band)
        .zip(nodata.par_chunks_mut(band))
        .enumerate()
        .for_each_init(Scratch::default, |s, (i, (out, out_nd))| {
            let y0 = i * ROWS_PER_TASK;
            let b = Block {
                x0: 0,
                y0,
                x1: w2,
                y1: y0 + out.len() / w2,
            };
            block(src.rows(), kernel, b, s, out, out_nd);
        });
    PyramidLevel {
        width: w2,
        height: h2,
        data,
        nodata,
        min: 0.0,
        max: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pyramid::Filter;

    /// The definition: each output sample filters its input line one tap at
    /// a time, skipping no-data taps; first along x, then along y.
    fn reference(src: &PyramidLevel, kernel: &[f64]) -> (Vec<f32>, Vec<bool>) {
        let (w, h) = (src.width, src.height);
        let (w2, h2) = ((w - 1) / 2 + 1, (h - 1) / 2 + 1);
        let r = (kernel.len() / 2) as i64;
        let line = |len_out: usize, n: usize, get: &dyn Fn(usize) -> (f32, bool)| {
            (0..len_out)
                .map(|j| {
                    let c = 2 * j as i64;
                    let (mut acc, mut wsum) = (0.0f64, 0.0f64);
                    for (k, &wk) in kernel.iter().enumerate() {
                        let (v, nd) = get((c + k as i64 - r).clamp(0, n as i64 - 1) as usize);
                        if !nd {
                            acc += wk * v as f64;
                            wsum += wk;
                        }
                    }
                    let (centre, nd) = get(c as usize);
                    let v = if wsum > 1e-6 {
                        (acc / wsum) as f32
                    } else {
                        centre
                    };
                    (v, nd)
                })
                .collect::<Vec<_>>()
        };
        let rows: Vec<Vec<(f32, bool)>> = (0..h)
            .map(|y| line(w2, w, &|x| (src.data[y * w + x], src.nodata[y * w + x])))
            .collect();
        let mut out = (vec![0.0; w2 * h2], vec![false; w2 * h2]);
        for x in 0..w2 {
            let col = |y: usize| rows.get(y).expect("row")[x];
            for (y, (v, nd)) in line(h2, h, &col).into_iter().enumerate() {
                out.0[y * w2 + x] = v;
                out.1[y * w2 + x] = nd;
            }
        }
        out
    }

    proptest::proptest! {
        /// The row-wise, branch-free passes give the definition's bits, with
        /// no-data, odd and even sizes, and every filter.
        #[test]
        fn downsample_equals_the_per_sample_definition(
            w in 3usize..40, h in 3usize..300, seed in 0u64..1000, holes in 0u32..4,
            taps in proptest::sample::select(vec![3usize, 5, 11, 21]),
        ) {
            let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
            let mut next = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let data: Vec<f32> = (0..w * h).map(|_| (next() % 20_000) as f32 * 0.37 - 3000.0).collect();
            let nodata: Vec<bool> = (0..w * h).map(|_| next() % 8 < holes as u64).collect();
            let src = PyramidLevel { width: w, height: h, data, nodata, min: 0.0, max: 0.0 };
            for f in [Filter::Point, Filter::Box, Filter::SincBlackman { taps }] {
                let k = f.kernel();
                let got = downsample(&src, &k);
                let (data, nodata) = reference(&src, &k);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                proptest::prop_assert_eq!(bits(&got.data), bits(&data), "{:?}", f);
                proptest::prop_assert_eq!(&got.nodata, &nodata);
            }
        }
    }
    /// Any block of the next level, filtered alone, gives the bits of the
    /// whole-level build: what lets the lazy pyramid build tiles in any
    /// order and still equal the eager one.
    #[test]
    fn blocks_equal_the_whole_level() {
        let (w, h) = (77, 53);
        let data: Vec<f32> = (0..w * h)
            .map(|i| ((i * 7919) % 1013) as f32 * 0.61 - 200.0)
            .collect();
        let nodata: Vec<bool> = (0..w * h).map(|i| i % 17 == 3).collect();
        let src = PyramidLevel {
            width: w,
            height: h,
            data,
            nodata,
            min: 0.0,
            max: 0.0,
        };
        let k = Filter::SincBlackman { taps: 11 }.kernel();
        let whole = downsample(&src, &k);
        let mut s = Scratch::default();
        for b in [
            Block {
                x0: 0,
                y0: 0,
                x1: 39,
                y1: 27,
            },
            Block {
                x0: 5,
                y0: 11,
                x1: 6,
                y1: 12,
            },
            Block {
                x0: 30,
                y0: 20,
                x1: 39,
                y1: 27,
            },
            Block {
                x0: 17,
                y0: 0,
                x1: 33,
                y1: 9,
            },
        ] {
            let (mut out, mut nd) = (vec![0.0; b.len()], vec![false; b.len()]);
            block(src.rows(), &k, b, &mut s, &mut out, &mut nd);
            for y in b.y0..b.y1 {
                for x in b.x0..b.x1 {
                    let i = (y - b.y0) * b.width() + x - b.x0;
                    assert_eq!(
                        out[i].to_bits(),
                        whole.data[y * 39 + x].to_bits(),
                        "{b:?} ({x}, {y})"
                    );
                    assert_eq!(nd[i], whole.nodata[y * 39 + x]);
                }
            }
        }
    }
}
