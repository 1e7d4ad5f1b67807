//! One clipmap level: its toroidal height window and this frame's regions.

use super::columns::ColumnCache;
use super::morph::MorphParams;
use super::region::LevelRegions;
use super::toroid::Toroid;

/// A level's state after an update.
#[derive(Clone, Debug)]
pub struct ClipLevel {
    /// Level index l; grid spacing is 2^l base texels.
    pub level: usize,
    /// Heights of the n×n window, in toroid order.
    pub heights: Toroid<f32>,
    /// Regions for the current viewer (active is `None` when inactive).
    pub regions: LevelRegions,
    /// Morph constants for the current viewer.
    pub morph: MorphParams,
    /// Source columns for east/west steps.
    pub columns: ColumnCache,
}

impl ClipLevel {
    /// Level `level` with an empty `n` × `n` toroid in `regions`; morphing off until the
    /// clipmap sets it up.
    pub fn new(level: usize, n: usize, regions: LevelRegions) -> Self {
        ClipLevel {
            level,
            heights: Toroid::new(n),
            regions,
            morph: MorphParams {
                viewer: [0.0; 2],
                half: ((n - 1) / 2) as f32,
                width: 1.0,
                enabled: false,
                boundary: [0; 4],
                stitched: [false; 4],
            },
            columns: ColumnCache::default(),
        }
    }
    /// Grid spacing in base texels.
    pub fn spacing(&self) -> i64 {
        1 << self.level
    }
    /// Whether the level has an active region (is drawn) this frame.
    pub fn is_active(&self) -> bool {
        self.regions.active.is_some()
    }
}
