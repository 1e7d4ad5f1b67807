//! What the documentation promises. The CLI contract: every command's
//! `--json` keys are exactly the keys `docs/reference/cli.md` lists for it. Scripts
//! depend on those keys, so a key added, renamed or dropped without the
//! page fails here, and so does a key the page promises that no run
//! prints. Every relative link in the README and `docs/` resolves, and no
//! page or comment names a session or an issue of the project by number.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

mod common;

/// The keys `docs/reference/cli.md` lists per command: `## \`name\`` headings, then
/// the first column of each table whose header is `JSON key`.
fn documented() -> BTreeMap<String, BTreeSet<String>> {
    let page = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/reference/cli.md"
    ))
    .expect("docs/reference/cli.md");
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut command: Option<String> = None;
    let mut in_keys = false;
    for line in page.lines() {
        if let Some(h) = line.strip_prefix("## ") {
            command = h
                .strip_prefix('`')
                .and_then(|h| h.strip_suffix('`'))
                .map(str::to_string);
            in_keys = false;
            continue;
        }
        if line.starts_with("| JSON key |") {
            in_keys = true;
            continue;
        }
        if !line.starts_with('|') {
            in_keys = false;
            continue;
        }
        let (Some(c), true) = (&command, in_keys) else {
            continue;
        };
        let cell = line
            .trim_start_matches('|')
            .split('|')
            .next()
            .unwrap()
            .trim();
        if cell.starts_with("---") {
            continue;
        }
        let key = cell
            .strip_prefix('`')
            .and_then(|k| k.strip_suffix('`'))
            .unwrap_or_else(|| {
                panic!("docs/reference/cli.md, {c}: key cell {cell:?} is not `code`")
            });
        assert!(
            out.entry(c.clone()).or_default().insert(key.to_string()),
            "docs/reference/cli.md, {c}: {key} listed twice"
        );
    }
    out
}

/// Every key path of a JSON value (`a.b`, `a[].b`), and the paths whose
/// value was null or an empty list, under which nothing more can show.
#[derive(Default)]
struct Keys {
    all: BTreeSet<String>,
    empty: BTreeSet<String>,
}

impl Keys {
    fn add(&mut self, v: &Value, path: &str) {
        match v {
            Value::Object(m) => {
                for (k, x) in m {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    self.all.insert(p.clone());
                    self.add(x, &p);
                }
            }
            Value::Array(a) => {
                if a.is_empty() {
                    self.empty.insert(path.to_string());
                }
                for x in a {
                    self.add(x, &format!("{path}[]"));
                }
            }
            Value::Null => {
                self.empty.insert(path.to_string());
            }
            _ => {}
        }
    }

    /// Whether `path` lies under a null or an empty list, so its absence
    /// says nothing.
    fn hidden(&self, path: &str) -> bool {
        path.char_indices()
            .filter(|&(i, c)| c == '.' || (c == '[' && path[i..].starts_with("[]")))
            .any(|(i, _)| self.empty.contains(&path[..i]))
    }
}

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_terraclip"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

/// Runs `terraclip ARGS --json` and returns its object, or the error text
/// when it failed.
fn json(args: &[&str]) -> Result<Value, String> {
    let out = bin()
        .args(args)
        .arg("--json")
        .output()
        .expect("run terraclip");
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    serde_json::from_slice(&out.stdout).map_err(|e| {
        format!(
            "terraclip {}: stdout is not one JSON object ({e}): {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stdout)
        )
    })
}

