//! ROAM (Duchaineau et al. 1997): a triangle bintree per patch of P×P
//! cells (two right isosceles roots per patch), kept from frame to frame
//! and adjusted by a split queue and a merge queue.
//!
//! Each triangle's priority is its nested geometric error (the height error
//! at its hypotenuse midpoint, maxed over its descendants) projected to
//! pixels at the distance of a bounding disc that contains its children's
//! discs, so priorities never grow down the tree. Each frame, mergeable
//! diamonds (both halves split, all four children leaves) whose priority is
//! at most τ merge, then leaves above τ split, highest first, until none is
//! left or the triangle budget is reached. A split first splits the base
//! neighbour if it is coarser (forced splits), so the mesh never has a
//! T-junction.

use super::grid::{self, MinMax};
use super::{Lod, LodMesh, LodUpdate, View};
use crate::lod::LodScheme;
use crate::pyramid::Pyramid;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::sync::Arc;

/// ROAM's settings (Duchaineau et al. 1997).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// Split while a triangle's error covers more than τ pixels.
    pub tau: f64,
    /// Triangle budget (may be overshot by one chain of forced splits).
    pub max_triangles: usize,
}

/// Patch side in cells: bintree depth 2·log2(P).
const PATCH: i64 = 64;
const NONE: u32 = u32::MAX;

#[derive(Clone, Copy, Debug)]
struct Tri {
    /// Apex, left and right corners (base-grid, unclamped).
    v: [[i64; 2]; 3],
    parent: u32,
    /// Left and right child, NONE for a leaf.
    child: [u32; 2],
    /// Neighbours across the base (hypotenuse), the left leg (apex–left)
    /// and the right leg (apex–right).
    base: u32,
    left: u32,
    right: u32,
    /// Patch and implicit bintree index (root 1, children 2k and 2k+1).
    patch: u32,
    node: u32,
    /// Which of the patch's two roots it descends from.
    root: u8,
    alive: bool,
}

/// ROAM: a binary triangle tree split and merged through priority queues by each
/// triangle's screen-space error, with forced splits keeping it crack-free.
pub struct Roam {
    pyramid: Arc<Pyramid>,
    cfg: Config,
    patches: [i64; 2],
    /// Nested error per patch, per root (2), per implicit node index.
    errors: Vec<Vec<f32>>,
    /// Height range per patch.
    bounds: Vec<(f32, f32)>,
    tris: Vec<Tri>,
    free: Vec<u32>,
    leaves: usize,
}

/// Max-heap entry.
#[derive(PartialEq)]
struct Entry(f64, u32);
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        self.0.total_cmp(&o.0).then(o.1.cmp(&self.1))
    }
}

impl Roam {
    /// The scheme over `pyramid`, starting from the two root triangles.
    pub fn new(pyramid: Arc<Pyramid>, cfg: Config) -> Self {
        let base = &pyramid.levels[0];
        let patches = [
            ((base.width as i64 - 1).max(1) + PATCH - 1) / PATCH,
            ((base.height as i64 - 1).max(1) + PATCH - 1) / PATCH,
        ];
        let count = (patches[0] * patches[1]) as usize;
        let depth = 2 * PATCH.trailing_zeros();
        let errors: Vec<Vec<f32>> = (0..count)
            .into_par_iter()
            .map(|p| {
                let mut e = vec![0.0f32; 1 << (depth + 1)];
                for (root, v) in Self::roots(p as i64, patches[0]).iter().enumerate() {
                    nested_error(
                        base,
                        *v,
                        1,
                        depth,
                        &mut e[root << depth..(root + 1) << depth],
                    );
                }
                e
            })
            .collect();
        let mm = MinMax::new(base);
        let k = PATCH.trailing_zeros() as usize;
        let bounds = (0..count as i64)
            .map(|p| mm.get(k, p % patches[0], p / patches[0]))
            .collect();
        let mut roam = Roam {
            pyramid,
            cfg,
            patches,
            errors,
            bounds,
            tris: Vec::new(),
            free: Vec::new(),
            leaves: 0,
        };
        roam.reset();
        roam
    }

    /// The two roots of patch `p`, split on the a–c diagonal.
    fn roots(p: i64, across: i64) -> [[[i64; 2]; 3]; 2] {
        let (x0, y0) = ((p % across) * PATCH, (p / across) * PATCH);
        let (x1, y1) = (x0 + PATCH, y0 + PATCH);
        [
            [[x1, y0], [x0, y0], [x1, y1]],
            [[x0, y1], [x1, y1], [x0, y0]],
        ]
    }

