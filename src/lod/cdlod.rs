//! CDLOD (Strugar 2009): a quadtree over the map whose nodes are drawn as
//! one fixed grid of `grid`×`grid` cells, scaled by 2^L at level L. Level L
//! covers what lies within range r_L of the eye; near the end of its range
//! each vertex morphs continuously toward level L+1 by moving its odd
//! coordinates onto the even neighbour below them, and takes the height of
//! the heightmap (bilinear) where it stands.
//!
//! Ranges are chosen so the morph closes every seam exactly: with D_L the
//! largest 3-D diagonal of a level-L node, a level-L area lies within
//! r_{L−1}+D_{L−1}… of the eye, so its morph starts at
//! s_L = r_{L−1} + D_{L−1} (α_L = 0 where level L−1 meets it), and
//! r_L ≥ r_{L−1} + 2·D_{L−1} keeps level L−2 away from level L. A level-L+1
//! area lies beyond r_L, where α_L = 1 and level L's odd vertices coincide
//! with level L+1's. The finest range is `range` × D_0.

use super::grid::{self, MinMax};
use super::{Lod, LodMesh, LodUpdate, LodVertex, View};
use crate::clipmap::cull::{classify, Class};
use crate::lod::LodScheme;
use crate::pyramid::Pyramid;
use glam::DVec3;
use std::sync::Arc;

/// CDLOD's settings (Strugar 2009).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// Node side in cells (2^k).
    pub grid: usize,
    /// r_0 as a multiple of the finest node's diagonal (≥ 1).
    pub range: f64,
    /// Whether vertices morph towards the coarser grid in each range's outer part.
    pub morph: bool,
}

/// A drawn area: cell rectangle and level.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Area {
    c0: i64,
    r0: i64,
    /// Side in cells.
    size: i64,
    level: u32,
}

/// CDLOD: a quadtree of nodes chosen by distance ranges, each drawn as one grid mesh
/// whose vertices morph in x, y and z towards the parent's grid.
pub struct Cdlod {
    pyramid: Arc<Pyramid>,
    cfg: Config,
    bounds: MinMax,
    root_level: u32,
    /// r_L and s_L per level (metres).
    ranges: Vec<(f64, f64)>,
    selected: Vec<Area>,
}

impl Cdlod {
    /// The scheme over `pyramid`, its quadtree's bounds taken from the pyramid.
    pub fn new(pyramid: Arc<Pyramid>, cfg: Config) -> Self {
        let base = &pyramid.levels[0];
        let side = (base.width.max(base.height) - 1).max(1) as i64;
        let mut root_level = 0;
        while (cfg.grid as i64) << root_level < side {
            root_level += 1;
        }
        Cdlod {
            bounds: MinMax::new(base),
            pyramid,
            cfg,
            root_level,
            ranges: Vec::new(),
            selected: Vec::new(),
        }
    }

    /// (r_L, s_L) for the view's world scale.
    fn ranges(&self, view: &View) -> Vec<(f64, f64)> {
        let base = &self.pyramid.levels[0];
        let relief = (base.max - base.min) as f64 * view.world.vertical_scale;
        let diag = |l: u32| {
            let s = (self.cfg.grid << l) as f64;
            let (x, y) = (s * view.world.cell[0], s * view.world.cell[1]);
            (x * x + y * y + relief * relief).sqrt()
        };
        let r0 = self.cfg.range * diag(0);
        let mut out = vec![(r0, 0.5 * r0)];
        for l in 1..=self.root_level {
            let (prev, _) = out[l as usize - 1];
            let d = diag(l - 1);
            out.push(((2.0 * prev).max(prev + 2.0 * d), prev + d));
        }
        out
    }

    /// The world box of an area (clamped to the map, over its heights);
    /// None when it lies wholly beyond the map.
    fn node_box(&self, view: &View, a: &Area) -> Option<(DVec3, DVec3)> {
        let base = &self.pyramid.levels[0];
        let (mw, mh) = (base.width as i64 - 1, base.height as i64 - 1);
        if a.c0 >= mw.max(1) || a.r0 >= mh.max(1) {
            return None;
        }
        let (lo, hi) = self.bounds.range(a.c0, a.r0, a.c0 + a.size, a.r0 + a.size);
        let (c1, r1) = ((a.c0 + a.size).min(mw), (a.r0 + a.size).min(mh));
        Some(view.world.aabb(
            a.c0 as f64,
            a.r0 as f64,
            c1 as f64,
            r1 as f64,
            lo as f64,
            hi as f64,
        ))
    }

