//! A lazy pyramid (`pyramid.lazy`): frames drawn while the pyramid is built
//! tile by tile around the viewer have the eager pipeline's bits, the first
//! frame of a large map needs only the tiles under its windows, and what a
//! lazy pyramid cannot serve is refused with the field named.

use terraclip::frame::stats::Passes;
use terraclip::render::{Image, RenderOptions, RenderStats, Session};
use terraclip::scene::{Effect, LodScheme, Scene};
use terraclip::terrain::procedural::Procedural;

/// The default scene on a procedural `size`² map with a fixed colour ramp,
/// lazy or not.
fn scene(size: usize, lazy: bool, budget: u64) -> Scene {
    let mut s = Scene::bench_scene();
    s.terrain.procedural = Some(Procedural::new(20041, size, size));
    s.pyramid.lazy = lazy;
    s.pyramid.budget = budget;
    s.shading.height_range = Some([-300.0, 300.0]);
    s.image.width = 160;
    s.image.height = 90;
    s
}

/// Renders a walk of `steps` frames (the eye moves 37 m east and 11 m south
/// per frame, so every level's window moves now and then).
fn walk(s: &Scene, steps: usize) -> Vec<(Image, RenderStats)> {
    let mut session = Session::new(s, &mut Passes::default()).unwrap();
    (0..steps)
        .map(|i| {
            let mut c = s.camera();
            let d = glam::DVec3::new(37.0 * i as f64, -11.0 * i as f64, 0.0);
            c.eye += d;
            c.target += d;
            session
                .render(&c, &RenderOptions::default(), Passes::default())
                .unwrap()
        })
        .collect()
}

fn same(a: &Image, b: &Image) -> bool {
    let bits = |d: &[f32]| d.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    a.rgba == b.rgba && bits(&a.depth) == bits(&b.depth)
}

/// With a budget for everything the windows need, every frame of a walk is
/// the eager frame, bit for bit, colour and depth; with 3 levels (the
/// coarsest window 252² of 1025² texels) the pyramid builds part of the map.
#[test]
fn lazy_frames_equal_eager_frames() {
    let three = |lazy: bool, budget: u64| {
        let mut s = scene(1025, lazy, budget);
        s.lod.levels = Some(3);
        s
    };
    let eager = walk(&three(false, 1), 6);
    let lazy = walk(&three(true, u64::MAX), 6);
    for (i, (e, l)) in eager.iter().zip(&lazy).enumerate() {
        assert!(same(&e.0, &l.0), "frame {i} differs");
        assert_eq!(e.1.triangles, l.1.triangles);
        assert!(e.1.triangles > 1000);
        assert_eq!(l.1.lazy.as_ref().unwrap().levels_unbuilt, 0);
    }
    let z = lazy.last().unwrap().1.lazy.clone().unwrap();
    println!("{z:?}");
    assert!(z.pyramid.tiles_built < z.pyramid.tiles_total, "{z:?}");
}

/// A small budget draws the finer levels first: the first frame is the
/// eager frame of a clipmap with only the ready levels (on a 2^k + 1 map
/// the usable bounds do not depend on the level count), later frames add
/// the coarser levels, and once all are built frames equal the eager ones.
#[test]
fn a_small_budget_draws_coarse_levels_later() {
    let budget = 60_000;
    let lazy = walk(&scene(1025, true, budget), 40);
    let first = &lazy[0].1;
    let z0 = first.lazy.clone().unwrap();
    assert!(z0.levels_unbuilt > 0, "{z0:?}");
    let ready = first.levels_drawn;
    let mut fewer = scene(1025, false, 1);
    fewer.lod.levels = Some(ready);
    let e = &walk(&fewer, 1)[0];
    assert!(
        same(&e.0, &lazy[0].0),
        "first frame ≠ eager {ready}-level frame"
    );

    let drawn: Vec<usize> = lazy.iter().map(|f| f.1.levels_drawn).collect();
    println!("levels drawn per frame: {drawn:?}");
    assert!(drawn.windows(2).all(|w| w[1] >= w[0]), "{drawn:?}");
    let full = lazy
        .iter()
        .position(|f| f.1.lazy.as_ref().unwrap().levels_unbuilt == 0)
        .expect("all levels built within 40 frames");
    let eager = walk(&scene(1025, false, 1), 40);
    for i in full..40 {
        assert!(same(&eager[i].0, &lazy[i].0), "frame {i} differs");
    }
}

/// What a lazy pyramid cannot serve is refused, naming the field.
#[test]
fn lazy_scenes_refuse_what_needs_the_whole_map() {
    let err = |edit: &dyn Fn(&mut Scene)| {
        let mut s = scene(257, true, 1000);
        edit(&mut s);
        s.validate().unwrap_err().to_string()
    };
    let e = err(&|s| s.lod.scheme = LodScheme::BruteForce);
    assert!(
        e.contains("pyramid.lazy") && e.contains("brute-force"),
        "{e}"
    );
    let e = err(&|s| s.effects.push(Effect::Shadows));
    assert!(e.contains("pyramid.lazy") && e.contains("shadows"), "{e}");
    let e = err(&|s| s.shading.height_range = None);
    assert!(e.contains("shading.height_range"), "{e}");
    let e = err(&|s| s.pyramid.budget = 0);
    assert!(e.contains("pyramid.budget"), "{e}");
    let e = err(&|s| s.shading.height_range = Some([5.0, f32::NAN]));
    assert!(e.contains("shading.height_range"), "{e}");
    // Level tint colours by level, not height: no range needed.
    let mut s = scene(257, true, 1000);
    s.shading.height_range = None;
    s.effects = vec![Effect::LevelTint];
    s.validate().unwrap();
}

/// A loaded map keeps its level 0 whole and builds only the coarser levels
/// lazily; with a small budget the frames match the eager ones once every
/// level is drawn, and the first one draws fewer levels.
#[test]
fn a_file_terrain_builds_its_coarse_levels_lazily() {
    let load = |lazy: bool| {
        let mut s = Scene::load(std::path::Path::new("golden/jacksboro-oblique.toml")).unwrap();
        s.pyramid.lazy = lazy;
        s.pyramid.budget = 20_000;
        s.shading.height_range = Some([230.0, 1080.0]);
        s.image.width = 160;
        s.image.height = 90;
        s.validate().unwrap();
        s
    };
    let eager = walk(&load(false), 12);
    let lazy = walk(&load(true), 12);
    let unbuilt: Vec<usize> = lazy
        .iter()
        .map(|f| f.1.lazy.as_ref().unwrap().levels_unbuilt)
        .collect();
    println!("levels unbuilt per frame: {unbuilt:?}");
    assert!(unbuilt[0] > 0, "{unbuilt:?}");
    let full = unbuilt
        .iter()
        .position(|&u| u == 0)
        .expect("complete in 12 frames");
    for i in full..12 {
        assert!(same(&eager[i].0, &lazy[i].0), "frame {i} differs");
    }
}
