//! LH04's compressed residual pyramid. The coarsest level is coded on its
//! own (each sample predicted from its left or upper neighbour); each finer
//! level is coded as residuals against predictions from the reconstructed
//! coarser level and from the level's own samples decoded before, and the
//! loop is closed: prediction reads reconstructed values, so quantisation
//! errors do not add up from level to level.
//!
//! LH04 predicts every fine sample from the coarser level by the tensor
//! four-point scheme (weights −1/16, 9/16, 9/16, −1/16). Here the samples
//! on the coarse grid are predicted from the coarser level (LH04's rule,
//! slightly sharpened), and the rest by the same four-point weights over
//! the fine samples already decoded, phase by phase, as a lifting scheme
//! does: on jacksboro and etopo5 at E = 1 m (64² tiles) that coded
//! 5 % and 2 % smaller than LH04's tensor prediction, before contexts.
//! The fitted predictor ([`Predictor::Fitted`], `pack::fitted`) keeps
//! those phases and lets each tile fit its own weights, which it carries
//! at the head of its side stream: 5.5–7.5 % smaller again.
//!
//! Each level is cut into square tiles coded apart, so any tile of any
//! level can be decoded alone from the reconstructed coarser level around
//! it: what a clipmap update needs for the strips it uncovers. A tile's
//! residuals are entropy-coded with constriction's ANS coder, in two
//! streams taken in turn, each sample under the model ([`super::model`])
//! the encoder picked for its context: its phase and the roughness of what
//! it was predicted from. No phase is predicted from its own samples, so a
//! decoder computes a whole phase's predictions and contexts before
//! entropy-decoding it (`pack::predict`).

use super::fast;
use super::fitted;
use super::model::{self, ESCAPE, K, SCALES};
use super::predict::{self, Coarse, Planes};
use crate::pyramid::{PyramidLevel, Rows};
pub use crate::terrain::Lattice;
use constriction::stream::model::DefaultContiguousCategoricalEntropyModel;
use constriction::stream::stack::DefaultAnsCoder;
use constriction::stream::{Decode, Encode};
use rayon::prelude::*;

/// How a level's samples are quantised (the pack header writes it as a
/// JSON object tagged by `kind`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Quant {
    /// Bounded error: residuals in steps of 2·`max_error`, so every
    /// decoded sample is within `max_error` of the input.
    Step {
        /// The bound E, metres (height units).
        max_error: f64,
    },
    /// Lossless on a lattice: every sample is `(offset + k·scale) as f32`
    /// for an integer k (a 16-bit PNG with its sidecar, say), and the
    /// residuals are in units of k.
    Lattice {
        /// The lattice's origin.
        offset: f64,
        /// Its step.
        scale: f64,
    },
    /// Lossless on the f32 bit patterns, as ordered integers.
    Bits,
    /// Bounded error against [`Predictor::Upsampled`]'s prediction, in f32:
    /// each sample decodes to `p + q·s` with `s` = 2·`max_error` as f32 and
    /// the residual |q| < 2^24, so that a GPU pass given `q` repeats the
    /// sum bit for bit.
    Upsampled {
        /// The bound E, metres (height units).
        max_error: f64,
    },
}

/// What a finer level's samples are predicted from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Predictor {
    /// Phase by phase, as a lifting scheme does: the samples on the
    /// coarse grid from the coarser level, the rest by four-point
    /// interpolation of the level's own samples decoded before (`pack::predict`
    /// says how). The library's default, and the fast coder's in `pack`:
    /// it decodes fastest.
    #[default]
    Lifting,
    /// Lifting's phases, each predicted by weights the encoder fits to
    /// the tile and writes in it (`pack::fitted` says how): 5.5–7.5 %
    /// smaller than lifting on jacksboro and etopo5, for an encode at half
    /// its speed and a decode at 0.6–0.8 of it. The ratio coder's default
    /// in `pack`.
    Fitted,
    /// Every sample from the coarser level alone, by its four-point
    /// upsampling (LH04's tensor prediction), reconstructed in f32: any
    /// rectangle of the level is then the coarser level around it plus
    /// the residuals, which is what the GPU update pass rebuilds from
    /// (`[gpu] update = "gpu"`). Bounded error only (`max_error` > 0).
    Upsampled,
}

impl Predictor {
    /// Its name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Predictor::Lifting => "lifting",
            Predictor::Fitted => "fitted",
            Predictor::Upsampled => "upsampled",
        }
    }

    /// Whether a pack's header leaves it unnamed: all but
    /// [`Predictor::Fitted`], which the levels' quantisation cannot say.
    pub fn is_implied(&self) -> bool {
        *self != Predictor::Fitted
    }

    /// The predictor called `name`.
    pub fn parse(name: &str) -> Option<Predictor> {
        [Predictor::Lifting, Predictor::Fitted, Predictor::Upsampled]
            .into_iter()
            .find(|p| p.name() == name)
    }
}

/// The entropy stage a pack's tiles are coded with; the header names it.
/// Both code the same residual symbols (the same prediction, quantisation
/// and escapes), so a pack's heights do not depend on its coder.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Coder {
    /// constriction's ANS under a model chosen per context (phase ×
    /// roughness): the smaller pack.
    #[default]
    Ratio,
    /// zstd on each tile's symbols in coding order, with no contexts:
    /// Huffman-coded bytes decode at several hundred M symbols/s, where
    /// ANS decodes one symbol at a time through one state.
    Fast,
}

impl Coder {
    /// Its name on the command line, in reports and in the header.
    pub fn name(self) -> &'static str {
        match self {
            Coder::Ratio => "ratio",
            Coder::Fast => "fast",
        }
    }

    /// The coder called `name`.
    pub fn parse(name: &str) -> Option<Coder> {
        [Coder::Ratio, Coder::Fast]
            .into_iter()
            .find(|c| c.name() == name)
    }

    /// Whether this is the default coder (which the header leaves unnamed,
    /// so packs made before there was a choice read as before).
    pub fn is_default(&self) -> bool {
        *self == Coder::Ratio
    }
}

/// How a level's tiles are coded, beyond their quantisation: the entropy
/// stage, and whether each tile carries fitted prediction weights
/// ([`Predictor::Fitted`]; a level with no coarser level, and an
/// upsampled one, never does).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct CodeAs {
    pub coder: Coder,
    pub fitted: bool,
}

/// Largest |residual| an upsampled level codes as a residual: its f32
/// value is exact, so shader and CPU multiply the same number.
const UPSAMPLED_Q: f64 = (1u32 << 24) as f64;

/// f32 bits as an integer that orders like the value.
fn ordered(v: f32) -> i64 {
    let b = v.to_bits() as i32;
    (if b < 0 { b ^ 0x7fff_ffff } else { b }) as i64
}

fn from_ordered(o: i64) -> Option<f32> {
    let b = i32::try_from(o).ok()?;
    Some(f32::from_bits(
        (if b < 0 { b ^ 0x7fff_ffff } else { b }) as u32,
    ))
}

/// A sample coded: its residual, and the raw bits when no residual
/// reconstructs it within the bound.
struct Coded {
    q: i64,
    raw: Option<u32>,
    rec: f32,
}

impl Quant {
    /// Codes `x` against prediction `p`.
    fn code(&self, x: f32, p: f64) -> Coded {
        let raw = Coded {
            q: 0,
            raw: Some(x.to_bits()),
            rec: x,
        };
        match *self {
            Quant::Step { max_error } | Quant::Upsampled { max_error } => {
                // The step as the reconstruction multiplies it, and the
                // largest residual it takes.
                let (s, limit) = match self {
                    Quant::Upsampled { .. } => ((2.0 * max_error) as f32 as f64, UPSAMPLED_Q - 2.0),
                    _ => (2.0 * max_error, 1e15),
                };
                let q = ((x as f64 - p) / s).round();
                if !q.is_finite() || q.abs() > limit {
                    return raw;
                }
                let q = q as i64;
                for q in [q, q - 1, q + 1] {
                    let rec = self.rec(p, q);
                    if (rec as f64 - x as f64).abs() <= max_error {
                        return Coded { q, raw: None, rec };
                    }
                }
                raw
            }
            Quant::Lattice { offset, scale } => {
                let k = ((x as f64 - offset) / scale).round();
                let kp = ((p - offset) / scale).round();
                if !(k.is_finite() && kp.is_finite() && k.abs() < 1e15 && kp.abs() < 1e15) {
                    return raw;
                }
                let q = k as i64 - kp as i64;
                let rec = self.rec(p, q);
                if rec.to_bits() == x.to_bits() {
                    Coded { q, raw: None, rec }
                } else {
                    raw
                }
            }
            Quant::Bits => {
                let q = ordered(x) - ordered(p as f32);
                Coded {
                    q,
                    raw: None,
                    rec: x,
                }
            }
        }
    }

