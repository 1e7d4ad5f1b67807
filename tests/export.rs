//! `terraclip export` and its reader: the files are the frame. Every golden
//! scene is exported, read back as a plain mesh (positions and varyings,
//! no clipmap), drawn again on the CPU and compared with the reference
//! bits; corrupt, truncated and mislabelled exports are clean errors that
//! name the file.

mod common;

use std::path::{Path, PathBuf};
use terraclip::export;
use terraclip::frame::stats::Passes;
use terraclip::render::{draw, RenderOptions};
use terraclip::scene::Scene;

fn tmp(name: &str) -> PathBuf {
    common::fresh_tmp("export", name)
}

fn export_golden(name: &str, dir: &Path) -> export::Written {
    let path = PathBuf::from(format!("golden/{name}.toml"));
    let scene = Scene::load(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    export::scene(&scene, name, Some(&text), 1, 0.0, dir).unwrap()
}

/// Every golden scene, drawn from its exported files alone, gives the
/// exported reference bit for bit, and that reference is the golden PNG.
#[test]
fn every_golden_redrawn_from_its_export_is_the_reference() {
    let scenes = terraclip::check::golden::scenes(Path::new("golden")).unwrap();
    assert!(scenes.len() >= 15);
    for p in scenes {
        let name = p.file_stem().unwrap().to_string_lossy().into_owned();
        let dir = tmp(&format!("golden-{name}"));
        let w = export_golden(&name, &dir);
        let e = export::read(&dir).unwrap();
        assert_eq!(e.frame.triangle_count(), w.frames[0].triangles, "{name}");
        // One frame lies in the folder itself, and its summary's hash is
        // the colour file's.
        assert_eq!(
            (w.frames.len(), w.frames[0].folder.as_str()),
            (1, "."),
            "{name}"
        );
        let png = std::fs::read(dir.join("colour.png")).unwrap();
        let sha: String =
            sha2::Digest::finalize(<sha2::Sha256 as sha2::Digest>::new_with_prefix(&png))
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect();
        assert_eq!(w.frames[0].colour_sha256, sha, "{name}");
        // GLSL for every frame, listed in the manifest; `.ci/outside-gl`
        // draws with it and compares exactly. The texture reads are there
        // exactly when the frame's effects read effects.exr.
        for shader in [
            "terrain.vert",
            "terrain.frag",
            "terrain-es.vert",
            "terrain-es.frag",
            "terrain.wgsl",
        ] {
            let listed = e.manifest.files.iter().any(|f| f.name == shader);
            assert!(dir.join(shader).is_file() && listed, "{name}: {shader}");
        }
        // The ES pair has neither qualifier ES 3.00 lacks, and carries
        // each linear varying through clip w: it is the desktop pair
        // otherwise (`.ci/outside-gl` draws both).
        let es = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
        let (es_vert, es_frag) = (es("terrain-es.vert"), es("terrain-es.frag"));
        for src in [&es_vert, &es_frag] {
            assert!(src.starts_with("#version 300 es\n"), "{name}");
            assert!(src.contains("precision highp float;"), "{name}");
            assert!(
                !src.contains("precise ") && !src.contains("noperspective"),
                "{name}"
            );
        }
        for v in e
            .info
            .varyings
            .iter()
            .filter(|v| v.interpolation == "linear")
        {
            let a = &v.attribute;
            assert!(
                es_vert.contains(&format!("w{a} = {a} * p.w;")),
                "{name}: {a}"
            );
            assert!(
                es_frag.contains(&format!("v{a} = w{a} * gl_FragCoord.w;")),
                "{name}: {a}"
            );
        }
        assert_eq!(
            es_frag.contains("gl_FragCoord.w"),
            name == "wireframe",
            "{name}: only the wire's varyings are linear"
        );
        // The WGSL parses and validates as WebGPU would take it (naga, the
        // front end wgpu uses), with both entry points, one `Frame` uniform
        // buffer of the documented 160 bytes, linear varyings marked so,
        // and texture bindings exactly for the effects that read maps.
        let wgsl = es("terrain.wgsl");
        let module = naga::front::wgsl::parse_str(&wgsl)
            .unwrap_or_else(|err| panic!("{name}: {}", err.emit_to_string(&wgsl)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|err| panic!("{name}: {}", err.emit_to_string(&wgsl)));
        let stages: Vec<_> = module.entry_points.iter().map(|p| p.stage).collect();
        assert_eq!(
            stages,
            [naga::ShaderStage::Vertex, naga::ShaderStage::Fragment],
            "{name}"
        );
        let frame = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("Frame"))
            .unwrap()
            .1;
        assert!(
            matches!(frame.inner, naga::TypeInner::Struct { span: 160, .. }),
            "{name}: {:?}",
            frame.inner
        );
        assert_eq!(
            wgsl.matches("@interpolate(linear)").count(),
            e.info
                .varyings
                .iter()
                .filter(|v| v.interpolation == "linear")
                .count(),
            "{name}"
        );
        let textures = module
            .global_variables
            .iter()
            .filter(|(_, g)| g.space == naga::AddressSpace::Handle)
            .count();
        let has = |effect: &str| e.info.effects.iter().any(|f| f.name() == effect);
        assert_eq!(
            textures,
            2 * usize::from(has("shadows")) + 2 * usize::from(has("normal-map")),
            "{name}"
        );
        let frag = std::fs::read_to_string(dir.join("terrain.frag")).unwrap();
        assert!(
            frag.starts_with("#version 450") && frag.contains("precise"),
            "{name}"
        );
        assert_eq!(
            frag.contains("wire_colour * 0.8"),
            name == "wireframe",
            "{name}"
        );
        assert_eq!(
            frag.contains("shadow_at(v_LEVEL_UV"),
            has("shadows"),
            "{name}"
        );
        assert_eq!(
            frag.contains("pixel_normal(v_LEVEL_UV"),
            has("normal-map"),
            "{name}"
        );
        // frame.json names the sun and the level palette the shading used.
        assert_eq!(
            e.info.sun_direction,
            Scene::load(&p)
                .unwrap()
                .shading
                .sun_direction()
                .map(|c| c as f32),
            "{name}"
        );
        assert_eq!(e.info.level_palette[3], [0, 130, 200], "{name}");
        let (img, _) = draw(&e.frame, &RenderOptions::default(), &mut Passes::default());
        let differ = img
            .rgba
            .chunks(4)
            .zip(e.image.rgba.chunks(4))
            .filter(|(a, b)| a != b)
            .count();
        let depth = img
            .depth
            .iter()
            .zip(&e.image.depth)
            .filter(|(a, b)| a.to_bits() != b.to_bits())
            .count();
        eprintln!(
            "{name}: {} triangles, {differ} colour px, {depth} depth px differ",
            e.frame.triangle_count()
        );
        assert_eq!((differ, depth), (0, 0), "{name}");
        let (gw, gh, golden) =
            terraclip::check::golden::load_png(&p.with_extension("png")).unwrap();
        assert_eq!((gw, gh), (img.width, img.height), "{name}");
        assert!(
            golden == e.image.rgba,
            "{name}: the export's colour is not the golden"
        );
    }
}

/// Replaces `name` in the export `dir` with `bytes` and updates the
/// manifest to match, so the reader's own checks (not the hash) meet them.
fn replace(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::write(dir.join(name), bytes).unwrap();
    let mpath = dir.join("manifest.json");
    let mut m: export::Manifest = serde_json::from_slice(&std::fs::read(&mpath).unwrap()).unwrap();
    let files: Vec<(String, Vec<u8>)> = m
        .files
        .iter()
        .map(|e| (e.name.clone(), std::fs::read(dir.join(&e.name)).unwrap()))
        .collect();
    m.files = export::manifest(&m.scene, vec![], &files).files;
    std::fs::write(&mpath, serde_json::to_vec(&m).unwrap()).unwrap();
}

/// The error reading `dir`, which must name `file` and say `why`.
fn refused(dir: &Path, file: &str, why: &str) {
    let e = match export::read(dir) {
        Ok(_) => panic!("{} read without error", dir.display()),
        Err(e) => e.to_string(),
    };
    assert!(e.contains(file) && e.contains(why), "{e}");
}

#[test]
fn a_damaged_export_is_an_error_naming_the_file() {
    let good = tmp("damaged-good");
    export_golden("wireframe", &good);
    let fresh = |name: &str| {
        let d = tmp(name);
        std::fs::create_dir_all(&d).unwrap();
        for f in std::fs::read_dir(&good).unwrap() {
            let f = f.unwrap();
            std::fs::copy(f.path(), d.join(f.file_name())).unwrap();
        }
        assert!(export::read(&d).is_ok());
        d
    };
    // One bit flipped: the hash.
    let d = fresh("damaged-bit");
    let mut b = std::fs::read(d.join("frame.glb")).unwrap();
    b[100] ^= 4;
    std::fs::write(d.join("frame.glb"), &b).unwrap();
    refused(&d, "frame.glb", "SHA-256 differs");
    // Cut short: the length.
    let d = fresh("damaged-short");
    std::fs::write(
        d.join("depth.f32"),
        &std::fs::read(good.join("depth.f32")).unwrap()[..1000],
    )
    .unwrap();
    refused(&d, "depth.f32", "1000 bytes where manifest.json says");
    // Gone.
    let d = fresh("damaged-gone");
    std::fs::remove_file(d.join("colour.png")).unwrap();
    refused(&d, "colour.png", "No such file");
    // Another version.
    let d = fresh("damaged-version");
    let m = std::fs::read_to_string(d.join("manifest.json")).unwrap();
    std::fs::write(
        d.join("manifest.json"),
        m.replace("\"version\": 1", "\"version\": 7"),
    )
    .unwrap();
    refused(&d, "manifest.json", "version 7");
    // Not JSON.
    let d = fresh("damaged-json");
    replace(&d, "camera.json", b"{\"width\": 4");
    refused(&d, "camera.json", "invalid JSON");
    // A GLB whose header lies about its length, and one cut short.
    let d = fresh("damaged-glb-length");
    let mut b = std::fs::read(good.join("frame.glb")).unwrap();
    b[8..12].copy_from_slice(&5u32.to_le_bytes());
    replace(&d, "frame.glb", &b);
    refused(&d, "frame.glb", "header says 5");
    let d = fresh("damaged-glb-cut");
    replace(
        &d,
        "frame.glb",
        &std::fs::read(good.join("frame.glb")).unwrap()[..4000],
    );
    refused(&d, "frame.glb", "stated length");
    // A well-formed GLB without a varying the effects need.
    let d = fresh("damaged-glb-varying");
    let e = export::read(&good).unwrap();
    // The wireframe's two varyings come last: the layout without them.
    let k = e.frame.layout.len();
    let mut plain = e.frame.layout.clone();
    (plain.bary, plain.edge) = (None, None);
    plain.linear.truncate(k - 6);
    let tris = export::glb::Triangles {
        positions: e.frame.positions.clone(),
        attrs: e
            .frame
            .attrs
            .chunks(k)
            .flat_map(|a| a[..plain.len()].to_vec())
            .collect(),
        levels: e.frame.mesh.levels.clone(),
    };
    replace(
        &d,
        "frame.glb",
        &export::glb::write(&tris, &plain, serde_json::json!({})).unwrap(),
    );
    refused(&d, "frame.glb", "no _BARY attribute");
    // Depth of the wrong size; colour of the wrong size.
    let d = fresh("damaged-depth-size");
    replace(&d, "depth.f32", &[0u8; 40]);
    refused(&d, "depth.f32", "40 bytes");
    let d = fresh("damaged-colour-size");
    let small = terraclip::render::Image {
        width: 2,
        height: 2,
        rgba: vec![9; 16],
        depth: vec![],
    };
    replace(&d, "colour.png", &small.png().unwrap());
    refused(&d, "colour.png", "2x2");
    // A manifest naming a file outside the folder, or no file: `merge
    // --dir` would read and write there. A plain nested name is fine.
    for (name, ok) in [
        ("../escape.bin", false),
        ("/etc/escape.bin", false),
        ("./escape.bin", false),
        ("", false),
        ("sub/inside.bin", true),
    ] {
        let d = fresh(&format!("damaged-name-{}", name.len()));
        let mpath = d.join("manifest.json");
        let mut m: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&mpath).unwrap()).unwrap();
        let mut entry = m["files"][0].clone();
        entry["name"] = name.into();
        m["files"].as_array_mut().unwrap().push(entry);
        std::fs::write(&mpath, serde_json::to_vec(&m).unwrap()).unwrap();
        match (export::read(&d), ok) {
            (Err(e), false) => {
                let e = e.to_string();
                assert!(
                    e.contains("manifest.json") && e.contains("not a path inside"),
                    "{name}: {e}"
                );
            }
            (Err(e), true) => assert!(!e.to_string().contains("not a path inside"), "{name}: {e}"),
            (Ok(_), true) => {}
            (Ok(_), false) => panic!("{name}: read"),
        }
    }
    // Not a folder at all.
    refused(&good.join("frame.glb"), "frame.glb", "not a folder");
}

