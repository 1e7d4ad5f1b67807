//! Brute force, the accuracy reference, at the scale of real maps: a cold
//! frame (the first of a new session), a warm one (a session that has
//! drawn before, whose buffers are kept), and one view of the crack
//! survey (brute force and the clipmap of the same view, and the pixels
//! compared), over the 4097 × 2049 procedural map of
//! `benches/scenes/survey.toml` (16.8 M cells).
//!
//! With `TERRACLIP_BENCH_HEIGHTMAP=PATH` the cold and warm frames are also
//! timed over that map as `render --heightmap PATH --lod brute-force
//! --size 320x180` frames it (`docs/get-etopo5.sh target` fetches the
//! ETOPO5 map the performance page quotes).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::path::Path;
use terraclip::frame::stats::Passes;
use terraclip::lod::LodScheme;
use terraclip::render::{draw, RenderOptions, Session};
use terraclip::scene::{Overrides, Scene};
use terraclip::studies::{cracks, metrics, views};

fn scene() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/scenes/survey.toml");
    let text = std::fs::read_to_string(&path).expect("benches/scenes/survey.toml");
    Scene::parse(&text, "survey.toml", path.parent().expect("folder")).expect("survey scene")
}

/// Times a cold frame and a warm one of `brute` in group `name`.
fn cold_and_warm(c: &mut Criterion, name: &str, brute: &Scene) {
    let opts = RenderOptions::default();
    let new_session = || Session::new(brute, &mut Passes::default()).expect("session");
    let cam = brute.camera();
    let mut g = c.benchmark_group(name);
    g.sample_size(10);
    g.bench_function("cold frame", |b| {
        b.iter_batched(
            new_session,
            |mut s| s.render(&cam, &opts, Passes::default()).expect("render"),
            BatchSize::PerIteration,
        )
    });
    let mut warm = new_session();
    warm.render(&cam, &opts, Passes::default()).expect("render");
    g.bench_function("warm frame", |b| {
        b.iter(|| warm.render(&cam, &opts, Passes::default()).expect("render"))
    });
    g.finish();
}

fn bench(c: &mut Criterion) {
    if let Some(map) = std::env::var_os("TERRACLIP_BENCH_HEIGHTMAP") {
        let mut s = Scene::default_scene();
        s.apply(&Overrides {
            heightmap: Some(map.into()),
            size: Some([320, 180]),
            lod: Some(LodScheme::BruteForce),
            ..Default::default()
        })
        .expect("overrides");
        terraclip::scene::frame_terrain(&mut s).expect("framed");
        s.fog_from_far();
        cold_and_warm(c, "brute_force_heightmap_320x180", &s);
    }
    let mut brute = scene().with_lod("brute-force").expect("brute force");
    brute.image.width = 320;
    brute.image.height = 180;
    cold_and_warm(c, "brute_force_4097x2049_320x180", &brute);

    let opts = RenderOptions::default();
    let mut g = c.benchmark_group("survey_4097x2049_200x120");
    g.sample_size(10);
    let survey = cracks::survey_scene(&scene(), [200, 120]);
    let mut reference = Session::new(
        &survey.with_lod("brute-force").expect("brute force"),
        &mut Passes::default(),
    )
    .expect("session");
    let mut clipmap = Session::new(&survey, &mut Passes::default()).expect("session");
    let cams = views::random_views(&reference, &survey.camera(), 10, 0x5EED_CAFE);
    let mut i = 0;
    g.bench_function("survey view (clipmap)", |b| {
        b.iter(|| {
            // The survey's own views, in turn.
            let cam = &cams[i % cams.len()];
            i += 1;
            let (want, _) = reference
                .render(cam, &opts, Passes::default())
                .expect("render");
            let (frame, _) = clipmap.frame(cam, &mut Passes::default()).expect("frame");
            let (got, _) = draw(&frame, &opts, &mut Passes::default());
            metrics::crack_candidates(&got, &want, [255, 0, 0]).len()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
