//! `terraclip compare`: an outside renderer's image against an export.
//! The exported reference passes every mode; a one-pixel crack line and a
//! clipmap level shifted by a texel fail every mode; a JPEG-recompressed
//! copy passes FLIP and fails exact; a depth buffer of another convention
//! is an error naming the convention.

mod common;

use std::path::{Path, PathBuf};
use terraclip::check::compare;
use terraclip::check::outside::{self, Mode};
use terraclip::export;
use terraclip::frame::stats::Passes;
use terraclip::render::{draw, Image, RenderOptions};
use terraclip::scene::Scene;

fn tmp(name: &str) -> PathBuf {
    common::fresh_tmp("compare", name)
}

/// Exports golden `name` to a folder of its own (the tests run at once).
fn exported(name: &str) -> export::Exported {
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = tmp(&format!("ref-{name}-{n}"));
    let scene = Scene::load(Path::new(&format!("golden/{name}.toml"))).unwrap();
    export::scene(&scene, name, None, 1, 0.0, &dir).unwrap();
    export::read(&dir).unwrap()
}

fn all_modes(e: &export::Exported, img: &Image, what: &str) -> Vec<outside::Outcome> {
    [Mode::Exact, Mode::Tiered, Mode::Flip]
        .iter()
        .map(|&m| {
            let o = outside::compare(e, img, &outside::Options::new(m), None).unwrap();
            eprintln!(
                "{what} {m}: pass {} colour {} depth {} tiers {:?} flip {:?}",
                o.pass, o.colour_px_differ, o.depth_px_differ, o.tiers, o.flip
            );
            o
        })
        .collect()
}

/// A JPEG of `img` at `quality`, decoded again.
fn jpeg(img: &Image, quality: u8) -> Image {
    let rgb: Vec<u8> = img
        .rgba
        .chunks(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    let mut bytes = vec![];
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality)
        .encode(&rgb, img.width, img.height, image::ExtendedColorType::Rgb8)
        .unwrap();
    let back = image::load_from_memory(&bytes).unwrap().to_rgba8();
    Image {
        rgba: back.into_raw(),
        depth: vec![],
        ..img.clone()
    }
}

const SCENES: [&str; 3] = ["jacksboro-oblique", "level-tint", "shadows-low-sun"];

/// The reference with one column of terrain pixels showing background, as
/// a crack between levels does; returns the image and the pixels painted.
fn crack(e: &export::Exported) -> (Image, usize) {
    let mut c = e.image.clone();
    let w = c.width as usize;
    let bg = e.frame.background.map(terraclip::raster::unorm8);
    let mut n = 0;
    for y in 0..c.height as usize {
        let i = y * w + w / 2;
        if e.image.depth[i] < 1.0 {
            c.rgba[4 * i..4 * i + 3].copy_from_slice(&bg);
            c.depth[i] = 1.0;
            n += 1;
        }
    }
    (c, n)
}

#[test]
fn the_reference_itself_passes_every_mode() {
    for name in SCENES {
        let e = exported(name);
        for o in all_modes(&e, &e.image.clone(), name) {
            assert!(
                o.pass && o.colour_px_differ == 0 && o.worst.is_none(),
                "{name}: {o:?}"
            );
            assert_eq!(o.tiers.same, (e.image.width * e.image.height) as usize);
        }
    }
}

#[test]
fn a_one_pixel_crack_line_fails_every_mode() {
    for name in SCENES {
        let e = exported(name);
        let (img, n) = crack(&e);
        assert!(n > 50, "{name}: {n}");
        for o in all_modes(&e, &img, &format!("{name} crack")) {
            assert!(!o.pass, "{name} {}: {o:?}", o.mode);
            assert_eq!(o.colour_px_differ, n);
        }
    }
}

/// The frame as a renderer would draw it whose toroid addressing for one
/// level is a texel off: that level's triangles moved by one of its texels.
#[test]
fn a_level_shifted_by_a_texel_fails_every_mode() {
    for name in SCENES {
        let e = exported(name);
        let level = e.info.levels[1].level;
        let step = (1u32 << level) as f32 * e.frame.uniforms.cell[0];
        let mut f = e.frame.clone();
        let mut moved = 0;
        for (t, &l) in f.mesh.levels.iter().enumerate() {
            if l as usize == level {
                for v in 0..3 {
                    f.positions[3 * t + v][0] += step;
                }
                moved += 1;
            }
        }
        assert!(moved > 100, "{name}: {moved}");
        let (img, _) = draw(&f, &RenderOptions::default(), &mut Passes::default());
        for o in all_modes(&e, &img, &format!("{name} shifted level {level}")) {
            assert!(!o.pass, "{name} {}: {o:?}", o.mode);
        }
    }
}