#[test]
fn an_export_of_a_path_holds_a_folder_per_frame() {
    let dir = tmp("path");
    let scene = Scene::load(Path::new("golden/morph-on.toml")).unwrap();
    let w = export::scene(&scene, "morph-on", None, 3, 37.0, &dir).unwrap();
    assert_eq!(w.frames.len(), 3);
    // The folder names its frames rather than reading as one.
    refused(&dir, "frame-0000", "lists 3 frame folders");
    let one = tmp("path-one");
    export::scene(&scene, "morph-on", None, 1, 37.0, &one).unwrap();
    let first = export::read(&one).unwrap();
    for (i, f) in w.frames.iter().enumerate() {
        assert_eq!(f.folder, format!("frame-{i:04}"));
        let e = export::read(&dir.join(&f.folder)).unwrap();
        let (img, _) = draw(&e.frame, &RenderOptions::default(), &mut Passes::default());
        assert!(
            img.rgba == e.image.rgba && img.depth == e.image.depth,
            "frame {i}"
        );
        // Frame 0 is the scene's own view; the others moved.
        assert_eq!(e.image.rgba == first.image.rgba, i == 0, "frame {i}");
    }
    // The top manifest lists every file of every frame.
    let m: export::Manifest =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(m.frames.len(), 3);
    assert_eq!(m.files.len() + 1, w.files);
}

