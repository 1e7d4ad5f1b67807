//! The wgpu back end against the CPU reference, on every golden scene (the
//! near-plane clip and grazing cases included) and along a 100-frame camera
//! path that scrolls and wraps the GPU's toroidal textures.
//!
//! Without an adapter the tests print why and return; with
//! `TERRACLIP_REQUIRE_GPU=1` (set by `.ci/run`) a missing adapter fails.
#![cfg(feature = "gpu")]

use std::path::Path;
use terraclip::check::{compare, parity};
use terraclip::gpu::{Api, Gpu, GpuRenderer};
use terraclip::pack::{stream, Coder, Predictor};
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

/// Every golden scene: each `golden/*.toml`, checked to be what the
/// golden sweep lists and to have its reference image and depth hash, so
/// a scene the sweep skipped fails here instead of leaving it unchecked.
fn every_golden() -> Vec<std::path::PathBuf> {
    let scenes = terraclip::check::golden::scenes(Path::new("golden")).unwrap();
    let mut tomls: Vec<_> = std::fs::read_dir("golden")
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    tomls.sort();
    let mut listed = scenes.clone();
    listed.sort();
    assert_eq!(listed, tomls, "the golden sweep's scenes");
    for p in &scenes {
        for ext in ["png", "depth"] {
            assert!(p.with_extension(ext).exists(), "{}: no .{ext}", p.display());
        }
    }
    scenes
}

fn out() -> std::path::PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("gpu-parity")
}

#[test]
fn every_golden_scene_matches_the_cpu() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    for p in every_golden() {
        let name = p.file_stem().unwrap().to_string_lossy().into_owned();
        let scene = Scene::load(&p).unwrap();
        let res = parity::check(&mut r, &scene, &name, 1, 0.0, &out(), exact).unwrap();
        eprintln!("{name}: {res:?} (exact: {exact})");
        assert!(res.pass, "{name}: {res:?}");
        if exact {
            assert_eq!(
                (res.diff.colour_px_differ, res.diff.depth_px_differ),
                (0, 0),
                "{name}"
            );
        }
    }
}

/// Golden scene `name` at the paths' size, 192×108.
fn path_scene(name: &str) -> Scene {
    let mut scene = Scene::load(Path::new(&format!("golden/{name}.toml"))).unwrap();
    scene
        .apply(&terraclip::scene::Overrides {
            size: Some([192, 108]),
            ..Default::default()
        })
        .unwrap();
    scene
}

/// The ten 100-frame paths the README reports: six (strips and footprints,
/// normal maps, wires, shadows, morph), two over packs decoded tile by
/// tile as the path goes (lossless and at E = 1 m), and two over synthesised
/// levels (made a tile at a time close to the ground, and whole under
/// shadows), each frame compared, the GPU's
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
        "pack-lossless",
        "pack-lossy",
        "synthesis-close",
        "synthesis-shadows",
    ] {
        let scene = path_scene(name);
        let res = parity::check(&mut r, &scene, name, 100, 37.0, &out(), exact).unwrap();
        eprintln!("{name} path: {res:?}");
        assert!(res.pass, "{name}: {res:?}");
        assert_eq!(res.frames, 100);
        if exact {
            assert_eq!(
                (res.diff.colour_px_differ, res.diff.depth_px_differ),
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
        if name.starts_with("synthesis") {
            assert!(res.texels.is_none() && res.texels_made.is_none());
        }
    }
}

/// The view-dependent clipmap (`lod.centre = "view"`) over the default
/// golden, seen through a 4° lens looking across the map, along a
/// 60-frame path: each level placed on its own, its morph centred on its
/// window and its rectangles culled in blocks, the GPU's toroids updated by
/// dirty rectangles as the placements move. Every frame matches the CPU.
#[test]
fn a_view_dependent_clipmap_path_matches() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    let mut scene = path_scene("default");
    scene.lod.centre = Some("view".into());
    scene
        .apply(&terraclip::scene::Overrides {
            fov: Some(4.0),
            look_at: Some([8200.0, -8000.0, 150.0]),
            ..Default::default()
        })
        .unwrap();
    let res = parity::check(&mut r, &scene, "clipmap-view", 60, 37.0, &out(), exact).unwrap();
    eprintln!("clipmap-view path: {res:?}");
    assert!(res.pass, "{res:?}");
    assert_eq!(res.frames, 60);
    if exact {
        assert_eq!(
            (res.diff.colour_px_differ, res.diff.depth_px_differ),
            (0, 0)
        );
    }
    assert!(res.texels_uploaded > 0, "{res:?}");
}

