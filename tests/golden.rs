//! Golden images: exact (0 pixels may differ), for 1, 2 and 8 threads and
//! for the scalar, the portable 8-lane and the AVX2 + FMA 8-lane paths (the
//! last is the portable build again on a CPU without them). On failure, the actual and
//! difference images go to target/golden-diff.

use std::path::Path;
use terraclip::check::golden::{check_one, scenes};
use terraclip::raster::Path as RasterPath;
use terraclip::render::{render, RenderOptions};
use terraclip::scene::{Effect, Scene};

mod common;

#[test]
fn every_golden_matches_for_any_thread_count_and_path() {
    let diff_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/golden-diff");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("golden");
    let all = scenes(&dir).unwrap();
    assert!(all.len() >= 8, "at least 8 golden scenes");
    let mut failures = vec![];
    for (threads, path) in [
        (1, RasterPath::Scalar),
        (2, RasterPath::Simd),
        (8, RasterPath::Scalar),
        (8, RasterPath::Simd),
        (2, RasterPath::Portable),
    ] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        for s in &all {
            let r = pool
                .install(|| check_one(s, false, Some(&diff_dir), &RenderOptions { path }))
                .unwrap();
            if !r.pass {
                failures.push(format!(
                    "{} ({threads} threads, {path:?}): {} px, depth {}",
                    r.scene,
                    r.px_differ,
                    if r.depth_pass { "same" } else { "differs" }
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "goldens differ (images in {}):\n{}",
        diff_dir.display(),
        failures.join("\n")
    );
}

fn golden_scene(name: &str) -> Scene {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("golden/{name}.toml"));
    Scene::load(&p).unwrap()
}

#[test]
fn without_shadows_no_lightmap_is_built_and_the_frame_costs_less() {
    let with = golden_scene("shadows-low-sun");
    let mut without = with.clone();
    without.effects.retain(|e| *e != Effect::Shadows);
    let opts = RenderOptions::default();
    // Best of three each, to keep a busy machine from deciding the result.
    let best = |s: &Scene| {
        (0..3)
            .map(|_| render(s, &opts).unwrap().1)
            .min_by(|a, b| a.ms_total.total_cmp(&b.ms_total))
            .unwrap()
    };
    let (a, b) = (best(&with), best(&without));
    let names = |s: &terraclip::render::RenderStats| {
        s.passes.iter().map(|p| p.name.clone()).collect::<Vec<_>>()
    };
    assert!(
        names(&a).contains(&"lightmap".to_string()),
        "{:?}",
        names(&a)
    );
    assert!(
        a.lightmap_rays > 100_000,
        "one ray per texel: {}",
        a.lightmap_rays
    );
    assert!(
        !names(&b).contains(&"lightmap".to_string()),
        "{:?}",
        names(&b)
    );
    assert_eq!(b.lightmap_rays, 0);
    let lightmap_ms = a.passes.iter().find(|p| p.name == "lightmap").unwrap().ms;
    println!(
        "with shadows {:.1} ms (lightmap {:.1} ms), without {:.1} ms",
        a.ms_total, lightmap_ms, b.ms_total
    );
    assert!(
        b.ms_total < a.ms_total,
        "without shadows {:.1} ms, with {:.1} ms",
        b.ms_total,
        a.ms_total
    );
}

#[test]
fn without_lighting_no_normals_are_computed() {
    let mut s = golden_scene("jacksboro-oblique");
    let (_, lit) = render(&s, &RenderOptions::default()).unwrap();
    assert!(lit.passes.iter().any(|p| p.name == "normals"));
    assert!(lit.normals_computed > 0);
    s.effects = vec![Effect::Fog, Effect::Morph];
    let (_, unlit) = render(&s, &RenderOptions::default()).unwrap();
    assert!(unlit
        .passes
        .iter()
        .all(|p| p.name != "normals" && p.name != "normal-map"));
    assert_eq!(unlit.normals_computed, 0);
    assert_eq!(unlit.lightmap_rays, 0);
}

/// `TERRACLIP_SIMD` picks the build that runs, `render --json` says which
/// (`raster_path`), every build draws the same bits, and a value the
/// variable does not take is refused before anything is rendered.
#[test]
fn terraclip_simd_selects_the_path() {
    let dir = std::env::temp_dir().join(format!("terraclip-simd-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Asked of the CPU here, not of `cpu::has_avx2_fma`, so that a detection
    // that lied would fail.
    #[cfg(target_arch = "x86_64")]
    let avx2 = std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
    #[cfg(not(target_arch = "x86_64"))]
    let avx2 = false;
    assert_eq!(terraclip::cpu::has_avx2_fma(), avx2);
    let run = |value: Option<&str>| {
        let out = dir.join(format!("{}.png", value.unwrap_or("unset")));
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"));
        cmd.args(["render", "--size", "96x54", "--json", "-o"])
            .arg(&out)
            .env_remove("TERRACLIP_SIMD");
        if let Some(v) = value {
            cmd.env("TERRACLIP_SIMD", v);
        }
        let o = cmd.output().unwrap();
        (o, out)
    };
    let mut images = vec![];
    for (value, want) in [
        (None, if avx2 { "avx2+fma" } else { "portable" }),
        (Some("1"), if avx2 { "avx2+fma" } else { "portable" }),
        (Some("0"), "scalar"),
        (Some("scalar"), "scalar"),
        (Some("portable"), "portable"),
    ] {
        let (o, out) = run(value);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{value:?}: {err}");
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["raster_path"], want, "TERRACLIP_SIMD={value:?}");
        images.push(std::fs::read(&out).unwrap());
    }
    assert!(
        images.windows(2).all(|w| w[0] == w[1]),
        "every path, same PNG"
    );
    let (o, out) = run(Some("avx512"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && o.stdout.is_empty(), "{err}");
    assert!(err.contains("TERRACLIP_SIMD=\"avx512\""), "{err}");
    assert!(!out.exists(), "nothing written for a refused value");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The depth hash is part of the golden: one depth value a ULP off, a
/// changed `.depth` file or a missing one fails a scene whose colour is
/// unchanged; `--bless` writes the file back.
#[test]
fn goldens_compare_depth_as_well_as_colour() {
    use terraclip::check::golden::depth_hash;
    let d = vec![0.25f32, 0.5, 1.0];
    let mut e = d.clone();
    e[1] = f32::from_bits(e[1].to_bits() + 1);
    assert_ne!(depth_hash(&d), depth_hash(&e));
    assert_ne!(depth_hash(&d), depth_hash(&d[..2]));
    assert_ne!(depth_hash(&[0.0]), depth_hash(&[-0.0]));

    let dir = std::env::temp_dir().join(format!("terraclip-golden-depth-{}", std::process::id()));
    common::copy_golden("level-tint", &dir, "level-tint");
    let scene = dir.join("level-tint.toml");
    let depth = dir.join("level-tint.depth");
    let opts = RenderOptions::default();
    let r = check_one(&scene, false, None, &opts).unwrap();
    assert!(r.pass && r.depth_pass && r.px_differ == 0, "{r:?}");
    let line = std::fs::read_to_string(&depth).unwrap();
    assert_eq!(line, format!("fnv1a64 {} 400x240\n", r.depth_hash));
    // One hex digit changed.
    let last = line.find(' ').unwrap() + 16;
    let mut changed = line.clone().into_bytes();
    changed[last] = if changed[last] == b'0' { b'1' } else { b'0' };
    std::fs::write(&depth, &changed).unwrap();
    let r = check_one(&scene, false, None, &opts).unwrap();
    assert!(!r.pass && !r.depth_pass && r.px_differ == 0, "{r:?}");
    std::fs::remove_file(&depth).unwrap();
    let r = check_one(&scene, false, None, &opts).unwrap();
    assert!(!r.pass && !r.depth_pass, "{r:?}");
    let r = check_one(&scene, true, None, &opts).unwrap();
    assert!(r.pass && r.blessed, "{r:?}");
    assert_eq!(std::fs::read_to_string(&depth).unwrap(), line);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The `morph-off` golden cracks on purpose and `morph-on` does not:
/// counted as background (red) pixels enclosed by terrain where a
/// brute-force render of the same view covers them. The renders are
/// deterministic, so the count is exact (measured 2026-12-01).
#[test]
fn the_morph_off_golden_cracks_and_morph_on_does_not() {
    let opts = RenderOptions::default();
    let cracks = |name: &str| {
        let s = golden_scene(name);
        let (img, _) = render(&s, &opts).unwrap();
        let (bf, _) = render(&s.with_lod("brute-force").unwrap(), &opts).unwrap();
        terraclip::studies::metrics::crack_pixels(&img, &bf, [255, 0, 0])
    };
    let (off, on) = (cracks("morph-off"), cracks("morph-on"));
    println!("enclosed background pixels: morph-off {off}, morph-on {on}");
    assert_eq!(on, 0, "morph-on is crack-free");
    assert_eq!(off, MORPH_OFF_CRACK_PIXELS, "morph-off cracks");
}

const MORPH_OFF_CRACK_PIXELS: usize = 69;
