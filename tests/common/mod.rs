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

/// A small procedural scene (257², n = 15, 96×54) for scheme and survey
/// tests.
pub const SMALL_SCENE: &str = r#"effects = ["morph", "lambert"]
[terrain]
procedural = { seed = 5, width = 257, height = 257, amplitude = 500.0, wavelength = 64.0 }
cell_size = 10.0
[lod]
n = 15
[camera]
position = [600.0, -600.0, 700.0]
look_at = [1500.0, -1500.0, 100.0]
near = 1.0
far = 20000.0
[image]
width = 96
height = 54
"#;

pub fn small_scene() -> terraclip::scene::Scene {
    terraclip::scene::Scene::parse(SMALL_SCENE, "test scene", std::path::Path::new(".")).unwrap()
}