    /// One residual step near `p`, in height units.
    fn unit(&self, p: f64) -> f64 {
        match *self {
            Quant::Step { max_error } | Quant::Upsampled { max_error } => 2.0 * max_error,
            Quant::Lattice { scale, .. } => scale,
            Quant::Bits => {
                let v = (p as f32).abs();
                (f32::from_bits(v.to_bits() + 1) - v).max(f32::MIN_POSITIVE) as f64
            }
        }
    }

    /// The sample residual `q` reconstructs against prediction `p`.
    #[inline(always)]
    fn rec(&self, p: f64, q: i64) -> f32 {
        match *self {
            Quant::Step { max_error } => (p + q as f64 * (2.0 * max_error)) as f32,
            // The product then the sum, each rounded to f32: the shader's
            // `p + f32(q) * s` (p is an f32 prediction widened).
            Quant::Upsampled { max_error } => {
                let s = (2.0 * max_error) as f32;
                p as f32 + q as f32 * s
            }
            Quant::Lattice { offset, scale } => {
                let kp = ((p - offset) / scale).round() as i64;
                (offset + kp.saturating_add(q) as f64 * scale) as f32
            }
            Quant::Bits => from_ordered(ordered(p as f32) + q).unwrap_or(f32::NAN),
        }
    }
}

/// The rows of the coarser level (`coarse_height` rows) that predicting
/// fine rows `[y0, y1)` of a level quantised by `quant` reads: fine rows
/// 2j and 2j + 1 read coarse rows j − 1 ..= j + 1 when lifting,
/// j − 1 ..= j + 2 when upsampling (the four-point stencil between j and
/// j + 1), and j − 2 ..= j + 2 when `fitted`. The same holds for columns.
pub fn coarse_rows(
    coarse_height: usize,
    y0: usize,
    y1: usize,
    quant: Quant,
    fitted: bool,
) -> std::ops::Range<usize> {
    let last = coarse_height - 1;
    let up = matches!(quant, Quant::Upsampled { .. });
    let (before, after) = (1 + usize::from(fitted), 1 + usize::from(up || fitted));
    (y0 / 2).saturating_sub(before).min(last)..((y1 - 1) / 2 + after).min(last) + 1
}

/// One level as coded.
#[derive(Clone, Debug)]
pub struct PackedLevel {
    /// Samples across.
    pub width: usize,
    /// Samples down.
    pub height: usize,
    /// How the level is quantised.
    pub quant: Quant,
    /// The least and greatest valid height it decodes to, so a reader
    /// learns the relief from the header alone.
    pub range: [f32; 2],
    /// The coded tiles, row-major.
    pub tiles: Vec<Vec<u8>>,
}

/// A coded pyramid.
#[derive(Clone, Debug)]
pub struct Packed {
    /// Tile side in samples.
    pub tile: usize,
    /// The tiles' entropy stage.
    pub coder: Coder,
    /// What the finer levels are predicted from.
    pub predictor: Predictor,
    /// The bound the pyramid was coded to; 0 is lossless.
    pub max_error: f64,
    /// The levels, finest first.
    pub levels: Vec<PackedLevel>,
}

/// What went wrong decoding a tile.
#[derive(Clone, Debug, PartialEq)]
pub struct TileError {
    /// Level, 0 the finest.
    pub level: usize,
    /// Tile column and row.
    pub tile: [usize; 2],
    /// Why.
    pub reason: String,
}

impl std::fmt::Display for TileError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "level {} tile ({}, {}): {}",
            self.level, self.tile[0], self.tile[1], self.reason
        )
    }
}

/// A decoded tile: its rectangle of the level and its samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    /// First column, first row, samples across and samples down.
    pub rect: [usize; 4],
    /// Heights, row-major.
    pub data: Vec<f32>,
    /// No-data flags, row-major.
    pub nodata: Vec<bool>,
}

/// Tile flags: the tile's no-data mask is mixed (coded), or all no-data.
pub(crate) const MIXED: u8 = 1;
const ALL_NODATA: u8 = 2;
/// Activity classes per phase: a sample's model is chosen by its phase and
/// by how rough the decoded samples its prediction came from are.
const CLASSES: usize = 8;
/// Contexts: phases × classes, one model index each in the tile header.
const CONTEXTS: usize = 4 * CLASSES;
/// Header bytes before the model indices: flags, side-stream length
/// (u32), no-data count (u32), the first ANS stream's length in words
/// (u32), and a mask (u32) of the contexts the tile uses, each of which
/// then has its model index in one byte.
const HEADER: usize = 1 + 4 + 4 + 4 + 4;
/// A tile's residuals go to two ANS streams, alternately (sample k of a
/// phase to stream k mod 2), so a decoder's two dependency chains through
/// the coder's state overlap: constriction's lookup decoder gave 135 M
/// symbols/s from one stream and 225–245 M from two taken in turn on the
/// 2-core machine, for 8 more bytes a tile (docs/how-to/pack.md).
const STREAMS: usize = 2;

fn zigzag(q: i64) -> u64 {
    ((q << 1) ^ (q >> 63)) as u64
}

fn unzigzag(z: u64) -> i64 {
    (z >> 1) as i64 ^ -((z & 1) as i64)
}

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn get_varint(bytes: &[u8], at: &mut usize) -> Option<u64> {
    let mut v = 0u64;
    for shift in (0..64).step_by(7) {
        let b = *bytes.get(*at)?;
        *at += 1;
        v |= ((b & 0x7f) as u64) << shift;
        if b & 0x80 == 0 {
            return Some(v);
        }
    }
    None
}

/// The binary model of a tile's no-data mask, from its count.
fn mask_model(count: u32, n: usize) -> DefaultContiguousCategoricalEntropyModel {
    let full = 1u64 << 24;
    let p1 = ((count as u64 * full) / n.max(1) as u64).clamp(1, full - 1);
    DefaultContiguousCategoricalEntropyModel::from_nonzero_fixed_point_probabilities(
        [(full - p1) as u32, p1 as u32],
        false,
    )
    .expect("two nonzero probabilities summing to 2^24")
}

/// The rectangle of tile (tx, ty) of a `w`×`h` level.
pub(crate) fn tile_rect(
    w: usize,
    h: usize,
    t: usize,
    tx: usize,
    ty: usize,
) -> (usize, usize, usize, usize) {
    let (x0, y0) = (tx * t, ty * t);
    (x0, y0, (x0 + t).min(w) - x0, (y0 + t).min(h) - y0)
}

/// The prediction of sample (tx, ty) of a coarsest-level tile, which has
/// no coarser level: its left neighbour, or at the start of a row the
/// sample above it (raster order).
#[inline]
fn predict_top(rec: &[f32], w: usize, tx: usize, ty: usize) -> f64 {
    if tx > 0 {
        rec[ty * w + tx - 1] as f64
    } else if ty > 0 {
        rec[(ty - 1) * w] as f64
    } else {
        0.0
    }
}

/// The activities at which a sample's class goes up: `unit`·2^b, exact
/// (a power-of-two scaling), so class c means c whole-step bit lengths
/// without a division.
#[inline]
fn thresholds(unit: f64) -> [f64; CLASSES - 1] {
    let mut t = [unit; CLASSES - 1];
    for b in 1..CLASSES - 1 {
        t[b] = t[b - 1] * 2.0;
    }
    t
}

/// The context of a sample of `phase` whose prediction saw `activity`,
/// classes split at `thresholds`: its class is the bit length of the
/// activity in whole quantisation steps, at most `CLASSES − 1`.
#[inline]
fn context(phase: usize, activity: f64, thresholds: &[f64; CLASSES - 1]) -> usize {
    let class: usize = thresholds.iter().map(|&t| usize::from(activity >= t)).sum();
    phase * CLASSES + class
}

