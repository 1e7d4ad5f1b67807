//! Pyramid build time per filter on the ETOPO5 DEM when present (else a
//! procedural map of similar size); procedural generation, eager and as
//! lazy tiles under a clipmap's first windows. ETOPO5 is read from
//! `target/etopo5_16.png`, where `docs/get-etopo5.sh target` writes it.
use criterion::{criterion_group, criterion_main, Criterion};
use terraclip::pyramid::{Filter, LazyBase, Pyramid};
use terraclip::terrain::procedural::Procedural;
use terraclip::terrain::Heightmap;

fn bench(c: &mut Criterion) {
    let etopo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/etopo5_16.png");
    let map = if etopo.exists() {
        Heightmap::load(&etopo).unwrap()
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
    // The same texels generated whole, and as the lazy pyramid's tiles
    // under the windows of a first frame (n = 255, 4 levels, every sample
    // of them built) on a 16384² map.
    let gen = Procedural::new(1, 2048, 2048);
    c.bench_function("procedural_2048x2048", |b| {
        b.iter(|| gen.generate().unwrap())
    });
    let big = Procedural::new(1, 16384, 16384);
    let windows: Vec<[i64; 4]> = (0..4)
        .map(|l| {
            let o = (8192 >> l) - 127;
            [o - 1, o - 1, o + 255, o + 255]
        })
        .collect();
    c.bench_function("lazy_first_windows_16384_n255_l4", |b| {
        b.iter(|| {
            let base = LazyBase::Procedural(big.clone());
            let mut p = Pyramid::lazy(base, Filter::default(), 9, u64::MAX).unwrap();
            p.build_around(&windows)
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
