//! Each LOD scheme's update step (and its mesh generation) on one walk over
//! a 1025² map, so the schemes' LOD costs compare side by side in one run.
//! The full error-against-time sweep is `terraclip tradeoff`.
use criterion::{criterion_group, criterion_main, Criterion};
use terraclip::frame::stats::Passes;
use terraclip::lod::View;
use terraclip::render::Session;
use terraclip::scene::Scene;

fn bench(c: &mut Criterion) {
    let base = Scene::bench_scene();
    for spec in terraclip::studies::cracks::all() {
        let scene = base.with_lod(&spec).expect("valid scheme");
        let mut s = Session::new(&scene, &mut Passes::default()).expect("session");
        let start = scene.camera();
        let mut i = 0usize;
        let name = spec.replace('/', "_");
        c.bench_function(&format!("update_{name}"), |b| {
            b.iter(|| {
                i += 1;
                let cam = terraclip::camera::path_camera(&start, i % 400, 5.0);
                let f = cam.frustum();
                let view = View {
                    camera: &cam,
                    frustum: &f,
                    world: &s.world,
                    viewport: [960, 540],
                };
                s.lod.update(&view)
            })
        });
        c.bench_function(&format!("mesh_{name}"), |b| {
            let f = start.frustum();
            let view = View {
                camera: &start,
                frustum: &f,
                world: &s.world,
                viewport: [960, 540],
            };
            s.lod.update(&view);
            b.iter(|| s.lod.mesh(&view).triangle_count())
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);