/// `[gpu] update = "gpu"` on both synthesis goldens over 100-frame paths:
/// the GPU makes the synthesised levels' texels itself, and after every
/// update every level's toroid (heights and slopes) equals the CPU's bit
/// for bit on lavapipe, as do the images. The CPU then uploads only the
/// map's own levels: the counts are the path's, not the image's
/// (`synthesis-close` uploads 238,938 texels with `update = "cpu"`, of
/// which the GPU now makes all but 30,926).
#[test]
fn the_gpu_update_pass_makes_the_cpus_texels() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    for (name, uploaded) in [("synthesis-close", 30_926), ("synthesis-shadows", 16_076)] {
        let mut scene = path_scene(name);
        scene.gpu.update = terraclip::scene::GpuUpdate::Gpu;
        let res = parity::check(&mut r, &scene, name, 100, 37.0, &out(), exact).unwrap();
        eprintln!("{name} gpu update: {res:?}");
        assert!(res.pass, "{name}: {res:?}");
        let t = res.texels.expect("texels checked");
        assert!(t.checked > 1_000_000, "{t:?}");
        assert!(res.texels_made.unwrap() > 50_000, "{res:?}");
        if exact {
            assert_eq!((t.differ, t.max_ulp), (0, 0), "{name}");
            assert_eq!(
                (res.diff.colour_px_differ, res.diff.depth_px_differ),
                (0, 0),
                "{name}"
            );
            assert_eq!(res.texels_uploaded, uploaded, "{name}");
        }
    }
}

/// A pack coded with `--predictor upsampled`: with `update = "gpu"` the
/// GPU rebuilds its levels from the coarser level's toroid and uploaded
/// residual codes, bit for bit the CPU's on lavapipe over a 100-frame
/// path; only the coarsest level is uploaded as texels. The same scene
/// over the lifting pack (`pack-lossy`'s) leaves every level to uploads.
/// The fast coder's pack of the same levels gives the same figures.
/// `pack-lossy`'s terrain (level-tint's procedural map) packed at E = 1 m
/// in 128² tiles with `predictor` and `coder`, as `name`.
fn level_tint_pack(name: &str, predictor: Predictor, coder: Coder) -> std::path::PathBuf {
    let src = Scene::load(Path::new("golden/level-tint.toml")).unwrap();
    let rows = terraclip::terrain::rows::for_terrain(&src.terrain, &src.base_dir).unwrap();
    std::fs::create_dir_all(out()).unwrap();
    let pack = out().join(name);
    let mut o = stream::Options::new(1.0, 128, Default::default(), "level-tint");
    (o.predictor, o.coder) = (predictor, coder);
    stream::pack(rows.as_ref(), &pack, &o, &mut |_, _| {}).unwrap();
    pack
}

#[test]
fn the_gpu_update_pass_rebuilds_an_upsampled_packs_levels() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    let pack = level_tint_pack(
        "procedural-513-e1-upsampled.tcz",
        Predictor::Upsampled,
        Coder::Ratio,
    );
    let mut scene = path_scene("pack-lossy");
    scene.gpu.update = terraclip::scene::GpuUpdate::Gpu;
    let lifting = parity::check(&mut r, &scene, "pack-lifting", 3, 37.0, &out(), exact).unwrap();
    assert_eq!(lifting.texels_made, Some(0), "{lifting:?}");
    scene.terrain.file = Some(pack);
    let res = parity::check(&mut r, &scene, "pack-upsampled", 100, 37.0, &out(), exact).unwrap();
    eprintln!("upsampled pack, gpu update: {res:?}");
    assert!(res.pass, "{res:?}");
    let t = res.texels.expect("texels checked");
    let made = res.texels_made.unwrap();
    let bytes = res.residual_bytes.unwrap();
    assert!(t.checked > 1_000_000 && made > 30_000, "{res:?}");
    // Two bytes a code, over each rectangle and a texel around it: under
    // the 12 bytes (height and slope) a texel the CPU would upload.
    assert!(bytes > 2 * made && bytes < 12 * made, "{res:?}");
    if exact {
        assert_eq!((t.differ, t.max_ulp), (0, 0));
        assert_eq!(
            (res.diff.colour_px_differ, res.diff.depth_px_differ),
            (0, 0)
        );
        assert_eq!((made, res.texels_uploaded, bytes), (37_444, 248, 130_060));
    }
    // The same pack with the fast coder decodes to the same heights, so the
    // pass rebuilds its levels with the same codes: the same figures.
    scene.terrain.file = Some(level_tint_pack(
        "procedural-513-e1-upsampled-fast.tcz",
        Predictor::Upsampled,
        Coder::Fast,
    ));
    let f = parity::check(
        &mut r,
        &scene,
        "pack-upsampled-fast",
        100,
        37.0,
        &out(),
        exact,
    )
    .unwrap();
    eprintln!("upsampled fast pack, gpu update: {f:?}");
    assert!(f.pass, "{f:?}");
    assert_eq!(
        (f.texels_made, f.texels_uploaded, f.residual_bytes),
        (res.texels_made, res.texels_uploaded, res.residual_bytes)
    );
    if exact {
        let t = f.texels.expect("texels checked");
        assert_eq!((t.differ, t.max_ulp), (0, 0));
        assert_eq!((f.diff.colour_px_differ, f.diff.depth_px_differ), (0, 0));
    }
}