/// The model of each sample of phase `ph` of a tile whose contexts chose
/// `best`, from its prediction and activity.
fn models_of(
    ph: usize,
    pred: &[f64],
    act: &[f64],
    quant: Quant,
    best: &[u8; CONTEXTS],
    class: &mut Vec<u64>,
    out: &mut Vec<u8>,
) {
    out.clear();
    match quant {
        Quant::Bits => out.extend(
            pred.iter()
                .zip(act)
                .map(|(&p, &a)| best[context(ph, a, &thresholds(quant.unit(p)))]),
        ),
        // One step for every prediction, so one set of thresholds: the
        // classes first, counted in u64 (the compared values' width) in one
        // straight loop that vectorises, then one table lookup a sample.
        _ => {
            let t = thresholds(quant.unit(0.0));
            let best = &best[ph * CLASSES..][..CLASSES];
            class.clear();
            class.extend(
                act.iter()
                    .map(|&a| t.iter().fold(0u64, |c, &t| c + u64::from(a >= t))),
            );
            out.extend(class.iter().map(|&c| best[c as usize]));
        }
    }
}

/// Decodes one symbol under each model of `mk` into `sym`, sample k from
/// stream k mod 2.
fn decode_symbols(
    ans: &mut [DefaultAnsCoder; STREAMS],
    mk: &[u8],
    sym: &mut Vec<u16>,
) -> Result<(), ()> {
    let models = model::decoders();
    let [a, b] = ans;
    sym.clear();
    sym.reserve(mk.len());
    let mut pairs = mk.chunks_exact(2);
    for k in &mut pairs {
        let x = a.decode_symbol(&models[k[0] as usize]);
        let y = b.decode_symbol(&models[k[1] as usize]);
        sym.push(x.map_err(|_| ())? as u16);
        sym.push(y.map_err(|_| ())? as u16);
    }
    if let [k] = pairs.remainder() {
        sym.push(a.decode_symbol(&models[*k as usize]).map_err(|_| ())? as u16);
    }
    Ok(())
}

/// Each context's cheapest model for the symbol `counts` seen in it (the
/// first of equals; model 0 for a context no sample uses).
fn cheapest(counts: &[Vec<u64>]) -> [u8; CONTEXTS] {
    let costs = model::all_costs();
    let mut best = [0u8; CONTEXTS];
    for (b, counts) in best.iter_mut().zip(counts) {
        if counts.iter().all(|&c| c == 0) {
            continue;
        }
        let bits = |k: usize| -> f64 {
            counts
                .iter()
                .zip(&costs[k])
                .map(|(&c, &b)| c as f64 * b)
                .sum()
        };
        *b = (0..SCALES)
            .min_by(|&a, &b| bits(a).total_cmp(&bits(b)))
            .unwrap_or(0) as u8;
    }
    best
}

/// Encodes one tile of `level` (its samples `src`), predicted from
/// `coarse` (`None` on the coarsest level); returns the tile's bytes and
/// its reconstruction.
pub(crate) fn encode_tile<C: Coarse + ?Sized>(
    src: Rows,
    coarse: Option<&C>,
    quant: Quant,
    code_as: CodeAs,
    rect: (usize, usize, usize, usize),
) -> (Vec<u8>, Vec<f32>) {
    let CodeAs { coder, fitted: fit } = code_as;
    let (x0, y0, w, h) = rect;
    let n = w * h;
    // Symbols and contexts in coding order.
    let mut sym = Vec::with_capacity(n);
    let mut ctx = Vec::with_capacity(n);
    let mut side = Vec::new();
    let mut code = |x: f32, p: f64, c: usize| {
        ctx.push(c);
        let coded = quant.code(x, p);
        sym.push(match coded.raw {
            Some(bits) => {
                put_varint(&mut side, 1);
                side.extend_from_slice(&bits.to_le_bytes());
                ESCAPE
            }
            None => {
                let s = model::symbol(coded.q);
                if s == ESCAPE {
                    put_varint(&mut side, zigzag(coded.q) << 1);
                }
                s
            }
        });
        coded.rec
    };
    let at = |tx: usize, ty: usize| src.data[src.index(x0 + tx, y0 + ty)];
    // A fitted tile's coefficients, which head its side stream.
    let mut coefs = Vec::new();
    // The phases' lengths in coding order.
    let mut segments = Vec::with_capacity(4);
    let rec = match coarse {
        None => {
            let mut rec = vec![0f32; n];
            for i in 0..n {
                let (tx, ty) = (i % w, i / w);
                let p = predict_top(&rec, w, tx, ty);
                // The coarsest level has one context: no activity is measured.
                rec[i] = code(at(tx, ty), p, 0);
            }
            segments.push(n);
            rec
        }
        Some(coarse) if matches!(quant, Quant::Upsampled { .. }) => {
            // One pass in row-major order: no sample is predicted from the
            // level's own.
            let (mut pred, mut act, mut phase) = (Vec::new(), Vec::new(), Vec::new());
            predict::upsampled(coarse, rect, &mut pred, &mut act, &mut phase);
            let t = thresholds(quant.unit(0.0));
            let mut rec = vec![0f32; n];
            for (i, r) in rec.iter_mut().enumerate() {
                let c = context(phase[i] as usize, act[i], &t);
                *r = code(at(i % w, i / w), pred[i], c);
            }
            segments.push(n);
            rec
        }
        Some(coarse) => {
            let mut planes = Planes::new(w, h);
            let (mut pred, mut act) = (Vec::new(), Vec::new());
            let (mut x, mut target) = (fitted::Features::default(), Vec::new());
            let mut sources = fitted::Sources::default();
            for ph in 0..4 {
                predict::phase::<true, _>(ph, &planes, coarse, (x0, y0), &mut pred, &mut act);
                if fit {
                    fitted::features(&mut sources, ph, &planes, coarse, (x0, y0), &mut x);
                    target.clear();
                    target.extend((0..pred.len()).map(|i| {
                        let (tx, ty) = planes.xy(ph, i);
                        at(tx, ty) as f64
                    }));
                    let coef = fitted::fit(&x, &target, |p| quant.unit(p));
                    fitted::predict(&x, &coef, &mut pred);
                    for c in coef {
                        put_varint(&mut coefs, zigzag(c));
                    }
                }
                for (i, (&p, &a)) in pred.iter().zip(&act).enumerate() {
                    let (tx, ty) = planes.xy(ph, i);
                    let c = context(ph, a, &thresholds(quant.unit(p)));
                    planes.planes[ph][i] = code(at(tx, ty), p, c);
                }
                segments.push(pred.len());
            }
            planes.interleave()
        }
    };
    if !coefs.is_empty() {
        coefs.extend_from_slice(&side);
        side = coefs;
    }
    let nodata: Vec<bool> = (0..n)
        .map(|i| src.nodata[src.index(x0 + i % w, y0 + i / w)])
        .collect();
    let count = nodata.iter().filter(|&&b| b).count() as u32;
    let flags = if count == 0 {
        0
    } else if count as usize == n {
        ALL_NODATA
    } else {
        MIXED
    };
    if coder == Coder::Fast {
        return (fast::encode(flags, count, &nodata, &side, &sym), rec);
    }
    let mut counts = vec![vec![0u64; model::SYMBOLS]; CONTEXTS];
    for (&c, &s) in ctx.iter().zip(&sym) {
        counts[c][s] += 1;
    }
    let best = cheapest(&counts);
    // ANS is a stack: push in the reverse of the decoding order (the mask
    // on the first stream, then the samples in coding order, sample k of
    // each phase on stream k mod 2).
    let models = model::models();
    let mut ans: [DefaultAnsCoder; STREAMS] = Default::default();
    let mut end = n;
    for &len in segments.iter().rev() {
        for k in (0..len).rev() {
            let i = end - len + k;
            ans[k % STREAMS]
                .encode_symbol(sym[i], &models[best[ctx[i]] as usize])
                .expect("every symbol has a nonzero probability");
        }
        end -= len;
    }
    if flags == MIXED {
        let mm = mask_model(count, n);
        for &b in nodata.iter().rev() {
            ans[0]
                .encode_symbol(usize::from(b), &mm)
                .expect("both mask symbols have nonzero probability");
        }
    }
    let [first, second] = ans.map(|a| a.into_compressed().unwrap_or_default());
    let used: u32 = (0..CONTEXTS)
        .filter(|&c| counts[c].iter().any(|&k| k > 0))
        .fold(0, |m, c| m | 1 << c);
    let words = first.len() + second.len();
    let mut out = Vec::with_capacity(HEADER + CONTEXTS + side.len() + 4 * words);
    out.push(flags);
    out.extend_from_slice(&(side.len() as u32).to_le_bytes());
    out.extend_from_slice(&count.to_le_bytes());
    out.extend_from_slice(&(first.len() as u32).to_le_bytes());
    out.extend_from_slice(&used.to_le_bytes());
    out.extend(
        (0..CONTEXTS)
            .filter(|&c| used >> c & 1 == 1)
            .map(|c| best[c]),
    );
    out.extend_from_slice(&side);
    for w in first.into_iter().chain(second) {
        out.extend_from_slice(&w.to_le_bytes());
    }
    (out, rec)
}

