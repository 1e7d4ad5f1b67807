//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod fuzz;
pub mod packs;
use std::collections::HashMap;
use std::sync::Arc;
use terraclip::clipmap::region::Rect;
use terraclip::clipmap::{Clipmap, ClipmapConfig, Layout, MeshVertex};
use terraclip::pyramid::{Filter, Pyramid};
use terraclip::terrain::procedural::Procedural;
use terraclip::terrain::Heightmap;

/// A procedural map of the given size (cell size 1).
pub fn terrain(seed: u64, w: usize, h: usize) -> Heightmap {
    let mut p = Procedural::new(seed, w, h);
    p.wavelength = 64.0;
    p.octaves = 6;
    p.generate().unwrap()
}

/// A clipmap over `map` with `levels` levels (None = max).
pub fn clipmap(map: &Heightmap, n: i64, levels: Option<usize>, layout: Layout) -> Clipmap {
    let count = levels
        .unwrap_or_else(|| terraclip::clipmap::region::max_levels(map.width(), map.height(), n));
    let p = Arc::new(Pyramid::build(map, Filter::SincBlackman { taps: 7 }, count));
    Clipmap::new(
        p,
        ClipmapConfig {
            n,
            levels: Some(count),
            layout,
            ..ClipmapConfig::default()
        },
    )
    .unwrap()
}

/// A small procedural scene (257², n = 15, 96×54) for scheme and survey
/// tests.
pub const SMALL_SCENE: &str = r#"effects = ["morph", "lambert"]
[terrain]
procedural = { seed = 5, width = 257, height = 257, amplitude = 500.0, wavelength = 64.0 }
cell_size = 10.0
[lod]
n = 15
[camera]
position = [600.0, -600.0, 700.0]
look_at = [1500.0, -1500.0, 100.0]
near = 1.0
far = 20000.0
[image]
width = 96
height = 54
"#;

pub fn small_scene() -> terraclip::scene::Scene {
    terraclip::scene::Scene::parse(SMALL_SCENE, "test scene", std::path::Path::new(".")).unwrap()
}

type Key = (i64, i64, u32);

fn key(v: &MeshVertex) -> Key {
    (v.x, v.y, v.zm.to_bits())
}

/// Checks that the mesh is watertight (see `tests/cracks.rs` for what is
/// checked) and returns how many triangles it checked: 0 when no level
/// meets the map, which is then checked to draw nothing. Otherwise a
/// description of the first violation.
pub fn watertight(cm: &Clipmap) -> Result<usize, String> {
    let levels = cm.levels();
    // Footprints draw full rings cut to the usable map; strips' active
    // regions are already within it.
    let outer: Option<Rect> = levels
        .iter()
        .rev()
        .find_map(|l| l.regions.active)
        .and_then(|a| a.intersect(&cm.level_bounds(0)));
    let Some(outer) = outer else {
        let drawn: usize = cm.meshes(None).iter().map(|m| cm.triangles(m).len()).sum();
        return match drawn {
            0 => Ok(0),
            n => Err(format!("{n} triangles drawn, but no level meets the map")),
        };
    };
    let mut triangles = 0usize;
    let mut edges: HashMap<(Key, Key), i32> = HashMap::new();
    let mut area2: i128 = 0;
    for mesh in cm.meshes(None) {
        for t in cm.triangles(&mesh) {
            let [a, b, c] = t;
            let cross = (b.x - a.x) as i128 * (c.y - a.y) as i128
                - (b.y - a.y) as i128 * (c.x - a.x) as i128;
            if cross <= 0 {
                return Err(format!(
                    "non-positive triangle at level {}: {t:?}",
                    mesh.level
                ));
            }
            area2 += cross;
            triangles += 1;
            for (p, q) in [(a, b), (b, c), (c, a)] {
                *edges.entry((key(&p), key(&q))).or_default() += 1;
            }
        }
    }
    if area2 != 2 * outer.cell_area() as i128 {
        return Err(format!(
            "area {} ≠ rendered area {}",
            area2 as f64 / 2.0,
            outer.cell_area()
        ));
    }
    let mut perimeter = 0i64;
    for (&(p, q), &count) in &edges {
        if count != 1 {
            return Err(format!("edge {p:?}→{q:?} used {count} times (overlap)"));
        }
        if edges.contains_key(&(q, p)) {
            continue;
        }
        // Unmatched: must run along the outer perimeter, counter-clockwise in
        // (column, row) space: top eastward, right southward, bottom
        // westward, left northward.
        let ok = (p.1 == outer.y0 && q.1 == outer.y0 && q.0 > p.0)
            || (p.0 == outer.x1 && q.0 == outer.x1 && q.1 > p.1)
            || (p.1 == outer.y1 && q.1 == outer.y1 && q.0 < p.0)
            || (p.0 == outer.x0 && q.0 == outer.x0 && q.1 < p.1);
        if !ok {
            return Err(format!("unmatched interior edge {p:?}→{q:?}"));
        }
        perimeter += (q.0 - p.0).abs() + (q.1 - p.1).abs();
    }
    let want = 2 * (outer.width() + outer.height());
    if perimeter != want {
        return Err(format!("perimeter {perimeter} ≠ {want}"));
    }
    Ok(triangles)
}

