//! Sweeps that outgrow one machine: `--shard i/N` runs the i-th of N
//! deterministic parts of a sweep, and [`merge`] joins the parts' JSON into
//! exactly what one run prints, timings aside. No scheduler: GNU parallel,
//! a Slurm job array or a shell loop starts the parts
//! (docs/verify-your-renderer.md shows each).
//!
//! A part owns the items `k` with `k mod N = i` (views, scenes), so the
//! parts take turns through the sweep and each gets a fair share of its
//! slow and fast items. A part's JSON carries a `shard` object: the
//! command, `index`, `count`, and `of`, the settings every part must share.

use crate::error::{Error, Result};
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

fn bad(what: &str, why: impl Into<String>) -> Error {
    Error::value(format!("merge: {what}"), why)
}

/// Joins the parts' JSON (each tagged by [`tag`], named by `names` in
/// errors) into what one run of the sweep prints: every part of one sweep,
/// once each, with the same settings.
pub fn merge(parts: &[(String, Value)]) -> Result<Value> {
    let mut tags = vec![];
    for (name, v) in parts {
        let t: ShardTag = serde_json::from_value(v["shard"].clone())
            .map_err(|_| bad(name, "not a shard's JSON (no 'shard' object)"))?;
        tags.push(t);
    }
    let first = tags.first().ok_or_else(|| bad("parts", "none given"))?;
    for ((name, _), t) in parts.iter().zip(&tags) {
        if (&t.command, t.count, &t.of) != (&first.command, first.count, &first.of) {
            return Err(bad(
                name,
                format!(
                    "part of another sweep ({} {}/{} of '{}', where the first is {} of {} parts of '{}')",
                    t.command, t.index, t.count, t.of, first.command, first.count, first.of
                ),
            ));
        }
    }
    let mut seen = vec![false; first.count];
    for ((name, _), t) in parts.iter().zip(&tags) {
        if std::mem::replace(&mut seen[t.index], true) {
            return Err(bad(name, format!("part {} given twice", t.index)));
        }
    }
    if let Some(i) = seen.iter().position(|s| !s) {
        return Err(bad(
            "parts",
            format!("part {i} of {} is missing", first.count),
        ));
    }
    // In part order, which is what puts the items back in sweep order.
    let mut order: Vec<usize> = (0..parts.len()).collect();
    order.sort_by_key(|&k| tags[k].index);
    let values: Vec<&Value> = order.iter().map(|&k| &parts[k].1).collect();
    let names: Vec<&str> = order.iter().map(|&k| parts[k].0.as_str()).collect();
    match first.command.as_str() {
        "cracks" => Ok(crate::studies::cracks::merge(&values)),
        "golden" | "check-gpu" => interleave(&values, &names, "scenes"),
        c => Err(bad("parts", format!("'{c}' has no merge"))),
    }
}

/// The parts' lists under `key` put back in sweep order (item k is item
/// k / N of part k mod N), under the keys the parts share, which must
/// agree: parts run on different adapters are not one sweep.
fn interleave(parts: &[&Value], names: &[&str], key: &str) -> Result<Value> {
    let lists: Vec<&Vec<Value>> = parts
        .iter()
        .zip(names)
        .map(|(v, name)| {
            v[key]
                .as_array()
                .ok_or_else(|| bad(name, format!("no '{key}' list")))
        })
        .collect::<Result<_>>()?;
    let total: usize = lists.iter().map(|l| l.len()).sum();
    let n = parts.len();
    let mut items = Vec::with_capacity(total);
    for k in 0..total {
        let item = lists[k % n].get(k / n).ok_or_else(|| {
            bad(
                names[k % n],
                format!("part {} has too few items for its share", k % n),
            )
        })?;
        items.push(item.clone());
    }
    let rest = |v: &Value| {
        let mut v = v.clone();
        if let Some(o) = v.as_object_mut() {
            o.remove(key);
            o.remove("shard");
        }
        v
    };
    let mut out = rest(parts[0]);
    for (v, name) in parts.iter().zip(names).skip(1) {
        if rest(v) != out {
            return Err(bad(
                name,
                "its other keys differ from part 0's (another adapter or settings?)",
            ));
        }
    }
    out[key] = Value::Array(items);
    Ok(out)
}
