//! Sweeps that outgrow one machine: `--shard i/N` runs the i-th of N
//! deterministic parts of a sweep, and [`merge`] joins the parts' JSON into
//! exactly what one run prints, timings aside. No scheduler: GNU parallel,
//! a Slurm job array or a shell loop starts the parts
//! (docs/verify-your-renderer.md shows each).
//!
//! A part owns the items `k` with `k mod N = i` (views, scenes, settings),
//! so the parts take turns through the sweep and each gets a fair share of
//! its slow and fast items. Paths (`fly`, `export`) are cut into runs of
//! frames instead ([`Shard::run_of`]): a frame follows from the one before. A part's JSON carries a `shard` object: the
//! command, `index`, `count`, and `of`, the settings every part must share.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::Path;

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

fn bad(what: &str, why: impl Into<String>) -> Error {
    Error::value(format!("merge: {what}"), why)
}

/// Joins the parts' JSON (each tagged by [`tag`], named by `names` in
/// errors) into what one run of the sweep prints: every part of one sweep,
/// once each, with the same settings. With `dir`, also writes there the
/// files one run writes that only the whole sweep can: `tradeoff`'s CSV
/// and charts, `fly`'s charts, and `export`'s folder (which an export's
/// merge needs: its parts are folders).
pub fn merge(parts: &[(String, Value)], dir: Option<&Path>) -> Result<Value> {
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
    let command = first.command.as_str();
    match (command, dir) {
        ("cracks", None) => Ok(crate::studies::cracks::merge(&values)),
        ("golden" | "check-gpu", None) => interleave(&values, &names, "scenes"),
        ("tradeoff", _) => {
            let r = crate::studies::tradeoff::merge(&typed(&values, &names)?)
                .map_err(|why| bad("parts", why))?;
            if let Some(dir) = dir {
                crate::studies::tradeoff::write(&r, dir)?;
            }
            to_value(&r)
        }
        ("fly", _) => {
            let r = crate::studies::fly::merge(&typed(&values, &names)?)
                .map_err(|why| bad("parts", why))?;
            if let Some(dir) = dir {
                crate::studies::fly::write_charts(&r, dir)?;
            }
            to_value(&r)
        }
        ("export", Some(dir)) => to_value(&crate::export::join(&typed(&values, &names)?, dir)?),
        ("export", None) => Err(bad(
            "--dir",
            "an export's parts are folders: name the folder to join them into",
        )),
        (_, Some(_)) => Err(bad(
            "--dir",
            format!("{command}'s parts have no files to join: leave --dir out"),
        )),
        _ => Err(bad("parts", format!("'{command}' has no merge"))),
    }
}

/// The parts' JSON as `T`s (a study's report), their `shard` tags left out.
fn typed<T: serde::de::DeserializeOwned>(values: &[&Value], names: &[&str]) -> Result<Vec<T>> {
    values
        .iter()
        .zip(names)
        .map(|(v, name)| {
            let mut v = (*v).clone();
            if let Some(o) = v.as_object_mut() {
                o.remove("shard");
            }
            serde_json::from_value(v)
                .map_err(|e| bad(name, format!("not what its command prints: {e}")))
        })
        .collect()
}

fn to_value(v: &impl Serialize) -> Result<Value> {
    serde_json::to_value(v).map_err(|e| Error::value("merge", e.to_string()))
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

/// The parts' lists under `key` put back in sweep order
/// ([`interleave_items`]), under the keys the parts share, which must
/// agree: parts run on different adapters are not one sweep.
fn interleave(parts: &[&Value], names: &[&str], key: &str) -> Result<Value> {
    let lists: Vec<&[Value]> = parts
        .iter()
        .zip(names)
        .map(|(v, name)| {
            v[key]
                .as_array()
                .map(Vec::as_slice)
                .ok_or_else(|| bad(name, format!("no '{key}' list")))
        })
        .collect::<Result<_>>()?;
    let items: Vec<Value> = interleave_items(&lists)
        .map_err(|why| bad("parts", why))?
        .into_iter()
        .cloned()
        .collect();
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
