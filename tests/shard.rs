//! Sweeps split with `--shard i/N` and joined by `merge` give exactly what
//! one run prints: the crack survey (every scheme, so ROAM's frame-to-frame
//! queues and the clipmap's toroids are in it) and the goldens.

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
    let one = ok(args);
    let mut files = vec![];
    let mut outs = vec![];
    for i in 0..n {
        let spec = format!("{i}/{n}");
        let mut a = args.to_vec();
        a.extend(["--shard", &spec]);
        let out = ok(&a);
        let f = dir.join(format!("part{i}.json"));
        std::fs::write(&f, &out).unwrap();
        files.push(f.to_str().unwrap().to_string());
        outs.push(out);
    }
    let mut m = vec!["merge"];
    m.extend(files.iter().map(String::as_str));
    (one, ok(&m), outs)
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
    assert_eq!(one, merged);
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
    if !probe.status.success() && std::env::var("TERRACLIP_REQUIRE_GPU").as_deref() != Ok("1") {
        eprintln!("skipping: {}", String::from_utf8_lossy(&probe.stderr));
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
