//! The LOD schemes beside the clipmap, and the surveys that compare them:
//! scheme invariants (GeoMipMapping's one-level rule, ROAM's budget and
//! frame-to-frame coherence, CDLOD and annulus sanity), scene validation,
//! and the tradeoff and fly reports on a small map.

use proptest::prelude::*;
use std::path::Path;
use std::sync::Arc;
use terraclip::camera::Camera;
use terraclip::lod::cbt::{self, Cbt};
use terraclip::lod::geomipmap::{Config, GeoMipMap, Mode};
use terraclip::lod::roam::{self, Roam};
use terraclip::lod::{Lod, View};
use terraclip::pyramid::{Filter, Pyramid};
use terraclip::scene::{Effect, Scene};
use terraclip::studies::shard::Shard;

const WHOLE: Shard = Shard::WHOLE;
use terraclip::terrain::world::WorldMap;

mod common;

fn scene() -> Scene {
    common::small_scene()
}

fn pyramid() -> Arc<Pyramid> {
    let map = common::terrain(9, 257, 193);
    Arc::new(Pyramid::build(&map, Filter::Box, 2))
}

fn camera(x: f64, y: f64, z: f64, tx: f64, ty: f64) -> Camera {
    Camera {
        eye: glam::DVec3::new(x, y, z),
        target: glam::DVec3::new(tx, ty, 0.0),
        fov_y_deg: 60.0,
        near: 0.5,
        far: 1e5,
        aspect: 16.0 / 9.0,
    }
}

