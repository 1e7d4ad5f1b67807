//! Clipmap update cost: a viewer walking diagonally, and mesh generation.
use criterion::{criterion_group, criterion_main, Criterion};
use std::sync::Arc;
use terraclip::clipmap::{Clipmap, ClipmapConfig, Layout};
use terraclip::heightmap::procedural::Procedural;
use terraclip::pyramid::{Filter, Pyramid};

fn bench(c: &mut Criterion) {
    let map = Procedural::new(1, 2049, 2049).generate().unwrap();
    let pyramid = Arc::new(Pyramid::build(&map, Filter::Box, 6));
    for layout in [Layout::Strips, Layout::Footprints] {
        let mut cm = Clipmap::new(
            pyramid.clone(),
            ClipmapConfig {
                n: 255,
                levels: Some(6),
                layout,
                ..Default::default()
            },
        )
        .unwrap();
        let mut t = 0.0;
        cm.update([600.0, 600.0]);
        c.bench_function(&format!("update_walk_n255_{layout:?}"), |b| {
            b.iter(|| {
                t += 3.0;
                cm.update([600.0 + t % 800.0, 600.0 + t % 800.0])
            })
        });
        c.bench_function(&format!("meshes_n255_{layout:?}"), |b| {
            b.iter(|| {
                let meshes = cm.meshes(None);
                meshes.iter().map(|m| cm.triangles(m).len()).sum::<usize>()
            })
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);
