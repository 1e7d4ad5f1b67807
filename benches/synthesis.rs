//! Synthesis on jacksboro (the repository's copy): one 128² tile of the
//! first level finer than the map, the unit a clipmap update makes, and a
//! 255² window, the size of GPU Gems 2's whole-level upsampling (1.0 ms on
//! its 2005 GPU), each with the noise and, for the four-point subdivision
//! alone, without.
use criterion::{criterion_group, criterion_main, Criterion};
use terraclip::pyramid::{Filter, Pyramid};
use terraclip::synthesis::{subdivide_window, synthesize_window, NoiseTable};
use terraclip::terrain::Heightmap;

fn bench(c: &mut Criterion) {
    let map = Heightmap::load(std::path::Path::new("tests/data/jacksboro_16.png")).unwrap();
    let base = &Pyramid::build(&map, Filter::default(), 1).levels[0];
    let table = NoiseTable::new(1);
    for (name, rect) in [
        ("tile_128", [128, 128, 128, 128]),
        ("window_255", [100, 100, 255, 255]),
    ] {
        c.bench_function(&format!("synthesis_{name}_jacksboro"), |b| {
            b.iter(|| synthesize_window(base, &table, 1, 5.0, None, rect))
        });
        c.bench_function(&format!("subdivision_{name}_jacksboro"), |b| {
            b.iter(|| subdivide_window(base, rect))
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