#[test]
fn a_jpeg_copy_passes_flip_and_fails_exact() {
    for name in SCENES {
        let e = exported(name);
        let img = jpeg(
            &Image {
                depth: vec![],
                ..e.image.clone()
            },
            90,
        );
        let o = all_modes(&e, &img, &format!("{name} jpeg90"));
        assert!(
            !o[0].pass && o[0].colour_px_differ > 1000,
            "{name}: {:?}",
            o[0]
        );
        assert!(o[2].pass, "{name}: {:?}", o[2]);
        assert!(!o[2].depth_compared);
        // With the reference's depth beside it, flip mode still judges the
        // geometry by depth alone: the JPEG's colour is no hole and no
        // depth outside the band, so it passes.
        let with_depth = Image {
            depth: e.image.depth.clone(),
            ..img
        };
        let o =
            outside::compare(&e, &with_depth, &outside::Options::new(Mode::Flip), None).unwrap();
        assert!(o.pass && o.depth_compared, "{name}: {o:?}");
        assert!(o.tiers.outside_band > 0, "{name}: {o:?}");
    }
}

/// An image one 8-bit step off everywhere passes tiered and flip; two
/// steps off fails both: FLIP's thresholds sit where tiered's do. Over
/// every golden, as `outside::FLIP_MEAN` and `FLIP_TAIL_MAX` state it,
/// over the pixels outside the tie band (what flip mode judges): one step
/// off has a mean FLIP of 0.0317–0.0406, two steps 0.0521–0.0665, and
/// neither passes 0.1106 at the 99.99th percentile (measured 2026-12-07;
/// the thresholds 0.05 and 0.15 lie between).
#[test]
fn flip_passes_one_step_and_fails_two() {
    let goldens = terraclip::check::golden::scenes(Path::new("golden")).unwrap();
    assert_eq!(goldens.len(), 16);
    let (mut means, mut tails) = ([[f32::MAX, 0f32]; 2], [[f32::MAX, 0f32]; 2]);
    for path in &goldens {
        let name = &*path.file_stem().unwrap().to_string_lossy();
        let e = exported(name);
        let off = |step: u8| {
            let mut s = Image {
                depth: vec![],
                ..e.image.clone()
            };
            for (k, v) in s.rgba.iter_mut().enumerate() {
                if k % 4 != 3 {
                    *v = if *v > 127 { *v - step } else { *v + step };
                }
            }
            all_modes(&e, &s, &format!("{name} {step} step"))
        };
        let one = off(1);
        assert!(
            !one[0].pass && one[1].pass && one[2].pass,
            "{name}: {one:?}"
        );
        let two = off(2);
        assert!(!two[1].pass && !two[2].pass, "{name}: {two:?}");
        for (k, o) in [&one[2], &two[2]].into_iter().enumerate() {
            means[k] = [means[k][0].min(o.flip.mean), means[k][1].max(o.flip.mean)];
            tails[k] = [tails[k][0].min(o.flip.p9999), tails[k][1].max(o.flip.p9999)];
        }
    }
    println!(
        "FLIP mean one step {:?}, two steps {:?}; p99.99 {tails:?}",
        means[0], means[1]
    );
    let within = |[lo, hi]: [f32; 2], [a, b]: [f32; 2]| lo >= a && hi <= b;
    assert!(within(means[0], [0.0317, 0.0406]), "{means:?}");
    assert!(within(means[1], [0.0521, 0.0665]), "{means:?}");
    assert!(tails[1][1].max(tails[0][1]) <= 0.1106, "{tails:?}");
}

fn scene_camera(name: &str) -> terraclip::camera::Camera {
    Scene::load(Path::new(&format!("golden/{name}.toml")))
        .unwrap()
        .camera()
}

fn write_depth(path: &Path, d: &[f32]) {
    std::fs::write(
        path,
        d.iter().flat_map(|z| z.to_le_bytes()).collect::<Vec<u8>>(),
    )
    .unwrap();
}

