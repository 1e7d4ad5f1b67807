//! Brute force: every heightmap vertex, two triangles per cell on the main
//! diagonal (the clipmap's convention), no LOD. The accuracy reference.
//! Blocks of cells wholly outside the frustum are skipped.

use super::{LevelInfo, LodMesh, LodVertex};
use crate::camera::Frustum;
use crate::clipmap::cull::{classify, Class};
use crate::pyramid::PyramidLevel;
use crate::world::WorldMap;

const BLOCK: usize = 32;

/// The full-resolution mesh of `base` seen through `frustum`.
pub fn mesh(base: &PyramidLevel, frustum: &Frustum, world: &WorldMap) -> LodMesh {
    let (w, h) = (base.width, base.height);
    let mut out = LodMesh {
        level_info: vec![Some(LevelInfo {
            level: 0,
            origin: [0, 0],
            size: [base.width, base.height],
            morph: false,
        })],
        ..Default::default()
    };
    let v = |c: usize, r: usize| {
        let z = base.data[r * w + c];
        LodVertex {
            col: c as i64,
            row: r as i64,
            z,
            zc: z,
            alpha: 0.0,
        }
    };
    for by in (0..h - 1).step_by(BLOCK) {
        for bx in (0..w - 1).step_by(BLOCK) {
            let (ex, ey) = ((bx + BLOCK).min(w - 1), (by + BLOCK).min(h - 1));
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for r in by..=ey {
                for &z in &base.data[r * w + bx..=r * w + ex] {
                    lo = lo.min(z);
                    hi = hi.max(z);
                }
            }
            let (a, b) = world.aabb(
                bx as f64, by as f64, ex as f64, ey as f64, lo as f64, hi as f64,
            );
            if classify(frustum, a, b) == Class::Outside {
                continue;
            }
            for r in by..ey {
                for c in bx..ex {
                    out.vertices.extend([v(c, r), v(c + 1, r), v(c + 1, r + 1)]);
                    out.vertices.extend([v(c, r), v(c + 1, r + 1), v(c, r + 1)]);
                    out.levels.extend([0, 0]);
                }
            }
        }
    }
    out
}
