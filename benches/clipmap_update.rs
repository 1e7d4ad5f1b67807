//! Clipmap update cost: a viewer walking diagonally, and mesh generation.
use criterion::{criterion_group, criterion_main, Criterion};
use std::sync::Arc;
use terraclip::clipmap::{Clipmap, ClipmapConfig, Layout};
use terraclip::pyramid::{Filter, Pyramid};
use terraclip::terrain::procedural::Procedural;

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
                    .texels_total
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

/// The incremental-update case of docs/explanation/performance.md: n = 255, L = 10, one texel per frame, against a
/// full rebuild of every level (the `scaling` command's map).
fn bench_n255_l10(c: &mut Criterion) {
    let pyramid = Arc::new(terraclip::studies::scaling::update_map(255, 10).unwrap());
    let centre = [
        pyramid.levels[0].width as f64 / 2.0,
        pyramid.levels[0].height as f64 / 2.0,
    ];
    let mut cm = Clipmap::new(
        pyramid,
        ClipmapConfig {
            n: 255,
            levels: Some(10),
            ..Default::default()
        },
    )
    .unwrap();
    cm.update(centre);
    c.bench_function("update_n255_l10_full_rebuild", |b| {
        b.iter(|| {
            cm.invalidate();
            cm.update(centre).texels_total
        })
    });
    for (name, d) in [("east", [1.0, 0.0]), ("south", [0.0, 1.0])] {
        let mut f = 0.0;
        cm.update(centre);
        c.bench_function(&format!("update_n255_l10_walk_{name}"), |b| {
            b.iter(|| {
                // 4096 steps, then one jump back: 1/4096 of the samples are a
                // rebuild, as in any long walk over a finite map.
                f = (f + 1.0) % 4096.0;
                cm.update([centre[0] + f * d[0], centre[1] + f * d[1]])
                    .texels_total
            })
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench, bench_n255_l10
}
criterion_main!(benches);