    /// Two roots per patch, linked to each other and to adjacent patches.
    fn reset(&mut self) {
        self.tris.clear();
        self.free.clear();
        let [pw, ph] = self.patches;
        for p in 0..pw * ph {
            for (k, v) in Self::roots(p, pw).iter().enumerate() {
                self.tris.push(Tri {
                    v: *v,
                    parent: NONE,
                    child: [NONE; 2],
                    base: (2 * p + 1 - k as i64) as u32,
                    left: NONE,
                    right: NONE,
                    patch: p as u32,
                    node: 1,
                    root: k as u8,
                    alive: true,
                });
            }
        }
        // Root 0 (apex top-right): left leg top edge, right leg right edge.
        // Root 1 (apex bottom-left): left leg bottom edge, right leg left edge.
        for p in 0..pw * ph {
            let (i, j) = (p % pw, p / pw);
            let id = |i: i64, j: i64, k: u32| {
                if i < 0 || j < 0 || i >= pw || j >= ph {
                    NONE
                } else {
                    (2 * (j * pw + i)) as u32 + k
                }
            };
            self.tris[(2 * p) as usize].left = id(i, j - 1, 1);
            self.tris[(2 * p) as usize].right = id(i + 1, j, 1);
            self.tris[(2 * p + 1) as usize].left = id(i, j + 1, 0);
            self.tris[(2 * p + 1) as usize].right = id(i - 1, j, 0);
        }
        self.leaves = self.tris.len();
    }

    fn error(&self, t: &Tri) -> f32 {
        let depth = 2 * PATCH.trailing_zeros();
        if t.node >= 1 << depth {
            return 0.0;
        }
        self.errors[t.patch as usize][((t.root as usize) << depth) + t.node as usize]
    }

    /// Priority in pixels (0 when the triangle cannot be split or is
    /// outside the view).
    fn priority(&self, view: &View, id: u32) -> f64 {
        let t = &self.tris[id as usize];
        let e = self.error(t) as f64;
        let bounds = self.bounds[t.patch as usize];
        grid::screen_error(&self.pyramid.levels[0], view, e, t.v, bounds)
    }

    fn alloc(&mut self, t: Tri) -> u32 {
        match self.free.pop() {
            Some(i) => {
                self.tris[i as usize] = t;
                i
            }
            None => {
                self.tris.push(t);
                (self.tris.len() - 1) as u32
            }
        }
    }

    /// Points neighbour `n`'s link that pointed at `old` to `new`.
    fn relink(&mut self, n: u32, old: u32, new: u32) {
        if n == NONE {
            return;
        }
        let t = &mut self.tris[n as usize];
        if t.base == old {
            t.base = new;
        } else if t.left == old {
            t.left = new;
        } else if t.right == old {
            t.right = new;
        }
    }

    /// Makes the two children of leaf `id` (links to the base side are
    /// fixed by `split`).
    fn split_one(&mut self, id: u32) {
        let t = self.tris[id as usize];
        let [a, l, r] = t.v;
        let m = [(l[0] + r[0]) / 2, (l[1] + r[1]) / 2];
        let mk = |v, node| Tri {
            v,
            parent: id,
            child: [NONE; 2],
            base: NONE,
            left: NONE,
            right: NONE,
            patch: t.patch,
            node,
            root: t.root,
            alive: true,
        };
        let tl = self.alloc(mk([m, a, l], 2 * t.node));
        let tr = self.alloc(mk([m, r, a], 2 * t.node + 1));
        self.tris[tl as usize].left = tr;
        self.tris[tl as usize].base = t.left;
        self.tris[tr as usize].right = tl;
        self.tris[tr as usize].base = t.right;
        self.relink(t.left, id, tl);
        self.relink(t.right, id, tr);
        self.tris[id as usize].child = [tl, tr];
        self.leaves += 1;
    }

    fn splittable(&self, id: u32) -> bool {
        let t = &self.tris[id as usize];
        let [_, l, r] = t.v;
        (l[0] + r[0]) % 2 == 0 && (l[1] + r[1]) % 2 == 0 && (l[0] != r[0] || l[1] != r[1])
    }

    /// Splits leaf `id` and its base neighbour (forcing splits down the
    /// base chain first). Returns the number of triangles split.
    fn split(&mut self, id: u32) -> u64 {
        if self.tris[id as usize].child[0] != NONE || !self.splittable(id) {
            return 0;
        }
        let mut n = 0;
        let b = self.tris[id as usize].base;
        if b != NONE && self.tris[b as usize].base != id {
            n += self.split(b);
        }
        let b = self.tris[id as usize].base;
        if b != NONE && self.tris[b as usize].base != id {
            return n; // the base could not be split (should not happen)
        }
        self.split_one(id);
        n += 1;
        if b != NONE {
            self.split_one(b);
            n += 1;
            let [tl, tr] = self.tris[id as usize].child;
            let [bl, br] = self.tris[b as usize].child;
            self.tris[tl as usize].right = br;
            self.tris[tr as usize].left = bl;
            self.tris[bl as usize].right = tr;
            self.tris[br as usize].left = tl;
        }
        n
    }

    fn is_leaf(&self, id: u32) -> bool {
        self.tris[id as usize].child[0] == NONE
    }

    /// Whether `id` heads a mergeable diamond: split, children leaves, and
    /// the same for its base neighbour.
    fn mergeable(&self, id: u32) -> bool {
        let ok = |t: u32| {
            let c = self.tris[t as usize].child;
            c[0] != NONE && self.is_leaf(c[0]) && self.is_leaf(c[1])
        };
        let b = self.tris[id as usize].base;
        self.tris[id as usize].alive && ok(id) && (b == NONE || ok(b))
    }