/// Decodes tile `bytes` covering `rect` of a level quantised by `quant`,
/// predicted from `coarse` (`None` on the coarsest level).
pub(crate) fn decode_tile<C: Coarse + ?Sized>(
    bytes: &[u8],
    coarse: Option<&C>,
    quant: Quant,
    code_as: CodeAs,
    range: [f32; 2],
    rect: (usize, usize, usize, usize),
) -> Result<(Vec<f32>, Vec<bool>), String> {
    let n = rect.2 * rect.3;
    let (mut data, mut nodata) = (vec![0f32; n], vec![false; n]);
    let out = TileOut {
        data: &mut data,
        nodata: &mut nodata,
        stride: rect.2,
        x0: 0,
    };
    decode_tile_into(
        bytes,
        coarse,
        quant,
        code_as,
        range,
        rect,
        &mut Scratch::default(),
        out,
    )?;
    Ok((data, nodata))
}

/// Buffers a thread reuses from tile to tile while it decodes, so a level
/// is not a round of allocations (and of zeroed pages) a tile.
#[derive(Default)]
pub(crate) struct Scratch {
    planes: Planes,
    pred: Vec<f64>,
    act: Vec<f64>,
    class: Vec<u64>,
    phases: Vec<u8>,
    models: Vec<u8>,
    sym: Vec<u16>,
    words: [Vec<u32>; STREAMS],
    fast: fast::Decoder,
    sources: fitted::Sources,
}

/// Where a decoded tile goes: rows `stride` apart, the tile's first
/// sample at `x0` of the first row.
pub(crate) struct TileOut<'a> {
    pub data: &'a mut [f32],
    pub nodata: &'a mut [bool],
    pub stride: usize,
    pub x0: usize,
}

