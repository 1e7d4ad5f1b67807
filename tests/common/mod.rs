//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::sync::Arc;
use terraclip::clipmap::{Clipmap, ClipmapConfig, Layout};
use terraclip::heightmap::procedural::Procedural;
use terraclip::heightmap::Heightmap;
use terraclip::pyramid::{Filter, Pyramid};

/// A procedural map of the given size (cell size 1).
pub fn terrain(seed: u64, w: usize, h: usize) -> Heightmap {
    let mut p = Procedural::new(seed, w, h);
    p.wavelength = 64.0;
    p.octaves = 6;
    p.generate().unwrap()
}

/// A clipmap over `map` with `levels` levels (None = max).
pub fn clipmap(map: &Heightmap, n: i64, levels: Option<usize>, layout: Layout) -> Clipmap {
    let count = levels
        .unwrap_or_else(|| terraclip::clipmap::region::max_levels(map.width(), map.height(), n));
    let p = Arc::new(Pyramid::build(map, Filter::SincBlackman { taps: 7 }, count));
    Clipmap::new(
        p,
        ClipmapConfig {
            n,
            levels: Some(count),
            layout,
            ..ClipmapConfig::default()
        },
    )
    .unwrap()
}