/// Copies golden scene `name` (scene, PNG and depth hash) into `dir` as
/// `as_name`, so a command can check that one scene alone.
pub fn copy_golden(name: &str, dir: &std::path::Path, as_name: &str) {
    std::fs::create_dir_all(dir).unwrap();
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("golden");
    for ext in ["toml", "png", "depth"] {
        std::fs::copy(
            src.join(format!("{name}.{ext}")),
            dir.join(format!("{as_name}.{ext}")),
        )
        .unwrap();
    }
}

/// Asserts level `l` of `got` has the bits and no-data flags of `want`
/// over level texels `[x0, y0, x1, y1]` (inclusive, clamped to the level).
pub fn same_window(
    got: &terraclip::pyramid::PyramidLevel,
    want: &terraclip::pyramid::PyramidLevel,
    l: usize,
    [x0, y0, x1, y1]: [i64; 4],
) {
    for y in y0.max(0)..=y1.min(want.height as i64 - 1) {
        for x in x0.max(0)..=x1.min(want.width as i64 - 1) {
            let i = y as usize * want.width + x as usize;
            assert_eq!(
                got.data[i].to_bits(),
                want.data[i].to_bits(),
                "level {l} ({x}, {y})"
            );
            assert_eq!(got.nodata[i], want.nodata[i], "level {l} ({x}, {y})");
        }
    }
}

/// An empty path `name` under the test target's temporary folder `group`
/// (its parent made, anything left there by an earlier run removed).
pub fn fresh_tmp(group: &str, name: &str) -> std::path::PathBuf {
    let d = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.parent().unwrap()).unwrap();
    d
}

/// Whether a GPU command's failure, `stderr`, may be skipped: only where
/// it found no adapter at all and `TERRACLIP_REQUIRE_GPU=1` is not set.
/// Any other failure of `check-gpu` or `bench` fails the test that ran it.
pub fn skippable_gpu_failure(stderr: &str) -> bool {
    std::env::var("TERRACLIP_REQUIRE_GPU").as_deref() != Ok("1") && stderr.contains("adapter found")
}

/// Every file under `roots`, sorted, walking into each folder `enter`
/// allows (the tests that read the repository's own text: layers, docs).
pub fn files_under(
    roots: &[std::path::PathBuf],
    enter: impl Fn(&std::path::Path) -> bool,
) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    let mut dirs = roots.to_vec();
    while let Some(d) = dirs.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if !p.is_dir() {
                files.push(p);
            } else if enter(&p) {
                dirs.push(p);
            }
        }
    }
    files.sort();
    files
}

/// `terraclip ARGS`: exit code (-1 if killed by a signal), stdout, stderr.
pub fn cli(args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// Packs procedural map `p` to `path` with `o`, streamed in bands as
/// `terraclip pack` does.
pub fn pack_procedural(
    p: &terraclip::terrain::procedural::Procedural,
    path: &std::path::Path,
    o: &terraclip::pack::stream::Options,
) {
    let rows = terraclip::terrain::rows::ProceduralRows::new(p.clone()).unwrap();
    terraclip::pack::stream::pack(&rows, path, o, &mut |_, _| {}).unwrap();
}
