//! Mapping between the base vertex grid and world space.
//!
//! World space is right-handed, z up: x = origin_x + column × cell_x,
//! y = origin_y − row × cell_y, z = height × vertical_scale. Positions are
//! f64; rendering subtracts a floating origin before going to f32, so a map
//! placed 10^7 m from the world origin renders exactly as one placed at it
//! (`tests/stability.rs`).

use glam::DVec3;

/// Where the heightmap's grid sits in the world: metres per cell, per height unit,
/// and the north-west corner. Every stage converts through it, so grid and world
/// agree everywhere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldMap {
    /// Cell size in metres along columns (x) and rows (y).
    pub cell: [f64; 2],
    /// Multiplier applied to heights.
    pub vertical_scale: f64,
    /// World (x, y) of grid point (0, 0), the map's north-west corner.
    pub origin: [f64; 2],
}

impl WorldMap {
    /// The placement a scene's `[terrain]` table gives a map of cell size
    /// `cell`: its vertical scale and origin.
    pub fn for_terrain(spec: &crate::terrain::Spec, cell: [f64; 2]) -> Self {
        WorldMap::new(cell, spec.vertical_scale).placed_at(spec.origin)
    }

    /// A map with `cell` metres per cell (x, y) and `vertical_scale` metres per height
    /// unit, its north-west corner at the world origin.
    pub fn new(cell: [f64; 2], vertical_scale: f64) -> Self {
        WorldMap {
            cell,
            vertical_scale,
            origin: [0.0; 2],
        }
    }
    /// The same map placed with its north-west corner at world (x, y).
    pub fn placed_at(self, origin: [f64; 2]) -> Self {
        WorldMap { origin, ..self }
    }
    /// World position of base-grid point (col, row) at height z.
    #[inline]
    pub fn to_world(&self, col: f64, row: f64, z: f64) -> DVec3 {
        DVec3::new(
            self.origin[0] + col * self.cell[0],
            self.origin[1] - row * self.cell[1],
            z * self.vertical_scale,
        )
    }
    /// Base-grid (col, row) under a world position.
    #[inline]
    pub fn to_grid(&self, p: DVec3) -> [f64; 2] {
        [
            (p.x - self.origin[0]) / self.cell[0],
            (self.origin[1] - p.y) / self.cell[1],
        ]
    }
    /// World-space box of grid rectangle `[c0, c1] × [r0, r1]` extruded over
    /// heights [z0, z1].
    pub fn aabb(&self, c0: f64, r0: f64, c1: f64, r1: f64, z0: f64, z1: f64) -> (DVec3, DVec3) {
        let a = self.to_world(c0, r0, z0);
        let b = self.to_world(c1, r1, z1);
        (a.min(b), a.max(b))
    }
}
