//! Malformed input, ≥ 10,000 cases in one bounded run: valid PNG (8 and
//! 16 bit), TGA, TIFF (f32, u16), ASCII-grid, raw f32 + JSON sidecar files,
//! packs, scene files, exports (one file damaged, the manifest made to
//! match), `compare`'s image and depth inputs and `merge`'s part files are truncated, bit-flipped, given absurd header sizes
//! (decompression bombs), NaN/inf/no-data patterns and wrong types. Every
//! case must either load, or fail with a typed error that names the file;
//! none may panic. A map that loads must hold only finite heights where it
//! has data, with its no-data count equal to its mask; a scene that parses
//! must build and render (at its own 32×24) without a panic, or fail with
//! an error that names it. The seeded run's split of loaded and rejected
//! cases per kind is asserted exactly, so a reader that starts accepting
//! what it used to reject (or the reverse) fails here. The run prints its case count and time (README "Hard
//! cases we test").

mod common;

use common::fuzz::{cli_exits, edit_json, mutate, mutate_text, Rng};
use common::packs::pack_once;
use serde_json::Value;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::Instant;
use terraclip::check::outside::Mode;
use terraclip::scene::Scene;
use terraclip::terrain::Heightmap;

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn png16(path: &Path) {
    image::ImageBuffer::<image::Luma<u16>, _>::from_fn(17, 11, |x, y| {
        image::Luma([(x * 977 + y * 131) as u16])
    })
    .save(path)
    .unwrap();
}

fn seeds(d: &Path) -> Vec<(&'static str, Vec<u8>)> {
    use tiff::encoder::{colortype, TiffEncoder};
    let (w, h) = (9u32, 7u32);
    let mut out = vec![];
    let p = d.join("seed16.png");
    png16(&p);
    out.push(("png", std::fs::read(&p).unwrap()));
    let p = d.join("seed8.png");
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([(x * 20 + y) as u8]))
        .save(&p)
        .unwrap();
    out.push(("png", std::fs::read(&p).unwrap()));
    let p = d.join("seed.tga");
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([(x + y * 9) as u8]))
        .save(&p)
        .unwrap();
    out.push(("tga", std::fs::read(&p).unwrap()));
    let f: Vec<f32> = (0..w * h).map(|i| i as f32 * 0.5).collect();
    let p = d.join("seed.tif");
    let mut enc = TiffEncoder::new(std::fs::File::create(&p).unwrap()).unwrap();
    enc.write_image::<colortype::Gray32Float>(w, h, &f).unwrap();
    out.push(("tif", std::fs::read(&p).unwrap()));
    let u: Vec<u16> = (0..w * h).map(|i| (i * 300) as u16).collect();
    let p = d.join("seed16.tif");
    let mut enc = TiffEncoder::new(std::fs::File::create(&p).unwrap()).unwrap();
    enc.write_image::<colortype::Gray16>(w, h, &u).unwrap();
    out.push(("tif", std::fs::read(&p).unwrap()));
    out
}

/// A 30″ geographic GeoTIFF (EPSG:4326) at 46° N.
fn geotiff_seed(d: &Path) -> Vec<u8> {
    use tiff::encoder::{colortype, TiffEncoder};
    use tiff::tags::Tag;
    let (w, h) = (9u32, 7u32);
    let f: Vec<f32> = (0..w * h).map(|i| i as f32 * 3.0).collect();
    let p = d.join("seed-geo.tif");
    let mut enc = TiffEncoder::new(std::fs::File::create(&p).unwrap()).unwrap();
    let mut img = enc.new_image::<colortype::Gray32Float>(w, h).unwrap();
    let e = img.encoder();
    let arc = 1.0f64 / 120.0;
    e.write_tag(Tag::ModelPixelScaleTag, &[arc, arc, 0.0][..])
        .unwrap();
    e.write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, 10.0, 46.0, 0.0][..])
        .unwrap();
    e.write_tag(
        Tag::GeoKeyDirectoryTag,
        &[1u16, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326][..],
    )
    .unwrap();
    img.write_data(&f).unwrap();
    std::fs::read(&p).unwrap()
}

const ASC: &str = "ncols 4\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 10\nNODATA_value -9999\n1 2 3 4\n5 -9999 7 8\n9 10 11 12\n";
const SIDECAR: &str = r#"{"width": 4, "height": 3, "cell_size_m": {"x": 10.0, "y": 20.0}, "nodata": -32768.0, "raw_offset_m": 100.0, "raw_scale_m_per_unit": 2.0}"#;
const SCENE: &str = r#"effects = ["morph", "lambert", "fog"]
camera = { position = [1300.0, -2300.0, 700.0], look_at = [1500.0, -2500.0, 100.0], near = 1.0, far = 20000.0 }
image = { width = 32, height = 24 }
[terrain]
procedural = { seed = 5, width = 65, height = 65, amplitude = 500.0, wavelength = 64.0 }
cell_size = 10.0
vertical_scale = 1.0
origin = [1000.0, -2000.0]
synthesis = { levels = 2, roughness = 0.8, seed = 3 }
[pyramid]
filter = "sinc-blackman"
[lod]
scheme = "clipmap"
n = 15
layout = "strips"
[gpu]
update = "gpu"
"#;