#[test]
fn depth_of_another_convention_is_named() {
    let dir = tmp("conventions");
    std::fs::create_dir_all(&dir).unwrap();
    let e = exported("jacksboro-oblique");
    let png = dir.join("theirs.png");
    std::fs::write(&png, e.image.png().unwrap()).unwrap();
    let run = |name: &str, d: Vec<f32>| {
        let p = dir.join(name);
        write_depth(&p, &d);
        outside::run(
            &e.dir,
            Some(&png),
            Some(&p),
            &outside::Options::new(Mode::Tiered),
            None,
        )
        .map_err(|e| e.to_string())
    };
    // Their own depth, as raw f32 and as EXR: passes exact.
    let o = run("same.f32", e.image.depth.clone()).unwrap();
    assert!(
        o.pass && o.depth_compared && o.depth_px_differ == 0,
        "{o:?}"
    );
    let o = outside::run(
        &e.dir,
        Some(&png),
        Some(&e.dir.join("depth.exr")),
        &outside::Options::new(Mode::Exact),
        None,
    )
    .unwrap();
    assert!(o.pass && o.depth_compared, "{o:?}");
    // Reversed Z: near is 1, cleared to 0.
    let reversed: Vec<f32> = e.image.depth.iter().map(|z| 1.0 - z).collect();
    let err = run("reversed.f32", reversed).unwrap_err();
    assert!(
        err.contains("reversed.f32") && err.contains("reversed-Z"),
        "{err}"
    );
    // Reversed Z but cleared to 1 like ours: the order gives it away.
    let flipped: Vec<f32> = e
        .image
        .depth
        .iter()
        .map(|&z| if z < 1.0 { 1.0 - z } else { 1.0 })
        .collect();
    let err = run("flipped.f32", flipped).unwrap_err();
    assert!(
        err.contains("reversed Z") && err.contains("ordered the other way"),
        "{err}"
    );
    // Ours, but cleared to 0.
    let zero: Vec<f32> = e
        .image
        .depth
        .iter()
        .map(|&z| if z < 1.0 { z } else { 0.0 })
        .collect();
    let err = run("zero.f32", zero).unwrap_err();
    assert!(err.contains("cleared to 0"), "{err}");
    // Distances in metres rather than window depth.
    let cam = scene_camera("jacksboro-oblique");
    let metres: Vec<f32> = e
        .image
        .depth
        .iter()
        .map(|&z| compare::linear_depth(z, &cam) as f32)
        .collect();
    let err = run("metres.f32", metres).unwrap_err();
    assert!(
        err.contains("metres.f32") && err.contains("outside 0..1"),
        "{err}"
    );
    // GL's default depth range with a 0..1 projection: 0.5 + 0.5 z.
    let gl: Vec<f32> = e.image.depth.iter().map(|&z| 0.5 + 0.5 * z).collect();
    let err = run("gl-range.f32", gl).unwrap_err();
    assert!(
        err.contains("gl-range.f32")
            && err.contains("default depth range")
            && err.contains("glClipControl"),
        "{err}"
    );
    // Rows bottom first, as glReadPixels returns them.
    let (w, h) = (e.image.width as usize, e.image.height as usize);
    let upside_down = |v: &[f32]| -> Vec<f32> {
        (0..h)
            .rev()
            .flat_map(|y| v[y * w..(y + 1) * w].to_vec())
            .collect()
    };
    let err = run("bottom-first.f32", upside_down(&e.image.depth)).unwrap_err();
    assert!(err.contains("bottom first"), "{err}");
    // Big-endian floats.
    let p = dir.join("big-endian.f32");
    std::fs::write(
        &p,
        e.image
            .depth
            .iter()
            .flat_map(|z| z.to_be_bytes())
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    let err = outside::run(
        &e.dir,
        Some(&png),
        Some(&p),
        &outside::Options::new(Mode::Tiered),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("big-endian.f32") && err.contains("big-endian floats"),
        "{err}"
    );
    // A 24-bit fixed-point buffer read back as float: seen below 0.5,
    // where a float is finer than the 24-bit grid; near-clip-cliff's
    // cliff has such depths (jacksboro-oblique's view has none).
    let cliff = exported("near-clip-cliff");
    let d24 = |z: f32| ((z as f64 * 16_777_215.0).round() / 16_777_215.0) as f32;
    let fixed: Vec<f32> = cliff.image.depth.iter().map(|&z| d24(z)).collect();
    let below = cliff
        .image
        .depth
        .iter()
        .zip(&fixed)
        .filter(|(z, f)| **z < 0.5 && z != f)
        .count();
    assert!(below >= 16, "{below} pixels below 0.5 differ in D24");
    let p = dir.join("d24.f32");
    write_depth(&p, &fixed);
    let cliff_png = dir.join("cliff.png");
    std::fs::write(&cliff_png, cliff.image.png().unwrap()).unwrap();
    let err = outside::run(
        &cliff.dir,
        Some(&cliff_png),
        Some(&p),
        &outside::Options::new(Mode::Exact),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("24-bit depth buffer (D24)"), "{below}: {err}");
    // A renderer whose depth is off by a few ULP is none of these: it
    // passes tiered.
    let near: Vec<f32> = e
        .image
        .depth
        .iter()
        .map(|&z| {
            if z < 1.0 {
                f32::from_bits(z.to_bits() + 3)
            } else {
                z
            }
        })
        .collect();
    assert!(run("three-ulp.f32", near).unwrap().pass);
    // The wrong length, and a format it cannot read.
    let err = run("short.f32", vec![0.5; 7]).unwrap_err();
    assert!(
        err.contains("short.f32") && err.contains("28 bytes"),
        "{err}"
    );
    let err = outside::run(
        &e.dir,
        Some(&png),
        Some(&png),
        &outside::Options::new(Mode::Exact),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains(".f32 (raw little-endian) or .exr"), "{err}");
}

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_terraclip")
}

