//! Raster + shade of the default scene at 1920×1080 (the frame is built
//! once; this times what a back end does per frame).

use criterion::{criterion_group, criterion_main, Criterion};
use terraclip::frame::stats::Passes;
use terraclip::raster::Path;
use terraclip::render::{build_frame, draw, RenderOptions};
use terraclip::scene::Scene;

fn bench(c: &mut Criterion) {
    let mut s = Scene::bench_scene();
    s.image.width = 1920;
    s.image.height = 1080;
    let frame = build_frame(&s, &mut Passes::default()).expect("default scene");
    let mut g = c.benchmark_group("raster_default_1920x1080");
    g.sample_size(20);
    for path in [Path::Simd, Path::Scalar] {
        g.bench_function(format!("{path:?}"), |b| {
            b.iter(|| draw(&frame, &RenderOptions { path }, &mut Passes::default()))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