/// Loads `path`; Ok(true) loaded (and the map is sound), Ok(false) clean
/// error naming the file, Err on a panic, an error that does not name the
/// file, or a loaded map with a non-finite height or a miscounted mask.
fn load_once(path: &Path) -> Result<bool, String> {
    match catch_unwind(AssertUnwindSafe(|| Heightmap::load(path))) {
        Err(_) => Err(format!("panic on {}", path.display())),
        Ok(Ok(m)) => {
            sound(&m, &path.display().to_string())?;
            synthesised(&m, &path.display().to_string())?;
            Ok(true)
        }
        Ok(Err(e)) => {
            let msg = e.to_string();
            let name = path.file_name().unwrap().to_string_lossy().to_string();
            if msg.contains(&name) {
                Ok(false)
            } else {
                Err(format!("error does not name {name}: {msg}"))
            }
        }
    }
}

/// A loaded map through the synthesis study (uniform and local noise):
/// figures or a clean error (a map too small or flat), never a panic, and
/// the figures finite.
fn synthesised(m: &Heightmap, name: &str) -> Result<(), String> {
    use terraclip::studies::synthesis::{run, Options};
    for local in [false, true] {
        let opts = Options {
            factor: 2,
            roughness: None,
            seed: 1,
            filter: Default::default(),
            local,
        };
        match catch_unwind(AssertUnwindSafe(|| run(m, &opts))) {
            Err(_) => return Err(format!("{name}: synthesis panicked")),
            Ok(Ok((r, _))) => {
                let s = &r.synthesised;
                let all = [s.variogram_slope, s.slope_ks, s.rmse, r.roughness];
                if !all.iter().all(|v| v.is_finite()) {
                    return Err(format!("{name}: synthesis figures not finite: {r:?}"));
                }
            }
            Ok(Err(_)) => {}
        }
    }
    Ok(())
}

/// A loaded map: as many values and mask entries as texels, every value
/// finite (no-data texels hold a finite fill, which the pyramid's filters
/// may read at zero weight), and `nodata_count` the mask's true entries.
fn sound(m: &Heightmap, name: &str) -> Result<(), String> {
    let (data, mask) = (m.data(), m.nodata_mask());
    let texels = m.width() * m.height();
    if data.len() != texels || (!mask.is_empty() && mask.len() != texels) {
        return Err(format!(
            "{name}: {} values and {} mask entries for {texels} texels",
            data.len(),
            mask.len()
        ));
    }
    let masked = mask.iter().filter(|&&b| b).count();
    if masked != m.nodata_count() {
        return Err(format!(
            "{name}: nodata_count {} but {masked} masked texels",
            m.nodata_count()
        ));
    }
    let bad = data.iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        return Err(format!("{name}: {bad} non-finite values"));
    }
    Ok(())
}

/// Parses, builds and renders a scene; Ok(true) rendered, Ok(false) a clean
/// error that names the scene, Err otherwise.
fn scene_once(text: &str, d: &Path) -> Result<bool, String> {
    let r = catch_unwind(AssertUnwindSafe(|| {
        let s = Scene::parse(text, "fuzz.toml", d)?;
        let (img, stats) = terraclip::render::render(&s, &Default::default())?;
        Ok::<_, terraclip::Error>((img, stats))
    }));
    match r {
        Err(_) => Err(format!("panic on scene:\n{text}")),
        Ok(Ok((img, stats))) => {
            let want = (img.width * img.height) as usize;
            if img.rgba.len() != 4 * want || stats.non_finite.raster > 0 {
                return Err(format!("scene rendered badly ({stats:?}):\n{text}"));
            }
            Ok(true)
        }
        Ok(Err(e)) if e.to_string().contains("fuzz.toml") => Ok(false),
        Ok(Err(e)) => Err(format!("scene error does not name the file: {e}\n{text}")),
    }
}

/// How many cases of each kind load in the seeded run (the rest are clean
/// errors), measured once and checked exactly.
const EXPECTED_LOADED: &[(&str, usize)] = &[
    ("seed 0 (png)", 145),
    ("seed 1 (png)", 174),
    ("seed 2 (tga)", 896),
    ("seed 3 (tif)", 614),
    ("seed 4 (tif)", 544),
    ("asc", 147),
    ("raw f32 + sidecar", 334),
    ("scene", 130),
    ("scene over a pack", 32),
    ("geographic tif", 617),
    ("pack", 2),
    ("upsampled pack", 0),
    ("export", 188),
    ("export manifest", 5),
    ("compare", 49),
    ("merge cracks", 21),
    ("merge fly", 21),
    ("merge golden", 34),
    ("merge tradeoff", 31),
    ("merge check-gpu", 32),
    ("merge export", 22),
];