#[test]
fn the_command_exits_non_zero_on_failure_and_writes_its_pictures() {
    let dir = tmp("cli");
    std::fs::create_dir_all(&dir).unwrap();
    let reference = dir.join("ref");
    let out = std::process::Command::new(bin())
        .args(["export", "golden/level-tint.toml", "--json", "--out"])
        .arg(&reference)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frames"][0]["folder"], ".");
    let e = export::read(&reference).unwrap();
    let (img, _) = crack(&e);
    let theirs = dir.join("theirs.png");
    std::fs::write(&theirs, img.png().unwrap()).unwrap();
    let pics = dir.join("pics");
    let run = |args: &[&str]| {
        std::process::Command::new(bin())
            .arg("compare")
            .arg(&reference)
            .args(args)
            .output()
            .unwrap()
    };
    for mode in ["exact", "tiered", "flip"] {
        let o = run(&[
            "--image",
            theirs.to_str().unwrap(),
            "--mode",
            mode,
            "--json",
            "--out",
            pics.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{mode}");
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["pass"], false);
        assert_eq!(v["mode"], mode);
        for key in ["colour_px_differ", "tiers", "worst", "flip", "outputs"] {
            assert!(!v[key].is_null(), "{key}: {v}");
        }
        assert!(v["flip"]["p9999"].as_f64().unwrap() > 0.15);
        assert!(String::from_utf8_lossy(&o.stderr).contains("does not match"));
    }
    let diff = image::open(pics.join("diff.png")).unwrap();
    assert_eq!(
        (diff.width(), diff.height()),
        (3 * e.image.width, e.image.height)
    );
    assert!(pics.join("flip.png").is_file());
    // The reference's own colour passes, exit 0.
    let own = reference.join("colour.png");
    let o = run(&[
        "--image",
        own.to_str().unwrap(),
        "--depth",
        reference.join("depth.f32").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Bad input: clean errors naming what is wrong, never a panic.
    let small = dir.join("small.png");
    std::fs::write(
        &small,
        Image {
            width: 3,
            height: 2,
            rgba: vec![0; 24],
            depth: vec![],
        }
        .png()
        .unwrap(),
    )
    .unwrap();
    for (args, want) in [
        (
            vec!["--image", small.to_str().unwrap()],
            "3x2 where the reference is 400x240",
        ),
        (
            vec!["--image", theirs.to_str().unwrap(), "--mode", "fuzzy"],
            "invalid value 'fuzzy'",
        ),
    ] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(want) && !err.contains("panicked"),
            "{err}"
        );
    }
    for bad_ref in [dir.join("missing"), dir.join("theirs.png")] {
        let o = std::process::Command::new(bin())
            .arg("compare")
            .arg(&bad_ref)
            .args(["--image", theirs.to_str().unwrap()])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success()
                && err.contains(bad_ref.to_str().unwrap())
                && !err.contains("panicked"),
            "{err}"
        );
    }
}