fn with_view<T>(cam: &Camera, f: impl FnOnce(&View) -> T) -> T {
    let world = WorldMap::new([1.0, 1.0], 1.0);
    let frustum = cam.frustum();
    f(&View {
        camera: cam,
        frustum: &frustum,
        world: &world,
        viewport: [320, 180],
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn geomipmap_neighbours_differ_by_at_most_one_level(
        x in 0.0..256.0f64, y in -192.0..0.0f64, z in 1.0..200.0f64,
        mode in 0..3usize, d in 4.0..64.0f64,
    ) {
        let mode = match mode {
            0 => Mode::Linear { distance: d },
            1 => Mode::Exponential { distance: d },
            _ => Mode::Error { tau: d / 16.0 },
        };
        let mut g = GeoMipMap::new(pyramid(), Config { cells: 16, mode, morph: true });
        let cam = camera(x, y, z, 128.0, -96.0);
        let levels = with_view(&cam, |v| { g.update(v); g.block_levels().to_vec() });
        let across = 256usize.div_ceil(16);
        for (b, &l) in levels.iter().enumerate() {
            let (i, j) = (b % across, b / across);
            if i + 1 < across {
                prop_assert!(l.abs_diff(levels[b + 1]) <= 1, "blocks {b} and {}", b + 1);
            }
            if b + across < levels.len() {
                prop_assert!(l.abs_diff(levels[b + across]) <= 1, "blocks {b} and {}", b + across);
            }
            let _ = j;
        }
    }

    #[test]
    fn roam_keeps_its_budget_and_settles(
        x in 0.0..256.0f64, y in -192.0..0.0f64, z in 5.0..200.0f64, budget in 200..3000usize,
    ) {
        let mut r = Roam::new(pyramid(), roam::Config { tau: 0.5, max_triangles: budget });
        let cam = camera(x, y, z, 128.0, -96.0);
        with_view(&cam, |v| {
            r.update(v);
            let first = r.triangle_count();
            let mesh = r.mesh(v);
            // A split may overshoot by one chain of forced splits (at most
            // 2 triangles per bintree depth, 12 in a 64-cell patch).
            prop_assert!(first <= budget + 48, "{first} > {budget} + 48");
            prop_assert!(mesh.triangle_count() <= first);
            // Frame-to-frame coherence: the same view again changes little.
            let again = r.update(v);
            prop_assert!(again.changes as usize <= first / 4 + 8, "{} changes", again.changes);
            Ok(())
        })?;
    }
}

/// Whether the triangles tile their square without a T-junction: every
/// edge is shared by exactly two triangles, or lies on the square's border
/// and belongs to one. Returns the first offending edge and its count.
fn non_conforming_edge(tris: &[[[i64; 2]; 3]], side: i64) -> Option<([[i64; 2]; 2], usize)> {
    let mut edges = std::collections::HashMap::new();
    for t in tris {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges
                .entry(if a < b { [a, b] } else { [b, a] })
                .or_insert(0usize) += 1;
        }
    }
    edges.into_iter().find(|&([a, b], n)| {
        let border = (a[0] == b[0] && a[0] % side == 0) || (a[1] == b[1] && a[1] % side == 0);
        n != if border { 1 } else { 2 }
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// The bisection stays conforming through any two views, a view seen
    /// again changes nothing, and the tree does not remember the way it
    /// came: merging then splitting reaches the same leaves as a fresh tree
    /// updated at the last view (the split and merge rules share one
    /// monotone error, so each view has one fixed point).
    #[test]
    fn cbt_stays_conforming_and_forgets_its_history(
        x in 0.0..256.0f64, y in -192.0..0.0f64, z in 2.0..200.0f64,
        x2 in 0.0..256.0f64, y2 in -192.0..0.0f64, z2 in 2.0..200.0f64,
        tau in 0.25..8.0f64,
    ) {
        let mut c = Cbt::new(pyramid(), cbt::Config { tau, morph: true });
        let side = c.side();
        for cam in [camera(x, y, z, 128.0, -96.0), camera(x2, y2, z2, x, y)] {
            with_view(&cam, |v| {
                let first = c.update(v);
                prop_assert!(first.changes > 0 || c.triangle_count() == 2);
                let tris = c.triangles();
                prop_assert_eq!(non_conforming_edge(&tris, side), None);
                prop_assert_eq!(c.update(v).changes, 0, "a second update of one view changed the tree");
                Ok(())
            })?;
        }
        let mut fresh = Cbt::new(pyramid(), cbt::Config { tau, morph: true });
        with_view(&camera(x2, y2, z2, x, y), |v| fresh.update(v));
        prop_assert_eq!(fresh.triangles(), c.triangles());
    }
}

/// The tree after an update is the same on one thread as on several: each
/// pass decides from the tree as it was and only then sets its bits.
#[test]
fn cbt_is_the_same_for_any_thread_count() {
    let cam = camera(40.0, -30.0, 25.0, 128.0, -96.0);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut c = Cbt::new(
                pyramid(),
                cbt::Config {
                    tau: 0.5,
                    morph: true,
                },
            );
            with_view(&cam, |v| {
                c.update(v);
                let mesh = c.mesh(v);
                (c.triangles(), mesh.vertices)
            })
        })
    };
    let one = run(1);
    assert!(
        one.0.len() > 1000,
        "{} triangles: the view should refine",
        one.0.len()
    );
    assert_eq!(one, run(2));
    assert_eq!(one, run(5));
}

#[test]
fn scheme_settings_are_validated() {
    for (from, to, word) in [
        (
            "n = 15",
            "n = 15\nscheme = \"geomipmap\"\nblock = 30",
            "2^k + 1",
        ),
        (
            "n = 15",
            "n = 15\nscheme = \"geomipmap\"\nmode = \"cubic\"",
            "cubic",
        ),
        ("n = 15", "n = 15\nscheme = \"roam\"\ntau = -1.0", "lod.tau"),
        ("n = 15", "n = 15\nscheme = \"cbt\"\ntau = 0.0", "lod.tau"),
        (
            "n = 15",
            "n = 15\ncentre = \"target\"",
            "unknown centre 'target'",
        ),
        ("n = 15", "n = 15\ncentre = \"view\"\ntau = -2.0", "lod.tau"),
        (
            "n = 15",
            "n = 15\ncentre = \"view\"\nlayout = \"footprints\"",
            "lod.layout = \"strips\"",
        ),
        (
            "n = 15",
            "n = 15\nscheme = \"cdlod\"\ngrid = 3",
            "power of two",
        ),
        ("n = 15", "n = 15\nscheme = \"cdlod\"\nrange = 0.5", ">= 1"),
        (
            "n = 15",
            "n = 15\nscheme = \"roam\"\nmax_triangles = 0",
            "> 0",
        ),
        (
            "n = 15",
            "n = 15\nscheme = \"quadtree\"",
            "unknown scheme 'quadtree' (known: clipmap",
        ),
    ] {
        let text = common::SMALL_SCENE.replace(from, to);
        let e = Scene::parse(&text, "s.toml", Path::new("."))
            .unwrap_err()
            .to_string();
        assert!(e.contains("s.toml") && e.contains(word), "{to}: {e}");
    }
}

