//! Pyramid build time per filter on the ETOPO5 DEM when present (else a
//! procedural map of similar size).
use criterion::{criterion_group, criterion_main, Criterion};
use terraclip::heightmap::procedural::Procedural;
use terraclip::heightmap::Heightmap;
use terraclip::pyramid::{Filter, Pyramid};

fn bench(c: &mut Criterion) {
    let etopo = std::path::Path::new("../shared/data/dem/etopo5_16.png");
    let map = if etopo.exists() {
        Heightmap::load(etopo).unwrap()
    } else {
        Procedural::new(1, 4320, 2161).generate().unwrap()
    };
    for f in [
        Filter::Point,
        Filter::Box,
        Filter::SincBlackman { taps: 11 },
    ] {
        c.bench_function(&format!("pyramid_8_levels_{f:?}"), |b| {
            b.iter(|| Pyramid::build(&map, f, 8))
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
