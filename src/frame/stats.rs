//! Render statistics: the passes that ran, with their times, so a test (or a
//! user) can see that an effect nobody listed cost nothing.

use serde::Serialize;
use std::time::Instant;

/// One pass and its wall time.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Pass {
    /// The pass, as `--json` names it (`terrain`, `lod`, `raster`, …).
    pub name: String,
    /// Wall time in milliseconds.
    pub ms: f64,
}

/// The passes of one render, in the order they ran.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Passes(pub Vec<Pass>);

impl Passes {
    /// Runs `f` as pass `name` and records its time.
    pub fn time<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        self.0.push(Pass {
            name: name.to_string(),
            ms: t.elapsed().as_secs_f64() * 1e3,
        });
        out
    }
    /// Adds the times of `more` to the passes of the same name (listing
    /// those not listed yet): a frame drawn in batches lists each pass
    /// once, with the time of all its batches.
    pub fn add(&mut self, more: Passes) {
        for p in more.0 {
            match self.0.iter_mut().rev().find(|q| q.name == p.name) {
                Some(q) => q.ms += p.ms,
                None => self.0.push(p),
            }
        }
    }
    /// Total time of the passes named `names` (ms).
    pub fn ms(&self, names: &[&str]) -> f64 {
        pass_ms(&self.0, names)
    }
    /// Whether a pass named `name` ran: how the statistics prove an unlisted effect cost nothing.
    pub fn ran(&self, name: &str) -> bool {
        self.0.iter().any(|p| p.name == name)
    }
    /// Wall time of every pass (ms).
    pub fn total_ms(&self) -> f64 {
        plus_sum(self.0.iter().map(|p| p.ms))
    }
}

/// Total time of the passes in `passes` named `names` (ms).
pub fn pass_ms(passes: &[Pass], names: &[&str]) -> f64 {
    plus_sum(
        passes
            .iter()
            .filter(|p| names.contains(&p.name.as_str()))
            .map(|p| p.ms),
    )
}

/// A sum that starts from +0: `Iterator::sum` of f64 starts from −0, so a pass that did not
/// run would print as "-0 ms".
fn plus_sum(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(0.0, |a, b| a + b)
}

/// The median of timings (the upper one of an even count).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pass_that_did_not_run_took_plus_zero() {
        assert_eq!(pass_ms(&[], &["pyramid"]).to_bits(), 0f64.to_bits());
        assert_eq!(Passes::default().total_ms().to_bits(), 0f64.to_bits());
    }
}