/// `frame` as a rasteriser with 4 sub-pixel bits would draw it (Vulkan's
/// least, SwiftShader's): every vertex with w > 0 moved in window space to
/// the nearest 1/16 px, its clip z and w kept.
fn snapped_to_sixteenths(frame: &terraclip::frame::Frame) -> terraclip::frame::Frame {
    use glam::{DMat4, DVec4};
    let vp = DMat4::from_cols_array_2d(&frame.uniforms.view_proj.map(|c| c.map(f64::from)));
    let inv = vp.inverse();
    let (w, h) = (frame.width as f64, frame.height as f64);
    let mut out = frame.clone();
    for p in &mut out.positions {
        let c = vp * DVec4::new(p[0] as f64, p[1] as f64, p[2] as f64, 1.0);
        if c.w <= 1e-9 {
            continue;
        }
        let snap = |v: f64| (v * 16.0).round() / 16.0;
        let x = snap((c.x / c.w + 1.0) / 2.0 * w);
        let y = snap((1.0 - c.y / c.w) / 2.0 * h);
        let moved = DVec4::new(
            (2.0 * x / w - 1.0) * c.w,
            (1.0 - 2.0 * y / h) * c.w,
            c.z,
            c.w,
        );
        let q = inv * moved;
        *p = [(q.x / q.w) as f32, (q.y / q.w) as f32, (q.z / q.w) as f32];
    }
    out
}

/// A renderer with 4 sub-pixel bits differs only by sub-pixel coverage,
/// and passes tiered on every golden: the tie band holds the edges of
/// every triangle that could be in front at a pixel, not only of those the
/// reference drew there (a sliver covers no pixel centre; a triangle a
/// hair behind another is drawn nowhere). With 8 bits claimed, the same
/// frames fail: their vertices moved further than 8 bits allow. Flip
/// mode passes all 16 too, judging FLIP away from the band; FLIP over
/// every pixel (`flip_all`) would fail 13 of them on the silhouettes.
/// In `phong-normal-map`, 7 pixels 0.11–0.22 px from an edge lie in
/// triangles a fraction of a pixel wide, where a 1/32 px move changes the
/// colour by 2 steps; they pass because the move's reach
/// (`compare::Reach`) holds their colour.
/// `morph-off` draws the cracks between levels that the morph closes; a
/// crack's border moved by a sixteenth turns a pixel from background to
/// surface, which is no hole since the crack's edges are open
/// (`compare::open_band`).
#[test]
fn a_four_bit_rasteriser_passes_tiered_and_not_at_eight_bits() {
    let goldens: Vec<_> = terraclip::check::golden::scenes(Path::new("golden"))
        .unwrap()
        .into_iter()
        .collect();
    assert_eq!(goldens.len(), 16);
    let (mut fails, mut fails_at_eight, mut flips_over_all) = (vec![], 0, 0);
    for path in &goldens {
        let name = &*path.file_stem().unwrap().to_string_lossy();
        let e = exported(name);
        let (theirs, _) = draw(
            &snapped_to_sixteenths(&e.frame),
            &RenderOptions::default(),
            &mut Passes::default(),
        );
        let mut opts = outside::Options::new(Mode::Tiered);
        let o = outside::compare(&e, &theirs, &opts, None).unwrap();
        eprintln!(
            "{name}: 4 bits: pass {} ({} colour, {} depth px differ, {:?}, band {} px)",
            o.pass, o.colour_px_differ, o.depth_px_differ, o.tiers, o.band_px
        );
        if !o.pass {
            fails.push(format!("{name}: {:?} {:?}", o.reason, o.failing));
        }
        // Flip mode judges FLIP away from the band, where the snapped
        // silhouettes lie.
        let flip = outside::compare(&e, &theirs, &outside::Options::new(Mode::Flip), None).unwrap();
        let all = flip.flip_all;
        eprintln!(
            "{name}: flip: pass {} (outside the band: mean {:.4} p99.99 {:.4}; every pixel: mean {:.4} p99.99 {:.4})",
            flip.pass, flip.flip.mean, flip.flip.p9999, all.mean, all.p9999
        );
        if !flip.pass {
            fails.push(format!("{name} flip: {:?}", flip.reason));
        }
        flips_over_all +=
            usize::from(all.mean > outside::FLIP_MEAN || all.p9999 > outside::FLIP_TAIL_MAX);
        opts.subpixel_bits = 8;
        let o8 = outside::compare(&e, &theirs, &opts, None).unwrap();
        eprintln!("{name}: 8 bits: pass {} band {} px", o8.pass, o8.band_px);
        assert!(o8.band_px < o.band_px, "{name}");
        fails_at_eight += usize::from(!o8.pass);
    }
    assert!(fails.is_empty(), "{fails:#?}");
    assert_eq!(fails_at_eight, goldens.len());
    eprintln!(
        "FLIP over every pixel would fail {flips_over_all} of {}",
        goldens.len()
    );
    assert_eq!(flips_over_all, 13, "FLIP over every pixel");
}

