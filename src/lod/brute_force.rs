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
}

/// The full-resolution mesh of `base` seen through `frustum`.
pub fn mesh(base: &PyramidLevel, bounds: &MinMax, frustum: &Frustum, world: &WorldMap) -> LodMesh {
    let (w, h) = (base.width, base.height);
    let mut out = LodMesh::base_level(w, h);
    let v = |c: usize, r: usize| LodVertex::on_grid(c as i64, r as i64, base.data[r * w + c]);
    for by in (0..h - 1).step_by(BLOCK) {
        for bx in (0..w - 1).step_by(BLOCK) {
            let (ex, ey) = ((bx + BLOCK).min(w - 1), (by + BLOCK).min(h - 1));
            let rect = [bx as i64, by as i64, ex as i64, ey as i64];
            let b = bounds.get(5, (bx / BLOCK) as i64, (by / BLOCK) as i64);
            if !grid::visible(base, frustum, world, rect, b) {
                continue;
            }
            for r in by..ey {
                for c in bx..ex {
                    grid::push_quad(&mut out, v(c, r), v(c + 1, r), v(c + 1, r + 1), v(c, r + 1));
                }
            }
        }
    }
    out
}
