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

/// What the process has cost the machine: CPU time in user code and in
/// the kernel, page faults and peak memory (`getrusage`). A run whose
/// system time is large next to its user time is paying for memory the
/// kernel maps and zeroes, not for rendering; these figures show it
/// without `/usr/bin/time`.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Rusage {
    /// CPU seconds in user code, all threads.
    pub user_s: f64,
    /// CPU seconds in the kernel on the process's behalf, all threads.
    pub system_s: f64,
    /// Page faults served without I/O (first touches of memory, mostly).
    pub minor_faults: u64,
    /// Page faults that read from disk.
    pub major_faults: u64,
    /// Peak resident memory of the process so far (bytes).
    pub peak_rss_bytes: u64,
}

impl Rusage {
    /// The process's figures so far (zeros where the system has no
    /// `getrusage`).
    pub fn now() -> Rusage {
        #[cfg(unix)]
        {
            // SAFETY: getrusage fills the zeroed struct it is given and
            // reads nothing else.
            let mut u: libc::rusage = unsafe { std::mem::zeroed() };
            if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } == 0 {
                let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
                return Rusage {
                    user_s: secs(u.ru_utime),
                    system_s: secs(u.ru_stime),
                    minor_faults: u.ru_minflt as u64,
                    major_faults: u.ru_majflt as u64,
                    // Linux reports kilobytes.
                    peak_rss_bytes: u.ru_maxrss as u64 * 1024,
                };
            }
        }
        Rusage::default()
    }

    /// What the process has cost since `start` (the peak stays the
    /// process's own).
    pub fn since(start: &Rusage) -> Rusage {
        let now = Rusage::now();
        Rusage {
            user_s: now.user_s - start.user_s,
            system_s: now.system_s - start.system_s,
            minor_faults: now.minor_faults.saturating_sub(start.minor_faults),
            major_faults: now.major_faults.saturating_sub(start.major_faults),
            peak_rss_bytes: now.peak_rss_bytes,
        }
    }
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
    fn passes_added_sum_by_name_in_first_order() {
        let p = |n: &str, ms: f64| Pass { name: n.into(), ms };
        let mut a = Passes(vec![p("mesh", 1.0), p("vertex", 2.0)]);
        a.add(Passes(vec![
            p("vertex", 0.5),
            p("raster", 3.0),
            p("mesh", 0.25),
        ]));
        assert_eq!(
            a,
            Passes(vec![p("mesh", 1.25), p("vertex", 2.5), p("raster", 3.0)])
        );
    }

    /// Touching fresh memory shows as minor faults and as peak memory.
    #[test]
    fn rusage_counts_the_pages_a_run_touches() {
        let start = Rusage::now();
        let mut v = vec![0u8; 64 << 20];
        for i in (0..v.len()).step_by(4096) {
            v[i] = 1;
        }
        std::hint::black_box(&v);
        let r = Rusage::since(&start);
        // 16,384 pages of 4 KiB; fewer where huge pages back them.
        assert!(r.minor_faults >= 32, "{r:?}");
        assert!(r.peak_rss_bytes >= 64 << 20, "{r:?}");
        assert!(r.user_s >= 0.0 && r.system_s >= 0.0, "{r:?}");
    }

    #[test]
    fn a_pass_that_did_not_run_took_plus_zero() {
        assert_eq!(pass_ms(&[], &["pyramid"]).to_bits(), 0f64.to_bits());
        assert_eq!(Passes::default().total_ms().to_bits(), 0f64.to_bits());
    }
}