/// [`decode_tile`] into `out`, with `scratch`'s buffers. Every valid
/// sample must decode into `range`, the level's range as the header gives
/// it (the encoder's own reconstruction's least and greatest valid
/// sample, so the bounds are exact): a tile whose checksum was made to
/// match damaged bytes is otherwise free to decode to NaN or to any
/// height. Returns the tile's least and greatest valid sample ((+∞, −∞)
/// for none), so a whole level's range needs no second pass.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decode_tile_into<C: Coarse + ?Sized>(
    bytes: &[u8],
    coarse: Option<&C>,
    quant: Quant,
    code_as: CodeAs,
    [lo, hi]: [f32; 2],
    rect: (usize, usize, usize, usize),
    scratch: &mut Scratch,
    out: TileOut,
) -> Result<(f32, f32), String> {
    let CodeAs { coder, fitted: fit } = code_as;
    let (x0, y0, w, h) = rect;
    let n = w * h;
    let Scratch {
        planes,
        pred,
        act,
        class,
        phases,
        models: mk,
        sym,
        words,
        fast: fast_dec,
        sources,
    } = scratch;
    let TileOut {
        data,
        nodata,
        stride,
        x0: ox,
    } = out;
    let place = |i: usize| (i / w) * stride + ox + i % w;
    // The no-data mask is read first (by both coders), then the side
    // stream and the symbols' entropy stage are kept for the phases.
    let (side, mut stage) = match coder {
        Coder::Ratio => ratio_stage(bytes, n, words, |i, b| nodata[place(i)] = b)?,
        Coder::Fast => {
            let p = fast::parts(bytes, n)?;
            check_mask(p.flags, p.count, n)?;
            if p.flags == MIXED {
                let seen = fast::unmask(p.mask, n, |i, b| nodata[place(i)] = b);
                if seen != p.count {
                    return Err(format!(
                        "no-data mask holds {seen} samples, the header says {}",
                        p.count
                    ));
                }
            }
            fast::symbols(p.coded, n, fast_dec, sym)?;
            (p.side, Stage::Fast { at: 0 })
        }
    };
    // Both coders' tiles start with the flags, which the stage checked.
    let flags = bytes[0];
    if flags != MIXED {
        for r in 0..h {
            nodata[r * stride + ox..][..w].fill(flags == ALL_NODATA);
        }
    }
    let broken = |what: &str| format!("coded stream broken in the {what}");
    let mut at = 0usize;
    // A fitted tile's side stream starts with each phase's weights.
    let mut coefs = [[0i64; fitted::NF]; 4];
    let fit = fit && coarse.is_some() && !matches!(quant, Quant::Upsampled { .. });
    if fit {
        for c in coefs.iter_mut().flatten() {
            let v = get_varint(side, &mut at)
                .map(unzigzag)
                .ok_or_else(|| broken("prediction weights"))?;
            if v.abs() > fitted::MAX_COEF {
                return Err(format!(
                    "a prediction weight of {v}/1024, past the largest, {}/1024",
                    fitted::MAX_COEF
                ));
            }
            *c = v;
        }
    }
    // Sample `s` decoded against prediction `p`.
    let mut value = |s: usize, p: f64| -> Result<f32, String> {
        if s != ESCAPE {
            return Ok(quant.rec(p, s as i64 - K));
        }
        let v = get_varint(side, &mut at).ok_or_else(|| broken("side stream"))?;
        Ok(if v == 1 {
            let b = side.get(at..at + 4).ok_or_else(|| broken("side stream"))?;
            at += 4;
            f32::from_bits(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        } else {
            quant.rec(p, unzigzag(v >> 1))
        })
    };
    match coarse {
        None => {
            // One context: the symbols first, then the serial prediction.
            let sym = stage
                .next(n, sym, mk, |best, mk| {
                    mk.clear();
                    mk.resize(n, best[0]);
                })
                .map_err(|_| broken("residuals"))?;
            let mut rec = vec![0f32; n];
            for (i, &s) in sym.iter().enumerate() {
                let p = predict_top(&rec, w, i % w, i / w);
                rec[i] = value(s as usize, p)?;
            }
            for r in 0..h {
                data[r * stride + ox..][..w].copy_from_slice(&rec[r * w..][..w]);
            }
        }
        Some(coarse) if matches!(quant, Quant::Upsampled { .. }) => {
            predict::upsampled(coarse, rect, pred, act, phases);
            let t = thresholds(quant.unit(0.0));
            let sym = stage
                .next(n, sym, mk, |best, mk| {
                    mk.clear();
                    mk.extend(
                        act.iter()
                            .zip(&*phases)
                            .map(|(&a, &ph)| best[context(ph as usize, a, &t)]),
                    );
                })
                .map_err(|_| broken("residuals"))?;
            // Row by row in straight loops ([`Quant::rec`]'s sum, with its
            // step, 2E rounded to f32, made once); an escape's value is
            // filled in after.
            let step = quant.unit(0.0) as f32;
            for (r, (sym, pred)) in sym.chunks_exact(w).zip(pred.chunks_exact(w)).enumerate() {
                let row = &mut data[r * stride + ox..][..w];
                for ((d, &s), &p) in row.iter_mut().zip(sym).zip(pred.iter()) {
                    *d = p as f32 + (s as i64 - K) as f32 * step;
                }
            }
            if any_escape(sym) {
                for (i, &s) in sym.iter().enumerate() {
                    if s as usize == ESCAPE {
                        data[place(i)] = value(ESCAPE, pred[i])?;
                    }
                }
            }
        }
        Some(coarse) => {
            planes.reset(w, h);
            for (ph, coef) in coefs.iter().enumerate() {
                // The fast coder has no contexts, so no activities; a
                // fitted tile's predictions are made after the phase's
                // activities.
                match (coder, fit) {
                    (Coder::Ratio, _) => {
                        predict::phase::<true, _>(ph, planes, coarse, (x0, y0), pred, act)
                    }
                    (Coder::Fast, false) => {
                        predict::phase::<false, _>(ph, planes, coarse, (x0, y0), pred, act)
                    }
                    (Coder::Fast, true) => {}
                }
                if fit {
                    fitted::predict_phase(sources, ph, planes, coarse, (x0, y0), coef, pred);
                }
                let sym = stage
                    .next(pred.len(), sym, mk, |best, mk| {
                        models_of(ph, pred, act, quant, best, class, mk)
                    })
                    .map_err(|_| broken("residuals"))?;
                let pred = &*pred;
                let plane = &mut planes.planes[ph];
                // An escape's value is filled in below; what this writes there is overwritten.
                match quant {
                    // [`Quant::rec`]'s arithmetic with its step made once,
                    // so the loop vectorises (the match inside `rec` kept
                    // it scalar).
                    Quant::Step { max_error } => {
                        let step = 2.0 * max_error;
                        for ((r, &s), &p) in plane.iter_mut().zip(sym).zip(pred) {
                            *r = (p + (s as i32 - K as i32) as f64 * step) as f32;
                        }
                    }
                    _ => {
                        for ((r, &s), &p) in plane.iter_mut().zip(sym).zip(pred) {
                            *r = quant.rec(p, s as i64 - K);
                        }
                    }
                }
                // Escapes, in coding order, from the side stream.
                if any_escape(sym) {
                    for (i, &s) in sym.iter().enumerate() {
                        if s as usize == ESCAPE {
                            plane[i] = value(ESCAPE, pred[i])?;
                        }
                    }
                }
            }
            planes.interleave_into(data, stride, ox);
        }
    }
    if at != side.len() {
        return Err(format!("{} side-stream bytes left over", side.len() - at));
    }
    if let Stage::Ans { ans, .. } = &stage {
        if ans.iter().any(|a| !a.is_empty()) {
            return Err("coded words left over".into());
        }
    }
    let extremes = checked_extremes(data, nodata, (stride, ox), rect, [lo, hi], flags)?;
    // The emptied streams' buffers, for the next tile.
    if let Stage::Ans { ans, .. } = stage {
        *words = ans.map(|a| a.into_compressed().unwrap_or_default());
    }
    Ok(extremes)
}

/// Whether any of `sym` is the escape: a fold with no early exit, so it
/// vectorises; escapes are rare, and the loop that finds them is then
/// skipped.
fn any_escape(sym: &[u16]) -> bool {
    sym.iter().fold(false, |a, &s| a | (s as usize == ESCAPE))
}

/// The least and greatest valid sample of a decoded tile ((+∞, −∞) for
/// none), each checked to lie in `[lo, hi]`, the level's range as the
/// header gives it (the encoder's own reconstruction's least and greatest
/// valid sample, so the bounds are exact): a tile whose checksum was made
/// to match damaged bytes is otherwise free to decode to NaN or to any
/// height. `flags` is the tile's no-data flag: a tile of only no-data is
/// not read, and one with none is read once a row ([`finite_extremes`]),
/// without its mask. Only a row that fails is searched for the sample to
/// name.
fn checked_extremes(
    data: &[f32],
    nodata: &[bool],
    (stride, ox): (usize, usize),
    (x0, y0, w, h): (usize, usize, usize, usize),
    [lo, hi]: [f32; 2],
    flags: u8,
) -> Result<(f32, f32), String> {
    let (mut min, mut max) = (f32::INFINITY, f32::NEG_INFINITY);
    if flags == ALL_NODATA {
        return Ok((min, max));
    }
    for r in 0..h {
        let row = r * stride + ox..r * stride + ox + w;
        let (d, nd) = (&data[row.clone()], &nodata[row]);
        let (a, b, nan) = if flags == MIXED {
            let (a, b) = crate::pyramid::range_of(d, nd);
            let nan = d
                .iter()
                .zip(nd)
                .fold(false, |acc, (&v, &n)| acc | (v.is_nan() & !n));
            (a, b, nan)
        } else {
            finite_extremes(d)
        };
        if nan || (a <= b && (a < lo || b > hi)) {
            let i = d
                .iter()
                .zip(nd)
                .position(|(&v, &n)| !n && !(lo..=hi).contains(&v))
                .unwrap_or(0);
            return Err(format!(
                "sample ({}, {}) decodes to {}, outside the level's range [{lo}, {hi}]",
                x0 + i,
                y0 + r,
                d[i]
            ));
        }
        min = min.min(a);
        max = max.max(b);
    }
    Ok((min, max))
}

/// The least and greatest of `d` and whether any is NaN or infinite, in
/// one pass of eight independent lanes that vectorises. The extremes are
/// comparisons and selects (one `minps`/`maxps` each; `f32::min`'s NaN
/// handling cost three more instructions), which skip a NaN; `v − v` is
/// +0 (no bits set) for a finite v and NaN otherwise, so OR-ing its bits
/// catches the NaN. (The mask's fold, the extremes and a NaN test were
/// three passes a row, an eighth of a fast decode of jacksboro.)
// `v - v` on purpose: it is not 0 for a NaN or an infinity.
#[allow(clippy::eq_op)]
fn finite_extremes(d: &[f32]) -> (f32, f32, bool) {
    const LANES: usize = 8;
    let mut lo = [f32::INFINITY; LANES];
    let mut hi = [f32::NEG_INFINITY; LANES];
    let mut nan = [0u32; LANES];
    let chunks = d.chunks_exact(LANES);
    let rest = chunks.remainder();
    for c in chunks {
        for k in 0..LANES {
            let v = c[k];
            lo[k] = if v < lo[k] { v } else { lo[k] };
            hi[k] = if v > hi[k] { v } else { hi[k] };
            nan[k] |= (v - v).to_bits();
        }
    }
    for &v in rest {
        lo[0] = if v < lo[0] { v } else { lo[0] };
        hi[0] = if v > hi[0] { v } else { hi[0] };
        nan[0] |= (v - v).to_bits();
    }
    let lo = lo.iter().fold(f32::INFINITY, |a, &b| a.min(b));
    let hi = hi.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
    (lo, hi, nan.iter().any(|&n| n != 0))
}

/// Where a tile's symbols come from while its phases are decoded.
enum Stage {
    /// The ratio coder's two ANS streams and each context's model.
    Ans {
        ans: Box<[DefaultAnsCoder; STREAMS]>,
        best: [u8; CONTEXTS],
    },
    /// The fast coder's symbols, all decoded already: the next phase's
    /// start.
    Fast { at: usize },
}

impl Stage {
    /// The next `len` symbols. The ratio coder decodes them into `sym`
    /// under the models `models` writes to `mk` from each context's model;
    /// the fast coder's are the next `len` of `sym`.
    fn next<'s>(
        &mut self,
        len: usize,
        sym: &'s mut Vec<u16>,
        mk: &mut Vec<u8>,
        models: impl FnOnce(&[u8; CONTEXTS], &mut Vec<u8>),
    ) -> Result<&'s [u16], ()> {
        match self {
            Stage::Ans { ans, best } => {
                models(best, mk);
                decode_symbols(ans, mk, sym)?;
                Ok(&sym[..])
            }
            Stage::Fast { at } => {
                let s = sym.get(*at..*at + len).ok_or(())?;
                *at += len;
                Ok(s)
            }
        }
    }
}

/// Whether a no-data `count` fits `n` samples and the tile's `flags`.
fn check_mask(flags: u8, count: u32, n: usize) -> Result<(), String> {
    if flags > ALL_NODATA {
        return Err(format!("unknown flags {flags:#x}"));
    }
    if count as usize > n || (flags == MIXED) != (count > 0 && (count as usize) < n) {
        return Err(format!(
            "no-data count {count} does not fit {n} samples and flags {flags:#x}"
        ));
    }
    Ok(())
}

