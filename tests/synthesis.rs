//! `[terrain] synthesis`: levels finer than the map, made a tile at a time
//! as the clipmap's windows reach them. They are the same bits whichever
//! tiles are made in whichever order, evicted or not, as the levels made
//! whole, and the same as the synthesis study's chain of [`synthesize`];
//! scenes draw them, crack-free, and bad values are refused by name.

use std::path::Path;
use terraclip::frame::stats::Passes;
use terraclip::pyramid::{Filter, Pyramid, PyramidLevel};
use terraclip::render::{RenderOptions, Session};
use terraclip::scene::Scene;
use terraclip::synthesis::source::{refine, Spec};
use terraclip::synthesis::{synthesize, NoiseTable};
use terraclip::terrain::procedural::Procedural;

fn base(size: usize, levels: usize) -> Pyramid {
    let map = Procedural::new(20041, size, size).generate().unwrap();
    Pyramid::from_heightmap(map, Filter::default(), levels)
}

fn spec(levels: usize) -> Spec {
    Spec {
        levels,
        roughness: None,
        seed: 5,
    }
}

fn bits(l: &PyramidLevel, [x0, y0, x1, y1]: [i64; 4]) -> Vec<(u32, bool)> {
    let c = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize;
    let mut out = Vec::new();
    for y in c(y0, l.height)..=c(y1, l.height) {
        for x in c(x0, l.width)..=c(x1, l.width) {
            let i = y * l.width + x;
            out.push((l.data[i].to_bits(), l.nodata[i]));
        }
    }
    out
}

/// The synthesised levels made whole are the study's chain: level k is
/// `synthesize` of level k + 1 with the k-th amplitude, from the map's own
/// finest level up.
#[test]
fn whole_levels_are_the_studys_synthesis() {
    let (p, how) = refine(base(129, 4), &spec(2), Path::new("test"), u64::MAX).unwrap();
    assert!(
        how.measured && how.roughness > 0.0 && how.detail > 0.0,
        "{how:?}"
    );
    assert_eq!(how.amplitudes.len(), 2);
    let p = p.whole().unwrap();
    assert_eq!(p.finer_levels(), 2);
    assert_eq!(p.levels.len(), 6);
    assert_eq!([p.levels[0].width, p.levels[1].width], [513, 257]);
    let t = NoiseTable::new(5);
    let one = synthesize(&p.levels[2], &t, 1, how.amplitudes[0]);
    let two = synthesize(&one, &t, 2, how.amplitudes[1]);
    assert!(bits(&p.levels[1], [0, 0, 256, 256]) == bits(&one, [0, 0, 256, 256]));
    assert!(bits(&p.levels[0], [0, 0, 512, 512]) == bits(&two, [0, 0, 512, 512]));
    // Whole, each level's range is its own.
    let (lo, hi) = two
        .data
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    assert_eq!([p.levels[0].min, p.levels[0].max], [lo, hi]);
    // The height ramp keeps the map's.
    assert_eq!(p.height_range(), [p.levels[2].min, p.levels[2].max]);
}