#[test]
fn export_replaces_an_export_and_refuses_anything_else() {
    let dir = tmp("replace");
    let scene = Scene::load(Path::new("golden/wireframe.toml")).unwrap();
    export::scene(&scene, "wireframe", None, 1, 0.0, &dir).unwrap();
    export::scene(&scene, "wireframe", None, 2, 10.0, &dir).unwrap();
    assert!(dir.join("frame-0001/frame.glb").is_file() && !dir.join("frame.glb").exists());
    // A folder holding something else is left as it was.
    let other = tmp("replace-other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "mine").unwrap();
    let e = export::scene(&scene, "wireframe", None, 1, 0.0, &other)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("replace-other") && e.contains("not a terraclip export"),
        "{e}"
    );
    assert_eq!(
        std::fs::read_to_string(other.join("notes.txt")).unwrap(),
        "mine"
    );
    assert_eq!(std::fs::read_dir(&other).unwrap().count(), 1);
    // No temporary folder is left beside either. (Other tests write their
    // own exports in the same parent at the same time, so only this
    // test's names count.)
    let left: Vec<_> = std::fs::read_dir(dir.parent().unwrap())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            name.contains(".tmp-") && name.contains("replace")
        })
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// The exported files say what they hold: the camera's matrix makes the
/// reference's clip positions, the depth EXR equals the raw depth, and
/// the clipmap's toroids are the scene's level heights at their origins.
#[test]
fn the_files_hold_what_the_manifest_says() {
    let dir = tmp("contents");
    let path = Path::new("golden/jacksboro-oblique.toml");
    let scene = Scene::load(path).unwrap();
    export::scene(&scene, "jacksboro-oblique", None, 1, 0.0, &dir).unwrap();
    let e = export::read(&dir).unwrap();
    assert_eq!(e.camera.depth, export::DepthConvention::terraclip());
    assert_eq!(
        [e.camera.width, e.camera.height],
        [scene.image.width, scene.image.height]
    );
    // Every field of camera.json against the scene's camera, worked out
    // here: the camera as the scene gives it, the viewport the whole
    // image, the floating origin the base-grid vertex the frame is drawn
    // relative to (the map's north-west corner at the terrain's origin,
    // the sidecar's cells), and the matrices of the camera moved to it.
    let cam = scene.camera();
    let c = &e.camera;
    assert_eq!(
        (c.eye, c.target),
        (cam.eye.to_array(), cam.target.to_array())
    );
    assert_eq!(
        [c.fov_y_deg, c.aspect, c.near, c.far],
        [50.0, 400.0 / 240.0, 10.0, 80000.0]
    );
    assert_eq!(
        [c.fov_y_deg, c.aspect, c.near, c.far],
        [cam.fov_y_deg, cam.aspect, cam.near, cam.far]
    );
    assert_eq!(c.viewport, [0, 0, 400, 240]);
    let cell = terraclip::terrain::Heightmap::load(Path::new("tests/data/jacksboro_16.png"))
        .unwrap()
        .cell_size;
    let [gx, gy] = c.floating_origin_grid;
    let origin = scene.terrain.origin;
    let fo = glam::DVec3::new(
        origin[0] + gx as f64 * cell[0],
        origin[1] - gy as f64 * cell[1],
        0.0,
    );
    assert_eq!(c.floating_origin, fo.to_array());
    // The origin is a vertex near the eye (within a cell of it).
    assert!(
        (cam.eye.x - fo.x).abs() <= cell[0] && (cam.eye.y - fo.y).abs() <= cell[1],
        "{fo}"
    );
    assert_eq!(c.eye_relative, (cam.eye - fo).as_vec3().to_array());
    let rel = terraclip::camera::Camera {
        eye: cam.eye - fo,
        target: cam.target - fo,
        ..cam
    };
    assert_eq!(c.view, rel.view().to_cols_array_2d());
    assert_eq!(c.projection, rel.projection().to_cols_array_2d());
    // The f64 matrices agree with the f32 one they were rounded into.
    let vp = glam::DMat4::from_cols_array_2d(&e.camera.projection)
        * glam::DMat4::from_cols_array_2d(&e.camera.view);
    for c in 0..4 {
        for r in 0..4 {
            assert_eq!(vp.col(c)[r] as f32, e.camera.view_proj[c][r], "({c},{r})");
        }
    }
    // Toroids: each drawn level's window, read through its origin, is the
    // pyramid's level there.
    let mut session = terraclip::Session::new(&scene, &mut Passes::default()).unwrap();
    session
        .frame(&scene.camera(), &mut Passes::default())
        .unwrap();
    let pyr = session.pyramid();
    assert!(!e.info.toroids.is_empty());
    // Every active level is checked: frame.json's drawn levels, each with
    // a toroid that holds texels.
    let active: Vec<usize> = e
        .info
        .toroids
        .iter()
        .filter(|t| t.active)
        .map(|t| t.level)
        .collect();
    let drawn: Vec<usize> = e.info.levels.iter().map(|l| l.level).collect();
    assert_eq!(active, drawn, "active toroids against drawn levels");
    let mut levels_checked = vec![];
    for (t, data) in e.info.toroids.iter().zip(&e.toroids) {
        let Some([ox, oy]) = t.origin else {
            assert!(!t.active, "level {}: active without a window", t.level);
            continue;
        };
        let lv = &pyr.levels[t.level];
        let n = t.size as i64;
        let mut checked = 0;
        for y in oy..oy + n {
            for x in ox..ox + n {
                if x < 0 || y < 0 || x >= lv.width as i64 || y >= lv.height as i64 {
                    continue;
                }
                let i = (y.rem_euclid(n) * n + x.rem_euclid(n)) as usize;
                assert_eq!(
                    data[i].to_bits(),
                    lv.data[y as usize * lv.width + x as usize].to_bits()
                );
                checked += 1;
            }
        }
        assert!(checked > 0, "level {}", t.level);
        if t.active {
            levels_checked.push(t.level);
        }
    }
    assert_eq!(levels_checked, drawn, "levels whose toroid was checked");
}