    /// Selects `node` (whose box is `bx`) or its children's areas.
    fn select(&self, view: &View, node: Area, bx: (DVec3, DVec3), out: &mut Vec<Area>) {
        let e = view.camera.eye;
        let distance = |(p, q): (DVec3, DVec3)| (e.clamp(p, q) - e).length();
        let visible = |(p, q): (DVec3, DVec3)| classify(view.frustum, p, q) != Class::Outside;
        if !visible(bx) {
            return;
        }
        let l = node.level;
        if l == 0 || distance(bx) > self.ranges[l as usize - 1].0 {
            out.push(node);
            return;
        }
        let h = node.size / 2;
        for (dc, dr) in [(0, 0), (h, 0), (0, h), (h, h)] {
            let child = Area {
                c0: node.c0 + dc,
                r0: node.r0 + dr,
                size: h,
                level: l - 1,
            };
            let Some(cb) = self.node_box(view, &child) else {
                continue;
            };
            if distance(cb) <= self.ranges[l as usize - 1].0 {
                self.select(view, child, cb, out);
            } else if visible(cb) {
                // The child's quarter, drawn at this node's level.
                out.push(Area { level: l, ..child });
            }
        }
    }

    /// Vertex (c, r) of level `l`'s grid, morphed toward level l+1.
    fn vertex(&self, view: &View, c: i64, r: i64, l: u32) -> LodVertex {
        let base = &self.pyramid.levels[0];
        let v = grid::vertex(base, c, r);
        let g = 1i64 << l;
        let (oc, or) = (c.rem_euclid(2 * g) != 0, r.rem_euclid(2 * g) != 0);
        if !self.cfg.morph || !(oc || or) {
            return v;
        }
        let (end, start) = self.ranges[l as usize];
        let p = view.world.to_world(v.col as f64, v.row as f64, v.z as f64);
        let d = (p - view.camera.eye).length();
        let alpha = ((d - start) / (end - start)).clamp(0.0, 1.0);
        if alpha == 0.0 {
            return v;
        }
        let (tc, tr) = (c - if oc { g } else { 0 }, r - if or { g } else { 0 });
        if alpha == 1.0 {
            return grid::vertex(base, tc, tr);
        }
        // Between the two: a point on the grid line, clamped to the map.
        let (mw, mh) = ((base.width - 1) as f64, (base.height - 1) as f64);
        let x = (c as f64 - alpha * (c - tc) as f64).clamp(0.0, mw);
        let y = (r as f64 - alpha * (r - tr) as f64).clamp(0.0, mh);
        let (fc, fr) = (x.floor(), y.floor());
        let z = grid::bilinear(base, x, y);
        LodVertex {
            col: fc as i64,
            row: fr as i64,
            offset: [(x - fc) as f32, (y - fr) as f32],
            ..LodVertex::on_grid(0, 0, z)
        }
    }

    fn emit(&self, view: &View, a: &Area, out: &mut LodMesh) {
        let g = 1i64 << a.level;
        let m = a.size / g;
        let row = |j: i64| -> Vec<LodVertex> {
            (0..=m)
                .map(|i| self.vertex(view, a.c0 + i * g, a.r0 + j * g, a.level))
                .collect()
        };
        let mut top = row(0);
        for j in 0..m {
            let bottom = row(j + 1);
            for i in 0..m as usize {
                grid::push_quad(out, top[i], top[i + 1], bottom[i + 1], bottom[i]);
            }
            top = bottom;
        }
    }
}

impl Lod for Cdlod {
    fn scheme(&self) -> LodScheme {
        LodScheme::Cdlod
    }
    fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    fn update(&mut self, view: &View) -> LodUpdate {
        self.ranges = self.ranges(view);
        let mut selected = Vec::new();
        let root = Area {
            c0: 0,
            r0: 0,
            size: (self.cfg.grid as i64) << self.root_level,
            level: self.root_level,
        };
        if let Some(bx) = self.node_box(view, &root) {
            self.select(view, root, bx, &mut selected);
        }
        let changes = selected
            .iter()
            .filter(|a| !self.selected.contains(a))
            .count();
        self.selected = selected;
        LodUpdate {
            texels_updated: 0,
            changes: changes as u64,
        }
    }

    fn mesh(&mut self, view: &View) -> LodMesh {
        let base = &self.pyramid.levels[0];
        let mut out = LodMesh::base_level(base.width, base.height);
        out.append_parallel(&self.selected, |a, m| self.emit(view, a, m));
        out
    }
}
