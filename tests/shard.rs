//! Sweeps split with `--shard i/N` and joined by `merge` give exactly what
//! one run prints, timings aside: the crack survey (every scheme, so ROAM's
//! frame-to-frame queues and the clipmap's toroids are in it), the goldens,
//! check-gpu, the tradeoff study, a flight and a path's export.

mod common;

use std::path::Path;
use std::process::Command;

fn terraclip(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_terraclip"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let o = terraclip(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

/// Runs `args` whole and in `n` shards, merges the shards, and returns
/// (one run, merged, the shards' outputs).
fn sharded(args: &[&str], n: usize, dir: &Path) -> (String, String, Vec<String>) {
    sharded_with(args, n, dir, |_| vec![], &[])
}

/// [`sharded`], where the one run also gets `run_args(None)`, part i
/// `run_args(Some(i))`, and the merge `merge_args`.
fn sharded_with(
    args: &[&str],
    n: usize,
    dir: &Path,
    run_args: impl Fn(Option<usize>) -> Vec<String>,
    merge_args: &[&str],
) -> (String, String, Vec<String>) {
    let whole = run_args(None);
    let mut a = args.to_vec();
    a.extend(whole.iter().map(String::as_str));
    let one = ok(&a);
    let mut files = vec![];
    let mut outs = vec![];
    for i in 0..n {
        let spec = format!("{i}/{n}");
        let extra = run_args(Some(i));
        let mut a = args.to_vec();
        a.extend(["--shard", &spec]);
        a.extend(extra.iter().map(String::as_str));
        let out = ok(&a);
        let f = dir.join(format!("part{i}.json"));
        std::fs::write(&f, &out).unwrap();
        files.push(f.to_str().unwrap().to_string());
        outs.push(out);
    }
    let mut m = vec!["merge"];
    m.extend(files.iter().map(String::as_str));
    m.extend(merge_args);
    (one, ok(&m), outs)
}

/// `json` with every timing (a key ending in "ms", or `ms_…`), the
/// process's resource use (`rusage`), the peak
/// memory and the fields worked out from timings (tradeoff's front and
/// budget) taken out, at any depth.
fn untimed(json: &str) -> serde_json::Value {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(o) => {
                o.retain(|k, _| {
                    !(k.ends_with("ms")
                        || k.starts_with("ms_")
                        || [
                            "peak_rss_bytes",
                            "rusage",
                            "pareto",
                            "budget_ms",
                            "best_in_budget",
                            // A flight's budget, worked out from its timings.
                            "texels_per_frame",
                            "texels_per_frame_at_10_percent",
                        ]
                        .contains(&k.as_str()))
                });
                o.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut v: serde_json::Value = serde_json::from_str(json).unwrap();
    strip(&mut v);
    v
}

/// A CSV's rows with the columns named in `keep` only.
fn columns(csv: &str, keep: &[&str]) -> Vec<Vec<String>> {
    let mut lines = csv.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let idx: Vec<usize> = keep
        .iter()
        .map(|k| head.iter().position(|h| h == k).unwrap())
        .collect();
    lines
        .map(|l| {
            // Configs are quoted and hold no commas.
            let cells: Vec<&str> = l.split(',').collect();
            idx.iter().map(|&i| cells[i].to_string()).collect()
        })
        .collect()
}

/// The `scene` of each of a JSON's `scenes`, in order.
fn scene_names(json: &str) -> Vec<String> {
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    v["scenes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["scene"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn three_crack_survey_shards_merged_equal_one_run() {
    let dir = common::fresh_tmp("shard", "cracks");
    std::fs::create_dir_all(&dir).unwrap();
    // Shards also move each scheme through the views they do not own, so
    // schemes with frame-to-frame state are where one run has them; on
    // these views, leaving that out changes nothing this JSON shows.
    let args = [
        "cracks", "--views", "9", "--lod", "all", "--size", "96x60", "--json",
    ];
    let (one, merged, parts) = sharded(&args, 3, &dir);
    assert_eq!(untimed(&one), untimed(&merged));
    let v: serde_json::Value = serde_json::from_str(&one).unwrap();
    // The annulus cracks on purpose, so the worst view is a real choice.
    assert!(v["crack_pixels"].as_u64().unwrap() > 0, "{v}");
    assert_eq!(v["views_surveyed"], 9);
    for (i, p) in parts.iter().enumerate() {
        let p: serde_json::Value = serde_json::from_str(p).unwrap();
        assert_eq!(p["shard"]["index"], i);
        assert_eq!(p["views_surveyed"], 3);
    }
}

/// A survey whose schemes keep state that changes what they draw: the
/// clipmap under a texel budget (levels whose update is cut short wait,
/// and what waits depends on every frame before) and ROAM (its split and
/// merge queues). A part must move each scheme through the views it does
/// not own; one that skipped them would meet its views in another state,
/// and its crack and missing-terrain counts would differ from one run's.
#[test]
fn stateful_crack_survey_shards_merged_equal_one_run() {
    let dir = common::fresh_tmp("shard", "cracks-stateful");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("budget.toml");
    let text = include_str!("../benches/scenes/bench.toml")
        .replace("[lod]\n", "[lod]\ntexel_budget = 3000\n");
    assert!(text.contains("texel_budget = 3000"));
    std::fs::write(&scene, text).unwrap();
    let s = scene.to_str().unwrap();
    let args = [
        "cracks",
        s,
        "--views",
        "9",
        "--lod",
        "clipmap,roam",
        "--size",
        "96x60",
        "--json",
    ];
    let (one, merged, _) = sharded(&args, 3, &dir);
    assert_eq!(untimed(&one), untimed(&merged));
    let v: serde_json::Value = serde_json::from_str(&one).unwrap();
    assert_eq!(v["views_surveyed"], 9);
    for s in v["schemes"].as_array().unwrap() {
        assert!(s["triangles"].as_u64().unwrap() > 0, "{s}");
    }
}

#[test]
fn three_golden_shards_merged_equal_one_run() {
    let dir = common::fresh_tmp("shard", "golden");
    let goldens = dir.join("g");
    for (name, as_name) in [
        ("wireframe", "a"),
        ("morph-on", "b"),
        ("level-tint", "b-c"),
        ("grazing-horizon", "b2"),
    ] {
        common::copy_golden(name, &goldens, as_name);
    }
    std::fs::create_dir_all(&dir).unwrap();
    let g = goldens.to_str().unwrap();
    let (one, merged, _) = sharded(&["golden", g, "--json"], 3, &dir);
    assert_eq!(one, merged);
    let names = scene_names(&one);
    assert_eq!(names, ["a", "b-c", "b", "b2"]);
}

#[test]
fn bad_shards_and_merges_are_errors() {
    for spec in ["0/0", "5/4", "4/4", "1", "a/2", "-1/2"] {
        let o = terraclip(&["cracks", "--views", "2", "--shard", spec]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains("--shard") && !err.contains("panicked"),
            "{spec}: {err}"
        );
    }
    let o = terraclip(&["golden", "--shard", "0/2", "--export", "/tmp/never"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("does not take --shard"));
    let dir = common::fresh_tmp("shard", "bad-merge");
    std::fs::create_dir_all(&dir).unwrap();
    let part = |i: usize, n: usize, views: &str| {
        let spec = format!("{i}/{n}");
        let out = ok(&[
            "cracks", "--views", views, "--size", "48x30", "--shard", &spec, "--json",
        ]);
        let f = dir.join(format!("p{i}of{n}v{views}.json"));
        std::fs::write(&f, out).unwrap();
        f.to_str().unwrap().to_string()
    };
    let (a, b) = (part(0, 2, "2"), part(1, 2, "2"));
    let other = part(1, 2, "3");
    let whole = dir.join("whole.json");
    std::fs::write(
        &whole,
        ok(&["cracks", "--views", "2", "--size", "48x30", "--json"]),
    )
    .unwrap();
    let garbage = dir.join("garbage.json");
    std::fs::write(&garbage, "{\"shard\": 7").unwrap();
    for (parts, want) in [
        (vec![a.as_str()], "part 1 of 2 is missing"),
        (vec![a.as_str(), a.as_str()], "part 0 given twice"),
        (vec![a.as_str(), other.as_str()], "part of another sweep"),
        (
            vec![a.as_str(), whole.to_str().unwrap()],
            "not a shard's JSON",
        ),
        (
            vec![a.as_str(), garbage.to_str().unwrap()],
            "garbage.json: not one JSON object",
        ),
    ] {
        let mut args = vec!["merge"];
        args.extend(parts);
        let o = terraclip(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(want) && !err.contains("panicked"),
            "{want}: {err}"
        );
    }
    assert!(terraclip(&["merge", &a, &b]).status.success());
}

/// check-gpu's parts, where an adapter is found (required under
/// `TERRACLIP_REQUIRE_GPU=1`, as in CI).
#[test]
fn three_check_gpu_shards_merged_equal_one_run() {
    let dir = common::fresh_tmp("shard", "check-gpu");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("images");
    let out = out.to_str().unwrap();
    let args = [
        "check-gpu",
        "golden/wireframe.toml",
        "golden/morph-on.toml",
        "golden/level-tint.toml",
        "golden/grazing-horizon.toml",
        "--frames",
        "2",
        "--out",
        out,
        "--json",
    ];
    let probe = terraclip(&args);
    let err = String::from_utf8_lossy(&probe.stderr);
    if !probe.status.success() && common::skippable_gpu_failure(&err) {
        eprintln!("skipping: {err}");
        return;
    }
    let (one, merged, parts) = sharded(&args, 3, &dir);
    assert_eq!(one, merged);
    let names = scene_names(&one);
    assert_eq!(
        names,
        ["wireframe", "morph-on", "level-tint", "grazing-horizon"]
    );
    let p: serde_json::Value = serde_json::from_str(&parts[0]).unwrap();
    assert_eq!(p["scenes"].as_array().unwrap().len(), 2);
}

#[test]
fn three_tradeoff_shards_merged_equal_one_run_and_write_its_csv() {
    let dir = common::fresh_tmp("shard", "tradeoff");
    std::fs::create_dir_all(&dir).unwrap();
    let (one_dir, merged_dir) = (dir.join("one"), dir.join("merged"));
    let args = [
        "tradeoff",
        "--quick",
        "--size",
        "48x27",
        "--path-frames",
        "2",
        "--out",
        one_dir.to_str().unwrap(),
        "--json",
    ];
    let merged_dir_s = merged_dir.to_str().unwrap().to_string();
    let (one, merged, parts) = sharded_with(&args, 3, &dir, |_| vec![], &["--dir", &merged_dir_s]);
    // Timings differ from run to run; everything measured from images does
    // not, ROAM's refinement over frames included.
    assert_eq!(untimed(&one), untimed(&merged));
    let rows = |j: &str| untimed(j)["rows"].as_array().unwrap().len();
    assert_eq!(rows(&one), 18);
    assert_eq!(parts.iter().map(|p| rows(p)).collect::<Vec<_>>(), [6, 6, 6]);
    // The merge's front is the whole sweep's, worked out from its rows.
    let m: serde_json::Value = serde_json::from_str(&merged).unwrap();
    let bf = m["rows"][0]["ms"].as_f64().unwrap();
    assert_eq!(m["rows"][0]["lod"], "brute-force");
    assert_eq!(m["budget_ms"].as_f64().unwrap(), bf / 10.0);
    // The front and the best row within the budget are worked out over
    // all the rows, not taken from the parts.
    let rows = m["rows"].as_array().unwrap();
    let f = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap();
    let eligible = |r: &&serde_json::Value| r["reference"] == "brute-force";
    for r in rows {
        let dominated = rows.iter().filter(eligible).any(|o| {
            let (better_ms, better_e) = (f(o, "ms") <= f(r, "ms"), f(o, "rmse") <= f(r, "rmse"));
            better_ms && better_e && (f(o, "ms") < f(r, "ms") || f(o, "rmse") < f(r, "rmse"))
        });
        let front = eligible(&r) && !dominated;
        assert_eq!(r["pareto"], front, "{r}");
    }
    let best = rows
        .iter()
        .filter(eligible)
        .filter(|r| r["lod"] != "brute-force" && f(r, "ms") <= bf / 10.0)
        .min_by(|a, b| f(a, "rmse").total_cmp(&f(b, "rmse")));
    assert_eq!(
        best.unwrap_or(&serde_json::Value::Null),
        &m["best_in_budget"]
    );
    // A part writes no CSV (its front would be its own); the merge writes
    // the one the whole run writes.
    let keep = [
        "lod",
        "config",
        "rmse",
        "max_abs",
        "depth_m",
        "triangles",
        "popping",
    ];
    let csv = |d: &Path| std::fs::read_to_string(d.join("tradeoff.csv")).unwrap();
    assert_eq!(
        columns(&csv(&one_dir), &keep),
        columns(&csv(&merged_dir), &keep)
    );
    assert!(merged_dir.join("tradeoff.png").is_file());
    assert!(merged_dir.join("tradeoff-low-fov.png").is_file());
}

#[test]
fn three_flight_shards_merged_equal_one_run() {
    let dir = common::fresh_tmp("shard", "fly");
    std::fs::create_dir_all(&dir).unwrap();
    // A texel budget and a pack decoded as the windows reach it: state
    // that carries from frame to frame, which a part rebuilds by moving
    // the clipmap through the frames before its own.
    let scene = std::fs::read_to_string("golden/pack-lossless.toml")
        .unwrap()
        .replace("n = 63", "n = 63\ntexel_budget = 30000")
        .replace(
            "jacksboro-e0.tcz",
            concat!(env!("CARGO_MANIFEST_DIR"), "/golden/jacksboro-e0.tcz"),
        );
    let dir_scene = dir.join("budget.toml");
    std::fs::write(&dir_scene, scene).unwrap();
    let charts = dir.join("charts");
    let charts_s = charts.to_str().unwrap().to_string();
    for (scene, lod) in [
        (dir_scene.to_str().unwrap(), "clipmap"),
        ("golden/morph-on.toml", "roam"),
    ] {
        let args = [
            "fly", scene, "--frames", "8", "--still", "2", "--step", "300", "--size", "64x40",
            "--lod", lod, "--json",
        ];
        let (one, merged, parts) = sharded_with(&args, 3, &dir, |_| vec![], &["--dir", &charts_s]);
        assert_eq!(untimed(&one), untimed(&merged), "{lod}");
        let frames = |j: &str| untimed(j)["frames"].as_array().unwrap().len();
        assert_eq!(
            parts.iter().map(|p| frames(p)).collect::<Vec<_>>(),
            [3, 3, 4]
        );
        let v = untimed(&one);
        let changes: u64 = v["frames"].as_array().unwrap()[1..]
            .iter()
            .map(|f| f["changes"].as_u64().unwrap())
            .sum();
        assert!(changes > 0, "{lod}: {v}");
        assert!(v["popping_max"].as_f64().unwrap() > 0.0, "{lod}: {v}");
    }
    assert!(charts.join("fly-ms.svg").is_file() && charts.join("fly-levels.png").is_file());
}

#[test]
fn three_export_shards_joined_are_one_runs_folder_byte_for_byte() {
    let dir = common::fresh_tmp("shard", "export");
    std::fs::create_dir_all(&dir).unwrap();
    let (one_dir, joined) = (dir.join("one"), dir.join("joined"));
    let joined_s = joined.to_str().unwrap().to_string();
    let args = [
        "export",
        "golden/morph-on.toml",
        "--frames",
        "4",
        "--size",
        "64x40",
        "--json",
    ];
    let part_dir = |i: Option<usize>| {
        let d = i.map_or(one_dir.clone(), |i| dir.join(format!("p{i}")));
        vec!["--out".to_string(), d.to_str().unwrap().to_string()]
    };
    let (one, merged, _) = sharded_with(&args, 3, &dir, part_dir, &["--dir", &joined_s]);
    let without_dir = |j: &str| {
        let mut v: serde_json::Value = serde_json::from_str(j).unwrap();
        v.as_object_mut().unwrap().remove("dir");
        v
    };
    assert_eq!(without_dir(&one), without_dir(&merged));
    let mut files = vec![];
    for e in walk(&one_dir) {
        let rel = e.strip_prefix(&one_dir).unwrap().to_path_buf();
        assert_eq!(
            std::fs::read(&e).unwrap(),
            std::fs::read(joined.join(&rel)).unwrap(),
            "{}",
            rel.display()
        );
        files.push(rel);
    }
    assert_eq!(files.len(), walk(&joined).len());
    assert!(files.len() > 4 * 8, "{files:?}");
    // Joined, it reads as an export of four frames.
    let e = terraclip::export::read(&joined.join("frame-0003")).unwrap();
    assert!(e.frame.triangle_count() > 0);
}

/// Every file under `dir`.
fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = vec![];
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out.sort();
    out
}

#[test]
fn sharded_paths_and_their_merges_refuse_what_cannot_be_joined() {
    let dir = common::fresh_tmp("shard", "path-errors");
    std::fs::create_dir_all(&dir).unwrap();
    let fails = |args: &[&str], want: &str| {
        let o = terraclip(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(want) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    };
    let out = dir.join("x");
    let out = out.to_str().unwrap();
    fails(
        &["export", "--frames", "2", "--out", out, "--shard", "0/3"],
        "would leave parts with none",
    );
    fails(
        &[
            "fly", "--frames", "2", "--out", out, "--gif", "--shard", "0/2",
        ],
        "does not take --shard",
    );
    // Part i of 2 of `args`, its JSON saved as NAMEi.json.
    let part = |args: &[&str], name: &str, i: usize| {
        let spec = format!("{i}/2");
        let mut a = args.to_vec();
        a.extend(["--shard", &spec, "--json"]);
        let f = dir.join(format!("{name}{i}.json"));
        std::fs::write(&f, ok(&a)).unwrap();
        f.to_str().unwrap().to_string()
    };
    let p1 = dir.join("p1");
    let export = |i: usize| {
        let d = dir.join(format!("p{i}"));
        let args = ["export", "--frames", "2", "--size", "32x18", "--out"];
        part(&[&args[..], &[d.to_str().unwrap()]].concat(), "e", i)
    };
    let (e0, e1) = (export(0), export(1));
    fails(&["merge", &e0, &e1], "name the folder to join them into");
    let cracks = ["cracks", "--views", "2", "--size", "32x18"];
    let (c0, c1) = (part(&cracks, "c", 0), part(&cracks, "c", 1));
    fails(&["merge", &c0, &c1, "--dir", out], "have no files to join");
    // A part's folder changed after it was written is found by its hash.
    let colour = p1.join("frame-0001/colour.png");
    let mut bytes = std::fs::read(&colour).unwrap();
    bytes[100] ^= 1;
    std::fs::write(&colour, bytes).unwrap();
    fails(&["merge", &e0, &e1, "--dir", out], "SHA-256 differs");
    assert!(!Path::new(out).exists(), "nothing half-written");
    // A manifest that lists a file outside its folder, with the right
    // length and hash, is refused before anything is read or written.
    std::fs::write(p1.join("frame-0001/colour.png"), {
        let mut b = std::fs::read(&colour).unwrap();
        b[100] ^= 1;
        b
    })
    .unwrap();
    let outside = dir.join("outside.txt");
    std::fs::write(&outside, b"not the export's").unwrap();
    let manifest = p1.join("manifest.json");
    let good = std::fs::read_to_string(&manifest).unwrap();
    let mut m: serde_json::Value = serde_json::from_str(&good).unwrap();
    let entry = |name: &str| {
        let mut e = m["files"][0].clone();
        e["name"] = name.into();
        e["bytes"] = 16.into();
        e["sha256"] = "d56ee6ac92d3c155fa1e66592a1c513c006c2f34353c7d4e6c0a8a861c8ba92c".into();
        e
    };
    for name in [
        "../outside.txt",
        outside.to_str().unwrap(),
        "frame-0001/../../outside.txt",
    ] {
        let mut bad = m.clone();
        bad["files"].as_array_mut().unwrap().push(entry(name));
        std::fs::write(&manifest, bad.to_string()).unwrap();
        fails(
            &["merge", &e0, &e1, "--dir", out],
            "not a path inside the export's folder",
        );
        assert!(!Path::new(out).exists(), "nothing written for {name}");
    }
    m["frames"][0] = "../frame-0001".into();
    std::fs::write(&manifest, m.to_string()).unwrap();
    fails(
        &["merge", &e0, &e1, "--dir", out],
        "not a path inside the export's folder",
    );
    std::fs::write(&manifest, good).unwrap();
    assert_eq!(std::fs::read(&outside).unwrap(), b"not the export's");
}

/// `merge --help` names every command whose own help offers `--shard`, so
/// a user reading it learns every sweep it joins.
#[test]
fn merge_help_names_every_sharded_command() {
    let top = ok(&["--help"]);
    let commands: Vec<&str> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| !["help", "merge"].contains(c))
        .collect();
    assert!(commands.len() > 10, "{commands:?}");
    let sharded: Vec<&str> = commands
        .iter()
        .copied()
        .filter(|c| ok(&[c, "--help"]).contains("--shard"))
        .collect();
    assert!(sharded.len() >= 6, "{sharded:?}");
    let merge = ok(&["merge", "--help"]);
    for c in sharded {
        assert!(
            merge.contains(&format!("`{c}`")),
            "merge --help omits {c}: {merge}"
        );
    }
}
