//! The entropy models residuals are coded with: a fixed family of
//! discretised two-sided geometric (Laplace) distributions over
//! `-K..=K` plus an escape symbol, one per scale. A tile picks the scale
//! that codes it in the fewest bits and names it in one byte, so no
//! histogram is stored and each tile adapts to its own roughness.
//!
//! The models are built from integers and correctly rounded f64 operations
//! only (no `exp`, whose last bit differs between C libraries), so every
//! machine builds the same fixed-point tables and decodes the same bits.

use constriction::stream::model::{
    ContiguousCategoricalEntropyModel, ContiguousLookupDecoderModel,
};
use std::sync::OnceLock;

/// Largest residual coded directly; larger ones are escaped.
pub const K: i64 = 255;
/// The symbol that says "escaped: the value follows in the side stream".
pub const ESCAPE: usize = (2 * K + 1) as usize;
/// Symbols per model: `-K..=K` and the escape.
pub const SYMBOLS: usize = ESCAPE + 1;
/// Models in the family.
pub const SCALES: usize = 40;
/// Fixed-point precision of the probabilities: 14 bits, so that a model
/// decodes through a lookup table of 2^14 entries (32 KB) instead of a
/// binary search over its 512 cumulative probabilities.
const PRECISION: u32 = 14;

/// A model of the family, for encoding.
pub type Model = ContiguousCategoricalEntropyModel<u16, Vec<u16>, 14>;
/// The same model as a lookup table, for decoding.
pub type Decoder = ContiguousLookupDecoderModel<u16, Vec<u16>, Box<[u16]>, 14>;

/// Symbol of residual `q`: `q + K` inside the range, else [`ESCAPE`].
#[inline]
pub fn symbol(q: i64) -> usize {
    if (-K..=K).contains(&q) {
        (q + K) as usize
    } else {
        ESCAPE
    }
}

/// The mean |q| model `k` is tuned for: 2^(k/2) / 8, from 0.125 to about
/// 2.9 × 10^4 (every √2).
pub fn scale(k: usize) -> f64 {
    let mut b = 0.125;
    for _ in 0..k / 2 {
        b *= 2.0;
    }
    if k % 2 == 1 {
        b *= std::f64::consts::SQRT_2;
    }
    b
}

/// Fixed-point probabilities of model `k`, summing to 2^PRECISION, each at
/// least 1. A two-sided geometric distribution with ratio r = b / (b + 1)
/// has mean |q| close to b; the escape takes the mass beyond ±K.
pub fn probabilities(k: usize) -> Vec<u16> {
    let b = scale(k);
    let r = b / (b + 1.0);
    let mut mass = vec![0f64; SYMBOLS];
    let mut p = 1.0f64;
    for q in 0..=K {
        mass[(K + q) as usize] = p;
        mass[(K - q) as usize] = p;
        p *= r;
    }
    // The tails beyond ±K: 2 · r^(K+1) / (1 − r), and a floor so an escape
    // is always codable.
    mass[ESCAPE] = 2.0 * p / (1.0 - r) + 1e-9;
    let total: f64 = mass.iter().sum();
    let full = 1u64 << PRECISION;
    // One count each, and the rest shared by mass, rounded down: the
    // counts never exceed the total, so the remainder is only ever given.
    let share = (full - SYMBOLS as u64) as f64;
    let mut fixed: Vec<u16> = mass
        .iter()
        .map(|&m| (1 + (m / total * share) as u64) as u16)
        .collect();
    // The remainder goes to the most likely symbol: the centre, or the
    // escape for the widest models (the first of equals, so every machine
    // picks the same).
    let sum: u64 = fixed.iter().map(|&f| f as u64).sum();
    let top = (0..SYMBOLS).fold(0, |a, i| if fixed[i] > fixed[a] { i } else { a });
    fixed[top] += (full - sum) as u16;
    fixed
}

/// Every model of the family, made by `make` from its counts.
fn family<M>(make: impl Fn(Vec<u16>) -> Result<M, ()>) -> Vec<M> {
    (0..SCALES)
        .map(|k| make(probabilities(k)).expect("each model's counts are nonzero and sum to 2^14"))
        .collect()
}

/// The family, built once.
pub fn models() -> &'static [Model] {
    static MODELS: OnceLock<Vec<Model>> = OnceLock::new();
    MODELS.get_or_init(|| family(|p| Model::from_nonzero_fixed_point_probabilities(p, false)))
}

/// The family as lookup decoders, built once.
pub fn decoders() -> &'static [Decoder] {
    static DECODERS: OnceLock<Vec<Decoder>> = OnceLock::new();
    DECODERS.get_or_init(|| family(|p| Decoder::from_nonzero_fixed_point_probabilities(p, false)))
}

/// Bits each symbol costs under model `k`: −log2 p, for choosing a tile's
/// model. Only compared, never stored, so their last bits need not agree
/// across machines.
pub fn costs(k: usize) -> Vec<f64> {
    let full = (1u64 << PRECISION) as f64;
    probabilities(k)
        .into_iter()
        .map(|p| -(p as f64 / full).log2())
        .collect()
}

/// [`costs`] of every model, built once.
pub fn all_costs() -> &'static [Vec<f64>] {
    static COSTS: OnceLock<Vec<Vec<f64>>> = OnceLock::new();
    COSTS.get_or_init(|| (0..SCALES).map(costs).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_model_sums_to_one_and_favours_zero() {
        for k in 0..SCALES {
            let p = probabilities(k);
            assert_eq!(p.iter().map(|&v| v as u64).sum::<u64>(), 1 << PRECISION);
            assert!(p.iter().all(|&v| v >= 1));
            assert!(p[K as usize] >= p[K as usize + 1], "model {k}");
            assert_eq!(p[K as usize - 3], p[K as usize + 3], "symmetric");
        }
        assert_eq!(models().len(), SCALES);
        assert_eq!(symbol(0), K as usize);
        assert_eq!(symbol(-K), 0);
        assert_eq!(symbol(K + 1), ESCAPE);
        assert_eq!(symbol(-K - 1), ESCAPE);
    }
}
