//! Brute force: every heightmap vertex, two triangles per cell on the main
//! diagonal (the clipmap's convention), no LOD. The accuracy reference.
//! Blocks of cells wholly outside the frustum are skipped.

use super::grid::{self, MinMax};
use super::{Lod, LodMesh, LodUpdate, LodVertex, View};
use crate::camera::Frustum;
use crate::lod::LodScheme;
use crate::pyramid::{Pyramid, PyramidLevel};
use crate::terrain::world::WorldMap;
use std::sync::Arc;

const BLOCK: usize = 32;

pub struct BruteForce {
    pyramid: Arc<Pyramid>,
    bounds: MinMax,
}

impl BruteForce {
    pub fn new(pyramid: Arc<Pyramid>) -> Self {
        let bounds = MinMax::new(&pyramid.levels[0]);
        BruteForce { pyramid, bounds }
    }
}

impl Lod for BruteForce {
    fn scheme(&self) -> LodScheme {
        LodScheme::BruteForce
    }
    fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }
    fn update(&mut self, _: &View) -> LodUpdate {
        LodUpdate::default()
    }
    fn mesh(&mut self, view: &View) -> LodMesh {
        mesh(
            &self.pyramid.levels[0],
            &self.bounds,
            view.frustum,
            view.world,
        )
    }
    fn mesh_batch(
        &mut self,
        view: &View,
        cursor: &mut usize,
        max: usize,
        out: &mut LodMesh,
    ) -> bool {
        let base = &self.pyramid.levels[0];
        let rows = block_rows(base);
        let mut batch = Batch::new(base, &self.bounds, view.frustum, view.world, out);
        while *cursor < rows {
            batch.block_row(*cursor);
            *cursor += 1;
            if batch.out.triangle_count() >= max {
                break;
            }
        }
        *cursor < rows
    }
}

/// Rows of blocks in the map.
fn block_rows(base: &PyramidLevel) -> usize {
    (base.height - 1).div_ceil(BLOCK)
}

/// A mesh being filled with rows of blocks, in draw order.
struct Batch<'a> {
    base: &'a PyramidLevel,
    bounds: &'a MinMax,
    frustum: &'a Frustum,
    world: &'a WorldMap,
    out: &'a mut LodMesh,
}

impl<'a> Batch<'a> {
    /// Empties `out` (keeping its memory) for the base level of `base`.
    fn new(
        base: &'a PyramidLevel,
        bounds: &'a MinMax,
        frustum: &'a Frustum,
        world: &'a WorldMap,
        out: &'a mut LodMesh,
    ) -> Self {
        out.vertices.clear();
        out.levels.clear();
        out.level_info = LodMesh::base_level(base.width, base.height).level_info;
        Batch {
            base,
            bounds,
            frustum,
            world,
            out,
        }
    }

    /// Appends the visible blocks of block row `row`.
    fn block_row(&mut self, row: usize) {
        let base = self.base;
        let (w, h) = (base.width, base.height);
        let v = |c: usize, r: usize| LodVertex::on_grid(c as i64, r as i64, base.data[r * w + c]);
        let by = row * BLOCK;
        let ey = (by + BLOCK).min(h - 1);
        for bx in (0..w - 1).step_by(BLOCK) {
            let ex = (bx + BLOCK).min(w - 1);
            let rect = [bx as i64, by as i64, ex as i64, ey as i64];
            let b = self.bounds.get(5, (bx / BLOCK) as i64, row as i64);
            if !grid::visible(base, self.frustum, self.world, rect, b) {
                continue;
            }
            for r in by..ey {
                for c in bx..ex {
                    grid::push_quad(self.out, v(c, r), v(c + 1, r), v(c + 1, r + 1), v(c, r + 1));
                }
            }
        }
    }
}

/// The full-resolution mesh of `base` seen through `frustum`.
pub fn mesh(base: &PyramidLevel, bounds: &MinMax, frustum: &Frustum, world: &WorldMap) -> LodMesh {
    let mut out = LodMesh::default();
    let mut batch = Batch::new(base, bounds, frustum, world, &mut out);
    for row in 0..block_rows(base) {
        batch.block_row(row);
    }
    out
}