/// The default pack (the ratio coder, the fitted predictor) of
/// `pack-lossy`'s terrain renders on the GPU exactly as on the CPU over a
/// path whose clipmap decodes its tiles as it goes: the fitted weights
/// change what is decoded, not what is drawn.
#[test]
fn a_fitted_pack_renders_as_the_cpu_does() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    let mut scene = path_scene("pack-lossy");
    scene.terrain.file = Some(level_tint_pack(
        "procedural-513-e1-fitted.tcz",
        Predictor::Fitted,
        Coder::Ratio,
    ));
    let res = parity::check(&mut r, &scene, "pack-fitted", 20, 37.0, &out(), exact).unwrap();
    eprintln!("fitted pack: {res:?}");
    assert!(res.pass, "{res:?}");
    if exact {
        assert_eq!(
            (res.diff.colour_px_differ, res.diff.depth_px_differ),
            (0, 0)
        );
    }
}

/// The golden size, so the tests that show what fails run where the
/// goldens do.
const W: usize = 960;
const H: usize = 540;
const PX: usize = W * H;

fn flat(v: u8) -> terraclip::render::Image {
    terraclip::render::Image {
        width: W as u32,
        height: H as u32,
        rgba: vec![v; 4 * PX],
        depth: vec![0.5; PX],
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
    let d = compare::Difference::of(&a, &b);
    assert_eq!((d.colour_px_differ, d.max_channel_diff), (1, 1));
    assert_eq!((d.shifted_px, d.unmatched_px), (0, 0));
    assert!(d.passes(false) && !d.passes(true));
    // Three steps: unmatched. No count of such pixels is budgeted: one
    // fails, unless it lies in the tie band, where a conforming rasteriser
    // may differ.
    b.rgba[4] = 13;
    let d = compare::Difference::of(&a, &b);
    assert_eq!((d.shifted_px, d.unmatched_px, d.outside_band_px), (0, 1, 1));
    assert!(!d.passes(false));
    let mut band = vec![false; PX];
    band[1] = true;
    let d = compare::Difference::within(&a, &b, Some(&band));
    assert_eq!((d.unmatched_px, d.outside_band_px), (1, 0));
    assert!(d.passes(false) && !d.passes(true));
    band[1] = false;
    band[2] = true;
    assert!(!compare::Difference::within(&a, &b, Some(&band)).passes(false));
    let mut c = flat(10);
    c.depth[3] = f32::from_bits(0.5f32.to_bits() + compare::TOLERANCE_DEPTH_ULP);
    let d = compare::Difference::of(&a, &c);
    assert_eq!(
        (d.depth_px_differ, d.max_depth_ulp),
        (1, compare::TOLERANCE_DEPTH_ULP)
    );
    assert!(d.passes(false));
    c.depth[3] = f32::from_bits(0.5f32.to_bits() + compare::TOLERANCE_DEPTH_ULP + 1);
    assert_eq!(compare::Difference::of(&a, &c).unmatched_px, 1);
}

/// An edge one pixel over is a shift; a hole (enclosed background where the
/// other image has surface) fails at a single pixel; a lost wire across the
/// frame or the same colour at another depth matches nowhere; a whole image
/// moved by a pixel is more shift than a frame may have.
#[test]
fn tolerance_mode_allows_edges_one_pixel_over_and_nothing_else() {
    // Terrain (10) over sky (200, cleared depth) with its silhouette at row
    // 270, columns 100..300 one row lower on the GPU.
    let mut cpu = flat(10);
    let mut gpu = flat(10);
    for y in 0..270 {
        for x in 0..W {
            paint(&mut cpu, x, y, 200, 1.0);
            paint(&mut gpu, x, y, 200, 1.0);
        }
    }
    for x in 100..300 {
        paint(&mut gpu, x, 270, 200, 1.0);
    }
    // The silhouette's rows are the tie band here.
    let band: Vec<bool> = (0..PX).map(|i| (269..=271).contains(&(i / W))).collect();
    let d = compare::Difference::within(&cpu, &gpu, Some(&band));
    assert_eq!(
        (d.shifted_px, d.unmatched_px, d.holes_px, d.max_channel_diff),
        (200, 0, 0, 190)
    );
    assert!(d.passes(false));
    // Off the band, the same shift fails.
    assert!(!compare::Difference::of(&cpu, &gpu).passes(false));

    // A one-pixel hole showing the sky inside the terrain: a hole, which no
    // legal difference makes, so it fails on its own.
    let mut crack = cpu.clone();
    paint(&mut crack, 600, 400, 200, 1.0);
    let d = compare::Difference::of(&cpu, &crack);
    assert_eq!((d.shifted_px, d.unmatched_px, d.holes_px), (0, 1, 1));
    assert!(!d.passes(false));
    // The same pixel in the other image's place (the GPU covers a hole the
    // CPU shows) counts too.
    let d = compare::Difference::of(&crack, &cpu);
    assert_eq!(d.holes_px, 1);
    assert!(!d.passes(false));
    // A crack line across the frame.
    let mut line = cpu.clone();
    for x in 0..W {
        paint(&mut line, x, 400, 200, 1.0);
    }
    let d = compare::Difference::of(&cpu, &line);
    assert_eq!(d.holes_px, 0, "a line across the frame joins the border");
    assert!(d.unmatched_px >= W - 2 && !d.passes(false), "{d:?}");

    // Two wire columns the GPU lost, over the frame's height: every pixel
    // unmatched, and none near a tie of the wire threshold.
    let mut wired = cpu.clone();
    for y in 0..H {
        paint(&mut wired, 700, y, 255, 0.5);
        paint(&mut wired, 720, y, 255, 0.5);
    }
    let d = compare::Difference::of(&wired, &cpu);
    assert_eq!((d.unmatched_px, d.holes_px), (2 * H, 0));
    assert!(!d.passes(false));

    // The same colour at another depth (a fogged surface behind another).
    let mut deeper = cpu.clone();
    paint(&mut deeper, 30, 470, 10, 0.75);
    assert_eq!(compare::Difference::of(&cpu, &deeper).unmatched_px, 1);

    // A wall whose depth steps 0.0004 per pixel: a GPU depth 1/32 of a step
    // off is the same pixel; half a step off everywhere is a shift over
    // the whole frame, far from any edge.
    let wall = |off: f32| {
        let mut img = flat(10);
        for y in 0..H {
            for x in 0..W {
                paint(&mut img, x, y, 10, 0.2 + 0.0004 * (x as f32 + off));
            }
        }
        img
    };
    let d = compare::Difference::of(&wall(0.0), &wall(1.0 / 32.0));
    assert!(d.max_depth_ulp > compare::TOLERANCE_DEPTH_ULP);
    assert_eq!((d.shifted_px, d.unmatched_px), (0, 0));
    let d = compare::Difference::of(&wall(0.0), &wall(0.5));
    assert!(d.shifted_px > PX / 2 && !d.passes(false), "{d:?}");

    // A ramp moved by a pixel everywhere: every pixel but those of the two
    // border columns has a matching neighbour, and far more than 1 % shifted.
    let ramp = |off: usize| {
        let mut img = flat(0);
        for y in 0..H {
            for x in 0..W {
                paint(&mut img, x, y, (2 * ((x + off) % 120) + y / 40) as u8, 0.5);
            }
        }
        img
    };
    let d = compare::Difference::of(&ramp(0), &ramp(1));
    // Unmatched only at the image's side columns and the ramp's 8 seams.
    assert!(d.unmatched_px <= 2 * 9 * H, "{d:?}");
    assert!(d.shifted_px > PX / 2 && !d.passes(false), "{d:?}");
}

#[test]
fn brute_force_passthrough_matches_the_cpu() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    let mut scene = Scene::load(Path::new("golden/jacksboro-oblique.toml")).unwrap();
    let effects = ["lambert", "fog", "shadows", "wireframe"];
    scene
        .apply(&terraclip::scene::Overrides {
            lod: Some(terraclip::scene::LodScheme::BruteForce),
            effects: Some(effects.iter().map(|s| s.parse().unwrap()).collect()),
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
    let mut scene = Scene::bench_scene();
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
        assert_eq!(
            (res.diff.colour_px_differ, res.diff.depth_px_differ),
            (0, 0)
        );
    }
}

/// What tolerance mode must still catch, at the golden size (960×540, the
/// `default` scene): the reference frame against the same frame with one
/// defect. Each defect is made on the CPU side, so no GPU is needed:
/// - a one-pixel crack line across the frame (background painted over a
///   terrain row, depth cleared);
/// - a missing clipmap level (its triangles dropped);
/// - a morph off by one level (a level drawn with the coarsest level's
///   constants, which disable the morph: α = 0 throughout its band);
/// - a toroid one texel off (a level's heights read one texel east);
/// - the whole frame one pixel over.
///
/// The last three are made for every visible level (1–4 in this view),
/// and each fails on the tie band ([`compare::tie_band`]), the one limit
/// tolerance mode puts on shifted and unmatched pixels. A conforming difference (vertices moved a fraction of
/// the sub-pixel precision) passes.
#[test]
fn tolerance_mode_fails_real_defects_at_the_golden_size() {
    use terraclip::frame::stats::Passes;
    use terraclip::render::{draw, RenderOptions, Session};
    let scene = Scene::load(Path::new("golden/default.toml")).unwrap();
    assert_eq!((scene.image.width, scene.image.height), (960, 540));
    let mut session = Session::new(&scene, &mut Passes::default()).unwrap();
    let (frame, _) = session
        .frame(&scene.camera(), &mut Passes::default())
        .unwrap();
    let opts = RenderOptions::default();
    let render = |f: &terraclip::frame::Frame| draw(f, &opts, &mut Passes::default()).0;
    let want = render(&frame);
    let px = (want.width * want.height) as usize;
    // The tie band of the reference frame, as `check-gpu` computes it.
    let band = compare::tie_band(
        &terraclip::render::raster(&frame, terraclip::raster::Path::Scalar),
        frame.effects.wireframe,
    );
    let in_band = band.iter().filter(|&&b| b).count();
    println!("tie band: {in_band} of {px} pixels");
    let check = |what: &str, got: &terraclip::render::Image| {
        let d = compare::Difference::within(&want, got, Some(&band));
        println!(
            "{what}: {} shifted, {} unmatched, {} outside the tie band, of {px}",
            d.shifted_px, d.unmatched_px, d.outside_band_px
        );
        assert!(!d.passes(false), "{what} passes tolerance mode: {d:?}");
        assert!(
            d.outside_band_px > 0,
            "{what}: nothing outside the tie band"
        );
        assert!(!d.passes(true), "{what} passes exact mode");
    };

    // What a conforming GPU may do passes: every vertex moved by a fraction
    // of the 1/16 px Vulkan allows. Positions are scaled by 1 + 2^-14 about
    // the frame's floating origin, about 900 m from the eye here, so a
    // vertex 1 km or more away (all of this view's terrain) moves by about
    // 0.05 px or less. 14 pixels shift, every one inside the tie band.
    let mut nudged = frame.clone();
    for p in &mut nudged.positions {
        for c in p.iter_mut() {
            *c *= 1.0 + 1.0 / 16_384.0;
        }
    }
    let d = compare::Difference::within(&want, &render(&nudged), Some(&band));
    println!("vertices nudged: {d:?}");
    assert!(d.passes(false), "a conforming difference fails: {d:?}");
    // The whole frame one pixel to the right: a shift everywhere, which no
    // tie explains.
    let mut moved = want.clone();
    for y in 0..540 {
        for x in (1..960).rev() {
            let (i, j) = (y * 960 + x, y * 960 + x - 1);
            moved.depth[i] = want.depth[j];
            moved.rgba.copy_within(4 * j..4 * j + 4, 4 * i);
        }
    }
    check("the frame one pixel over", &moved);

    // A crack line: the first row whose pixels are all terrain.
    let row = (0..want.height as usize)
        .find(|&y| (0..want.width as usize).all(|x| want.depth[y * 960 + x] < 1.0))
        .expect("a row of terrain");
    let mut cracked = want.clone();
    let bg = frame.background.map(|c| (c * 255.0).round() as u8);
    for x in 0..960 {
        let i = row * 960 + x;
        cracked.rgba[4 * i..4 * i + 3].copy_from_slice(&bg);
        cracked.depth[i] = 1.0;
    }
    check(&format!("crack line at row {row}"), &cracked);

    // Per level (each drawn level but the coarsest), with its vertices
    // edited and their positions recomputed by the vertex stage.
    let levels: Vec<u32> = frame
        .mesh
        .level_info
        .iter()
        .flatten()
        .map(|l| l.level as u32)
        .collect();
    let coarsest = *levels.iter().max().unwrap();
    // `None` drops the vertex (a NaN position, whose triangles the
    // rasteriser discards); otherwise the edited vertex goes through the
    // vertex stage again.
    let edit = |level: u32, f: &dyn Fn(&mut terraclip::lod::LodVertex) -> Option<()>| {
        let mut g = frame.clone();
        for (t, &l) in frame.mesh.levels.iter().enumerate() {
            if l != level {
                continue;
            }
            for i in 3 * t..3 * t + 3 {
                g.positions[i] = match f(&mut g.mesh.vertices[i]) {
                    Some(()) => g.uniforms.position(&g.mesh.vertices[i]),
                    None => [f32::NAN; 3],
                };
            }
        }
        render(&g)
    };
    let mut tested = 0;
    for &level in levels.iter().filter(|&&l| l != coarsest) {
        let missing = edit(level, &|_| None);
        if missing.rgba == want.rgba {
            // Drawn but culled or hidden from this view: nothing to lose.
            println!("level {level}: not visible in this view");
            continue;
        }
        tested += 1;
        check(&format!("level {level} missing"), &missing);
        let unmorphed = edit(level, &|v| {
            v.alpha = 0.0;
            Some(())
        });
        check(
            &format!("level {level} morphed with the coarsest level's constants"),
            &unmorphed,
        );
        // Heights one texel east: the level's own vertex there, where it has one.
        let spacing = 1i64 << level;
        let heights: std::collections::HashMap<(i64, i64), f32> = frame
            .mesh
            .levels
            .iter()
            .enumerate()
            .filter(|(_, &l)| l == level)
            .flat_map(|(t, _)| frame.mesh.vertices[3 * t..3 * t + 3].iter())
            .map(|v| ((v.col, v.row), v.z))
            .collect();
        let shifted = edit(level, &|v| {
            if let Some(&z) = heights.get(&(v.col + spacing, v.row)) {
                v.z = z;
            }
            Some(())
        });
        check(&format!("level {level} toroid one texel off"), &shifted);
    }
    assert!(tested >= 3, "only {tested} levels visible");
}

/// `bench --update` times a jump that makes every synthesised level's
/// whole toroid (3 levels of 63², 11,907 texels) and a walk that makes
/// fewer; a scene without synthesis is refused by name.
#[test]
fn the_update_bench_times_a_jump_and_a_walk() {
    let Some(mut r) = renderer() else { return };
    let scene = Scene::load(Path::new("golden/synthesis-close.toml")).unwrap();
    let b = parity::update_bench(&mut r, &scene, 3, 37.0).unwrap();
    assert_eq!((b.levels, b.n, b.jump.texels), (3, 63, 11_907));
    assert!(b.walk.texels > 0 && b.walk.texels < b.jump.texels, "{b:?}");
    for t in [&b.jump, &b.walk] {
        assert!(
            t.cpu_update_ms > 0.0 && t.upload_ms > 0.0 && t.gpu_pass_ms > 0.0,
            "{t:?}"
        );
    }
    let plain = Scene::load(Path::new("golden/level-tint.toml")).unwrap();
    let e = parity::update_bench(&mut r, &plain, 3, 37.0).unwrap_err();
    assert!(e.to_string().contains("synthesis"), "{e}");
}

/// Every golden scene's export (`terraclip export`), read back and drawn
/// by the wgpu back end as a plain mesh (the vertex stage's positions and
/// varyings from `frame.glb`, no clipmap vertex pulling), gives the
/// exported reference: the file is the frame, on the GPU too.
#[test]
fn every_golden_export_drawn_as_a_plain_mesh_matches() {
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    for (name, d) in golden_exports_as_plain_meshes(&mut r, "export") {
        assert!(d.passes(exact), "{name}: {d:?}");
    }
}

/// Each golden exported, read back and drawn by `r` as a plain mesh, and
/// compared with the export's reference (colour alone where `r` reads back
/// no depth, as GL does), with the tie band of the export's triangles.
fn golden_exports_as_plain_meshes(
    r: &mut GpuRenderer,
    tag: &str,
) -> Vec<(String, compare::Difference)> {
    let scenes = terraclip::check::golden::scenes(Path::new("golden")).unwrap();
    let mut out_list = vec![];
    for p in scenes {
        let name = p.file_stem().unwrap().to_string_lossy().into_owned();
        let dir = out().join(format!("{tag}-{name}"));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(out()).unwrap();
        let scene = Scene::load(&p).unwrap();
        terraclip::export::scene(&scene, &name, None, 1, 0.0, &dir).unwrap();
        let e = terraclip::export::read(&dir).unwrap();
        r.forget_textures();
        let img = r.draw(&e.frame, None).unwrap();
        let mut reference = e.image.clone();
        if img.depth.is_empty() {
            reference.depth.clear();
        }
        let band = compare::tie_band(
            &terraclip::render::raster(&e.frame, terraclip::raster::Path::from_env()),
            e.frame.effects.wireframe,
        );
        let d = compare::Difference::within(&reference, &img, Some(&band));
        eprintln!("{tag} {name}: {d:?}");
        out_list.push((name, d));
    }
    out_list
}

/// `compare`'s exact mode on what an outside renderer would hand it:
/// lavapipe's own image and depth of every golden scene (the clipmap drawn
/// from its toroidal textures), as a PNG and raw f32 files, against the
/// scene's export.
#[test]
fn lavapipes_image_of_every_golden_passes_compare() {
    use terraclip::check::outside::{self, Mode};
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    let mode = if exact { Mode::Exact } else { Mode::Tiered };
    for p in terraclip::check::golden::scenes(Path::new("golden")).unwrap() {
        let name = p.file_stem().unwrap().to_string_lossy().into_owned();
        let dir = out().join(format!("compare-{name}"));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(out()).unwrap();
        let scene = Scene::load(&p).unwrap();
        terraclip::export::scene(&scene, &name, None, 1, 0.0, &dir).unwrap();
        let (img, _) = terraclip::render::gpu::render(&mut r, &scene).unwrap();
        let (png, f32s) = (
            out().join(format!("{name}-gpu.png")),
            out().join(format!("{name}-gpu.f32")),
        );
        std::fs::write(&png, img.png().unwrap()).unwrap();
        std::fs::write(
            &f32s,
            img.depth
                .iter()
                .flat_map(|z| z.to_le_bytes())
                .collect::<Vec<u8>>(),
        )
        .unwrap();
        let o = outside::run(
            &dir,
            Some(&png),
            Some(&f32s),
            &outside::Options::new(mode),
            None,
        )
        .unwrap();
        eprintln!(
            "{name}: {} {} colour, {} depth px differ",
            o.mode, o.colour_px_differ, o.depth_px_differ
        );
        assert!(o.pass && o.depth_compared, "{name}: {o:?}");
    }
}

/// The GL back end (llvmpipe), where one is found: every golden through
/// the clipmap path (toroid textures, vertex pulling) over a 3-frame path,
/// and every golden's export as a plain mesh, pass tolerance mode (GL
/// reads back no depth, so colour alone). The clipmap path failed every
/// golden on GL until the shaders stopped taking `%` of negative integers
/// (undefined in GLSL) and the toroid arrays stopped having 6k layers
/// (which wgpu's GL back end makes a cube map).
#[test]
fn gl_draws_every_golden_within_tolerance() {
    let gpu = match Gpu::new(Api::Gl) {
        Ok(g) => g,
        Err(e) if required() => {
            panic!("TERRACLIP_REQUIRE_GPU=1 but no GL adapter (.ci/run installs Mesa's EGL and GL): {e}")
        }
        Err(e) => {
            eprintln!("skipping: no GL adapter ({e})");
            return;
        }
    };
    let mut r = GpuRenderer::new(gpu);
    for p in &every_golden() {
        let scene = Scene::load(p).unwrap();
        let res = parity::check(&mut r, &scene, "gl", 3, 37.0, &out(), false).unwrap();
        eprintln!("gl clipmap {}: {res:?}", p.display());
        assert!(res.pass, "{}: {res:?}", p.display());
    }
    for (name, d) in golden_exports_as_plain_meshes(&mut r, "gl-export") {
        assert!(d.passes(false), "{name}: {d:?}");
    }
    // The GPU update pass needs storage textures GL's downlevel rules
    // forbid: a clean error.
    let scene = Scene::load(Path::new("golden/synthesis-close.toml")).unwrap();
    let mut gpu_update = scene.clone();
    gpu_update.gpu.update = terraclip::scene::GpuUpdate::Gpu;
    let e = parity::check(&mut r, &gpu_update, "gl", 1, 0.0, &out(), false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("[gpu] update") && e.contains("storage textures"),
        "{e}"
    );
}

/// Every scheme whose mesh the CPU makes, drawn from the back end's
/// resident vertex buffer (the shader making positions, fog and view
/// vectors from grid places and heights, as the CPU vertex stage does)
/// along a 12-frame path with morphing on: CDLOD's and the annulus's
/// off-grid offsets, GeoMipMapping's and ROAM's changing meshes, the CBT.
/// Every frame matches the CPU.
#[test]
fn every_cpu_made_mesh_matches_from_resident_vertices() {
    use terraclip::scene::LodScheme;
    let Some(mut r) = renderer() else { return };
    let exact = r.gpu.exact_expected();
    for lod in [
        LodScheme::Geomipmap,
        LodScheme::Roam,
        LodScheme::Cdlod,
        LodScheme::Annulus,
        LodScheme::Cbt,
    ] {
        let mut scene = path_scene("morph-on");
        scene
            .apply(&terraclip::scene::Overrides {
                lod: Some(lod),
                ..Default::default()
            })
            .unwrap();
        let name = format!("mesh-{}", lod.name());
        let res = parity::check(&mut r, &scene, &name, 12, 37.0, &out(), exact).unwrap();
        eprintln!("{name}: {res:?}");
        assert!(res.pass && res.triangles > 0, "{name}: {res:?}");
        if exact {
            assert_eq!(
                (res.diff.colour_px_differ, res.diff.depth_px_differ),
                (0, 0),
                "{name}"
            );
        }
    }
}

/// What a frame costs the device is counted from what the back end
/// writes. A still camera over a brute-force mesh re-sends nothing but
/// the frame's uniforms and atlases, so the second and third frames
/// upload the same bytes, under 1 % of the mesh's; a clipmap stepping
/// along a path uploads at least its dirty texels (4 bytes each, with
/// their slopes' 8 under lighting) and draws one call per level with
/// strips, more with footprints; held still it sends exactly what the
/// still brute-force frame sent, and from fresh toroids that plus each
/// texel's bytes. The pass time is `Some` exactly when the
/// adapter has timestamp queries.
#[test]
fn frame_costs_count_what_the_back_end_writes() {
    use terraclip::frame::stats::Passes;
    use terraclip::render::Session;
    let Some(mut r) = renderer() else { return };
    let mut scene = path_scene("default");
    scene
        .apply(&terraclip::scene::Overrides {
            lod: Some(terraclip::scene::LodScheme::BruteForce),
            ..Default::default()
        })
        .unwrap();
    let mut passes = Passes::default();
    let mut s = Session::new(&scene, &mut passes).unwrap();
    let cam = scene.camera();
    let mut costs = vec![];
    let mut vertices = 0;
    for _ in 0..3 {
        let (frame, _, _) =
            terraclip::render::gpu::frame(&mut r, &mut s, &cam, &mut passes).unwrap();
        vertices = frame.mesh.vertices.len() as u64;
        costs.push(r.costs());
    }
    eprintln!("brute force, still: {costs:?} ({vertices} vertices)");
    let mesh_bytes = 48 * vertices;
    assert!(costs[0].upload_bytes >= mesh_bytes, "{costs:?}");
    assert_eq!(costs[1].upload_bytes, costs[2].upload_bytes, "{costs:?}");
    assert!(costs[1].upload_bytes * 100 < mesh_bytes, "{costs:?}");
    assert_eq!(costs[2].draw_calls, 1);
    for c in &costs {
        assert_eq!(c.gpu_ms.is_some(), r.gpu.timestamps, "{c:?}");
        assert!(c.gpu_ms.is_none_or(|ms| ms > 0.0), "{c:?}");
    }

    // The default golden's clipmap (Lambert), one step at a time, with
    // strips (per-frame index lists) and footprints (static shapes).
    for name in ["default", "non-square-edge"] {
        let scene = path_scene(name);
        let mut s = Session::new(&scene, &mut passes).unwrap();
        r.forget_textures();
        let base = scene.camera();
        for i in 0..4 {
            let cam = terraclip::camera::path_camera(&base, i, 37.0);
            let (frame, _, _) =
                terraclip::render::gpu::frame(&mut r, &mut s, &cam, &mut passes).unwrap();
            let c = r.costs();
            let texels = r.texels_uploaded();
            let mut drawn = frame.mesh.levels.clone();
            drawn.dedup();
            let levels = drawn.len() as u64;
            eprintln!("{name} frame {i}: {c:?}, {texels} texels, {levels} levels");
            let texel_bytes = texels * if frame.effects.lit() { 12 } else { 4 };
            assert!(c.upload_bytes >= texel_bytes, "{c:?}");
            if name == "default" {
                // Strips: one draw per level.
                assert_eq!(c.draw_calls, levels, "{c:?}");
            } else {
                // Footprints: a draw per shape instance, several a level.
                assert!(c.draw_calls > levels, "{c:?}");
            }
            assert!(i == 0 || texels > 0, "the camera moved: {c:?}");
        }
        // Still again: nothing but the uniforms and atlases a still
        // brute-force frame sends, byte for byte.
        let last = terraclip::camera::path_camera(&base, 3, 37.0);
        terraclip::render::gpu::frame(&mut r, &mut s, &last, &mut passes).unwrap();
        assert_eq!(r.costs().upload_bytes, costs[2].upload_bytes, "{name}");
        assert_eq!(r.texels_uploaded(), 0, "{name}");
        // Still, from fresh toroids: exactly those bytes and every texel,
        // its height (4 bytes) and its slope (8) under lighting.
        r.forget_textures();
        let (frame, _, _) =
            terraclip::render::gpu::frame(&mut r, &mut s, &last, &mut passes).unwrap();
        let per_texel = if frame.effects.lit() { 12 } else { 4 };
        assert_eq!(
            r.costs().upload_bytes - costs[2].upload_bytes,
            r.texels_uploaded() * per_texel,
            "{name}"
        );
    }
}

/// `fly --gpu`: every frame drawn by the back end too, from a session of
/// its own. A part of the flight brings the GPU's session up to its first
/// frame and draws the frame before it, so each frame it reports costs
/// exactly what the whole flight's same frame did: the same bytes and the
/// same draw calls.
#[test]
fn a_flights_gpu_costs_are_the_same_whole_or_in_parts() {
    use terraclip::studies::fly;
    use terraclip::studies::shard::Shard;
    if renderer().is_none() {
        return;
    }
    let scene = path_scene("default");
    let run = |shard: &str| {
        let sh = Shard::parse(shard).unwrap();
        fly::fly_with(&scene, (6, 0), 30.0, false, sh, true, |_, _| Ok(())).unwrap()
    };
    let whole = run("0/1");
    let part = run("1/2");
    let costs = |r: &fly::FlyReport| -> Vec<(usize, u64, u64)> {
        r.frames
            .iter()
            .map(|f| {
                let g = f.gpu.expect("a GPU frame");
                (f.frame, g.upload_bytes, g.draw_calls)
            })
            .collect()
    };
    eprintln!("whole: {:?}\npart 1/2: {:?}", costs(&whole), costs(&part));
    assert_eq!(costs(&part), costs(&whole)[3..].to_vec());
    // The first frame uploads every level; the later ones their changes.
    let c = costs(&whole);
    assert!(c[1..].iter().all(|f| f.1 < c[0].1), "{c:?}");
    assert!(whole.mean_upload_bytes.is_some());
}
