//! `merge`: joins the JSON of a sweep's parts (`--shard i/N`) into what one
//! run prints. It sits above the studies it dispatches to (`cracks`,
//! `tradeoff`, `fly`) and `export`, which know only [`crate::shard::Shard`]: none of them
//! imports this module.

use crate::error::{Error, Result};
use crate::shard::{interleave_items, ShardTag};
use serde::Serialize;
use serde_json::Value;
use std::path::Path;

fn bad(what: &str, why: impl Into<String>) -> Error {
    Error::value(format!("merge: {what}"), why)
}

/// Joins the parts' JSON (each tagged by [`crate::shard::tag`], named by `names` in
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
    // A tag is read from a file: its numbers are checked before they size
    // or index anything.
    for ((name, _), t) in parts.iter().zip(&tags) {
        if t.index >= t.count {
            return Err(bad(
                name,
                format!("part {} of {} parts does not exist", t.index, t.count),
            ));
        }
    }
    let mut seen = vec![false; first.count.min(parts.len())];
    for ((name, _), t) in parts.iter().zip(&tags) {
        match seen.get_mut(t.index) {
            Some(s) if *s => return Err(bad(name, format!("part {} given twice", t.index))),
            Some(s) => *s = true,
            None => {}
        }
    }
    if let Some(i) = (0..first.count).find(|&i| !seen.get(i).copied().unwrap_or(false)) {
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
        ("cracks", None) => to_value(
            &crate::studies::cracks::merge(&typed(&values, &names)?)
                .map_err(|why| bad("parts", why))?,
        ),
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
        ("export", Some(dir)) => {
            let written: Vec<crate::export::Written> = typed(&values, &names)?;
            // The folder a part names is read from the part's file: where
            // it is not a folder, the part file is what is wrong.
            for (w, name) in written.iter().zip(&names) {
                if !w.dir.is_dir() {
                    return Err(bad(
                        name,
                        format!(
                            "dir '{}' is not a folder (the folder this part wrote)",
                            w.dir.display()
                        ),
                    ));
                }
            }
            to_value(&crate::export::join(&written, &names, dir)?)
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shard::{tag, Shard};
    use serde_json::json;

    /// Part `index` of `count` of a golden sweep holding `scenes`.
    fn golden(index: usize, count: usize, scenes: &[&str], adapter: &str) -> (String, Value) {
        let v = json!({"adapter": adapter, "scenes": scenes});
        let s = Shard { index, count };
        (format!("p{index}"), tag(v, "golden", s, "goldens"))
    }

    fn err(parts: &[(String, Value)], dir: Option<&Path>) -> String {
        merge(parts, dir).unwrap_err().to_string()
    }

    #[test]
    fn merges_interleave_and_refuse_what_is_not_one_sweep() {
        let parts = [
            golden(1, 2, &["b", "d"], "x"),
            golden(0, 2, &["a", "c", "e"], "x"),
        ];
        let m = merge(&parts, None).unwrap();
        assert_eq!(
            m,
            json!({"adapter": "x", "scenes": ["a", "b", "c", "d", "e"]})
        );
        let other_adapter = [golden(0, 2, &["a"], "x"), golden(1, 2, &["b"], "y")];
        assert!(err(&other_adapter, None).contains("p1: its other keys differ"));
        let twice = [golden(0, 2, &["a"], "x"), golden(0, 2, &["a"], "x")];
        assert!(err(&twice, None).contains("part 0 given twice"));
        let missing = [golden(1, 3, &["b"], "x"), golden(0, 3, &["a"], "x")];
        assert!(err(&missing, None).contains("part 2 of 3 is missing"));
        let other_count = [golden(0, 2, &["a"], "x"), golden(1, 3, &["b"], "x")];
        assert!(err(&other_count, None).contains("p1: part of another sweep"));
        let untagged = [
            golden(0, 2, &["a"], "x"),
            ("w".into(), json!({"scenes": []})),
        ];
        assert!(err(&untagged, None).contains("w: not a shard's JSON"));
        assert!(err(&[], None).contains("none given"));
        let dir = Path::new("/nonexistent/terraclip-merge");
        assert!(err(&parts, Some(dir)).contains("golden's parts have no files to join"));
        let unknown = [
            (
                "u".into(),
                tag(json!({}), "render", Shard { index: 0, count: 2 }, ""),
            ),
            (
                "v".into(),
                tag(json!({}), "render", Shard { index: 1, count: 2 }, ""),
            ),
        ];
        assert!(err(&unknown, None).contains("'render' has no merge"));
        let two = |command: &str, v: Value| {
            let p = |i| {
                (
                    format!("{command}{i}"),
                    tag(v.clone(), command, Shard { index: i, count: 2 }, ""),
                )
            };
            [p(0), p(1)]
        };
        let export = two("export", json!({}));
        assert!(err(&export, None).contains("name the folder to join them into"));
        let bad_fly = two("f", json!({"lod": 3}));
        assert!(err(&bad_fly, None).contains("'f' has no merge"));
        let bad_fly = two("fly", json!({"lod": 3}));
        assert!(err(&bad_fly, None).contains("fly0: not what its command prints"));
        let bad_tradeoff = two("tradeoff", json!({"rows": 1}));
        assert!(err(&bad_tradeoff, None).contains("tradeoff0: not what its command prints"));
        let bad_cracks = two("cracks", json!({"views": "x"}));
        assert!(err(&bad_cracks, None).contains("cracks0: not what its command prints"));
    }

    #[test]
    fn tag_numbers_from_a_file_neither_index_nor_size_anything() {
        // Tags as a hand-edited file may hold them.
        let edited = |index: usize, count: usize| {
            let mut p = golden(0, 2, &["a"], "x");
            p.1["shard"]["index"] = index.into();
            p.1["shard"]["count"] = count.into();
            (format!("p{index}"), p.1)
        };
        let past = [edited(0, 2), edited(5, 2)];
        assert!(err(&past, None).contains("p5: part 5 of 2 parts does not exist"));
        // A count of 2^40 would be a 1 TB vector of flags.
        let huge = [edited(0, 1 << 40), edited(1, 1 << 40)];
        assert!(err(&huge, None).contains("part 2 of 1099511627776 is missing"));
        let none = [edited(0, 0), edited(0, 0)];
        assert!(err(&none, None).contains("part 0 of 0 parts does not exist"));
    }

    #[test]
    fn a_list_key_that_is_missing_is_named() {
        let parts = [
            golden(0, 2, &["a"], "x"),
            (
                "p1".into(),
                tag(
                    json!({"adapter": "x"}),
                    "golden",
                    Shard { index: 1, count: 2 },
                    "goldens",
                ),
            ),
        ];
        assert!(err(&parts, None).contains("p1: no 'scenes' list"));
    }
}