/// The ratio coder's tile header read and checked, its no-data mask
/// decoded (each flag given to `put` with its index), and its side
/// stream and ANS streams (made from `words`' buffers).
fn ratio_stage<'b>(
    bytes: &'b [u8],
    n: usize,
    words: &mut [Vec<u32>; STREAMS],
    mut put: impl FnMut(usize, bool),
) -> Result<(&'b [u8], Stage), String> {
    if bytes.len() < HEADER {
        return Err(format!(
            "{} bytes, shorter than the {HEADER}-byte header",
            bytes.len()
        ));
    }
    let flags = bytes[0];
    let le =
        |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let side_len = le(1) as usize;
    let count = le(5);
    let first = le(9) as usize;
    let used = le(13);
    check_mask(flags, count, n)?;
    let listed = used.count_ones() as usize;
    if bytes.len() < HEADER + listed {
        return Err(format!(
            "{} bytes, shorter than the header and its {listed} model indices",
            bytes.len()
        ));
    }
    // Unused contexts keep model 0: no sample reads them.
    let mut best = [0u8; CONTEXTS];
    let mut next = HEADER;
    for (c, b) in best.iter_mut().enumerate() {
        if used >> c & 1 == 1 {
            *b = bytes[next];
            next += 1;
        }
    }
    if let Some(&k) = best.iter().find(|&&k| k as usize >= SCALES) {
        return Err(format!("model {k} does not exist (there are {SCALES})"));
    }
    let rest = &bytes[next..];
    if side_len > rest.len() || (rest.len() - side_len) % 4 != 0 {
        return Err(format!(
            "side stream of {side_len} bytes does not fit the tile's {} bytes",
            rest.len()
        ));
    }
    let side = &rest[..side_len];
    let coded = &rest[side_len..];
    let total = coded.len() / 4;
    if first > total {
        return Err(format!(
            "first stream of {first} words does not fit the tile's {total}"
        ));
    }
    let [wa, wb] = std::mem::take(words);
    let stream = |mut buf: Vec<u32>, bytes: &[u8]| {
        buf.clear();
        buf.extend(
            bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])),
        );
        DefaultAnsCoder::from_compressed(buf)
            .map_err(|_| "a coded stream ends in a zero word".to_string())
    };
    let mut ans = Box::new([
        stream(wa, &coded[..4 * first])?,
        stream(wb, &coded[4 * first..])?,
    ]);
    if flags == MIXED {
        let mm = mask_model(count, n);
        for i in 0..n {
            let b = ans[0]
                .decode_symbol(&mm)
                .map_err(|_| "coded stream broken in the no-data mask".to_string())?;
            put(i, b == 1);
        }
    }
    Ok((side, Stage::Ans { ans, best }))
}

/// The quantisation of a level: bounded error when `max_error` > 0;
/// otherwise lossless, on `lattice` where every sample lies on it.
fn quant_for(
    level: &PyramidLevel,
    max_error: f64,
    lattice: Option<Lattice>,
    predictor: Predictor,
) -> Quant {
    let lattice = usable(lattice)
        .filter(|&l| max_error == 0.0 && level.data.par_iter().all(|&x| on_lattice(x, l)));
    quant(max_error, lattice, predictor)
}

/// The quantisation of a level coded to `max_error` with `predictor`,
/// where every sample is known to lie on `lattice` (if any). A lossless
/// level is always predicted by lifting.
pub(crate) fn quant(max_error: f64, lattice: Option<Lattice>, predictor: Predictor) -> Quant {
    match lattice {
        _ if max_error > 0.0 && predictor == Predictor::Upsampled => Quant::Upsampled { max_error },
        _ if max_error > 0.0 => Quant::Step { max_error },
        Some(Lattice { offset, scale }) => Quant::Lattice { offset, scale },
        None => Quant::Bits,
    }
}

/// `lattice` if a quantiser can use it (a finite origin, a finite step > 0).
pub(crate) fn usable(lattice: Option<Lattice>) -> Option<Lattice> {
    lattice.filter(|l| l.scale > 0.0 && l.scale.is_finite() && l.offset.is_finite())
}

/// Whether `x` is exactly a point of `lattice`.
#[inline]
pub(crate) fn on_lattice(x: f32, Lattice { offset, scale }: Lattice) -> bool {
    let k = ((x as f64 - offset) / scale).round();
    k.is_finite() && (offset + k * scale) as f32 == x
}

impl Packed {
    /// Codes `levels` (finest first, each the filtered half of the one
    /// before) to within `max_error` of every sample, in `tile`² tiles.
    /// `lattice` is level 0's, where the reader knows one (it makes
    /// `max_error` 0 cheap). Returns the pack and its reconstruction, which
    /// is what decoding gives.
    pub fn encode(
        levels: &[PyramidLevel],
        max_error: f64,
        tile: usize,
        lattice: Option<Lattice>,
    ) -> (Packed, Vec<PyramidLevel>) {
        Self::encode_with(levels, max_error, tile, lattice, Predictor::Lifting)
    }

    /// [`Packed::encode_coded`] with the ratio coder.
    pub fn encode_with(
        levels: &[PyramidLevel],
        max_error: f64,
        tile: usize,
        lattice: Option<Lattice>,
        predictor: Predictor,
    ) -> (Packed, Vec<PyramidLevel>) {
        Self::encode_coded(levels, max_error, tile, lattice, predictor, Coder::Ratio)
    }

    /// [`Packed::encode`] with the finer levels predicted by `predictor`
    /// (lifting where `max_error` is 0) and the tiles coded by `coder`.
    pub fn encode_coded(
        levels: &[PyramidLevel],
        max_error: f64,
        tile: usize,
        lattice: Option<Lattice>,
        predictor: Predictor,
        coder: Coder,
    ) -> (Packed, Vec<PyramidLevel>) {
        // Even, so a tile's local parity is the level's.
        let tile = tile.max(2).next_multiple_of(2);
        let code_as = CodeAs {
            coder,
            fitted: predictor == Predictor::Fitted,
        };
        let mut packed: Vec<PackedLevel> = Vec::with_capacity(levels.len());
        let mut recon: Vec<PyramidLevel> = Vec::with_capacity(levels.len());
        for (l, src) in levels.iter().enumerate().rev() {
            let lattice = if l == 0 { lattice } else { None };
            let quant = quant_for(src, max_error, lattice, predictor);
            let coarse = recon.last();
            let (tx, ty) = (src.width.div_ceil(tile), src.height.div_ceil(tile));
            let coded: Vec<(Vec<u8>, Vec<f32>)> = (0..tx * ty)
                .into_par_iter()
                .map(|t| {
                    let rect = tile_rect(src.width, src.height, tile, t % tx, t / tx);
                    encode_tile(src.rows(), coarse, quant, code_as, rect)
                })
                .collect();
            let mut data = vec![0f32; src.width * src.height];
            let mut bytes = Vec::with_capacity(coded.len());
            for (t, (b, r)) in coded.into_iter().enumerate() {
                let (x0, y0, w, h) = tile_rect(src.width, src.height, tile, t % tx, t / tx);
                for row in 0..h {
                    data[(y0 + row) * src.width + x0..][..w].copy_from_slice(&r[row * w..][..w]);
                }
                bytes.push(b);
            }
            let level = PyramidLevel::from_parts(src.width, src.height, data, src.nodata.clone());
            packed.push(PackedLevel {
                width: src.width,
                height: src.height,
                quant,
                range: [level.min, level.max],
                tiles: bytes,
            });
            recon.push(level);
        }
        packed.reverse();
        recon.reverse();
        (
            Packed {
                tile,
                coder,
                predictor,
                max_error,
                levels: packed,
            },
            recon,
        )
    }

    /// How the tiles are coded.
    pub(crate) fn code_as(&self) -> CodeAs {
        CodeAs {
            coder: self.coder,
            fitted: self.predictor == Predictor::Fitted,
        }
    }

    /// Tiles across and down of level `l`.
    pub fn tiles_of(&self, l: usize) -> [usize; 2] {
        let lv = &self.levels[l];
        [lv.width.div_ceil(self.tile), lv.height.div_ceil(self.tile)]
    }

    /// Decodes tile (tx, ty) of level `l`, predicted from `coarse`, the
    /// reconstructed level l + 1 (ignored on the coarsest level).
    pub fn decode_tile<C: Coarse + ?Sized>(
        &self,
        l: usize,
        [tx, ty]: [usize; 2],
        coarse: &C,
    ) -> Result<Tile, TileError> {
        let lv = &self.levels[l];
        let [nx, ny] = self.tiles_of(l);
        let err = |reason: String| TileError {
            level: l,
            tile: [tx, ty],
            reason,
        };
        if tx >= nx || ty >= ny {
            return Err(err(format!("outside the level's {nx} × {ny} tiles")));
        }
        let rect = tile_rect(lv.width, lv.height, self.tile, tx, ty);
        let top = l + 1 == self.levels.len();
        let c = (!top).then_some(coarse);
        let (data, nodata) = decode_tile(
            &lv.tiles[ty * nx + tx],
            c,
            lv.quant,
            self.code_as(),
            lv.range,
            rect,
        )
        .map_err(err)?;
        Ok(Tile {
            rect: [rect.0, rect.1, rect.2, rect.3],
            data,
            nodata,
        })
    }