/// The open band (where a crack of the mesh's own may open or close by a
/// sub-pixel move, see `compare::open_band`) touches enclosed background
/// only in `morph-off`, whose level seams crack on purpose: on every
/// watertight golden its pixels lie at the rim against the sky, where no
/// hole is counted, so it excuses nothing there. Behind a surface in
/// front of everything (depth 0) no open edge is seen and it is empty.
#[test]
fn only_the_cracked_golden_has_open_edges_beside_enclosed_background() {
    for path in terraclip::check::golden::scenes(Path::new("golden")).unwrap() {
        let name = &*path.file_stem().unwrap().to_string_lossy();
        let e = exported(name);
        let (w, h) = (e.image.width as usize, e.image.height as usize);
        let open = compare::open_band(&e.frame, &e.image.depth, 4);
        let bg: Vec<bool> = e.image.depth.iter().map(|&z| z == 1.0).collect();
        let enclosed = compare::enclosed(&bg, w, h);
        let beside = (0..w * h)
            .filter(|&i| open[i])
            .filter(|&i| {
                let (px, py) = (i % w, i / w);
                (py.saturating_sub(1)..=(py + 1).min(h - 1)).any(|y| {
                    (px.saturating_sub(1)..=(px + 1).min(w - 1)).any(|x| enclosed[y * w + x])
                })
            })
            .count();
        let n = open.iter().filter(|&&b| b).count();
        eprintln!("{name}: open band {n} px, {beside} beside enclosed background");
        if name == "morph-off" {
            assert!(beside > 0, "{name}: its cracks are open edges");
        } else {
            assert_eq!(beside, 0, "{name}");
        }
        let hidden = compare::open_band(&e.frame, &vec![0.0; w * h], 4);
        assert!(
            !hidden.contains(&true),
            "{name}: open edges seen through a wall"
        );
    }
}

/// A renderer that mishandles vertices at or behind the eye plane (w ≤ 0)
/// by nudging them to just in front of it, rather than clipping the
/// triangle at the near plane, draws the visible part of each such
/// triangle with another plane: its depth is wrong where a vertex has
/// w = 0. With every other vertex snapped to 1/16 px as well, tiered and
/// flip mode must still fail it at 4 bits, whatever the reach and band
/// allow for the snap.
#[test]
fn a_wrong_depth_where_a_vertex_has_w_zero_fails_at_four_bits() {
    let e = exported("grazing-horizon");
    let mut frame = snapped_to_sixteenths(&e.frame);
    let m = e.frame.uniforms.view_proj;
    let row3 = [m[0][3], m[1][3], m[2][3], m[3][3]].map(f64::from);
    let n2 = row3[0] * row3[0] + row3[1] * row3[1] + row3[2] * row3[2];
    let mut nudged = 0;
    for p in &mut frame.positions {
        let w = row3[0] * p[0] as f64 + row3[1] * p[1] as f64 + row3[2] * p[2] as f64 + row3[3];
        if w <= 0.0 {
            let k = (1e-3 - w) / n2;
            *p = [0, 1, 2].map(|i| (p[i] as f64 + row3[i] * k) as f32);
            nudged += 1;
        }
    }
    assert_eq!(nudged, 62, "vertices at or behind the eye plane");
    let (theirs, _) = draw(&frame, &RenderOptions::default(), &mut Passes::default());
    for mode in [Mode::Tiered, Mode::Flip] {
        let o = outside::compare(&e, &theirs, &outside::Options::new(mode), None).unwrap();
        eprintln!(
            "{mode:?}: {nudged} vertices nudged: pass {} ({} depth px differ, {:?})",
            o.pass, o.depth_px_differ, o.tiers
        );
        assert!(!o.pass, "{mode:?}");
    }
}
