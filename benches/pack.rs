//! Pack encode and decode on jacksboro (the repository's copy) at E = 1 m
//! and losslessly, and one 128² tile of its level 0 decoded alone, the unit
//! a clipmap update will decode, with both predictors at E = 1 m.
//! `benches/pack_anchors.rs` sets these against LERC and zstd.
use criterion::{criterion_group, criterion_main, Criterion};
use terraclip::pack::{Packed, Predictor};
use terraclip::pyramid::{Filter, Pyramid};
use terraclip::terrain::Heightmap;

fn bench(c: &mut Criterion) {
    let map = Heightmap::load(std::path::Path::new("tests/data/jacksboro_16.png")).unwrap();
    let levels = Pyramid::build(&map, Filter::default(), 64).levels;
    for e in [0.0, 1.0] {
        c.bench_function(&format!("pack_encode_jacksboro_e{e}"), |b| {
            b.iter(|| Packed::encode(&levels, e, 128, map.lattice))
        });
        let (packed, recon) = Packed::encode(&levels, e, 128, map.lattice);
        c.bench_function(&format!("pack_decode_jacksboro_e{e}"), |b| {
            b.iter(|| packed.decode().unwrap())
        });
        c.bench_function(&format!("pack_decode_tile_jacksboro_e{e}"), |b| {
            b.iter(|| packed.decode_tile(0, [1, 1], &recon[1]).unwrap())
        });
    }
    let (packed, recon) = Packed::encode_with(&levels, 1.0, 128, None, Predictor::Upsampled);
    c.bench_function("pack_decode_tile_jacksboro_e1_upsampled", |b| {
        b.iter(|| packed.decode_tile(0, [1, 1], &recon[1]).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