/// `golden --export`: a folder per scene that `compare` reads, a README,
/// a manifest over all; none at all when a golden fails.
#[test]
fn golden_export_writes_a_conformance_pack_only_from_passing_goldens() {
    let goldens = tmp("pack-goldens");
    std::fs::create_dir_all(&goldens).unwrap();
    common::copy_golden("grazing-horizon", &goldens, "a");
    common::copy_golden("wireframe", &goldens, "b");
    let out = tmp("pack-out");
    let run = || {
        std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
            .arg("golden")
            .arg(&goldens)
            .arg("--json")
            .arg("--export")
            .arg(&out)
            .output()
            .unwrap()
    };
    let o = run();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["export"]["scenes"], serde_json::json!(["a", "b"]));
    let readme = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(readme.contains("terraclip compare") && readme.contains("Licence"));
    for name in ["a", "b"] {
        let e = export::read(&out.join(name)).unwrap();
        let (_, _, png) =
            terraclip::check::golden::load_png(&goldens.join(format!("{name}.png"))).unwrap();
        assert!(png == e.image.rgba, "{name}");
    }
    let m: export::Manifest =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(m.frames, ["a", "b"]);
    assert!(
        m.files.iter().any(|f| f.name == "b/frame.glb")
            && m.files.iter().any(|f| f.name == "README.md")
    );
    // A golden that fails: an error, and no pack.
    let _ = std::fs::remove_dir_all(&out);
    let (w, h, mut rgba) = terraclip::check::golden::load_png(&goldens.join("b.png")).unwrap();
    rgba[0] ^= 0xff;
    let img = terraclip::render::Image {
        width: w,
        height: h,
        rgba,
        depth: vec![],
    };
    std::fs::write(goldens.join("b.png"), img.png().unwrap()).unwrap();
    let o = run();
    assert!(!o.status.success());
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["export"].is_null(), "{v}");
    assert!(!out.exists());
}