#[test]
fn every_scheme_renders_the_default_view_near_brute_force() {
    let s = scene();
    let opts = terraclip::render::RenderOptions::default();
    let cam = s.camera();
    let (bf, _) = terraclip::render::render(&s.with_lod("brute-force").unwrap(), &opts).unwrap();
    // The renders are deterministic, so each RMSE is a fixed number:
    // measured (2026-12-01) 20.23, 14.94, 16.28, 7.01 and 22.29, and CBT's
    // (2026-12-07) 12.11. The bound
    // is the measured value plus 10 %, room for a small legitimate change
    // (a cull or split tweak) while a scheme that drops detail, samples the
    // wrong level or misplaces its mesh moves it by far more.
    for (lod, measured) in [
        ("clipmap", 20.23),
        ("geomipmap", 14.94),
        ("roam", 16.28),
        ("cdlod", 7.01),
        ("annulus", 22.29),
        ("cbt", 12.11),
    ] {
        let (img, st) = terraclip::render::render(&s.with_lod(lod).unwrap(), &opts).unwrap();
        let e = terraclip::check::compare::image_error(&img, &bf, &cam);
        println!("{lod}: {} triangles, rmse {:.2}", st.triangles, e.rmse);
        assert!(st.triangles > 0, "{lod} drew nothing");
        assert_eq!(st.non_finite_vertices, 0);
        let bound = 1.1 * measured;
        assert!(e.rmse < bound, "{lod}: rmse {} ≥ {bound}", e.rmse);
    }
}

/// Through a narrow lens looking across the map, an eye-centred clipmap
/// draws what the view sees from coarse levels; the view-dependent one
/// places its levels over that terrain. Each RMSE against brute force is
/// a fixed number (the renders are deterministic), measured 2026-12-07 at
/// 31.40 (eye, 87 triangles) and 5.29 (view, 995): the bound on the view's
/// is that plus 10 %, as in the test above, and the eye's must stay far
/// above it, or the view no longer tests a narrow view.
#[test]
fn the_view_dependent_clipmap_sees_what_a_narrow_view_sees() {
    let mut s = scene();
    s.apply(&terraclip::scene::Overrides {
        camera: Some([100.0, -100.0, 400.0]),
        look_at: Some([2000.0, -1700.0, 0.0]),
        fov: Some(3.0),
        size: Some([160, 90]),
        ..Default::default()
    })
    .unwrap();
    let opts = terraclip::render::RenderOptions::default();
    let cam = s.camera();
    let (bf, _) = terraclip::render::render(&s.with_lod("brute-force").unwrap(), &opts).unwrap();
    let rmse = |lod: &str| {
        let (img, st) = terraclip::render::render(&s.with_lod(lod).unwrap(), &opts).unwrap();
        let e = terraclip::check::compare::image_error(&img, &bf, &cam);
        println!("{lod}: {} triangles, rmse {:.3}", st.triangles, e.rmse);
        e.rmse
    };
    let (eye, view) = (rmse("clipmap"), rmse("clipmap/view"));
    assert!(view < 1.1 * 5.29, "view {view}");
    assert!(eye > 3.0 * 5.29, "eye {eye}");
}

/// Whether the sweep below also draws on the GPU: always under
/// `TERRACLIP_REQUIRE_GPU=1` (set by `.ci/run`), else where an adapter
/// opens.
fn with_gpu() -> bool {
    #[cfg(feature = "gpu")]
    {
        std::env::var("TERRACLIP_REQUIRE_GPU").is_ok_and(|v| v == "1")
            || terraclip::gpu::Gpu::new(terraclip::gpu::Api::Vulkan).is_ok()
    }
    #[cfg(not(feature = "gpu"))]
    false
}