/// Windows that walk across the map, with a budget small enough that
/// levels wait and tiles are evicted behind them: whatever is ready under
/// each window is the whole levels' bits. Walked twice: with a window per
/// level, nested as a clipmap's, and with the finest level's alone, whose
/// tiles then find the coarser samples they read only by what they ask for.
#[test]
fn tiles_made_in_any_order_are_the_whole_levels_bits() {
    let whole = refine(base(129, 4), &spec(2), Path::new("test"), u64::MAX)
        .unwrap()
        .0
        .whole()
        .unwrap();
    // East, then west from the east edge, so both sides of a tile's reads
    // are first needed when the coarser tiles they reach are missing.
    for (drawn, x0, dx) in [(5, 290, 5), (1, 290, 5), (1, 500, -5)] {
        let (mut tiled, _) = refine(base(129, 4), &spec(2), Path::new("test"), 10_000).unwrap();
        let (mut evicted, mut waited, mut made) = (0, 0, 0);
        // Checks per level: every drawn level, the two synthesised ones
        // among them, must be checked somewhere along the walk.
        let mut checks = vec![0usize; drawn];
        for step in 0..40i64 {
            // Level l's window: 63 texels wide, centred on a point moving
            // diagonally across the finest level.
            let c = [x0 + dx * step, 480 - 9 * step];
            let windows: Vec<[i64; 4]> = (0..drawn)
                .map(|l| {
                    let (x, y) = (c[0] >> l, c[1] >> l);
                    [x - 31, y - 31, x + 31, y + 31]
                })
                .collect();
            let built = tiled.build_around(&windows);
            evicted += built.evicted;
            made += built.tiles;
            waited += built.ready.start;
            for l in built.ready.clone() {
                // Every tile under the window, whole.
                let t = tiled.tile_side().unwrap() as i64;
                let [x0, y0, x1, y1] = windows[l].map(|v| v.max(0));
                let tiles = [
                    x0 / t * t,
                    y0 / t * t,
                    x1 / t * t + t - 1,
                    y1 / t * t + t - 1,
                ];
                assert!(
                    bits(&tiled.levels[l], tiles) == bits(&whole.levels[l], tiles),
                    "{drawn} windows, step {step}, level {l}"
                );
                checks[l] += 1;
            }
        }
        assert!(
            checks.iter().all(|&c| c > 0),
            "{drawn} windows: checks per level {checks:?}"
        );
        assert!(evicted > 0 && made > 20, "{evicted} {made}");
        assert!(drawn == 1 || waited > 0, "{waited}");
    }
}

/// The noise continues the map: its amplitude is the map's finest detail
/// times 2^(−H k), and a roughness given by hand is used as given.
#[test]
fn amplitudes_continue_the_maps_detail() {
    let (_, how) = refine(base(129, 4), &spec(3), Path::new("test"), 1).unwrap();
    for (k, a) in how.amplitudes.iter().enumerate() {
        let want = how.detail * 2f64.powf(-how.roughness * (k + 1) as f64);
        assert!((a / want - 1.0).abs() < 1e-12, "level {k}: {a} vs {want}");
    }
    let given = Spec {
        roughness: Some(0.5),
        ..spec(1)
    };
    let (_, how) = refine(base(129, 4), &given, Path::new("test"), 1).unwrap();
    assert!(!how.measured && how.roughness == 0.5);
    let want = how.detail / std::f64::consts::SQRT_2;
    assert!((how.amplitudes[0] / want - 1.0).abs() < 1e-15);
}

/// A close-to-the-ground scene over a procedural map with two synthesised
/// levels: the clipmap draws the two levels finer than the map, the same
/// frames on one thread as on two, a walk never cracks, and the images
/// differ from the map's without synthesis.
fn close_scene(levels: Option<usize>) -> Scene {
    let mut s = Scene::bench_scene();
    s.terrain.procedural = Some(Procedural::new(7, 257, 257));
    s.terrain.cell_size = Some(terraclip::scene::CellSize::Square(16.0));
    s.terrain.synthesis = levels.map(spec);
    s.camera.position = [2000.0, -2000.0, 400.0];
    s.camera.look_at = Some([2600.0, -2600.0, 0.0]);
    s.image.width = 160;
    s.image.height = 100;
    s
}