    fn merge_one(&mut self, id: u32) {
        let [tl, tr] = self.tris[id as usize].child;
        let (nl, nr) = (self.tris[tl as usize].base, self.tris[tr as usize].base);
        self.tris[id as usize].left = nl;
        self.tris[id as usize].right = nr;
        self.relink(nl, tl, id);
        self.relink(nr, tr, id);
        for c in [tl, tr] {
            self.tris[c as usize].alive = false;
            self.free.push(c);
        }
        self.tris[id as usize].child = [NONE; 2];
        self.leaves -= 1;
    }

    fn merge(&mut self, id: u32) -> u64 {
        let b = self.tris[id as usize].base;
        self.merge_one(id);
        if b != NONE {
            self.merge_one(b);
            2
        } else {
            1
        }
    }

    /// Triangles in the current mesh.
    pub fn triangle_count(&self) -> usize {
        self.leaves
    }
}

/// Fills `out[node]` with the nested error of bintree node `node` (corners
/// `v`) and returns it: the hypotenuse midpoint's height error, maxed with
/// the children's.
fn nested_error(
    base: &crate::pyramid::PyramidLevel,
    v: [[i64; 2]; 3],
    node: usize,
    depth: u32,
    out: &mut [f32],
) -> f32 {
    if node >= 1 << depth {
        return 0.0;
    }
    let [a, l, r] = v;
    let m = [(l[0] + r[0]) / 2, (l[1] + r[1]) / 2];
    let z = |p: [i64; 2]| base.get_clamped(p[0], p[1]);
    let own = (z(m) - 0.5 * (z(l) + z(r))).abs();
    let e = own
        .max(nested_error(base, [m, a, l], 2 * node, depth, out))
        .max(nested_error(base, [m, r, a], 2 * node + 1, depth, out));
    out[node] = e;
    e
}

impl Lod for Roam {
    fn scheme(&self) -> LodScheme {
        LodScheme::Roam
    }
    fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    fn update(&mut self, view: &View) -> LodUpdate {
        let tau = self.cfg.tau;
        let mut changes = 0;
        // Merge queue: lowest priority first.
        let mut merges: BinaryHeap<Entry> = (0..self.tris.len() as u32)
            .filter(|&i| {
                self.mergeable(i)
                    && self.tris[i as usize].base.min(i) == i.min(self.tris[i as usize].base)
            })
            .filter_map(|i| {
                let b = self.tris[i as usize].base;
                let p = self.priority(view, i).max(if b == NONE {
                    0.0
                } else {
                    self.priority(view, b)
                });
                (p <= tau).then_some(Entry(-p, i))
            })
            .collect();
        while let Some(Entry(_, i)) = merges.pop() {
            if !self.mergeable(i) {
                continue;
            }
            changes += self.merge(i);
            // The parent diamond may now be mergeable.
            let p = self.tris[i as usize].parent;
            if p != NONE && self.mergeable(p) {
                let b = self.tris[p as usize].base;
                let pr = self.priority(view, p).max(if b == NONE {
                    0.0
                } else {
                    self.priority(view, b)
                });
                if pr <= tau {
                    merges.push(Entry(-pr, p));
                }
            }
        }
        // Split queue: highest priority first.
        let mut splits: BinaryHeap<Entry> = (0..self.tris.len() as u32)
            .filter(|&i| self.tris[i as usize].alive && self.is_leaf(i))
            .filter_map(|i| {
                let p = self.priority(view, i);
                (p > tau).then_some(Entry(p, i))
            })
            .collect();
        while let Some(Entry(_, i)) = splits.pop() {
            // The budget may be overshot by one chain of forced splits.
            if self.leaves >= self.cfg.max_triangles {
                break;
            }
            if !self.tris[i as usize].alive || !self.is_leaf(i) {
                continue;
            }
            changes += self.split(i);
            for c in self.tris[i as usize].child {
                if c != NONE {
                    let p = self.priority(view, c);
                    if p > tau {
                        splits.push(Entry(p, c));
                    }
                }
            }
        }
        LodUpdate {
            texels_updated: 0,
            changes,
        }
    }

    fn mesh(&mut self, view: &View) -> LodMesh {
        let base = &self.pyramid.levels[0];
        let mut out = LodMesh::base_level(base.width, base.height);
        let leaves: Vec<&Tri> = self
            .tris
            .iter()
            .filter(|t| t.alive && t.child[0] == NONE)
            .collect();
        let chunks: Vec<&[&Tri]> = leaves.chunks(4096).collect();
        out.append_parallel(&chunks, |chunk, m| {
            for t in chunk.iter() {
                let [a, l, r] = t.v;
                let (lo, hi) = self.bounds[t.patch as usize];
                let rect = [
                    a[0].min(l[0]).min(r[0]),
                    a[1].min(l[1]).min(r[1]),
                    a[0].max(l[0]).max(r[0]),
                    a[1].max(l[1]).max(r[1]),
                ];
                if grid::visible(base, view.frustum, view.world, rect, (lo, hi)) {
                    m.push(t.v.map(|p| grid::vertex(base, p[0], p[1])));
                }
            }
        });
        out
    }
}
