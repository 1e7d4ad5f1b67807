//! Imports run one way. The library's top-level modules stand in layers,
//! lowest first (the table below, drawn in docs/explanation/architecture.md); a module
//! may name (`crate::x`) only modules of lower layers. So there is no
//! import cycle between modules, and no stage reads the scene, a study or a
//! check. A failure names the file and line of each import that runs the
//! wrong way, and the cycle it closes where there is one.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

mod common;

/// The layers, lowest first. A module in none of them fails the test: a
/// new module takes its place here and in docs/explanation/architecture.md.
const LAYERS: &[&[&str]] = &[
    &["error", "cpu", "camera", "names", "shard"],
    &["raster"],
    &["terrain"],
    &["pyramid"],
    &["synthesis", "pack"],
    &["clipmap"],
    &["lod"],
    &["shade"],
    &["frame"],
    &["gpu"],
    &["scene"],
    &["render"],
    &["export"],
    &["check"],
    &["studies"],
];

fn layer(m: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&m))
}

/// Every `crate::NAME` a line of code names (comments left out), with its
/// line number.
fn named_modules(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let code = line.split("//").next().unwrap_or("");
        for (at, _) in code.match_indices("crate::") {
            if code[..at].ends_with(|c: char| c.is_alphanumeric() || c == '_') {
                continue; // `terraclip_crate::`, say
            }
            let name: String = code[at + 7..]
                .chars()
                .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
                .collect();
            if !name.is_empty() {
                out.push((i + 1, name));
            }
        }
    }
    out
}

/// The top-level module of each `.rs` file under `src/` (the binary's
/// `main.rs` and `cli/` stand above the library and are left out).
fn sources(src: &Path) -> Vec<(String, std::path::PathBuf)> {
    common::files_under(&[src.to_path_buf()], |_| true)
        .into_iter()
        .filter(|p| p.extension().is_some_and(|x| x == "rs"))
        .filter_map(|p| {
            let rel = p.strip_prefix(src).unwrap();
            let top = rel.components().next()?.as_os_str().to_string_lossy();
            let top = top.trim_end_matches(".rs").to_string();
            (!["lib", "main", "cli"].contains(&top.as_str())).then_some((top, p))
        })
        .collect()
}

/// A path `from` ->* `to` in `graph`, if any.
fn path(graph: &BTreeMap<String, BTreeSet<String>>, from: &str, to: &str) -> Option<Vec<String>> {
    let mut seen = BTreeSet::new();
    let mut stack = vec![vec![from.to_string()]];
    while let Some(p) = stack.pop() {
        let last = p.last().unwrap().clone();
        if last == to {
            return Some(p);
        }
        if !seen.insert(last.clone()) {
            continue;
        }
        for n in graph.get(&last).into_iter().flatten() {
            let mut q = p.clone();
            q.push(n.clone());
            stack.push(q);
        }
    }
    None
}

/// The import graph's wrong-way edges over `files` (module, file name,
/// text), each with where it is and the cycle it closes.
fn wrong_way(files: &[(&str, &str, &str)]) -> Vec<String> {
    let modules: BTreeSet<&str> = files.iter().map(|(m, _, _)| *m).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut edges = Vec::new();
    for (from, file, text) in files {
        for (line, to) in named_modules(text) {
            if to != *from && modules.contains(to.as_str()) {
                graph
                    .entry(from.to_string())
                    .or_default()
                    .insert(to.clone());
                edges.push((from.to_string(), to, file, line));
            }
        }
    }
    let mut bad = Vec::new();
    for m in &modules {
        if layer(m).is_none() {
            bad.push(format!("module '{m}' is in no layer: give it one"));
        }
    }
    for (from, to, file, line) in edges {
        let (Some(a), Some(b)) = (layer(&from), layer(&to)) else {
            continue;
        };
        if b >= a {
            let cycle = path(&graph, &to, &from)
                .map(|p| format!("; cycle {from} -> {}", p.join(" -> ")))
                .unwrap_or_default();
            bad.push(format!(
                "{file}:{line}: {from} (layer {a}) names {to} (layer {b}){cycle}"
            ));
        }
    }
    bad
}

#[test]
fn imports_run_one_way() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let files: Vec<(String, String, String)> = sources(&src)
        .into_iter()
        .map(|(m, p)| {
            let text = std::fs::read_to_string(&p).unwrap();
            let rel = Path::new("src").join(p.strip_prefix(&src).unwrap());
            (m, rel.display().to_string(), text)
        })
        .collect();
    assert!(files.len() > 80, "{} files read", files.len());
    let files: Vec<(&str, &str, &str)> = files
        .iter()
        .map(|(m, f, t)| (m.as_str(), f.as_str(), t.as_str()))
        .collect();
    let bad = wrong_way(&files);
    assert!(
        bad.is_empty(),
        "imports that run the wrong way:\n{}",
        bad.join("\n")
    );
}

/// The check itself: an upward import is found, named by line, and the
/// cycle it closes is spelt out; an import downward is not reported.
#[test]
fn a_stage_naming_the_scene_is_reported_with_its_cycle() {
    let terrain = "use crate::error::Result;\n// crate::scene in a comment\nfn f(s: &crate::scene::Scene) {}\n";
    let files = [
        ("terrain", "t.rs", terrain),
        ("scene", "s.rs", "use crate::terrain::Spec;\n"),
        ("error", "e.rs", ""),
    ];
    assert_eq!(
        wrong_way(&files),
        ["t.rs:3: terrain (layer 2) names scene (layer 10); cycle terrain -> scene -> terrain"]
    );
    let down = [
        ("scene", "s.rs", "use crate::terrain::Spec;\n"),
        ("terrain", "t.rs", ""),
    ];
    assert!(wrong_way(&down).is_empty());
    let stray = [("widgets", "w.rs", "")];
    assert_eq!(
        wrong_way(&stray),
        ["module 'widgets' is in no layer: give it one"]
    );
}