    /// Decodes level `l` whole from `coarse`, the reconstructed level l + 1
    /// (`None` on the coarsest level), tiles in parallel.
    pub fn decode_level(
        &self,
        l: usize,
        coarse: Option<&PyramidLevel>,
    ) -> Result<PyramidLevel, TileError> {
        let lv = &self.levels[l];
        let [nx, _] = self.tiles_of(l);
        let empty = PyramidLevel::single();
        let c = coarse.unwrap_or(&empty);
        // On huge pages where granted: a level's first touch was a sixth
        // of a whole decode in page faults on 4 KB pages.
        let mut data = crate::terrain::huge::filled(lv.width * lv.height, 0f32);
        let mut nodata = crate::terrain::huge::filled(lv.width * lv.height, false);
        // A row of tiles at a time, each tile copied into the level as it
        // is decoded (so its buffers are reused, not held until the end).
        let band = self.tile * lv.width;
        let top = l + 1 == self.levels.len();
        // Each row of tiles gives its least and greatest valid height,
        // found while its samples were in cache.
        let none = || (f32::INFINITY, f32::NEG_INFINITY);
        let range = data
            .par_chunks_mut(band)
            .zip(nodata.par_chunks_mut(band))
            .enumerate()
            .map(|(ty, (data, nodata))| {
                let mut scratch = Scratch::default();
                let mut range = none();
                for tx in 0..nx {
                    let rect = tile_rect(lv.width, lv.height, self.tile, tx, ty);
                    let out = TileOut {
                        data: &mut *data,
                        nodata: &mut *nodata,
                        stride: lv.width,
                        x0: rect.0,
                    };
                    let bytes = &lv.tiles[ty * nx + tx];
                    let coarse = (!top).then_some(c);
                    let q = lv.quant;
                    let (lo, hi) = decode_tile_into(
                        bytes,
                        coarse,
                        q,
                        self.code_as(),
                        lv.range,
                        rect,
                        &mut scratch,
                        out,
                    )
                    .map_err(|reason| TileError {
                        level: l,
                        tile: [tx, ty],
                        reason,
                    })?;
                    range = (range.0.min(lo), range.1.max(hi));
                }
                Ok(range)
            })
            .try_reduce(none, |a, b| Ok((a.0.min(b.0), a.1.max(b.1))))?;
        Ok(PyramidLevel::from_parts_ranged(
            lv.width, lv.height, data, nodata, range,
        ))
    }

    /// Decodes every level, coarse to fine; finest first.
    pub fn decode(&self) -> Result<Vec<PyramidLevel>, TileError> {
        let mut out: Vec<PyramidLevel> = Vec::with_capacity(self.levels.len());
        for l in (0..self.levels.len()).rev() {
            let next = self.decode_level(l, out.last())?;
            out.push(next);
        }
        out.reverse();
        Ok(out)
    }

    /// Bytes of every coded tile.
    pub fn coded_bytes(&self) -> usize {
        self.levels
            .iter()
            .flat_map(|l| l.tiles.iter())
            .map(|t| t.len())
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every lane and the remainder: the extremes of any length, and a
    /// NaN or an infinity at any place is seen (the extremes' selects
    /// alone skip a NaN).
    #[test]
    fn finite_extremes_sees_every_place_of_any_row() {
        for len in 0..=40usize {
            let d: Vec<f32> = (0..len).map(|i| (i * 7 % 40) as f32 - 10.0).collect();
            let want = d
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            assert_eq!(finite_extremes(&d), (want.0, want.1, false), "{len}");
            for at in 0..len {
                for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                    let mut e = d.clone();
                    e[at] = bad;
                    assert!(finite_extremes(&e).2, "{bad} at {at} of {len}");
                }
            }
        }
    }

    /// The raw fallback: where no residual reconstructs a sample within
    /// the bound, its f32 bits are sent whole and come back exact.
    #[test]
    fn a_sample_no_residual_reaches_is_coded_raw() {
        // Upsampled: 1e9 + 1e7 metres over steps of 0.02 is past 2^24.
        let up = Quant::Upsampled { max_error: 0.01 };
        let c = up.code(1e9, -1e7);
        assert_eq!(
            (c.raw, c.rec.to_bits()),
            (Some(1e9f32.to_bits()), 1e9f32.to_bits())
        );
        // Within 2^24 steps it is a residual.
        let c = up.code(-1e7 + 1000.0, -1e7);
        assert_eq!(c.raw, None);
        assert!((c.rec as f64 - (-1e7 + 1000.0)).abs() <= 0.01);
        // Step: a residual past 1e15 steps.
        let step = Quant::Step { max_error: 0.01 };
        let c = step.code(3e38, -3e38);
        assert_eq!((c.raw, c.rec), (Some(3e38f32.to_bits()), 3e38));
        assert_eq!(step.code(1e9, -1e7).raw, None);
        // Lattice: a sample off the lattice.
        let lat = Quant::Lattice {
            offset: 0.0,
            scale: 0.5,
        };
        let c = lat.code(0.3, 0.0);
        assert_eq!((c.raw, c.rec), (Some(0.3f32.to_bits()), 0.3));
        assert_eq!(lat.code(1.5, 0.0).raw, None);
    }

    /// The largest upsampled residual is 2^24 − 2 steps: that many is a
    /// residual, one more is raw, and half as many is a residual.
    #[test]
    fn the_upsampled_residual_limit_is_two_to_the_24_less_two() {
        let up = Quant::Upsampled { max_error: 0.5 };
        let at = |x: f32| up.code(x, 0.0);
        let c = at(16_777_214.0);
        assert_eq!((c.q, c.raw), (16_777_214, None));
        assert_eq!(at(16_777_215.0).raw, Some(16_777_215f32.to_bits()));
        assert_eq!(at(8_388_608.0).raw, None);
    }

    /// Where the rounded residual misses the bound by the f32 rounding of
    /// the reconstruction, the one below or above it is tried, in that
    /// order. The cases were found by search: x and p as f32 values, a
    /// bound of 1e-5 against f32 spacings of 1e-6 to 1e-4 between 14 and 1,651,
    /// and residuals within the upsampled limit.
    #[test]
    fn a_residual_one_off_the_rounded_one_is_taken_when_it_reaches() {
        let (up, step) = (
            Quant::Upsampled { max_error: 1e-5 },
            Quant::Step { max_error: 1e-5 },
        );
        let cases = [
            (up, 406.12503f32, 117.56102752685547, -1),
            (up, 14.798, -235.8000030517578, 1),
            (step, 128.0, 1650.93212890625, -1),
            (step, 64.0, 391.14801025390625, 1),
        ];
        for (quant, x, p, off) in cases {
            let s = match quant {
                Quant::Upsampled { max_error } => (2.0 * max_error) as f32 as f64,
                _ => 2e-5,
            };
            let rounded = ((x as f64 - p) / s).round() as i64;
            let c = quant.code(x, p);
            assert_eq!((c.q, c.raw), (rounded + off, None), "{quant:?} {x} {p}");
            assert!((c.rec as f64 - x as f64).abs() <= 1e-5);
            assert!((quant.rec(p, rounded) as f64 - x as f64).abs() > 1e-5);
        }
    }

    /// A lattice index of 1e15 or more, of the sample or of the
    /// prediction, is coded raw (the i64 arithmetic is kept far from
    /// overflow), even where the residual would reconstruct it.
    #[test]
    fn lattice_indices_from_1e15_on_are_raw() {
        let x = (1u64 << 50) as f32;
        let lat = Quant::Lattice {
            offset: 0.0,
            scale: 1.125899906842624,
        };
        assert_eq!(((x as f64) / 1.125899906842624).round(), 1e15);
        assert_eq!(lat.rec(0.0, 1_000_000_000_000_000).to_bits(), x.to_bits());
        assert_eq!(lat.code(x, 0.0).raw, Some(x.to_bits()));
        assert_eq!(lat.code(0.0, x as f64).raw, Some(0f32.to_bits()));
        // Half the index: a residual.
        let y = (1u64 << 49) as f32;
        assert_eq!(lat.code(y, 0.0).raw, None);
        assert_eq!(lat.code(0.0, y as f64).raw, None);
    }