#[test]
fn scenes_draw_the_synthesised_levels() {
    let plain = close_scene(None);
    let synth = close_scene(Some(2));
    let render = |s: &Scene| {
        let mut session = Session::new(s, &mut Passes::default()).unwrap();
        let cam = s.camera();
        let (img, stats) = session
            .render(&cam, &RenderOptions::default(), Passes::default())
            .unwrap();
        (img, stats, session.world)
    };
    let (a, sa, wa) = render(&plain);
    let (b, sb, wb) = render(&synth);
    assert_eq!(wb.cell, [wa.cell[0] / 4.0, wa.cell[1] / 4.0]);
    assert_ne!(a.rgba, b.rgba);
    assert!(sb.triangles > 0 && sa.triangles > 0);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let (c, _, _) = one.install(|| render(&synth));
    assert_eq!(b.rgba, c.rgba);
    assert_eq!(
        b.depth.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        c.depth.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
}

/// Bad values are refused with the key named: too many levels, a negative
/// roughness, and synthesis over a lazy pyramid, which cannot apply.
#[test]
fn bad_synthesis_values_are_clean_errors() {
    let check = |edit: &dyn Fn(&mut Scene), want: &str| {
        let mut s = close_scene(Some(2));
        edit(&mut s);
        let e = match s.validate() {
            Err(e) => e.to_string(),
            Ok(()) => Session::new(&s, &mut Passes::default())
                .err()
                .expect("refused")
                .to_string(),
        };
        assert!(e.contains(want), "{e}");
    };
    check(
        &|s| s.terrain.synthesis = Some(spec(5)),
        "terrain.synthesis.levels",
    );
    check(
        &|s| s.terrain.synthesis = Some(spec(0)),
        "terrain.synthesis.levels",
    );
    check(
        &|s| {
            s.terrain.synthesis = Some(Spec {
                roughness: Some(-0.5),
                ..spec(1)
            })
        },
        "terrain.synthesis.roughness",
    );
    check(
        &|s| {
            s.terrain.synthesis = Some(Spec {
                roughness: Some(f64::NAN),
                ..spec(1)
            })
        },
        "terrain.synthesis.roughness",
    );
    check(
        &|s| {
            s.pyramid.lazy = true;
            s.shading.height_range = Some([0.0, 1.0]);
        },
        "lazy",
    );
    // Shadows read the finest level whole: 2049² three levels down is
    // 16,385², just over the 2^28 samples held whole.
    check(
        &|s| {
            s.terrain.procedural = Some(Procedural::new(7, 2049, 2049));
            s.terrain.synthesis = Some(spec(3));
            s.effects.push(terraclip::scene::Effect::Shadows);
        },
        "held whole",
    );
    // A flat map has no detail to continue.
    check(
        &|s| {
            s.terrain.procedural = Some(Procedural {
                amplitude: 0.0,
                ..Procedural::new(7, 257, 257)
            })
        },
        "flat",
    );
}

/// Synthesis over a lossless pack, its levels decoded a tile at a time
/// beneath the synthesised ones (and, as the camera crosses the map,
/// evicted and decoded again), draws the same bits as over the map
/// itself, frame after frame; and the detail it continues is measured the
/// same (jacksboro fits the pack's measuring window whole).
#[test]
fn synthesis_over_a_lossless_pack_draws_as_over_the_map() {
    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("golden");
    let mut map = Scene::load(&golden.join("jacksboro-oblique.toml")).unwrap();
    map.terrain.synthesis = Some(spec(2));
    map.image.width = 160;
    map.image.height = 100;
    let mut pack = map.clone();
    pack.terrain.file = Some("jacksboro-e0.tcz".into());
    let mut a = Session::new(&map, &mut Passes::default()).unwrap();
    let mut b = Session::new(&pack, &mut Passes::default()).unwrap();
    assert_eq!(a.synthesis, b.synthesis);
    let mut evicted = 0;
    for i in 0..11 {
        let mut c = map.camera();
        // From the map's west edge to its east: tiles left behind are
        // evicted, and the pack's own levels decoded again ahead.
        // Low, looking down ahead, so the finest levels are in view.
        c.eye = glam::DVec3::new(2500.0 * i as f64 + 2000.0, -26000.0, 1400.0);
        c.target = c.eye + glam::DVec3::new(0.0, 3000.0, -1200.0);
        let opts = RenderOptions::default();
        let (x, sx) = a.render(&c, &opts, Passes::default()).unwrap();
        let (y, sy) = b.render(&c, &opts, Passes::default()).unwrap();
        evicted += sy.lazy.as_ref().unwrap().tiles_evicted.unwrap();
        assert_eq!(sx.levels_drawn, sy.levels_drawn);
        assert!(sx.triangles > 1000, "frame {i}: {} triangles", sx.triangles);
        assert!(x.rgba == y.rgba, "frame {i}: colour differs");
        assert!(x
            .depth
            .iter()
            .zip(&y.depth)
            .all(|(p, q)| p.to_bits() == q.to_bits()));
    }
    assert!(evicted > 0);
}

/// `height_at` and `ray_hit` answer on the synthesised surface: at the
/// finest level's vertices under the camera (inside its ring, where nothing
/// morphs) they give the synthesised samples, to the f32 rounding of
/// camera-relative positions, not the map's own heights there.
#[test]
fn heights_and_rays_answer_on_the_synthesised_surface() {
    let scene = Scene::load(Path::new("golden/synthesis-close.toml")).unwrap();
    let mut session = Session::new(&scene, &mut Passes::default()).unwrap();
    let mut cam = scene.camera();
    // Straight down, so the finest level's interior is in view.
    cam.target = cam.eye + glam::DVec3::new(0.1, 0.0, -50.0);
    let surface = session.surface(&cam).unwrap();
    let world = session.world;
    let fine = &session.pyramid().levels[0];
    let coarse = &session.pyramid().levels[3];
    let g = world.to_grid(cam.eye);
    let (mut checked, mut off_map, mut worst) = (0, 0, 0f64);
    for dy in -6i64..=6 {
        for dx in -6i64..=6 {
            let (c, r) = (g[0].round() as i64 + dx, g[1].round() as i64 + dy);
            let p = world.to_world(c as f64, r as f64, 0.0);
            let want = fine.data[r as usize * fine.width + c as usize] as f64;
            // The drawn vertex holds the sample as an f32 (the vertical
            // scale is 1, so one rounding, none here: the sample is an
            // f32); `height_at` interpolates it in f64 from the f32
            // camera-relative positions, whose horizontal rounding (an
            // ulp of a few metres, 5e-7 m) moves the point across a
            // triangle of ~1 m slope by as much. So 4 ulps of the height.
            let ulp = |z: f64| (z as f32).abs().max(1.0) * f32::EPSILON;
            let tol = 4.0 * ulp(want) as f64;
            let got = surface.height_at(p.x, p.y).expect("drawn");
            assert!(
                (got - want).abs() <= tol,
                "({c}, {r}): {got} vs {want}, tol {tol}"
            );
            let hit = surface
                .ray_hit(p + glam::DVec3::new(0.0, 0.0, 500.0), glam::DVec3::NEG_Z)
                .expect("hit");
            assert!(
                (hit.point.z - want).abs() <= tol,
                "({c}, {r}) ray: {:?}, tol {tol}",
                hit.point
            );
            worst = worst
                .max((got - want).abs() / tol)
                .max((hit.point.z - want).abs() / tol);
            // The map's own height at the same point (bilinear in its cells).
            let (mc, mr) = (c as f64 / 8.0, r as f64 / 8.0);
            let m = |x: f64, y: f64| coarse.get_clamped(x as i64, y as i64) as f64;
            let (fx, fy) = (mc.fract(), mr.fract());
            let (x0, y0) = (mc.floor(), mr.floor());
            let map = (m(x0, y0) * (1.0 - fx) + m(x0 + 1.0, y0) * fx) * (1.0 - fy)
                + (m(x0, y0 + 1.0) * (1.0 - fx) + m(x0 + 1.0, y0 + 1.0) * fx) * fy;
            off_map += usize::from((got - map).abs() > 0.01);
            checked += 1;
        }
    }
    println!("worst error {worst} of the tolerance");
    assert_eq!(checked, 169);
    assert!(
        off_map > 150,
        "{off_map} of {checked} differ from the map's own surface"
    );
}

/// A map with too few levels to measure its roughness is refused, and
/// with a roughness given it needs only the two its detail is measured
/// over.
#[test]
fn measuring_needs_the_maps_levels() {
    let tiny = || base(3, 4);
    assert_eq!(tiny().levels.len(), 2);
    let e = refine(tiny(), &spec(1), Path::new("tiny"), 1).unwrap_err();
    assert!(e.contains("2 levels") && e.contains("needs 3"), "{e}");
    let given = Spec {
        roughness: Some(0.5),
        ..spec(1)
    };
    let (p, _) = refine(tiny(), &given, Path::new("tiny"), 1).unwrap();
    assert_eq!(p.levels[0].width, 5);
}

/// A pack larger than the measuring window is measured in its central
/// 1024², decoded for the purpose: the detail and roughness are those of
/// the map's own levels over that window, bit for bit (a lossless pack).
#[test]
fn a_large_pack_is_measured_in_its_central_window() {
    use terraclip::pack::reader::PackReader;
    use terraclip::pack::{file, Packed};
    // Even sides: level 0's last column and row lie past level 1's
    // subdivision (2 · 769 − 1 = 1537 of 1538), and are left out.
    let map = Procedural::new(31, 1538, 1282).generate().unwrap();
    let levels = Pyramid::build(&map, Filter::default(), usize::MAX).levels;
    let (packed, _) = Packed::encode(&levels, 0.0, 128, map.lattice);
    let path = std::env::temp_dir().join(format!("terraclip-synth-{}.tcz", std::process::id()));
    file::write(
        &path,
        &packed,
        map.cell_size,
        &Filter::default().name(),
        "test",
    )
    .unwrap();
    let reader = PackReader::open(&path).unwrap();
    let decoded = Pyramid::decoded(std::sync::Arc::new(reader), Filter::default(), 1).unwrap();
    let (_, how) = refine(decoded, &spec(1), &path, 1).unwrap();
    let _ = std::fs::remove_file(&path);
    // The central 1024² of level 0, and level 1's samples under it.
    let r0 = [(1537 - 1024) / 2, (1281 - 1024) / 2, 1024, 1024];
    assert_eq!([levels[1].width, levels[1].height], [769, 641]);
    let r1 = [r0[0] / 2, r0[1] / 2, 512, 512];
    let d0 = terraclip::synthesis::detail_rms_window(&levels[0], &levels[1], r0).unwrap();
    let d1 = terraclip::synthesis::detail_rms_window(&levels[1], &levels[2], r1).unwrap();
    assert_eq!(how.detail.to_bits(), d0.to_bits(), "{} vs {d0}", how.detail);
    assert_eq!(how.next_detail.map(f64::to_bits), Some(d1.to_bits()));
    assert_eq!(
        how.roughness,
        terraclip::synthesis::roughness_between(d0, d1).unwrap()
    );
    // Not the whole map's.
    let whole = terraclip::synthesis::detail_rms(&levels[0], &levels[1]).unwrap();
    assert_ne!(whole, d0);
}

/// A synthesised level's height bounds, before any tile is made: the
/// map's range widened per level by 2.25 r / 8 (the four-point overshoot
/// of a centre) plus six times the amplitude (the table's reach), times
/// 1.001 plus 1 mm for rounding; exactly that, and they hold for every
/// sample once made.
#[test]
fn synthesised_levels_have_bounds_that_hold() {
    let (tiled, how) = refine(base(129, 4), &spec(3), Path::new("test"), 1).unwrap();
    let whole = refine(base(129, 4), &spec(3), Path::new("test"), 1)
        .unwrap()
        .0
        .whole()
        .unwrap();
    let map = &tiled.levels[3];
    let (mut lo, mut hi) = (map.min as f64, map.max as f64);
    for k in 1..=3 {
        let e = (2.25 * (hi - lo) / 8.0 + 6.0 * how.amplitudes[k - 1]) * 1.001 + 1e-3;
        (lo, hi) = (lo - e, hi + e);
        let (t, w) = (&tiled.levels[3 - k], &whole.levels[3 - k]);
        assert_eq!(
            [t.min, t.max],
            [lo as f32, hi as f32],
            "level {k} below the map"
        );
        assert!(
            t.min <= w.min && w.max <= t.max,
            "{k}: {:?} outside {:?}",
            [w.min, w.max],
            [t.min, t.max]
        );
    }
}
