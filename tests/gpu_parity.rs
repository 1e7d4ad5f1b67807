//! The wgpu back end against the CPU reference, on every golden scene (the
//! near-plane clip and grazing cases included) and along a 100-frame camera
//! path that scrolls and wraps the GPU's toroidal textures.
//!
//! Without an adapter the tests print why and return; with
//! `TERRACLIP_REQUIRE_GPU=1` (set by `.ci/run`) a missing adapter fails.
#![cfg(feature = "gpu")]

use std::path::Path;
use terraclip::gpu::{parity, Api, Gpu, GpuRenderer};
use terraclip::scene::Scene;

fn renderer() -> Option<GpuRenderer> {
    match Gpu::new(Api::Vulkan) {
        Ok(g) => Some(GpuRenderer::new(g)),
        Err(e) => {
            if std::env::var("TERRACLIP_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("TERRACLIP_REQUIRE_GPU=1 but no adapter: {e}");
            }
            eprintln!("skipping GPU parity: {e}");
            None
        }
    }
}

fn out() -> std::path::PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("gpu-parity")
}

#[test]
fn every_golden_scene_matches_the_cpu() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    let scenes = terraclip::golden::scenes(Path::new("golden")).unwrap();
    assert!(scenes.len() >= 10);
    for p in scenes {
        let name = p.file_stem().unwrap().to_string_lossy().into_owned();
        let scene = Scene::load(&p).unwrap();
        let res = parity::check(&mut r, &scene, &name, 1, 0.0, &out(), exact).unwrap();
        eprintln!("{name}: {res:?} (exact: {exact})");
        assert!(res.pass, "{name}: {res:?}");
        if exact {
            assert_eq!(
                (res.colour_px_differ, res.depth_px_differ),
                (0, 0),
                "{name}"
            );
        }
    }
}

#[test]
fn a_100_frame_path_matches_with_incremental_texture_updates() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    // Strips (default) and footprints (non-square-edge) layouts.
    for name in ["default", "non-square-edge"] {
        let mut scene = Scene::load(Path::new(&format!("golden/{name}.toml"))).unwrap();
        scene
            .apply(&terraclip::scene::Overrides {
                size: Some([192, 108]),
                ..Default::default()
            })
            .unwrap();
        let res = parity::check(&mut r, &scene, name, 100, 37.0, &out(), exact).unwrap();
        eprintln!("{name} path: {res:?}");
        assert!(res.pass, "{name}: {res:?}");
        // The camera moved, so texels were rewritten, but far fewer than
        // full uploads would write.
        assert!(res.texels_uploaded > 0, "{res:?}");
        assert!(res.texels_uploaded * 10 < res.texels_full, "{res:?}");
    }
}

#[test]
fn tolerance_mode_accepts_one_step_and_rejects_more() {
    use terraclip::render::Image;
    let img = |v: u8| Image {
        width: 100,
        height: 100,
        rgba: vec![v; 40_000],
        depth: vec![0.5; 10_000],
    };
    let a = img(10);
    let mut b = img(10);
    b.rgba[0] = 11;
    let d = parity::Difference::of(&a, &b);
    assert_eq!((d.colour_px_differ, d.max_channel_diff), (1, 1));
    assert!(d.passes(false, 10_000) && !d.passes(true, 10_000));
    b.rgba[4] = 13;
    assert!(!parity::Difference::of(&a, &b).passes(false, 10_000));
    let mut c = img(10);
    c.depth[3] = f32::from_bits(0.5f32.to_bits() + 5);
    let d = parity::Difference::of(&a, &c);
    assert_eq!((d.depth_px_differ, d.max_depth_ulp), (1, 5));
    assert!(!d.passes(false, 10_000));
}

#[test]
fn brute_force_passthrough_matches_the_cpu() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    let mut scene = Scene::load(Path::new("golden/jacksboro-oblique.toml")).unwrap();
    let effects = ["lambert", "fog", "shadows", "wireframe"];
    scene
        .apply(&terraclip::scene::Overrides {
            lod: Some("brute-force".into()),
            effects: Some(effects.iter().map(|s| s.to_string()).collect()),
            ..Default::default()
        })
        .unwrap();
    let res = parity::check(&mut r, &scene, "brute-force", 1, 0.0, &out(), exact).unwrap();
    eprintln!("brute force: {res:?}");
    assert!(res.pass && res.triangles > 100_000, "{res:?}");
}

/// A lazy pyramid whose coarse levels join over the path (a small budget):
/// the GPU's textures follow levels that appear mid-path.
#[test]
fn a_lazy_pyramid_path_matches_as_coarse_levels_join() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    let mut scene = Scene::default_scene();
    scene.pyramid.lazy = true;
    scene.pyramid.budget = 100_000;
    scene.shading.height_range = Some([-300.0, 300.0]);
    scene.image.width = 192;
    scene.image.height = 108;
    scene.validate().unwrap();
    let res = parity::check(&mut r, &scene, "lazy", 30, 37.0, &out(), exact).unwrap();
    eprintln!("lazy path: {res:?}");
    assert!(res.pass, "{res:?}");
    if exact {
        assert_eq!((res.colour_px_differ, res.depth_px_differ), (0, 0));
    }
}
