//! Sweeps that outgrow one machine: `--shard i/N` runs the i-th of N
//! deterministic parts of a sweep, and `studies::merge` joins the parts'
//! JSON into exactly what one run prints, timings aside. No scheduler: GNU parallel,
//! a Slurm job array or a shell loop starts the parts
//! (docs/tutorials/verify-your-renderer.md shows each).
//!
//! A part owns the items `k` with `k mod N = i` (views, scenes, settings),
//! so the parts take turns through the sweep and each gets a fair share of
//! its slow and fast items. Paths (`fly`, `export`) are cut into runs of
//! frames instead ([`Shard::run_of`]): a frame follows from the one before. A part's JSON carries a `shard` object: the
//! command, `index`, `count`, and `of`, the settings every part must share.

use serde::{Deserialize, Serialize};
use serde_json::Value;

/// Part `index` of `count`, from `--shard i/N` (0 ≤ i < N).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// Which part, from 0.
    pub index: usize,
    /// How many parts.
    pub count: usize,
}

impl Shard {
    /// The whole sweep: part 0 of 1.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Parses `i/N`; `0/0`, `5/4` and anything not two integers are errors
    /// that say why.
    pub fn parse(s: &str) -> std::result::Result<Shard, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("'{s}': a shard is i/N, such as 0/4"))?;
        let num = |v: &str| {
            v.trim()
                .parse::<usize>()
                .map_err(|_| format!("'{s}': '{v}' is not a whole number"))
        };
        let (index, count) = (num(i)?, num(n)?);
        if count == 0 {
            return Err(format!("'{s}': the number of parts must be at least 1"));
        }
        if index >= count {
            return Err(format!(
                "'{s}': parts are numbered 0 to {}, so {index} is not one of them",
                count - 1
            ));
        }
        Ok(Shard { index, count })
    }

    /// Whether item `k` of the sweep is this part's.
    pub fn owns(&self, k: usize) -> bool {
        k % self.count == self.index
    }

    /// This part's run of `total` items in order, for sweeps along a path
    /// (`fly`, `export`), where each frame follows from the ones before:
    /// a part owns frames `[i·total/N, (i+1)·total/N)` and moves the LOD
    /// scheme through the frames before them without drawing them.
    pub fn run_of(&self, total: usize) -> std::ops::Range<usize> {
        self.index * total / self.count..(self.index + 1) * total / self.count
    }

    /// Whether this is the whole sweep.
    pub fn is_whole(&self) -> bool {
        self.count == 1
    }
}

/// The `shard` object a part adds to its command's JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardTag {
    /// The command (`cracks`, `golden`, `check-gpu`).
    pub command: String,
    /// Which part.
    pub index: usize,
    /// Of how many.
    pub count: usize,
    /// The settings every part of one sweep must share.
    pub of: String,
}

/// `value` with its `shard` tag, when `shard` is a part.
pub fn tag(mut value: Value, command: &str, shard: Shard, of: &str) -> Value {
    if !shard.is_whole() {
        value["shard"] = serde_json::json!(ShardTag {
            command: command.into(),
            index: shard.index,
            count: shard.count,
            of: of.into(),
        });
    }
    value
}

/// The parts' items (in part order) put back in sweep order: item k is
/// item k / N of part k mod N, so part i must hold ⌈(total − i) / N⌉.
pub fn interleave_items<'a, T>(lists: &[&'a [T]]) -> std::result::Result<Vec<&'a T>, String> {
    let n = lists.len();
    let total: usize = lists.iter().map(|l| l.len()).sum();
    for (i, l) in lists.iter().enumerate() {
        let share = (total + n - 1 - i) / n;
        if l.len() != share {
            return Err(format!(
                "part {i} has {} items where its share of {total} is {share}",
                l.len()
            ));
        }
    }
    Ok((0..total).map(|k| &lists[k % n][k / n]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn specs_parse_and_bad_ones_say_why() {
        assert_eq!(Shard::parse("2/5"), Ok(Shard { index: 2, count: 5 }));
        assert_eq!(Shard::parse(" 0 / 1 "), Ok(Shard::WHOLE));
        for (spec, why) in [
            ("0/0", "at least 1"),
            ("5/4", "0 to 3, so 5"),
            ("4/4", "0 to 3, so 4"),
            ("1", "a shard is i/N"),
            ("a/2", "'a' is not a whole number"),
            ("1/b", "'b' is not a whole number"),
            ("-1/2", "'-1' is not a whole number"),
        ] {
            let e = Shard::parse(spec).unwrap_err();
            assert!(e.contains(why) && e.contains(spec), "{spec}: {e}");
        }
    }

    #[test]
    fn parts_own_every_item_once() {
        let n = 3;
        for total in [0usize, 1, 2, 7, 10] {
            let mut owned = vec![0; total];
            let mut runs = vec![];
            for index in 0..n {
                let s = Shard { index, count: n };
                assert!(!s.is_whole());
                for (k, o) in owned.iter_mut().enumerate() {
                    *o += usize::from(s.owns(k));
                }
                runs.push(s.run_of(total));
            }
            assert!(owned.iter().all(|&o| o == 1), "{total}: {owned:?}");
            // The runs are consecutive, cover 0..total and differ by at
            // most one in length.
            assert_eq!(runs[0].start, 0);
            assert_eq!(runs[n - 1].end, total);
            for w in runs.windows(2) {
                assert_eq!(w[0].end, w[1].start, "{total}: {runs:?}");
            }
            let lens: Vec<usize> = runs.iter().map(|r| r.len()).collect();
            let (lo, hi) = (lens.iter().min().unwrap(), lens.iter().max().unwrap());
            assert!(hi - lo <= 1, "{total}: {lens:?}");
        }
        assert_eq!(Shard { index: 1, count: 3 }.run_of(10), 3..6);
        assert_eq!(Shard { index: 2, count: 3 }.run_of(10), 6..10);
        assert_eq!(Shard::WHOLE.run_of(4), 0..4);
        assert!(Shard::WHOLE.is_whole() && Shard::WHOLE.owns(5));
        assert!(!Shard { index: 1, count: 2 }.owns(4));
    }

    #[test]
    fn only_a_part_is_tagged() {
        let v = json!({"scenes": []});
        assert_eq!(tag(v.clone(), "golden", Shard::WHOLE, "x"), v);
        let t = tag(v, "golden", Shard { index: 1, count: 2 }, "x");
        assert_eq!(
            t["shard"],
            json!({"command": "golden", "index": 1, "count": 2, "of": "x"})
        );
    }

    #[test]
    fn items_go_back_in_sweep_order_and_short_parts_are_errors() {
        let (a, b, c) = ([0, 3, 6], [1, 4], [2, 5]);
        let got: Vec<i32> = interleave_items(&[&a[..], &b[..], &c[..]])
            .unwrap()
            .into_iter()
            .copied()
            .collect();
        assert_eq!(got, [0, 1, 2, 3, 4, 5, 6]);
        let e = interleave_items(&[&a[..], &c[..2], &b[..1]]).unwrap_err();
        assert!(
            e.contains("part 0 has 3 items where its share of 6 is 2"),
            "{e}"
        );
        let e = interleave_items(&[&b[..], &a[..]]).unwrap_err();
        assert!(
            e.contains("part 0 has 2 items where its share of 5 is 3"),
            "{e}"
        );
    }
}