/// A lossy pack of a small procedural map, its finer levels predicted by
/// `predictor`.
fn pack_seed(d: &Path, predictor: terraclip::pack::Predictor) -> Vec<u8> {
    let map = terraclip::terrain::procedural::Procedural::new(9, 40, 30)
        .generate()
        .unwrap();
    let levels = terraclip::pyramid::Pyramid::build(&map, Default::default(), 64).levels;
    let (packed, _) = terraclip::pack::Packed::encode_with(&levels, 1.0, 16, None, predictor);
    let p = d.join("seed.tcz");
    terraclip::pack::file::write(&p, &packed, [10.0; 2], "sinc-blackman:11", "seed").unwrap();
    std::fs::read(&p).unwrap()
}

/// A small export with every varying and both effect textures: jacksboro
/// with every effect but level-tint, at 64×36.
fn export_seed(d: &Path) -> PathBuf {
    let mut scene = Scene::load(Path::new("golden/jacksboro-oblique.toml")).unwrap();
    let effects = [
        "lambert",
        "phong",
        "fog",
        "shadows",
        "normal-map",
        "wireframe",
        "morph",
    ];
    scene
        .apply(&terraclip::scene::Overrides {
            effects: Some(effects.iter().map(|e| e.parse().unwrap()).collect()),
            size: Some([64, 36]),
            ..Default::default()
        })
        .unwrap();
    let out = d.join("export-seed");
    terraclip::export::scene(&scene, "seed", None, 1, 0.0, &out).unwrap();
    out
}

/// The files of an export a case may replace.
const EXPORT_FILES: [&str; 9] = [
    "frame.glb",
    "frame.glb",
    "camera.json",
    "frame.json",
    "depth.exr",
    "clipmap.exr",
    "effects.exr",
    "colour.png",
    "depth.f32",
];

/// Writes `bytes` as `name` of the export `d` and rewrites its manifest
/// to match, so that the reader's own checks meet the damage.
fn reexport(d: &Path, name: &str, bytes: &[u8]) {
    std::fs::write(d.join(name), bytes).unwrap();
    let files: Vec<(String, Vec<u8>)> = EXPORT_FILES[1..]
        .iter()
        .map(|n| (n.to_string(), std::fs::read(d.join(n)).unwrap()))
        .collect();
    let m = terraclip::export::manifest("seed", vec![], &files);
    std::fs::write(d.join("manifest.json"), serde_json::to_vec(&m).unwrap()).unwrap();
}

/// Reads the export `d` whose file `name` was damaged: Ok(true) read and
/// drawn (finite depth, the stated size), Ok(false) an error naming the
/// file (or the export), never a panic.
fn export_once(d: &Path, name: &str) -> Result<bool, String> {
    use terraclip::render::{draw, RenderOptions};
    let r = catch_unwind(AssertUnwindSafe(|| {
        terraclip::export::read(d).map(|e| {
            let (img, _) = draw(&e.frame, &RenderOptions::default(), &mut Default::default());
            (img, e.image)
        })
    }));
    match r {
        Err(_) => Err(format!("panic reading the export with a damaged {name}")),
        Ok(Ok((img, reference))) => {
            let n = (img.width * img.height) as usize;
            if img.depth.len() != n || img.depth.iter().any(|z| !z.is_finite()) {
                return Err(format!("{name}: drawn badly"));
            }
            if (img.width, img.height) != (reference.width, reference.height) {
                return Err(format!("{name}: drawn at another size"));
            }
            Ok(true)
        }
        Ok(Err(e)) => {
            let msg = e.to_string();
            // The damaged file by its path in the export, or (where the
            // damage shows as a disagreement) that file named beside the
            // one that disagrees with it: never the folder alone.
            let path = format!("export-case/{name}");
            if msg.contains(&path) || (msg.contains("export-case/") && msg.contains(name)) {
                Ok(false)
            } else {
                Err(format!("export error does not name {path}: {msg}"))
            }
        }
    }
}

/// `compare` of an outside image or depth file `p` (damaged) against the
/// export `r`: an outcome, or an error naming the file; never a panic.
fn compare_once(
    r: &Path,
    image: &Path,
    depth: Option<&Path>,
    named: &Path,
    mode: Mode,
) -> Result<bool, String> {
    use terraclip::check::outside::run;
    match catch_unwind(AssertUnwindSafe(|| {
        run(
            r,
            Some(image),
            depth,
            &terraclip::check::outside::Options::new(mode),
            None,
        )
    })) {
        Err(_) => Err(format!("compare panicked on {}", named.display())),
        Ok(Ok(o)) => Ok(o.pass),
        Ok(Err(e)) => {
            let name = named.file_name().unwrap().to_string_lossy().to_string();
            if e.to_string().contains(&name) {
                Ok(false)
            } else {
                Err(format!("compare error does not name {name}: {e}"))
            }
        }
    }
}

/// A part's `--json` output as its `shard` tag and the rest, apart, so that
/// a case can damage either (the tag holds a few tokens of hundreds).
type Part = [String; 2];

/// The text of `p`, the tag first.
fn part_text([tag, rest]: &Part) -> String {
    match rest.strip_prefix('{') {
        Some(body) => format!("{{\n  \"shard\": {tag},{body}"),
        None => rest.clone(),
    }
}