#[test]
fn tradeoff_rows_cover_every_scheme_and_measure_what_they_claim() {
    let gpu = with_gpu();
    let opts = terraclip::studies::tradeoff::Options {
        size: [64, 36],
        path_frames: 4,
        quick: true,
        shard: WHOLE,
        gpu,
    };
    let r = terraclip::studies::tradeoff::run(&scene(), &opts, |_| {}).unwrap();
    for lod in [
        "brute-force",
        "clipmap",
        "geomipmap",
        "roam",
        "cdlod",
        "annulus",
        "cbt",
        "supersample",
    ] {
        assert!(r.rows.iter().any(|x| x.lod == lod), "no {lod} row");
    }
    assert!(
        r.rows.iter().any(|x| x.config.ends_with(" view")),
        "no view-dependent clipmap row"
    );
    let bf = r.rows.iter().find(|x| x.lod == "brute-force").unwrap();
    assert_eq!((bf.rmse, bf.max_abs, bf.popping), (0.0, 0, 0.0));
    assert!(bf.pareto, "nothing beats brute force's error");
    for x in &r.rows {
        assert!(
            x.rmse.is_finite() && x.ms > 0.0 && x.triangles > 0.0,
            "{x:?}"
        );
    }
    let off = r
        .rows
        .iter()
        .find(|x| x.config.contains("morph off"))
        .unwrap();
    assert!(off.popping > 0.0, "morph off shows no popping");
    let on = r
        .rows
        .iter()
        .find(|x| x.lod == "clipmap" && x.config == off.config.replace("morph off", "strips"))
        .unwrap_or_else(|| panic!("no morph-on row beside {:?}", off.config));
    println!(
        "tradeoff popping: {} {:.3}, {} {:.3}",
        on.config, on.popping, off.config, off.popping
    );
    assert!(on.popping < 0.8 * off.popping, "{on:?} against {off:?}");
    let ss: Vec<f64> = r
        .rows
        .iter()
        .filter(|x| x.lod == "supersample")
        .map(|x| x.rmse)
        .collect();
    assert!(
        ss.windows(2).all(|w| w[1] < w[0]),
        "1x > 4x > 16x error: {ss:?}"
    );
    // The CSV and the chart hold every row.
    let dir = std::env::temp_dir().join(format!("terraclip-tradeoff-{}", std::process::id()));
    terraclip::studies::tradeoff::write(&r, &dir).unwrap();
    let csv = std::fs::read_to_string(dir.join("tradeoff.csv")).unwrap();
    assert_eq!(csv.lines().count(), r.rows.len() + 1);
    let svg = std::fs::read_to_string(dir.join("tradeoff.svg")).unwrap();
    assert!(svg.contains("ms per frame (log)") && svg.contains(">cdlod</text>"));
    assert!(image::open(dir.join("tradeoff.png")).is_ok());
    // The low-FOV chart: the view-dependent clipmap is its own series.
    let low = std::fs::read_to_string(dir.join("tradeoff-low-fov.svg")).unwrap();
    assert!(low.contains("ms per low-FOV frame (log)") && low.contains(">clipmap (view)</text>"));
    assert!(image::open(dir.join("tradeoff-low-fov.png")).is_ok());
    let cpu_lod = std::fs::read_to_string(dir.join("tradeoff-cpu-lod.svg")).unwrap();
    assert!(cpu_lod.contains("ms of LOD update and mesh generation per frame (log)"));
    if gpu {
        gpu_costs_are_measured(&r, &dir);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The sweep's GPU side: every row drawn, with its draw calls and upload.
/// Brute force's mesh never changes, so along the path it sends only the
/// frame's uniforms; every clipmap row sends those and its dirty texels,
/// so more. Pass times are there exactly when the adapter has timestamp
/// queries, and the upload and GPU charts are written.
fn gpu_costs_are_measured(r: &terraclip::studies::tradeoff::Report, dir: &Path) {
    let g = |x: &terraclip::studies::tradeoff::Row| {
        x.gpu
            .clone()
            .unwrap_or_else(|| panic!("no GPU costs: {x:?}"))
    };
    let bf = g(r.rows.iter().find(|x| x.lod == "brute-force").unwrap());
    let timed = bf.ms.is_some();
    for x in &r.rows {
        let c = g(x);
        println!(
            "{} {}: {:?} B/frame, {:?} draws, {:?} ms",
            x.lod, x.config, c.upload_bytes, c.draw_calls, c.ms
        );
        let (upload, draws) = (c.upload_bytes.unwrap(), c.draw_calls.unwrap());
        assert!(draws >= 1.0 && upload > 0.0, "{x:?}");
        assert_eq!(c.ms.is_some(), timed, "{x:?}");
        assert_eq!(c.note.is_some(), !timed, "{x:?}");
        if x.lod == "clipmap" {
            assert!(upload > bf.upload_bytes.unwrap(), "{x:?} against {bf:?}");
        }
    }
    assert_eq!(bf.draw_calls, Some(1.0));
    let svg = std::fs::read_to_string(dir.join("tradeoff-upload.svg")).unwrap();
    assert!(svg.contains("bytes uploaded per frame along the path (log)"));
    assert_eq!(dir.join("tradeoff-gpu.svg").exists(), timed);
}

/// Popping, per frame, is the part of the image's change that brute force's
/// change along the same path does not share. Some of it is not popping at
/// all (a coarse mesh moves differently from the fine one), so morph on
/// stays above 0; what geomorphing removes is the jump when a window
/// shifts. On this path (24 frames of 3 m, 2026-12-01) morph on measured
/// mean 4.81 and max 6.52 against 7.04 and 10.61 off: ratios 0.68 and
/// 0.61. Both must stay under 0.8; a morph that does nothing gives 1.
#[test]
fn fly_reports_updates_and_sees_pops_without_morph() {
    let mut s = scene();
    let on = terraclip::studies::fly::fly(&s, (24, 0), 3.0, true, WHOLE, |_, _| Ok(())).unwrap();
    s.effects.retain(|e| *e != Effect::Morph);
    let off = terraclip::studies::fly::fly(&s, (24, 0), 3.0, true, WHOLE, |_, _| Ok(())).unwrap();
    assert_eq!(on.frames.len(), 24);
    assert!(on.texels_updated > 0, "the clipmap never updated");
    let mean = |r: &terraclip::studies::fly::FlyReport| {
        r.frames.iter().map(|f| f.popping).sum::<f64>() / r.frames.len() as f64
    };
    println!(
        "popping: morph on mean {:.3} max {:.3}, off mean {:.3} max {:.3}",
        mean(&on),
        on.popping_max,
        mean(&off),
        off.popping_max
    );
    assert!(off.popping_max > 0.0);
    assert!(mean(&on) < 0.8 * mean(&off), "mean popping, on against off");
    assert!(
        on.popping_max < 0.8 * off.popping_max,
        "max popping, on against off"
    );
    let bf = terraclip::studies::fly::fly(
        &s.with_lod("brute-force").unwrap(),
        (3, 0),
        7.0,
        true,
        WHOLE,
        |_, _| Ok(()),
    )
    .unwrap();
    assert_eq!(bf.popping_max, 0.0, "brute force cannot pop against itself");
}

/// The CBT's morph (this project's; the paper has none) lowers its largest
/// pop along a flight: vertices appear at their diamond's hypotenuse and
/// rise to their height as the error grows from τ to 2τ. Measured
/// (2026-12-07, 24 frames of 0.3 m): the largest frame's popping 2.47 with
/// the morph, 3.14 without (means 1.32 and 1.41).
#[test]
fn cbt_pops_less_with_its_morph() {
    let mut s = scene().with_lod("cbt").unwrap();
    s.lod.tau = Some(1.0);
    let fly = |s: &Scene| {
        terraclip::studies::fly::fly(s, (24, 0), 0.3, true, WHOLE, |_, _| Ok(())).unwrap()
    };
    let on = fly(&s);
    s.effects.retain(|e| *e != Effect::Morph);
    let off = fly(&s);
    let mean = |r: &terraclip::studies::fly::FlyReport| {
        r.frames.iter().map(|f| f.popping).sum::<f64>() / r.frames.len() as f64
    };
    println!(
        "cbt popping: morph on max {:.3} mean {:.3}, off max {:.3} mean {:.3}",
        on.popping_max,
        mean(&on),
        off.popping_max,
        mean(&off)
    );
    assert!(
        on.popping_max < 0.85 * off.popping_max,
        "max popping, on {} against off {}",
        on.popping_max,
        off.popping_max
    );
}

/// Brute force drawn batch by batch, the target compacted between them,
/// gives what its whole mesh drawn at once gives: colour, depth and the
/// statistics, with effects that read per-vertex (fog, normals), per-
/// triangle (wireframe) and per-level data (normal map, lightmap), over
/// two views and batch sizes from a few hundred triangles to the whole.
#[test]
fn brute_force_in_batches_draws_what_its_whole_mesh_draws() {
    let sets: [&[&str]; 2] = [
        &["lambert", "fog", "normal-map", "shadows", "wireframe"],
        &["phong", "fog", "morph", "level-tint"],
    ];
    let mut batches_seen = 0;
    for effects in sets {
        batches_seen += batches_match(effects);
    }
    assert!(batches_seen > 200, "{batches_seen} batches");
}

/// Draws two views batched and whole with `effects`; the batches drawn.
fn batches_match(effects: &[&str]) -> usize {
    let mut scene = scene().with_lod("brute-force").unwrap();
    scene.effects = effects.iter().map(|e| e.parse().unwrap()).collect();
    scene.image.width = 120;
    scene.image.height = 70;
    let opts = terraclip::render::RenderOptions::default();
    let passes = terraclip::frame::stats::Passes::default;
    let mut whole = terraclip::render::Session::new(&scene, &mut passes()).unwrap();
    let mut batched = terraclip::render::Session::new(&scene, &mut passes()).unwrap();
    let views = [
        scene.camera(),
        camera(100.0, -2400.0, 400.0, 1200.0, -600.0),
    ];
    let mut batches_seen = 0;
    for cam in views {
        let (frame, _) = whole.frame(&cam, &mut passes()).unwrap();
        let total = frame.triangle_count();
        // Per-vertex normals where no normal map replaces them.
        assert_eq!(
            frame.layout.normal.is_some(),
            !effects.contains(&"normal-map")
        );
        let (want, raster) = terraclip::render::draw(&frame, &opts, &mut passes());
        assert!(raster.covered_pixels > 1000, "{raster:?}");
        let vp = terraclip::raster::setup::Viewport::new(scene.image.width, scene.image.height);
        let u = &frame.uniforms;
        let reach = frame
            .positions
            .chunks(3)
            .filter(|t| {
                terraclip::raster::fate([0, 1, 2].map(|j| u.clip(t[j])), &vp)
                    == terraclip::raster::Fate::Draw
            })
            .count();
        // Most of brute force's triangles are smaller than a pixel here.
        assert!(reach < total / 2, "{reach} of {total}");
        for batch in [300, 7_001, total] {
            batched.batch_triangles = batch;
            let (got, stats) = batched.render(&cam, &opts, passes()).unwrap();
            assert!(
                got.rgba == want.rgba,
                "{effects:?}: colour, batches of {batch}"
            );
            let bits = |d: &[f32]| d.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert!(
                bits(&got.depth) == bits(&want.depth),
                "depth, batches of {batch}"
            );
            assert_eq!(stats.raster, raster, "batches of {batch}");
            assert_eq!(stats.triangles, total);
            // Normals only for the vertices of triangles that can reach a
            // pixel: the rest are left out before the vertex stage.
            let maps: usize = frame
                .resources
                .normal_maps
                .iter()
                .flatten()
                .map(|m| m.data.len())
                .sum();
            assert_eq!(
                stats.normals_computed,
                frame.layout.normal.map_or(0, |_| 3 * reach) + maps
            );
            batches_seen += total.div_ceil(batch);
        }
    }
    batches_seen
}
