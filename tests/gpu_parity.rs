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

fn required() -> bool {
    std::env::var("TERRACLIP_REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// The first Vulkan adapter. Under `TERRACLIP_REQUIRE_GPU=1` lavapipe must
/// be the pinned one, so that exact mode is taken: a CI whose Mesa moved
/// would otherwise fall back to tolerance mode and pass without checking a
/// single bit.
fn renderer() -> Option<GpuRenderer> {
    match Gpu::new(Api::Vulkan) {
        Ok(g) => {
            let lavapipe = g.info.name.starts_with("llvmpipe");
            if required() && lavapipe && !g.exact_expected() {
                panic!(
                    "TERRACLIP_REQUIRE_GPU=1 and the adapter is lavapipe, but not the pinned \
                     one (Mesa 22.3.6 on x86-64 with FMA), so exact mode would not be taken: \
                     {} / {}",
                    g.info.name, g.info.driver_info
                );
            }
            eprintln!(
                "adapter: {} / {} (exact: {})",
                g.info.name,
                g.info.driver_info,
                g.exact_expected()
            );
            Some(GpuRenderer::new(g))
        }
        Err(e) => {
            if required() {
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

/// The six 100-frame paths the README reports (strips and footprints,
/// normal maps, wires, shadows, morph), each frame compared, the GPU's
/// toroids updated only by dirty rectangles. The uploads are a property of
/// the path, not of the image size, so the `default` path's counts are the
/// README's exactly: 64,538 texels rewritten where full uploads would write
/// 2,750,517 (2.3 %).
#[test]
fn a_100_frame_path_matches_with_incremental_texture_updates() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    for name in [
        "default",
        "non-square-edge",
        "phong-normal-map",
        "wireframe",
        "shadows-low-sun",
        "morph-on",
    ] {
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
        assert_eq!(res.frames, 100);
        if exact {
            assert_eq!(
                (res.colour_px_differ, res.depth_px_differ),
                (0, 0),
                "{name}"
            );
        }
        // The camera moved, so texels were rewritten, but far fewer than
        // full uploads would write.
        assert!(res.texels_uploaded > 0, "{res:?}");
        assert!(res.texels_uploaded * 10 < res.texels_full, "{res:?}");
        if name == "default" {
            assert_eq!((res.texels_uploaded, res.texels_full), (64_538, 2_750_517));
        }
    }
}

fn flat(v: u8) -> terraclip::render::Image {
    terraclip::render::Image {
        width: 100,
        height: 100,
        rgba: vec![v; 40_000],
        depth: vec![0.5; 10_000],
    }
}

fn paint(img: &mut terraclip::render::Image, x: usize, y: usize, v: u8, z: f32) {
    let i = y * img.width as usize + x;
    img.rgba[4 * i..4 * i + 3].fill(v);
    img.depth[i] = z;
}

#[test]
fn tolerance_mode_accepts_one_step_and_rejects_more() {
    let a = flat(10);
    let mut b = flat(10);
    b.rgba[0] = 11;
    let d = parity::Difference::of(&a, &b);
    assert_eq!((d.colour_px_differ, d.max_channel_diff), (1, 1));
    assert_eq!((d.shifted_px, d.unmatched_px), (0, 0));
    assert!(d.passes(false, 10_000) && !d.passes(true, 10_000));
    // Three steps: unmatched, and over the 0.1 % budget at 11 pixels.
    b.rgba[4] = 13;
    let d = parity::Difference::of(&a, &b);
    assert_eq!((d.shifted_px, d.unmatched_px), (0, 1));
    for i in 2..12 {
        b.rgba[4 * i] = 13;
    }
    let d = parity::Difference::of(&a, &b);
    assert_eq!((d.shifted_px, d.unmatched_px), (0, 11));
    assert!(!d.passes(false, 10_000));
    let mut c = flat(10);
    c.depth[3] = f32::from_bits(0.5f32.to_bits() + parity::TOLERANCE_DEPTH_ULP);
    let d = parity::Difference::of(&a, &c);
    assert_eq!(
        (d.depth_px_differ, d.max_depth_ulp),
        (1, parity::TOLERANCE_DEPTH_ULP)
    );
    assert!(d.passes(false, 10_000));
    c.depth[3] = f32::from_bits(0.5f32.to_bits() + parity::TOLERANCE_DEPTH_ULP + 1);
    assert_eq!(parity::Difference::of(&a, &c).unmatched_px, 1);
}

/// An edge one pixel over is a shift; a crack, a lost wire or a wrong depth
/// under an unchanged colour matches nowhere; a whole image moved by a pixel
/// is more shift than a frame may have.
#[test]
fn tolerance_mode_allows_edges_one_pixel_over_and_nothing_else() {
    // Terrain (10) over sky (200) with its silhouette at row 50, columns
    // 20..40 one row lower on the GPU.
    let mut cpu = flat(10);
    let mut gpu = flat(10);
    for y in 0..50 {
        for x in 0..100 {
            paint(&mut cpu, x, y, 200, 1.0);
            paint(&mut gpu, x, y, 200, 1.0);
        }
    }
    for x in 20..40 {
        paint(&mut gpu, x, 50, 200, 1.0);
    }
    let d = parity::Difference::of(&cpu, &gpu);
    assert_eq!(
        (d.shifted_px, d.unmatched_px, d.max_channel_diff),
        (20, 0, 190)
    );
    assert!(d.passes(false, 10_000));

    // A crack showing the sky inside the terrain: one pixel is counted but
    // within the 0.1 % a tie may flip; a crack along an 11-pixel edge is not.
    let mut crack = cpu.clone();
    paint(&mut crack, 60, 80, 200, 1.0);
    let d = parity::Difference::of(&cpu, &crack);
    assert_eq!((d.shifted_px, d.unmatched_px), (0, 1));
    assert!(d.passes(false, 10_000));
    for x in 61..71 {
        paint(&mut crack, x, 80, 200, 1.0);
    }
    let d = parity::Difference::of(&cpu, &crack);
    assert_eq!((d.shifted_px, d.unmatched_px), (0, 11));
    assert!(!d.passes(false, 10_000));

    // A wire column the GPU lost: every one of its pixels is unmatched.
    let mut wired = cpu.clone();
    for y in 60..90 {
        paint(&mut wired, 70, y, 255, 0.5);
    }
    let d = parity::Difference::of(&wired, &cpu);
    assert_eq!(d.unmatched_px, 30);
    assert!(!d.passes(false, 10_000));

    // The same colour at another depth (a fogged surface behind another).
    let mut deeper = cpu.clone();
    paint(&mut deeper, 30, 70, 10, 0.75);
    assert_eq!(parity::Difference::of(&cpu, &deeper).unmatched_px, 1);

    // A wall whose depth steps 0.004 per pixel: a GPU depth 1/32 of a step
    // off is the same pixel; half a step off everywhere is a shift of far
    // more than 1 % of the frame.
    let wall = |off: f32| {
        let mut img = flat(10);
        for y in 0..100 {
            for x in 0..100 {
                paint(&mut img, x, y, 10, 0.2 + 0.004 * (x as f32 + off));
            }
        }
        img
    };
    let d = parity::Difference::of(&wall(0.0), &wall(1.0 / 32.0));
    assert!(d.max_depth_ulp > parity::TOLERANCE_DEPTH_ULP);
    assert_eq!((d.shifted_px, d.unmatched_px), (0, 0));
    let d = parity::Difference::of(&wall(0.0), &wall(0.5));
    assert!(d.shifted_px > 9_000 && !d.passes(false, 10_000), "{d:?}");

    // A ramp moved by a pixel everywhere: every pixel but those of the two
    // border columns has a matching neighbour, and far more than 1 % shifted.
    let ramp = |off: usize| {
        let mut img = flat(0);
        for y in 0..100 {
            for x in 0..100 {
                paint(&mut img, x, y, (2 * (x + off) + y / 2) as u8, 0.5);
            }
        }
        img
    };
    let d = parity::Difference::of(&ramp(0), &ramp(1));
    assert!(d.unmatched_px <= 200, "{d:?}");
    assert!(d.shifted_px > 9_000 && !d.passes(false, 10_000), "{d:?}");
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
    // Coarse levels were missing at first and joined along the path, every
    // frame matching the CPU's: the count of unbuilt levels starts above 0,
    // never grows, and reaches 0.
    let unbuilt = res.levels_unbuilt.as_ref().expect("a lazy scene");
    assert_eq!(unbuilt.len(), 30);
    assert!(unbuilt[0] > 0, "{unbuilt:?}");
    assert!(unbuilt.windows(2).all(|w| w[1] <= w[0]), "{unbuilt:?}");
    assert_eq!(unbuilt.last(), Some(&0), "{unbuilt:?}");
    if exact {
        assert_eq!((res.colour_px_differ, res.depth_px_differ), (0, 0));
    }
}