/// Two parts of each sweep `merge` joins, as `--json` prints them: a crack
/// survey and a flight of the fuzz scene (real runs, 4 views or frames at
/// 32×24), and a golden run's parts (its `scenes` lists interleaved).
fn merge_seeds(d: &Path) -> Vec<(&'static str, [Part; 2])> {
    use terraclip::studies::{cracks, fly, shard};
    let scene = Scene::parse(SCENE, "merge-seed.toml", d).unwrap();
    let parts = |f: &dyn Fn(shard::Shard) -> Value| {
        [0, 1].map(|i| {
            let sh = shard::Shard { index: i, count: 2 };
            let mut v = shard::tag(f(sh), "sweep", sh, "seed");
            steady(&mut v);
            let tag = v.as_object_mut().unwrap().remove("shard").unwrap();
            [&tag, &v].map(|v| serde_json::to_string_pretty(v).unwrap())
        })
    };
    let survey = parts(&|sh| {
        let r = cracks::survey(&scene, &["clipmap".into()], 4, [32, 24], sh, || {}).unwrap();
        serde_json::to_value(r).unwrap()
    });
    let flight = parts(&|sh| {
        let r = fly::fly(&scene, (4, 0), 5.0, true, sh, |_, _| Ok(())).unwrap();
        serde_json::to_value(r).unwrap()
    });
    let golden = parts(&|sh| {
        let scenes: Vec<Value> = (0..3)
            .filter(|k| sh.owns(*k))
            .map(|k| serde_json::json!({ "name": format!("s{k}"), "pass": true, "pixels": k }))
            .collect();
        serde_json::json!({ "adapter": "cpu", "scenes": scenes })
    });
    let tradeoff = parts(&|shard| {
        let o = terraclip::studies::tradeoff::Options {
            size: [32, 18],
            path_frames: 2,
            quick: true,
            shard,
            gpu: false,
        };
        let r = terraclip::studies::tradeoff::run(&scene, &o, |_| {}).unwrap();
        serde_json::to_value(r).unwrap()
    });
    let check_gpu = parts(&|sh| {
        let scenes: Vec<Value> = (0..3)
            .filter(|k| sh.owns(*k))
            .map(|k| {
                serde_json::json!({ "scene": format!("s{k}"), "pass": true, "frames": 1,
                    "colour_px_differ": k, "depth_px_differ": 0, "unmatched_example": null })
            })
            .collect();
        serde_json::json!({ "adapter": "llvmpipe", "mode": "exact", "exact_expected": true, "scenes": scenes })
    });
    // An export's parts are folders: two real ones, written by the CLI.
    let scene_file = d.join("merge-seed.toml");
    std::fs::write(&scene_file, SCENE).unwrap();
    // Named relative to `d`, the folder the merges run in: the parts'
    // text, and so the damage drawn for it, is then the same in any clone.
    let export = [0, 1].map(|i| {
        let out = format!("export-part{i}");
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
            .current_dir(d)
            .args(["export", "merge-seed.toml"])
            .args([
                "--frames",
                "2",
                "--shard",
                &format!("{i}/2"),
                "--json",
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let mut v: Value = serde_json::from_slice(&o.stdout).unwrap();
        let tag = v.as_object_mut().unwrap().remove("shard").unwrap();
        let tag = serde_json::to_string_pretty(&tag)
            .unwrap()
            .replace("\"export\"", "\"sweep\"");
        [tag, serde_json::to_string_pretty(&v).unwrap()]
    });
    let mut seeds = vec![
        ("cracks", survey),
        ("fly", flight),
        ("golden", golden),
        ("tradeoff", tradeoff),
        ("check-gpu", check_gpu),
        ("export", export),
    ];
    for (kind, parts) in &mut seeds {
        for [tag, _] in parts.iter_mut() {
            *tag = tag.replace("\"sweep\"", &format!("\"{kind}\""));
        }
        let dir = (*kind == "export").then(|| d.join("export-joined"));
        assert_eq!(
            merge_once(&parts.clone().map(|p| part_text(&p)), dir.as_deref()),
            (true, Ok(true)),
            "the {kind} seed"
        );
    }
    seeds
}

/// Timings set to 1, and what a part works out from them cleared: a
/// run's timings differ from run to run, and the damage drawn for a part
/// depends on its text, so the seeded run's counts are reproducible only
/// without them.
fn steady(v: &mut Value) {
    match v {
        Value::Object(o) => {
            for (k, v) in o.iter_mut() {
                let timing = k.starts_with("ms")
                    || ["ms", "_s", "seconds", "fps", "rss_bytes"]
                        .iter()
                        .any(|t| k.ends_with(t));
                // What a tradeoff part works out from its timings (merge
                // works it out again over the joined rows).
                match k.as_str() {
                    "pareto" => *v = serde_json::json!(false),
                    "best_in_budget" => *v = Value::Null,
                    // A flight's budget is worked out from its timings.
                    "update_budget" => *v = Value::Null,
                    _ => {}
                }
                let one = |x: &mut Value| {
                    if x.is_u64() {
                        *x = serde_json::json!(1);
                    } else if x.is_number() {
                        *x = serde_json::json!(1.0);
                    }
                };
                if timing && v.is_array() {
                    v.as_array_mut().unwrap().iter_mut().for_each(one);
                } else if timing {
                    one(v);
                } else {
                    steady(v);
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(steady),
        _ => {}
    }
}

/// `merge` of two part files, one of them damaged: whether the parts
/// parsed as JSON and so reached `merge`, and Ok(true) merged (into an
/// object, never a null standing for parts it dropped), Ok(false) an error
/// naming a part file or the parts, Err on a panic or an error that names
/// neither. `dir` is emptied first (an export's parts are joined there).
fn merge_once(texts: &[String; 2], dir: Option<&Path>) -> (bool, Result<bool, String>) {
    let mut parts = vec![];
    for (i, t) in texts.iter().enumerate() {
        match serde_json::from_str::<Value>(t) {
            Ok(v) => parts.push((format!("part{i}.json"), v)),
            // The CLI's own parse error, which names the file (tests/shard.rs).
            Err(_) => return (false, Ok(false)),
        }
    }
    if let Some(dir) = dir {
        let _ = std::fs::remove_dir_all(dir);
    }
    (true, merge_result(texts, &parts, dir))
}

fn merge_result(
    texts: &[String; 2],
    parts: &[(String, Value)],
    dir: Option<&Path>,
) -> Result<bool, String> {
    match catch_unwind(AssertUnwindSafe(|| {
        terraclip::studies::merge::merge(parts, dir)
    })) {
        Err(_) => Err(format!("merge panicked on {texts:?}")),
        // A crack survey's merge sums every part's views: none dropped.
        Ok(Ok(v)) if v.get("views_surveyed").is_some() => {
            let each: Option<u64> = parts.iter().map(|p| p.1["views_surveyed"].as_u64()).sum();
            match each == v["views_surveyed"].as_u64() {
                true => Ok(true),
                false => Err(format!("merge dropped a part: {v} from {texts:?}")),
            }
        }
        Ok(Ok(v)) if v.is_object() => Ok(true),
        Ok(Ok(v)) => Err(format!("merge gave {v} for {texts:?}")),
        Ok(Err(e)) => {
            let msg = e.to_string();
            if msg.contains("part0.json") || msg.contains("part1.json") || msg.contains("parts") {
                Ok(false)
            } else {
                Err(format!("merge error names no part: {msg}"))
            }
        }
    }
}

/// Cases per kind of merge whose parts both parse as JSON (of 200 each:
/// a third are edited as a tree, which keeps the JSON whole).
const EXPECTED_MERGED: &[(&str, usize)] = &[
    ("cracks", 78),
    ("fly", 73),
    ("golden", 76),
    ("tradeoff", 75),
    ("check-gpu", 71),
    ("export", 86),
];

/// `terraclip merge` of the two parts written to files: an exit with a
/// code, never a signal, and a failure that names a part or the parts.
fn merge_through_cli(d: &Path, texts: &[String; 2], dir: Option<&Path>) -> Result<(), String> {
    let files = [0, 1].map(|i| d.join(format!("cli-part{i}.json")));
    for (f, t) in files.iter().zip(texts) {
        std::fs::write(f, t).unwrap();
    }
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"));
    c.arg("merge").args(&files).arg("--json");
    if let Some(dir) = dir {
        let _ = std::fs::remove_dir_all(dir);
        c.arg("--dir").arg(dir);
    }
    let out = c.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    match out.status.code() {
        None => Err(format!("killed by a signal: {:?}", out.status)),
        Some(0) => Ok(()),
        Some(_)
            if (err.contains("cli-part") || err.contains("parts")) && !err.contains("panicked") =>
        {
            Ok(())
        }
        Some(c) => Err(format!("exit {c}: {err}")),
    }
}

#[test]
fn ten_thousand_malformed_inputs_never_panic() {
    let d = dir();
    let start = Instant::now();
    let mut rng = Rng(0x5EED_F00D_1234_5678);
    let (mut cases, mut loaded, mut failures) = (0usize, 0usize, vec![]);
    // Loaded cases per kind, in the order the kinds run.
    let mut split: Vec<(String, usize, usize)> = vec![];
    let mut record = |kind: &str, r: Result<bool, String>| {
        if split.last().is_none_or(|k| k.0 != kind) {
            split.push((kind.to_string(), 0, 0));
        }
        let k = split.last_mut().unwrap();
        k.1 += 1;
        match r {
            Ok(l) => {
                loaded += usize::from(l);
                k.2 += usize::from(l);
            }
            Err(e) => failures.push(e),
        }
    };
    // Binary formats: 1,600 cases per seed (8,000). The first rejected
    // cases of each seed are kept for the CLI check below.
    let mut samples: Vec<PathBuf> = vec![];
    for (k, (ext, seed)) in seeds(&d).into_iter().enumerate() {
        let p = d.join(format!("case.{ext}"));
        for _ in 0..1600 {
            let bytes = mutate(&mut rng, &seed);
            std::fs::write(&p, &bytes).unwrap();
            let r = load_once(&p);
            if r == Ok(false) && samples.len() < 4 * (k + 1) {
                let keep = d.join(format!("sample{}.{ext}", samples.len()));
                std::fs::write(&keep, &bytes).unwrap();
                samples.push(keep);
            }
            record(&format!("seed {k} ({ext})"), r);
            cases += 1;
        }
    }
    // ASCII grids (1,500) and raw f32 with a mutated body or sidecar (1,500).
    let asc = d.join("case.asc");
    for _ in 0..1500 {
        let text = if rng.below(3) == 0 {
            String::from_utf8_lossy(&mutate(&mut rng, ASC.as_bytes())).into_owned()
        } else {
            mutate_text(&mut rng, ASC)
        };
        std::fs::write(&asc, text).unwrap();
        record("asc", load_once(&asc));
        cases += 1;
    }
    let raw = d.join("case.f32");
    let body: Vec<u8> = [
        1.0f32,
        2.0,
        f32::NAN,
        4.0,
        -32768.0,
        6.0,
        f32::INFINITY,
        8.0,
        9.0,
        10.0,
        11.0,
        12.0,
    ]
    .iter()
    .flat_map(|v| v.to_le_bytes())
    .collect();
    for i in 0..1500 {
        if i % 2 == 0 {
            std::fs::write(&raw, mutate(&mut rng, &body)).unwrap();
            std::fs::write(d.join("case.json"), SIDECAR).unwrap();
        } else {
            std::fs::write(&raw, &body).unwrap();
            std::fs::write(d.join("case.json"), mutate_text(&mut rng, SIDECAR)).unwrap();
        }
        let r = load_once(&raw);
        // A sidecar error names the sidecar; accept either file's name.
        let r = match r {
            Err(e) if e.contains("case.json") => Ok(false),
            r => r,
        };
        record("raw f32 + sidecar", r);
        cases += 1;
    }
    // Scenes: wrong types, missing fields, out-of-range values (2,000).
    for _ in 0..2000 {
        let text = mutate_text(&mut rng, SCENE);
        record("scene", scene_once(&text, &d));
        cases += 1;
    }
    // Scenes over a pack (600, a generator of their own so the kinds
    // above keep their draws): the pack alone, with a decode budget, and
    // with synthesis below it, each mutated as the scenes above are.
    let pack = pack_seed(&d, terraclip::pack::Predictor::Upsampled);
    std::fs::write(d.join("fuzz-pack.tcz"), &pack).unwrap();
    let over_pack = SCENE.replace(
        "procedural = { seed = 5, width = 65, height = 65, amplitude = 500.0, wavelength = 64.0 }",
        "file = \"fuzz-pack.tcz\"",
    );
    assert_ne!(over_pack, SCENE);
    let plain = over_pack.replace(
        "synthesis = { levels = 2, roughness = 0.8, seed = 3 }\n",
        "",
    );
    let budget = plain.replace("[pyramid]\n", "[pyramid]\nbudget = 400\n");
    let seeds = [plain, budget, over_pack];
    for (k, seed) in seeds.iter().enumerate() {
        assert!(
            scene_once(seed, &d) == Ok(true),
            "scene over a pack, seed {k}"
        );
    }
    let mut scene_rng = Rng(0x5CE_E0FE_A9AC_0001);
    // Cases sent through the CLI binary too, and what went wrong there.
    let (mut cli_cases, mut cli_failures) = (0, Vec::<String>::new());
    for i in 0..600 {
        let text = mutate_text(&mut scene_rng, &seeds[i % 3]);
        record("scene over a pack", scene_once(&text, &d));
        // Every twentieth through `terraclip render`.
        if i % 20 == 0 {
            cli_cases += 1;
            let (file, png) = (d.join("fuzz.toml"), d.join("fuzz.png"));
            std::fs::write(&file, &text).unwrap();
            if let Err(e) = cli_exits(
                &[
                    "render".as_ref(),
                    file.as_os_str(),
                    "-o".as_ref(),
                    png.as_os_str(),
                ],
                "fuzz.toml",
            ) {
                cli_failures.push(format!("scene over a pack case {i}: {e}"));
            }
        }
        cases += 1;
    }
    // Kinds on generators of their own, so the kinds above keep their
    // draws: GeoTIFFs with a GeoKey directory and a tie point (1,600:
    // mutated keys, model types, units, scales and latitudes), and packs
    // (1,000: cut, flipped and header-edited copies of a small lossy one;
    // 500 more of one coded with the upsampled predictor).
    type Loader = fn(&Path) -> Result<bool, String>;
    /// Kind, generator seed, seed file, case file name, cases, loader.
    type Own<'a> = (&'a str, u64, Vec<u8>, &'a str, usize, Loader);
    let own: [Own; 3] = [
        (
            "geographic tif",
            0x6E0_7EFF_5EED_0001,
            geotiff_seed(&d),
            "case-geo.tif",
            1600,
            load_once,
        ),
        (
            "pack",
            0x7C2_5EED_0000_0001,
            pack_seed(&d, terraclip::pack::Predictor::Lifting),
            "case.tcz",
            1000,
            pack_once,
        ),
        (
            "upsampled pack",
            0x7C2_5EED_0000_0002,
            pack_seed(&d, terraclip::pack::Predictor::Upsampled),
            "case.tcz",
            500,
            pack_once,
        ),
    ];
    for (kind, seed, bytes, name, n, load) in own {
        let mut own_rng = Rng(seed);
        let p = d.join(name);
        for _ in 0..n {
            std::fs::write(&p, mutate(&mut own_rng, &bytes)).unwrap();
            record(kind, load(&p));
            cases += 1;
        }
    }
    // Exports (1,000: one file cut, flipped or edited, the manifest made
    // to match so the parsers meet it) and `compare`'s inputs (400:
    // damaged PNGs and depth files of their own renderer).
    let mut ex_rng = Rng(0xE7_0057_5EED_0001);
    let seed = export_seed(&d);
    let case = d.join("export-case");
    let _ = std::fs::remove_dir_all(&case);
    std::fs::create_dir_all(&case).unwrap();
    for f in std::fs::read_dir(&seed).unwrap() {
        let f = f.unwrap();
        std::fs::copy(f.path(), case.join(f.file_name())).unwrap();
    }
    for i in 0..1000 {
        let name = EXPORT_FILES[ex_rng.below(EXPORT_FILES.len())];
        let good = std::fs::read(seed.join(name)).unwrap();
        let bytes = if name.ends_with(".json") && ex_rng.below(2) == 0 {
            mutate_text(&mut ex_rng, &String::from_utf8_lossy(&good)).into_bytes()
        } else {
            mutate(&mut ex_rng, &good)
        };
        reexport(&case, name, &bytes);
        record("export", export_once(&case, name));
        // Every twentieth through the CLI: `compare` reads the export.
        if i % 20 == 0 {
            cli_cases += 1;
            let image = seed.join("colour.png");
            if let Err(e) = cli_exits(
                &[
                    "compare".as_ref(),
                    case.as_os_str(),
                    "--image".as_ref(),
                    image.as_os_str(),
                ],
                "export-case",
            ) {
                cli_failures.push(format!("export case {i}: {e}"));
            }
        }
        reexport(&case, name, &good);
        cases += 1;
    }
    // The manifest itself (300, a generator of its own): edited as a
    // JSON tree, or a listed name made `..`-relative or absolute, an entry
    // repeated or dropped, frame folders claimed (one, or outside).
    let mut man_rng = Rng(0x3A_41F3_5EED_0001);
    let good_manifest: Value =
        serde_json::from_slice(&std::fs::read(case.join("manifest.json")).unwrap()).unwrap();
    for i in 0..300 {
        let mut m = good_manifest.clone();
        let files = m["files"].as_array().unwrap().len();
        let k = man_rng.below(files);
        match man_rng.below(7) {
            0 => edit_json(&mut man_rng, &mut m),
            1 => {
                let n = m["files"][k]["name"].as_str().unwrap().to_string();
                m["files"][k]["name"] = serde_json::json!(format!("../{n}"));
            }
            2 => m["files"][k]["name"] = serde_json::json!("/etc/hostname"),
            3 => {
                let e = m["files"][k].clone();
                m["files"].as_array_mut().unwrap().push(e);
            }
            4 => {
                m["files"].as_array_mut().unwrap().remove(k);
            }
            5 => m["frames"] = serde_json::json!(["frame-0000"]),
            _ => m["frames"] = serde_json::json!(["../outside"]),
        }
        std::fs::write(case.join("manifest.json"), serde_json::to_vec(&m).unwrap()).unwrap();
        record("export manifest", export_once(&case, "manifest.json"));
        if i % 20 == 0 {
            cli_cases += 1;
            let image = seed.join("colour.png");
            let args = [
                "compare".as_ref(),
                case.as_os_str(),
                "--image".as_ref(),
                image.as_os_str(),
            ];
            if let Err(e) = cli_exits(&args, "export-case") {
                cli_failures.push(format!("export manifest case {i}: {e}"));
            }
        }
        cases += 1;
    }
    std::fs::write(
        case.join("manifest.json"),
        serde_json::to_vec(&good_manifest).unwrap(),
    )
    .unwrap();
    let (theirs, theirs_depth) = (d.join("theirs.png"), d.join("theirs-depth.f32"));
    let theirs_exr = d.join("theirs-depth.exr");
    let png = std::fs::read(seed.join("colour.png")).unwrap();
    let raw = std::fs::read(seed.join("depth.f32")).unwrap();
    let exr = std::fs::read(seed.join("depth.exr")).unwrap();
    for i in 0..600 {
        std::fs::write(&theirs, &png).unwrap();
        // Each mode in turn; FLIP compares colour alone, so its cases
        // damage the image.
        let mode = [Mode::Exact, Mode::Tiered, Mode::Flip][i / 3 % 3];
        let damage = if mode == Mode::Flip { 0 } else { i % 3 };
        let (depth, named) = match damage {
            0 => {
                std::fs::write(&theirs, mutate(&mut ex_rng, &png)).unwrap();
                std::fs::write(&theirs_depth, &raw).unwrap();
                (&theirs_depth, &theirs)
            }
            1 => {
                std::fs::write(&theirs_depth, mutate(&mut ex_rng, &raw)).unwrap();
                (&theirs_depth, &theirs_depth)
            }
            _ => {
                std::fs::write(&theirs_exr, mutate(&mut ex_rng, &exr)).unwrap();
                (&theirs_exr, &theirs_exr)
            }
        };
        let depth = (mode != Mode::Flip).then_some(depth.as_path());
        record("compare", compare_once(&seed, &theirs, depth, named, mode));
        if i % 20 == 0 {
            cli_cases += 1;
            let mut args = vec![
                "compare".as_ref(),
                seed.as_os_str(),
                "--image".as_ref(),
                theirs.as_os_str(),
            ];
            if let Some(d) = depth {
                args.extend(["--depth".as_ref(), d.as_os_str()]);
            }
            let m: &std::ffi::OsStr = mode.name().as_ref();
            args.extend(["--mode".as_ref(), m]);
            let name = named.file_name().unwrap().to_string_lossy().into_owned();
            if let Err(e) = cli_exits(&args, &name) {
                cli_failures.push(format!("compare case {i}: {e}"));
            }
        }
        cases += 1;
    }
    // `merge`'s part files (1,200: one of two parts of a crack survey, a
    // flight, a golden run, a tradeoff sweep, a check-gpu run or an export
    // cut, flipped or edited; a flight's merge every tenth case also draws
    // its charts, an export's joins its folders). Every tenth case also
    // goes through `terraclip merge`.
    let mut merge_rng = Rng(0x3E26_E5EE_D000_0001);
    // The export parts name their folders relative to `d`. This is the
    // file's only test, so no other thread minds the working folder.
    let cwd = std::env::current_dir().unwrap();
    std::env::set_current_dir(&d).unwrap();
    let charts = d.join("merge-charts");
    let joined = d.join("export-joined");
    let mut reached: Vec<(&str, usize)> = vec![];
    let mut merge_cli = 0;
    for (kind, good) in merge_seeds(&d) {
        reached.push((kind, 0));
        for i in 0..200 {
            let mut parts = good.clone();
            let (k, half) = (merge_rng.below(2), merge_rng.below(2));
            let text = &good[k][half];
            parts[k][half] = match merge_rng.below(3) {
                0 => String::from_utf8_lossy(&mutate(&mut merge_rng, text.as_bytes())).into_owned(),
                1 => mutate_text(&mut merge_rng, text),
                // Edited as a tree, so the JSON still parses and `merge`
                // itself meets the damage.
                _ => {
                    let mut v: Value = serde_json::from_str(text).unwrap();
                    edit_json(&mut merge_rng, &mut v);
                    serde_json::to_string_pretty(&v).unwrap()
                }
            };
            let dir = match kind {
                "fly" if i % 10 == 0 => Some(charts.as_path()),
                "export" => Some(joined.as_path()),
                _ => None,
            };
            let texts = parts.map(|p| part_text(&p));
            let (merged, r) = merge_once(&texts, dir);
            reached.last_mut().unwrap().1 += usize::from(merged);
            record(&format!("merge {kind}"), r);
            if i % 10 == 0 {
                merge_cli += 1;
                if let Err(e) = merge_through_cli(&d, &texts, dir) {
                    cli_failures.push(format!("merge {kind} case {i}: {e}"));
                }
            }
            cases += 1;
        }
    }
    std::env::set_current_dir(&cwd).unwrap();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "fuzz: {cases} cases in {secs:.1} s: {loaded} loaded, {} clean errors, {} failures",
        cases - loaded - failures.len(),
        failures.len()
    );
    for (kind, n, ok) in &split {
        println!("  {kind}: {ok} of {n} loaded");
    }
    // From the CLI: a non-zero exit and a message naming the file.
    for p in &samples {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
            .arg("info")
            .arg(p)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        let name = p.file_name().unwrap().to_string_lossy();
        assert!(!out.status.success(), "{name} accepted by the CLI");
        assert!(
            err.contains(&*name) && !err.contains("panicked"),
            "{name}: {err}"
        );
    }
    assert_eq!(samples.len(), 20, "CLI samples");
    let _ = std::fs::remove_dir_all(&d);
    assert!(cases >= 10_000, "{cases} cases");
    assert!(
        failures.is_empty(),
        "{} failures: {:#?}",
        failures.len(),
        failures
    );
    // The seeded run is reproducible, so its split is exact: a reader that
    // starts accepting what it used to reject, or the reverse, changes it.
    let got: Vec<(&str, usize)> = split.iter().map(|k| (k.0.as_str(), k.2)).collect();
    assert_eq!(got, EXPECTED_LOADED, "loaded cases per kind");
    // Cases whose parts both parse, so that `merge` itself meets the damage.
    println!("merge reached: {reached:?}");
    assert_eq!(reached, EXPECTED_MERGED, "cases reaching merge per kind");
    assert_eq!(merge_cli, 6 * 20);
    assert_eq!(cli_cases, 30 + 50 + 15 + 30);
    assert!(cli_failures.is_empty(), "{cli_failures:?}");
}
