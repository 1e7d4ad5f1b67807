//! The "draping" annulus: one quadrant mesh of m×m cells (m = (n+1)/2),
//! mirrored into four and scaled by 2 per ring, centred on the eye with no
//! snapping. Ring r samples pyramid level r bilinearly, texels addressed by
//! floor. Because the vertices slide with the eye, the surface they sample
//! changes shape as the eye moves ("swimming"), and because a ring's outer
//! edge has twice the vertices of the next ring's inner edge, with heights
//! from a different level, the rings meet with T-junctions: cracks. This is
//! the scheme that shows why clipmaps snap and morph.

use super::grid;
use super::{Lod, LodMesh, LodUpdate, LodVertex, View};
use crate::clipmap::cull::{classify, Class};
use crate::lod::LodScheme;
use crate::pyramid::Pyramid;
use std::sync::Arc;

/// The draping annulus's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// Ring width parameter, 2^k − 1 as for the clipmap.
    pub n: i64,
    /// Rings, each twice the spacing of the one inside it.
    pub rings: usize,
}

/// A "draping" annulus: fixed rings of grid around the viewer, unsnapped, that
/// sample the terrain where they fall; the baseline clipmaps improve on by snapping.
pub struct Annulus {
    pyramid: Arc<Pyramid>,
    cfg: Config,
    eye: [f64; 2],
}

impl Annulus {
    /// The scheme over `pyramid`.
    pub fn new(pyramid: Arc<Pyramid>, cfg: Config) -> Self {
        Annulus {
            pyramid,
            cfg,
            eye: [0.0; 2],
        }
    }

    /// Vertex at base-grid point (x, y) of ring `r`, clamped to the map.
    fn vertex(&self, x: f64, y: f64, r: usize) -> LodVertex {
        let base = &self.pyramid.levels[0];
        let x = x.clamp(0.0, (base.width - 1) as f64);
        let y = y.clamp(0.0, (base.height - 1) as f64);
        let l = r.min(self.pyramid.levels.len() - 1);
        let s = (1u64 << l) as f64;
        let z = grid::bilinear(&self.pyramid.levels[l], x / s, y / s);
        let (c, w) = (x.floor(), y.floor());
        LodVertex {
            col: c as i64,
            row: w as i64,
            offset: [(x - c) as f32, (y - w) as f32],
            ..LodVertex::on_grid(0, 0, z)
        }
    }

    /// Ring `r`, quadrant (sx, sy).
    fn emit(&self, view: &View, (r, sx, sy): (usize, f64, f64), out: &mut LodMesh) {
        let m = (self.cfg.n + 1) / 2;
        let hole = if r == 0 { 0 } else { m / 2 };
        let s = (1u64 << r) as f64;
        let [ex, ey] = self.eye;
        let p = |i: i64, j: i64| (ex + sx * s * i as f64, ey + sy * s * j as f64);
        // Cull the quadrant as a whole (heights: the map's range).
        let base = &self.pyramid.levels[0];
        let (a, b) = (p(0, 0), p(m, m));
        let (lo, hi) = view.world.aabb(
            a.0.min(b.0),
            a.1.min(b.1),
            a.0.max(b.0),
            a.1.max(b.1),
            base.min as f64,
            base.max as f64,
        );
        if classify(view.frustum, lo, hi) == Class::Outside {
            return;
        }
        let row = |j: i64| -> Vec<LodVertex> {
            (0..=m)
                .map(|i| {
                    let (x, y) = p(i, j);
                    self.vertex(x, y, r)
                })
                .collect()
        };
        let mut top = row(0);
        for j in 0..m {
            let bottom = row(j + 1);
            for i in 0..m {
                if i < hole && j < hole {
                    continue;
                }
                let i = i as usize;
                grid::push_quad(out, top[i], top[i + 1], bottom[i + 1], bottom[i]);
            }
            top = bottom;
        }
    }
}

impl Lod for Annulus {
    fn scheme(&self) -> LodScheme {
        LodScheme::Annulus
    }
    fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    fn update(&mut self, view: &View) -> LodUpdate {
        self.eye = view.world.to_grid(view.camera.eye);
        LodUpdate::default()
    }

    fn mesh(&mut self, view: &View) -> LodMesh {
        let base = &self.pyramid.levels[0];
        let parts: Vec<(usize, f64, f64)> = (0..self.cfg.rings)
            .flat_map(|r| {
                [
                    (r, 1.0, 1.0),
                    (r, -1.0, 1.0),
                    (r, -1.0, -1.0),
                    (r, 1.0, -1.0),
                ]
            })
            .collect();
        let mut out = LodMesh::base_level(base.width, base.height);
        out.append_parallel(&parts, |&q, m| self.emit(view, q, m));
        out
    }
}