    /// f32 bits as ordered integers and back: every value comes back with
    /// its bits, ±0 included, and the order is the values'.
    #[test]
    fn ordered_bits_round_trip_and_sort() {
        let vs = [
            f32::MIN,
            -1.0,
            -f32::MIN_POSITIVE,
            -f32::from_bits(1),
            -0.0,
            0.0,
            f32::from_bits(1),
            1.0,
            f32::MAX,
        ];
        for v in vs {
            assert_eq!(
                from_ordered(ordered(v)).map(f32::to_bits),
                Some(v.to_bits())
            );
        }
        assert!(vs.windows(2).all(|w| ordered(w[0]) < ordered(w[1])));
        assert_eq!(from_ordered(1 << 40), None);
    }

    /// A bit-pattern step is one f32 spacing at the prediction.
    #[test]
    fn a_bits_unit_is_the_spacing_at_the_prediction() {
        assert_eq!(Quant::Bits.unit(1.0), f32::EPSILON as f64);
        assert_eq!(Quant::Bits.unit(-1024.0), 1024.0 * f32::EPSILON as f64);
        assert_eq!(Quant::Bits.unit(0.0), f32::MIN_POSITIVE as f64);
    }

    /// Predicting rows y0..y1 reads coarse rows j − 1 ..= j + 1 (j + 2
    /// when upsampling) for j from y0 / 2 to (y1 − 1) / 2, within the level.
    #[test]
    fn coarse_rows_are_the_predictors_reach() {
        let step = Quant::Step { max_error: 1.0 };
        let up = Quant::Upsampled { max_error: 1.0 };
        assert_eq!(coarse_rows(10, 4, 8, step, false), 1..5);
        assert_eq!(coarse_rows(10, 4, 8, up, false), 1..6);
        assert_eq!(coarse_rows(10, 4, 5, step, false), 1..4);
        assert_eq!(coarse_rows(10, 0, 20, step, false), 0..10);
        assert_eq!(coarse_rows(10, 17, 20, up, false), 7..10);
        assert_eq!(coarse_rows(10, 4, 8, step, true), 0..6);
        assert_eq!(coarse_rows(10, 8, 12, step, true), 2..8);
        assert_eq!(coarse_rows(10, 17, 20, step, true), 6..10);
    }

    /// The start of a coarsest-level row is predicted by the sample above
    /// it, every other sample by its left neighbour, the first by 0.
    #[test]
    fn the_top_predictor_reads_left_then_above() {
        let rec: Vec<f32> = (0..12).map(|i| i as f32 * 10.0).collect();
        assert_eq!(predict_top(&rec, 4, 0, 0), 0.0);
        assert_eq!(predict_top(&rec, 4, 3, 1), 60.0);
        assert_eq!(predict_top(&rec, 4, 0, 2), 40.0);
        assert_eq!(predict_top(&rec, 4, 0, 1), 0.0);
    }

    /// In bit-pattern mode a step is an f32 spacing at the prediction, so
    /// the same activity is a large one near 1 and a small one near 1024:
    /// each sample's thresholds come from its own prediction.
    #[test]
    fn bit_pattern_contexts_scale_with_the_prediction() {
        let best: [u8; CONTEXTS] = std::array::from_fn(|i| i as u8);
        let (mut class, mut out) = (vec![], vec![]);
        let (pred, act) = ([1.0, 1024.0], [1e-5, 1e-5]);
        models_of(1, &pred, &act, Quant::Bits, &best, &mut class, &mut out);
        let expect = pred.map(|p| context(1, 1e-5, &thresholds(Quant::Bits.unit(p))) as u8);
        assert_eq!(out, expect);
        assert!(out[0] > out[1], "{out:?}");
    }

    /// A context's model is the cheapest for its counts, also where the
    /// context has seen every symbol (white noise wider than ±K), and an
    /// unused context keeps model 0.
    #[test]
    fn each_context_gets_its_cheapest_model() {
        let costs = model::all_costs();
        let mut counts = vec![vec![0u64; model::SYMBOLS]; CONTEXTS];
        counts[3] = vec![1; model::SYMBOLS];
        counts[5][model::K as usize] = 100;
        counts[5][model::K as usize + 1] = 3;
        let best = cheapest(&counts);
        for c in [3, 5] {
            let bits = |k: usize| -> f64 {
                counts[c]
                    .iter()
                    .zip(&costs[k])
                    .map(|(&n, &b)| n as f64 * b)
                    .sum()
            };
            let want = (0..SCALES)
                .min_by(|&a, &b| bits(a).total_cmp(&bits(b)))
                .unwrap();
            assert_eq!(best[c] as usize, want, "context {c}");
        }
        assert_ne!(best[3], best[5], "noise and a spike want different models");
        assert_ne!(
            best[3], 0,
            "every symbol seen: not the unused context's model"
        );
        assert!(best
            .iter()
            .enumerate()
            .all(|(c, &b)| b == 0 || c == 3 || c == 5));
    }

    /// A lattice is used only where a quantiser can (finite origin, a
    /// finite step > 0), a sample is on it only where it is exactly a
    /// point of it, and a lossless level takes it only where every sample
    /// is on it.
    #[test]
    fn lattices_are_used_only_where_every_sample_is_on_them() {
        let l = |offset: f64, scale: f64| Some(Lattice { offset, scale });
        assert_eq!(usable(l(1.0, 0.5)), l(1.0, 0.5));
        for bad in [
            l(1.0, 0.0),
            l(1.0, -0.5),
            l(1.0, f64::INFINITY),
            l(1.0, f64::NAN),
            l(f64::NAN, 0.5),
            l(f64::INFINITY, 0.5),
        ] {
            assert_eq!(usable(bad), None, "{bad:?}");
        }
        let half = Lattice {
            offset: 0.25,
            scale: 0.5,
        };
        assert!(on_lattice(1.75, half));
        assert!(!on_lattice(1.5, half));
        assert!(!on_lattice(f32::INFINITY, half));
        // A step so fine that k overflows to infinity: not on it.
        let fine = Lattice {
            offset: 0.0,
            scale: 1e-308,
        };
        assert!(!on_lattice(3e38, fine));
        let on = PyramidLevel::from_parts(2, 1, vec![0.75, 1.25], vec![false; 2]);
        let off = PyramidLevel::from_parts(2, 1, vec![0.75, 1.3], vec![false; 2]);
        let lossless = |lv: &PyramidLevel| quant_for(lv, 0.0, Some(half), Predictor::Lifting);
        assert_eq!(
            lossless(&on),
            Quant::Lattice {
                offset: 0.25,
                scale: 0.5
            }
        );
        assert_eq!(lossless(&off), Quant::Bits);
        assert_eq!(
            quant_for(&on, 1.0, Some(half), Predictor::Lifting),
            Quant::Step { max_error: 1.0 }
        );
    }

    /// A tile outside the level's grid in either direction is an error
    /// naming it, not a panic or another tile.
    #[test]
    fn tiles_outside_the_grid_are_refused() {
        let lv =
            PyramidLevel::from_parts(8, 4, (0..32).map(|i| i as f32).collect(), vec![false; 32]);
        let (packed, _) = Packed::encode(std::slice::from_ref(&lv), 0.5, 4, None);
        assert_eq!(packed.tiles_of(0), [2, 1]);
        assert!(packed.decode_tile(0, [1, 0], &lv).is_ok());
        for t in [[2, 0], [0, 1], [2, 1]] {
            let e = packed.decode_tile(0, t, &lv).unwrap_err();
            assert_eq!(e.tile, t);
            assert!(
                e.reason.contains("outside the level's 2 × 1 tiles"),
                "{}",
                e.reason
            );
        }
    }

    /// The mask model gives no-data the tile's share of 2^24, clamped so
    /// both symbols stay codable.
    #[test]
    fn the_mask_model_is_the_tiles_share() {
        use constriction::stream::model::EncoderModel;
        let p1 = |count: u32, n: usize| {
            let m = mask_model(count, n);
            let (_, p) = m.left_cumulative_and_probability(1usize).unwrap();
            p.get()
        };
        assert_eq!(p1(4, 16), 1 << 22);
        assert_eq!(p1(1, 3), (1 << 24) / 3);
        assert_eq!(p1(0, 16), 1);
    }
}
