//! Render statistics: the passes that ran, with their times, so a test (or a
//! user) can see that an effect nobody listed cost nothing.

use serde::Serialize;
use std::time::Instant;

/// One pass and its wall time.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Pass {
    pub name: String,
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
    pub fn ran(&self, name: &str) -> bool {
        self.0.iter().any(|p| p.name == name)
    }
    pub fn total_ms(&self) -> f64 {
        self.0.iter().map(|p| p.ms).sum()
    }
}