/// [`json`] of a run that may fail (`compare` exits non-zero on a
/// mismatch): its JSON either way, so a failing run's keys are checked too.
fn json_any(args: &[&str]) -> Result<Value, String> {
    let out = bin()
        .args(args)
        .arg("--json")
        .output()
        .expect("run terraclip");
    if out.status.code().is_none() {
        return Err(format!("terraclip {}: killed by a signal", args.join(" ")));
    }
    serde_json::from_slice(&out.stdout).map_err(|e| {
        format!(
            "terraclip {}: stdout is not one JSON object ({e}): {}; {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-cli-contract-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// The benchmark's scene with a lazy pyramid, so the lazy keys show.
fn lazy_scene() -> PathBuf {
    let scene = terraclip::scene::BENCH_SCENE
        .replace(
            "filter = \"sinc-blackman\"",
            "filter = \"sinc-blackman\"\nlazy = true\nbudget = 20000",
        )
        .replace("[shading]\n", "[shading]\nheight_range = [-300.0, 300.0]\n");
    assert!(scene.contains("height_range"));
    assert!(scene.contains("lazy = true"));
    let p = tmp("lazy.toml");
    std::fs::write(&p, scene).unwrap();
    p
}

/// One golden scene in a folder of its own, so `golden` checks one.
fn one_golden() -> PathBuf {
    let d = tmp("golden");
    common::copy_golden("grazing-horizon", &d, "g");
    d
}

#[test]
fn every_json_key_is_in_docs_cli_md() {
    let docs = documented();
    let s = |p: &PathBuf| p.to_str().unwrap().to_string();
    let (lazy, golden) = (s(&lazy_scene()), s(&one_golden()));
    let (png, diagram) = (s(&tmp("r.png")), s(&tmp("d.png")));
    let tradeoff_out = s(&tmp("tradeoff"));
    let pack = s(&tmp("j.tcz"));
    let unpacked = s(&tmp("u.png"));
    let jacksboro = "tests/data/jacksboro_16.png";
    // A pack to render from, decoded tile by tile (the `lazy.tiles_*` keys).
    let render_pack = s(&tmp("render.tcz"));
    {
        use terraclip::pack::stream;
        let src = terraclip::terrain::rows::open(std::path::Path::new(jacksboro)).unwrap();
        let o = stream::Options::new(1.0, 64, Default::default(), "jacksboro");
        stream::pack(
            src.as_ref(),
            std::path::Path::new(&render_pack),
            &o,
            &mut |_, _| {},
        )
        .unwrap();
    }
    // An export to compare with: its own colour and depth pass.
    let (golden_pack, export_dir) = (s(&tmp("pack")), s(&tmp("export")));
    let export_part = s(&tmp("export-part"));
    let quick_tradeoff = [
        "tradeoff",
        "--quick",
        "--size",
        "32x18",
        "--path-frames",
        "2",
    ];
    let (one_frame, compare_out) = (s(&tmp("one-frame")), s(&tmp("compare")));
    let (one_frame_png, one_frame_depth) = (
        format!("{one_frame}/colour.png"),
        format!("{one_frame}/depth.f32"),
    );
    json(&[
        "export",
        "golden/level-tint.toml",
        "--size",
        "64x36",
        "--out",
        &one_frame,
    ])
    .unwrap();
    // Another scene's frame at the same size: a comparison that fails, so
    // the keys of a mismatch (`worst` and its fields) are printed.
    let other = s(&tmp("other-frame"));
    json(&[
        "export",
        "golden/wireframe.toml",
        "--size",
        "64x36",
        "--out",
        &other,
    ])
    .unwrap();
    let (other_png, other_depth) = (format!("{other}/colour.png"), format!("{other}/depth.f32"));
    // Each command's runs: together they print every key the page lists.
    let runs: Vec<(&str, Vec<Vec<&str>>)> = vec![
        (
            "render",
            vec![
                vec!["render", "--size", "48x27", "-o", &png],
                vec!["render", &lazy, "--size", "48x27", "-o", &png],
                vec![
                    "render",
                    "golden/synthesis-close.toml",
                    "--size",
                    "48x27",
                    "-o",
                    &png,
                ],
                vec![
                    "render",
                    "--heightmap",
                    &render_pack,
                    "--size",
                    "48x27",
                    "-o",
                    &png,
                ],
            ],
        ),
        (
            "golden",
            vec![
                vec!["golden", &golden],
                vec!["golden", &golden, "--export", &golden_pack],
                vec!["golden", &golden, "--shard", "0/2"],
            ],
        ),
        (
            "export",
            vec![
                vec!["export", "--size", "48x27", "--out", &export_dir],
                vec![
                    "export",
                    "--size",
                    "32x18",
                    "--frames",
                    "2",
                    "--shard",
                    "1/2",
                    "--out",
                    &export_part,
                ],
            ],
        ),
        (
            "compare",
            vec![vec![
                "compare",
                &one_frame,
                "--image",
                &one_frame_png,
                "--depth",
                &one_frame_depth,
                "--out",
                &compare_out,
            ]]
            .into_iter()
            // Failing runs, one per mode (FLIP compares colour alone).
            .chain(["exact", "tiered", "flip"].map(|mode| {
                let mut a = vec!["compare", &one_frame, "--image", &other_png];
                if mode != "flip" {
                    a.extend(["--depth", &other_depth]);
                }
                a.extend(["--mode", mode]);
                a
            }))
            .collect(),
        ),
        (
            "check-gpu",
            vec![
                vec!["check-gpu", &lazy, "--frames", "2", "--out", &tradeoff_out],
                vec![
                    "check-gpu",
                    "golden/synthesis-close.toml",
                    "--update",
                    "gpu",
                    "--frames",
                    "2",
                    "--out",
                    &tradeoff_out,
                ],
                vec![
                    "check-gpu",
                    "golden/wireframe.toml",
                    "golden/morph-on.toml",
                    "--shard",
                    "1/2",
                    "--out",
                    &tradeoff_out,
                ],
            ],
        ),
        (
            "bench",
            vec![
                vec![
                    "bench",
                    "--frames",
                    "1",
                    "--repeats",
                    "1",
                    "--size",
                    "32x18",
                ],
                vec![
                    "bench",
                    "golden/synthesis-close.toml",
                    "--update",
                    "--frames",
                    "2",
                    "--size",
                    "32x18",
                ],
            ],
        ),
        (
            "tradeoff",
            vec![
                [
                    &quick_tradeoff[..],
                    &["--heightmap", jacksboro, "--out", &tradeoff_out],
                ]
                .concat(),
                [&quick_tradeoff[..], &["--shard", "5/6"]].concat(),
            ],
        ),
        (
            "fly",
            vec![
                vec!["fly", "--frames", "2", "--size", "32x18"],
                vec!["fly", "--frames", "2", "--size", "32x18", "--shard", "1/2"],
            ],
        ),
        (
            "cracks",
            vec![
                vec!["cracks", "--views", "2", "--size", "32x20", "--lod", "all"],
                vec![
                    "cracks", "--views", "2", "--size", "32x20", "--shard", "1/2",
                ],
            ],
        ),
        (
            "height",
            vec![vec![
                "height",
                "--size",
                "48x27",
                "--at",
                "6400,-6600",
                "--at",
                "1e9,1e9",
                "--ray",
                "5120,-5120,900,0.5,-0.6,-0.3",
            ]],
        ),
        (
            "scaling",
            vec![vec![
                "scaling",
                "--sizes",
                "128,256",
                "--n",
                "15",
                "--levels",
                "2",
                "--frames",
                "1",
                "--brute-max",
                "128",
                "--update-n",
                "15",
                "--update-levels",
                "2",
                "--update-repeats",
                "1",
                "--first-n",
                "15",
                "--first-budget",
                "5000",
            ]],
        ),
        (
            "pack",
            vec![vec!["pack", jacksboro, "-o", &pack, "--max-error", "1"]],
        ),
        ("info", vec![vec!["info", jacksboro], vec!["info", &pack]]),
        (
            "unpack",
            vec![vec![
                "unpack",
                &pack,
                "--level",
                "1",
                "--window",
                "2,3,40,30",
                "-o",
                &unpacked,
            ]],
        ),
        (
            "synthesis",
            vec![vec!["synthesis", jacksboro, "--factor", "4"]],
        ),
        (
            "diagram",
            vec![vec!["diagram", "--size", "64", "-o", &diagram]],
        ),
    ];
    let listed: BTreeSet<&str> = runs.iter().map(|(c, _)| *c).collect();
    let pages: BTreeSet<&str> = docs.keys().map(String::as_str).collect();
    assert_eq!(
        listed, pages,
        "commands run here against commands in docs/reference/cli.md"
    );

    let mut problems = Vec::new();
    for (command, args) in &runs {
        let mut keys = Keys::default();
        let mut skipped = false;
        for a in args {
            let run = if *command == "compare" {
                json_any
            } else {
                json
            };
            match run(a) {
                Ok(v) => {
                    // The other scene's frame must fail, in every mode.
                    if a.contains(&other_png.as_str()) {
                        assert_eq!(v["pass"], false, "{a:?}: {v}");
                    }
                    keys.add(&v, "")
                }
                Err(e)
                    if matches!(*command, "check-gpu" | "bench")
                        && common::skippable_gpu_failure(&e) =>
                {
                    eprintln!("{command}: skipped, no GPU adapter ({})", e.trim());
                    skipped = true;
                }
                Err(e) => panic!("terraclip {} --json failed: {e}", a.join(" ")),
            }
        }
        if skipped {
            continue;
        }
        let doc = &docs[*command];
        for k in keys.all.difference(doc) {
            problems.push(format!(
                "{command}: prints `{k}`, which docs/reference/cli.md does not list"
            ));
        }
        for k in doc.difference(&keys.all) {
            if !keys.hidden(k) {
                problems.push(format!(
                    "{command}: docs/reference/cli.md lists `{k}`, which no run printed"
                ));
            }
        }
        eprintln!(
            "{command}: {} keys printed, {} documented",
            keys.all.len(),
            doc.len()
        );
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The parser above must see a key that is missing from the page, or the
/// test would pass on an empty page.
#[test]
fn the_page_lists_the_keys_of_every_command() {
    let docs = documented();
    assert_eq!(docs.len(), 16, "{:?}", docs.keys().collect::<Vec<_>>());
    assert!(docs["render"].contains("non_finite.clip"));
    assert!(docs["check-gpu"].contains("scenes[].unmatched_example.a_rgba"));
    assert!(docs["scaling"].contains("update.walks[].overheads"));
    assert!(docs["synthesis"].contains("subdivided.slope_ks"));
    let total: usize = docs.values().map(BTreeSet::len).sum();
    assert!(total > 200, "{total} keys");
    let mut k = Keys::default();
    k.add(
        &serde_json::json!({"a": null, "b": [], "c": [{"d": 1}]}),
        "",
    );
    assert!(k.hidden("a.x") && k.hidden("b[].x") && !k.hidden("c[].e") && !k.hidden("a"));
}

/// GitHub's anchor for a heading: lower case, punctuation other than `-`
/// and `_` dropped, spaces as `-`.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, '-' | '_' | ' '))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

fn anchors(page: &str) -> BTreeSet<String> {
    let mut fenced = false;
    let mut out = BTreeSet::new();
    for line in page.lines() {
        if line.starts_with("```") {
            fenced = !fenced;
        } else if !fenced && line.starts_with('#') {
            out.insert(anchor(line.trim_start_matches('#')));
        }
    }
    out
}

/// Relative links `[text](path#anchor)` of a Markdown page.
fn links(page: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = page;
    while let Some(i) = rest.find("](") {
        rest = &rest[i + 2..];
        let end = rest.find(')').unwrap_or(rest.len());
        let target = &rest[..end];
        if !target.contains("://") && !target.contains(char::is_whitespace) {
            out.push(target.to_string());
        }
    }
    out
}

#[test]
fn every_link_in_the_docs_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut pages = vec![root.join("README.md")];
    // docs/ and its folders (tutorials, how-to, reference, explanation).
    pages.extend(
        common::files_under(&[root.join("docs")], |_| true)
            .into_iter()
            .filter(|p| p.extension().is_some_and(|x| x == "md")),
    );
    assert!(pages.len() > 20, "{} pages", pages.len());
    let mut checked = 0;
    let mut broken = Vec::new();
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for link in links(&text) {
            let (file, frag) = link.split_once('#').unwrap_or((&link, ""));
            let target = if file.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(file)
            };
            checked += 1;
            if !target.exists() {
                broken.push(format!("{}: {link}: no such file", page.display()));
            } else if !frag.is_empty() && target.extension().is_some_and(|x| x == "md") {
                let t = std::fs::read_to_string(&target).unwrap();
                if !anchors(&t).contains(frag) {
                    broken.push(format!("{}: {link}: no such heading", page.display()));
                }
            }
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
    // The README alone links every page of docs/.
    assert!(checked >= 30, "{checked} links checked");
    assert_eq!(anchor("Hard cases we test"), "hard-cases-we-test");
    assert_eq!(anchor("`render`"), "render");
}

/// Where `text` names a piece of the project's own history: a word from
/// `words` followed by a number (`session 31`, `session-31`, `issue #7`).
fn history_refs(text: &str, words: &[&str]) -> Vec<String> {
    let lower = text.to_lowercase();
    let mut found = Vec::new();
    for w in words {
        for (at, _) in lower.match_indices(w) {
            let before = lower[..at].chars().next_back();
            // Another project's issues are citations: "wgpu issues #1574".
            let cited = ["wgpu ", "naga ", "mesa ", "gfx-rs "]
                .iter()
                .any(|p| lower[..at].ends_with(p));
            if before.is_some_and(|c| c.is_alphanumeric()) || cited {
                continue;
            }
            let rest = lower[at + w.len()..].trim_start_matches([' ', '-', '#', 's']);
            if rest.starts_with(|c: char| c.is_ascii_digit()) {
                let line = lower[..at].matches('\n').count() + 1;
                let end = (at + w.len() + 6).min(text.len());
                found.push(format!("line {line}: {}", text.get(at..end).unwrap_or(w)));
            }
        }
    }
    found
}

/// Pages and comments read as a manual: the history of the work belongs in
/// `docs/changelog.md`'s topics and the git log, so no page of `docs/`,
/// the README, nor any source, test, bench, example or CI script names a
/// session or an issue by number.
#[test]
fn no_page_or_comment_names_a_session_or_an_issue() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // Spelt in pieces so this file does not name them itself.
    let words = [["ses", "sion"].concat(), ["iss", "ue"].concat()];
    let words: Vec<&str> = words.iter().map(String::as_str).collect();
    assert_eq!(
        history_refs(
            "See Session 12, the session-31 decoder and issue #7.",
            &words
        )
        .len(),
        3
    );
    assert!(history_refs("a session of 3 frames; 2 issues", &words).is_empty());
    assert!(history_refs("wgpu issues #1574 and #1614", &words).is_empty());
    let roots = ["docs", "src", "tests", "benches", "examples", ".ci"].map(|d| root.join(d));
    let text_file = |p: &PathBuf| {
        p.extension().is_none_or(|x| {
            ["md", "rs", "py", "sh", "toml", "wgsl"].contains(&x.to_str().unwrap_or(""))
        })
    };
    let mut files = vec![root.join("README.md")];
    files.extend(
        common::files_under(&roots, |d| {
            !d.ends_with("data") && !d.ends_with("__pycache__")
        })
        .into_iter()
        .filter(text_file),
    );
    let mut named = Vec::new();
    for f in &files {
        let Ok(text) = std::fs::read_to_string(f) else {
            continue;
        };
        // This file spells the patterns out in its own examples.
        if f.ends_with("tests/docs.rs") {
            continue;
        }
        for r in history_refs(&text, &words) {
            named.push(format!("{}: {r}", f.strip_prefix(root).unwrap().display()));
        }
    }
    assert!(files.len() > 100, "{} files read", files.len());
    assert!(named.is_empty(), "{}", named.join("\n"));
}
