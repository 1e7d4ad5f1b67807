//! Longest-edge bisection held in a concurrent binary tree (Dupuy,
//! "Concurrent Binary Trees (with application to longest edge bisection)",
//! HPG 2020).
//!
//! The map is covered by a square of side 2^k cells, cut on its diagonal
//! into two right isosceles triangles; bisecting a triangle's hypotenuse
//! makes its two children, down to triangles whose legs are one cell. The
//! mesh is the set of leaves of that bisection tree, and the tree is held
//! the paper's way: one bit per node of the deepest level (a leaf sets the
//! bit of its leftmost deepest descendant) and a sum-reduction tree above
//! the bits, so that the n-th leaf is found by walking down the sums. A
//! split sets one bit, a merge clears one; every pass decides from the tree
//! as it was, in parallel over the leaves, and then sets or clears its
//! bits, so the result is the same for any thread count.
//!
//! The split rule is ROAM's screen-space error: the nested wedgie
//! thickness (each hypotenuse midpoint's height error plus the larger of
//! the children's), projected at the distance of a bounding disc, zero
//! outside the frustum. Splits are conforming: a
//! triangle is split together with the neighbour across its hypotenuse,
//! whose own ancestors are split first where it does not exist yet (the
//! paper's compatibility chain), so the mesh never has a T-junction. A
//! diamond (a split triangle and its hypotenuse neighbour, all four
//! children leaves) merges when both halves' errors are at most τ. The
//! paper runs one split or merge pass a frame and lets the tree converge
//! over frames; here each update runs merge passes and then split passes
//! until none changes anything, so every frame shows the tree for its own
//! view, as ROAM's queues do.
//!
//! The paper does not address popping. With `morph`, each vertex a split
//! made moves from its diamond's hypotenuse to its own height as the
//! diamond's error grows from τ to 2τ, so a split or a merge does not move
//! the surface (`Cbt::morph_weight`).

use super::grid::{self, MinMax};
use super::{Lod, LodMesh, LodUpdate, LodVertex, View};
use crate::lod::LodScheme;
use crate::pyramid::{Pyramid, PyramidLevel};
use rayon::prelude::*;
use std::sync::Arc;

/// The CBT scheme's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// Split while a triangle's error covers more than τ pixels; merge a
    /// diamond when both halves cover at most τ.
    pub tau: f64,
    /// Geomorph each vertex a split made from the midpoint of its
    /// diamond's hypotenuse to its own height, as the diamond's error goes
    /// from τ to 2τ (`Cbt::morph_weight`).
    pub morph: bool,
}

/// Smallest square side in cells: the tree's leaves are then at depth 7,
/// so the bit field has at least two 64-bit words under the sums.
const MIN_SIDE: i64 = 8;
/// Leaves one parallel task handles.
const CHUNK: usize = 4096;
/// Bits per word of the bit field: sums stop at the depth where a node
/// covers one word; below it, counts are popcounts of part of a word.
const WORD_DEPTH: u32 = 6;

/// A node of the bisection tree: heap index (the square 1, children 2k
/// and 2k + 1) and depth (the square 0, its two triangles 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Node {
    id: u64,
    depth: u32,
}

impl Node {
    const SQUARE: Node = Node { id: 1, depth: 0 };

    fn child(self, b: u64) -> Node {
        Node {
            id: 2 * self.id + b,
            depth: self.depth + 1,
        }
    }

    fn parent(self) -> Node {
        Node {
            id: self.id >> 1,
            depth: self.depth - 1,
        }
    }
}

/// The concurrent binary tree: a bit field over the deepest level's nodes
/// and the sums above it.
struct Tree {
    /// Depth of the deepest nodes (the bit field has 2^depth bits).
    depth: u32,
    bits: Vec<u64>,
    /// `sums[d][i]`: leaves under node 2^d + i, for d ≤ depth − 6.
    sums: Vec<Vec<u32>>,
}

impl Tree {
    /// The tree whose leaves are the square's two triangles.
    fn new(depth: u32) -> Tree {
        let top = depth - WORD_DEPTH;
        let mut t = Tree {
            depth,
            bits: vec![0; 1 << top],
            sums: (0..=top).map(|d| vec![0u32; 1 << d]).collect(),
        };
        t.set(t.pos(Node::SQUARE.child(0)));
        t.set(t.pos(Node::SQUARE.child(1)));
        t.rebuild();
        t
    }

    /// The bit of `n`'s leftmost descendant at the deepest level.
    fn pos(&self, n: Node) -> u64 {
        (n.id << (self.depth - n.depth)) - (1u64 << self.depth)
    }

    fn get(&self, p: u64) -> bool {
        self.bits[(p / 64) as usize] >> (p % 64) & 1 == 1
    }

    fn set(&mut self, p: u64) {
        self.bits[(p / 64) as usize] |= 1 << (p % 64);
    }

    fn clear(&mut self, p: u64) {
        self.bits[(p / 64) as usize] &= !(1 << (p % 64));
    }

    /// The sum reduction, a level at a time from the words up.
    fn rebuild(&mut self) {
        let top = (self.depth - WORD_DEPTH) as usize;
        self.sums[top]
            .par_iter_mut()
            .zip(self.bits.par_iter())
            .for_each(|(s, w)| *s = w.count_ones());
        for d in (0..top).rev() {
            let (upper, lower) = self.sums.split_at_mut(d + 1);
            let src = &lower[0];
            upper[d]
                .par_iter_mut()
                .enumerate()
                .for_each(|(i, s)| *s = src[2 * i] + src[2 * i + 1]);
        }
    }

    /// Leaves under `n` (0 when `n` lies inside a leaf and is not its
    /// leftmost descendant, 1 when `n` is a leaf or inside one).
    fn count(&self, n: Node) -> u32 {
        let top = self.depth - WORD_DEPTH;
        if n.depth <= top {
            return self.sums[n.depth as usize][(n.id - (1 << n.depth)) as usize];
        }
        let p = self.pos(n);
        let len = 1u64 << (self.depth - n.depth);
        let w = self.bits[(p / 64) as usize] >> (p % 64);
        (w & ((1u64 << len) - 1)).count_ones()
    }

    fn leaves(&self) -> usize {
        self.sums[0][0] as usize
    }

    /// The `n`-th leaf, in the tree's order: down the sums.
    fn leaf(&self, mut n: u32) -> Node {
        let mut node = Node::SQUARE;
        while self.count(node) > 1 {
            let left = node.child(0);
            let c = self.count(left);
            node = if n < c {
                left
            } else {
                n -= c;
                node.child(1)
            };
        }
        node
    }

    /// Whether `n` is split: its right child's bit is set, which no leaf
    /// that contains `n` can have (a right child is never a leftmost
    /// descendant of its parent), so `n` exists and has children.
    fn is_split(&self, n: Node) -> bool {
        n.depth < self.depth && self.get(self.pos(n.child(1)))
    }
}

/// Corners (apex, left, right) of triangle `n` (depth ≥ 1) in the square
/// of side `s`: the root the first bit picks, then the child each further
/// bit picks (0: apex at the midpoint, left half; 1: right half).
fn corners(s: i64, n: Node) -> [[i64; 2]; 3] {
    corners_made(s, n).0
}

/// [`corners`], and for each corner the node whose split made it (its
/// hypotenuse's midpoint), `None` for the square's own corners.
fn corners_made(s: i64, n: Node) -> ([[i64; 2]; 3], [Option<Node>; 3]) {
    let d = n.depth;
    let which = (n.id >> (d - 1)) & 1;
    let mut v = root(s, which);
    let mut by = [None; 3];
    let mut node = Node::SQUARE.child(which);
    for k in (0..d - 1).rev() {
        let b = (n.id >> k) & 1;
        by = if b == 0 {
            [Some(node), by[0], by[1]]
        } else {
            [Some(node), by[2], by[0]]
        };
        v = split(v, b);
        node = node.child(b);
    }
    (v, by)
}

/// The square's two triangles, cut on its (0, 0)–(s, s) diagonal: 0 above
/// it (x > y), 1 below.
fn root(s: i64, which: u64) -> [[i64; 2]; 3] {
    if which == 0 {
        [[s, 0], [0, 0], [s, s]]
    } else {
        [[0, s], [s, s], [0, 0]]
    }
}

/// Child `b` of triangle `v`, as ROAM splits: the hypotenuse's midpoint
/// becomes the apex.
fn split(v: [[i64; 2]; 3], b: u64) -> [[i64; 2]; 3] {
    let [a, l, r] = v;
    let m = [(l[0] + r[0]) / 2, (l[1] + r[1]) / 2];
    if b == 0 {
        [m, a, l]
    } else {
        [m, r, a]
    }
}

/// The node at `depth` whose triangle holds the point `c3 / 3` (a
/// triangle's centroid, never on an edge), `None` outside the square.
fn locate(s: i64, c3: [i64; 2], depth: u32) -> Option<Node> {
    if c3[0] <= 0 || c3[1] <= 0 || c3[0] >= 3 * s || c3[1] >= 3 * s {
        return None;
    }
    let which = u64::from(c3[1] > c3[0]);
    let mut n = Node::SQUARE.child(which);
    let mut v = root(s, which);
    while n.depth < depth {
        let [a, l, r] = v;
        let m = [(l[0] + r[0]) / 2, (l[1] + r[1]) / 2];
        let side =
            |p: [i64; 2]| (m[0] - a[0]) * (p[1] - 3 * a[1]) - (m[1] - a[1]) * (p[0] - 3 * a[0]);
        let left = side([3 * l[0], 3 * l[1]]);
        let b = u64::from((side(c3) > 0) != (left > 0));
        n = n.child(b);
        v = split(v, b);
    }
    Some(n)
}

/// The triangle across `n`'s hypotenuse at the same depth, `None` on the
/// square's border.
fn edge_neighbour(s: i64, n: Node) -> Option<Node> {
    let [a, l, r] = corners(s, n);
    let apex = [l[0] + r[0] - a[0], l[1] + r[1] - a[1]];
    let c3 = [apex[0] + l[0] + r[0], apex[1] + l[1] + r[1]];
    locate(s, c3, n.depth)
}

/// `e` rounded up to a bfloat16 (the upper 16 bits of an f32): an upper
/// bound within 2⁻⁷ of it in half the memory, and rounding up keeps the
/// nested errors nested.
fn up16(e: f32) -> u16 {
    let e = if e.is_nan() { 0.0 } else { e.min(f32::MAX) };
    let b = e.to_bits();
    let hi = (b >> 16) as u16;
    hi + u16::from(b & 0xffff != 0)
}

fn from16(u: u16) -> f32 {
    f32::from_bits((u as u32) << 16)
}

/// Whether triangle `v` covers any of the map's inside (the square reaches
/// past a map that is not 2^k + 1 square; triangles wholly past it are
/// never split or drawn).
fn on_map(base: &PyramidLevel, v: [[i64; 2]; 3]) -> bool {
    let b = grid::bounding_box(v);
    b[0] < base.width as i64 - 1 && b[1] < base.height as i64 - 1
}

/// Nested errors of every node at depths 1..depth − 3 (`[d][id − 2^d]`),
/// rounded up: the height error at the hypotenuse midpoint plus the larger
/// of the children's ([`wedgie`]). The two levels above the deepest hold three quarters of the
/// nodes and their errors take at most three midpoints, so they are
/// computed when asked ([`nested`]) instead of stored. Subtrees from depth
/// 8 are made in parallel, each into its own contiguous runs of the levels
/// below it; a subtree wholly off the map is left at 0 unvisited.
fn nested_errors(base: &PyramidLevel, s: i64, depth: u32) -> Vec<Vec<u16>> {
    let stored = depth - 2;
    let top = 8.min(stored - 1);
    let mut levels: Vec<Vec<u16>> = (0..stored).map(|d| vec![0u16; 1usize << d]).collect();
    let mut runs: Vec<Vec<&mut [u16]>> = (0..1usize << top).map(|_| Vec::new()).collect();
    for (d, level) in levels.iter_mut().enumerate().skip(top as usize) {
        for (i, run) in level.chunks_mut(1 << (d - top as usize)).enumerate() {
            runs[i].push(run);
        }
    }
    let mut below: Vec<f32> = runs
        .into_par_iter()
        .enumerate()
        .map(|(i, mut runs)| {
            let n = Node {
                id: (1u64 << top) + i as u64,
                depth: top,
            };
            fill(base, corners(s, n), 0, 0, &mut runs)
        })
        .collect();
    for d in (1..top).rev() {
        let here: Vec<f32> = (0..1u64 << d)
            .map(|i| {
                let n = Node {
                    id: (1 << d) + i,
                    depth: d,
                };
                let e = wedgie(
                    own_error(base, corners(s, n)),
                    below[2 * i as usize],
                    below[2 * i as usize + 1],
                );
                levels[d as usize][i as usize] = up16(e);
                e
            })
            .collect();
        below = here;
    }
    levels
}

/// Fills `runs[k][j]` for the subtree under triangle `v` (relative depth
/// `k`, index `j` within its run) and returns its nested error.
fn fill(base: &PyramidLevel, v: [[i64; 2]; 3], k: usize, j: usize, runs: &mut [&mut [u16]]) -> f32 {
    if k == runs.len() {
        return nested(base, v, 2); // two levels above the deepest
    }
    if !on_map(base, v) {
        return 0.0;
    }
    let e = wedgie(
        own_error(base, v),
        fill(base, split(v, 0), k + 1, 2 * j, runs),
        fill(base, split(v, 1), k + 1, 2 * j + 1, runs),
    );
    runs[k][j] = up16(e);
    e
}

/// The nested error ([`wedgie`]) of triangle `v` over `levels` levels of
/// bisection, its own included (the deepest triangles, legs of one cell, have no midpoint
/// and count 0).
fn nested(base: &PyramidLevel, v: [[i64; 2]; 3], levels: u32) -> f32 {
    if levels == 0 || !on_map(base, v) {
        return 0.0;
    }
    wedgie(
        own_error(base, v),
        nested(base, split(v, 0), levels - 1),
        nested(base, split(v, 1), levels - 1),
    )
}

/// ROAM's nested wedgie thickness (Duchaineau et al. 1997): a triangle's
/// own midpoint error plus the larger of its children's, which bounds how
/// far the finest surface under it lies from its plane. The largest of
/// the three instead (what `roam` uses, with its 64-cell patches as a
/// floor) lets one big triangle stand for a range whose errors add up
/// level by level: on ETOPO5 it left 9 triangles at τ = 4 px. Adding keeps
/// the errors nested in f32 too (a + b ≥ b for a ≥ 0 after rounding).
fn wedgie(own: f32, a: f32, b: f32) -> f32 {
    own + a.max(b)
}

/// The height error at `v`'s hypotenuse midpoint against the hypotenuse's
/// linear interpolation (0 for a triangle off the map, and for no-data).
fn own_error(base: &PyramidLevel, v: [[i64; 2]; 3]) -> f32 {
    if !on_map(base, v) {
        return 0.0;
    }
    let [_, l, r] = v;
    let m = [(l[0] + r[0]) / 2, (l[1] + r[1]) / 2];
    let z = |p: [i64; 2]| base.get_clamped(p[0], p[1]);
    let e = (z(m) - 0.5 * (z(l) + z(r))).abs();
    if e.is_nan() {
        0.0
    } else {
        e
    }
}

/// Longest-edge bisection in a concurrent binary tree, split and merged
/// by screen-space error.
pub struct Cbt {
    pyramid: Arc<Pyramid>,
    cfg: Config,
    /// Side of the square in cells.
    side: i64,
    tree: Tree,
    /// Nested errors per depth down to three above the deepest, rounded
    /// up ([`nested_errors`]).
    errors: Vec<Vec<u16>>,
    bounds: MinMax,
}

impl Cbt {
    /// The scheme over `pyramid`, starting from the square's two
    /// triangles.
    pub fn new(pyramid: Arc<Pyramid>, cfg: Config) -> Self {
        let base = &pyramid.levels[0];
        let cells = (base.width.max(2) - 1).max(base.height.max(2) - 1) as i64;
        let side = (cells as u64).next_power_of_two().max(MIN_SIDE as u64) as i64;
        let depth = 2 * side.trailing_zeros() + 1;
        let errors = nested_errors(base, side, depth);
        let bounds = MinMax::new(base);
        Cbt {
            pyramid,
            cfg,
            side,
            tree: Tree::new(depth),
            errors,
            bounds,
        }
    }

    /// Triangles in the current mesh (the tree's leaves, those off the
    /// map included).
    pub fn triangle_count(&self) -> usize {
        self.tree.leaves()
    }

    /// Every leaf's corners (apex, left, right) in base-grid cells, in the
    /// tree's order, those off the map included: what a test checks the
    /// mesh's conformity on (each inner edge shared by exactly two).
    pub fn triangles(&self) -> Vec<[[i64; 2]; 3]> {
        (0..self.tree.leaves())
            .map(|i| corners(self.side, self.tree.leaf(i as u32)))
            .collect()
    }

    /// Side of the square the bisection starts from, in cells.
    pub fn side(&self) -> i64 {
        self.side
    }

    /// Depth of the deepest triangles (legs of one cell).
    pub fn max_depth(&self) -> u32 {
        self.tree.depth
    }

    /// Screen-space error of node `n` in pixels (0 for one that cannot be
    /// split).
    fn priority(&self, view: &View, n: Node) -> f64 {
        if n.depth == 0 || n.depth >= self.tree.depth {
            return 0.0;
        }
        let v = corners(self.side, n);
        let e = match self.errors.get(n.depth as usize) {
            Some(level) => from16(level[(n.id - (1 << n.depth)) as usize]),
            None => nested(&self.pyramid.levels[0], v, self.tree.depth - n.depth),
        };
        let b = grid::bounding_box(v);
        let bounds = self.bounds.range(b[0], b[1], b[2], b[3]);
        grid::screen_error(&self.pyramid.levels[0], view, e as f64, v, bounds)
    }

    /// Morph weight of the vertex that `made`'s split put at its
    /// hypotenuse's midpoint: 1 (the hypotenuse's own height, as if not
    /// split) while the larger error of the diamond's two halves is τ or
    /// less, falling linearly to 0 (the vertex's height) at 2τ. A split
    /// happens above τ and a merge at τ or under, so neither moves the
    /// surface; the weight depends on the diamond alone, so every triangle
    /// that shares the vertex draws it at one height.
    fn morph_weight(&self, view: &View, made: Node) -> f32 {
        let q = edge_neighbour(self.side, made).map_or(0.0, |q| self.priority(view, q));
        let p = self.priority(view, made).max(q);
        (2.0 - p / self.cfg.tau).clamp(0.0, 1.0) as f32
    }

    /// The vertex at `p`, made by `made`'s split: on the grid, morphed
    /// toward its diamond's hypotenuse with `morph`. A vertex past the map
    /// is clamped onto its edge unmorphed, so two of them clamped to one
    /// point keep one height.
    /// `made` caches each diamond's weight over a run of leaves: a vertex
    /// is shared by up to eight triangles, mostly neighbours in the tree's
    /// order, and its weight costs two errors and a neighbour search.
    fn vertex(
        &self,
        view: &View,
        p: [i64; 2],
        made: Option<Node>,
        weights: &mut std::collections::HashMap<u64, f32>,
    ) -> LodVertex {
        let base = &self.pyramid.levels[0];
        let mut v = grid::vertex(base, p[0], p[1]);
        let inside = (v.col, v.row) == (p[0], p[1]);
        if let (true, true, Some(m)) = (self.cfg.morph, inside, made) {
            let [_, l, r] = corners(self.side, m);
            v.zc = 0.5 * (base.get_clamped(l[0], l[1]) + base.get_clamped(r[0], r[1]));
            v.alpha = *weights
                .entry(m.id)
                .or_insert_with(|| self.morph_weight(view, m));
        }
        v
    }

    /// The bits a conforming split of leaf `t` sets: `t`'s right child,
    /// then along the compatibility chain the hypotenuse neighbour, and
    /// where that does not exist yet its parent and the parent's
    /// neighbour, until a node already split in the tree (whose chain is
    /// then already conforming).
    fn split_bits(&self, t: Node, out: &mut Vec<u64>) {
        let tree = &self.tree;
        out.push(tree.pos(t.child(1)));
        let mut n = edge_neighbour(self.side, t);
        while let Some(m) = n {
            if tree.is_split(m) {
                return;
            }
            out.push(tree.pos(m.child(1)));
            let p = m.parent();
            if tree.is_split(p) {
                return;
            }
            out.push(tree.pos(p.child(1)));
            n = edge_neighbour(self.side, p);
        }
    }

    /// The bits merging the diamond over leaf `t` clears, if `t` is a left
    /// child, its sibling a leaf, its parent's hypotenuse neighbour split
    /// into two leaves, and both parents' errors at most τ.
    fn merge_bits(&self, view: &View, t: Node, out: &mut Vec<u64>) {
        let tree = &self.tree;
        if t.depth < 2 || t.id & 1 == 1 {
            return;
        }
        let p = t.parent();
        if tree.count(p) != 2 || self.priority(view, p) > self.cfg.tau {
            return;
        }
        let q = edge_neighbour(self.side, p);
        if let Some(q) = q {
            if tree.count(q) != 2 || self.priority(view, q) > self.cfg.tau {
                return;
            }
            out.push(tree.pos(q.child(1)));
        }
        out.push(tree.pos(p.child(1)));
    }

    /// One pass over every leaf: each decides from the tree as it is, then
    /// the bits are set (`set`) or cleared. Returns the bits changed.
    fn pass(&mut self, set: bool, decide: impl Fn(&Cbt, Node, &mut Vec<u64>) + Sync) -> u64 {
        let n = self.tree.leaves();
        let starts: Vec<usize> = (0..n).step_by(CHUNK).collect();
        let this = &*self;
        let bits: Vec<Vec<u64>> = starts
            .par_iter()
            .map(|&s0| {
                let mut out = Vec::new();
                for i in s0..(s0 + CHUNK).min(n) {
                    decide(this, this.tree.leaf(i as u32), &mut out);
                }
                out
            })
            .collect();
        let mut changed = 0;
        for &p in bits.iter().flatten() {
            if self.tree.get(p) != set {
                changed += 1;
                if set {
                    self.tree.set(p);
                } else {
                    self.tree.clear(p);
                }
            }
        }
        if changed > 0 {
            self.tree.rebuild();
        }
        changed
    }
}

impl Lod for Cbt {
    fn scheme(&self) -> LodScheme {
        LodScheme::Cbt
    }

    fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    fn update(&mut self, view: &View) -> LodUpdate {
        let tau = self.cfg.tau;
        let deepest = self.tree.depth;
        let mut changes = 0;
        loop {
            let merged = self.pass(false, |c, t, out| c.merge_bits(view, t, out));
            changes += merged;
            if merged == 0 {
                break;
            }
        }
        loop {
            let split = self.pass(true, |c, t, out| {
                if t.depth < deepest && c.priority(view, t) > tau {
                    c.split_bits(t, out);
                }
            });
            changes += split;
            if split == 0 {
                break;
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
        let n = self.tree.leaves();
        let ranges: Vec<std::ops::Range<usize>> = (0..n)
            .step_by(CHUNK)
            .map(|s0| s0..(s0 + CHUNK).min(n))
            .collect();
        out.append_parallel(&ranges, |r, m| {
            let mut weights = std::collections::HashMap::new();
            for i in r.clone() {
                let (v, made) = corners_made(self.side, self.tree.leaf(i as u32));
                if !on_map(base, v) {
                    continue;
                }
                let b = grid::bounding_box(v);
                let bounds = self.bounds.range(b[0], b[1], b[2], b[3]);
                if grid::visible(base, view.frustum, view.world, b, bounds) {
                    m.push([0, 1, 2].map(|k| self.vertex(view, v[k], made[k], &mut weights)));
                }
            }
        });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_node_is_found_where_its_triangle_is() {
        let s = 16;
        for depth in 1..=9u32 {
            for id in 1u64 << depth..2u64 << depth {
                let n = Node { id, depth };
                let [a, l, r] = corners(s, n);
                let c3 = [a[0] + l[0] + r[0], a[1] + l[1] + r[1]];
                assert_eq!(locate(s, c3, depth), Some(n));
            }
        }
    }

    #[test]
    fn hypotenuse_neighbours_share_the_hypotenuse_and_are_mutual() {
        let s = 16;
        let mut border = 0;
        for depth in 1..=9u32 {
            for id in 1u64 << depth..2u64 << depth {
                let n = Node { id, depth };
                let [_, l, r] = corners(s, n);
                match edge_neighbour(s, n) {
                    Some(m) => {
                        let [_, l2, r2] = corners(s, m);
                        assert_eq!((l2, r2), (r, l), "{n:?} and {m:?}");
                        assert_eq!(edge_neighbour(s, m), Some(n));
                    }
                    None => {
                        border += 1;
                        let on_border =
                            (l[0] == r[0] && l[0] % s == 0) || (l[1] == r[1] && l[1] % s == 0);
                        assert!(on_border, "{n:?} has no neighbour inside the square");
                    }
                }
            }
        }
        assert!(border > 0);
    }

    #[test]
    fn each_corner_is_the_midpoint_of_the_node_that_made_it() {
        let s = 16;
        for depth in 1..=9u32 {
            for id in 1u64 << depth..2u64 << depth {
                let n = Node { id, depth };
                let (v, made) = corners_made(s, n);
                for (p, by) in v.iter().zip(made) {
                    match by {
                        Some(m) => {
                            assert!(m.depth < depth && n.id >> (depth - m.depth) == m.id);
                            let [_, l, r] = corners(s, m);
                            assert_eq!(*p, [(l[0] + r[0]) / 2, (l[1] + r[1]) / 2]);
                        }
                        None => assert!(p[0] % s == 0 && p[1] % s == 0, "{p:?}"),
                    }
                }
            }
        }
    }

    #[test]
    fn leaves_are_found_by_the_sums() {
        let mut t = Tree::new(9);
        assert_eq!(t.leaves(), 2);
        assert_eq!(t.leaf(0), Node { id: 2, depth: 1 });
        assert_eq!(t.leaf(1), Node { id: 3, depth: 1 });
        // Split node 3 then its right child 7.
        t.set(t.pos(Node { id: 7, depth: 2 }));
        t.set(t.pos(Node { id: 15, depth: 3 }));
        t.rebuild();
        let leaves: Vec<u64> = (0..t.leaves() as u32).map(|i| t.leaf(i).id).collect();
        assert_eq!(leaves, [2, 6, 14, 15]);
        assert!(t.is_split(Node { id: 3, depth: 1 }));
        assert!(!t.is_split(Node { id: 6, depth: 2 }));
        assert!(!t.is_split(Node { id: 12, depth: 3 }));
    }

    #[test]
    fn bfloat_rounding_is_an_upper_bound_within_a_part_in_128() {
        for e in [0.0f32, 1e-9, 0.3, 1.0, 1.0 + 1e-6, 7.77, 1234.5, 3e7] {
            let u = from16(up16(e));
            assert!(u >= e && u <= e * (1.0 + 1.0 / 128.0), "{e} -> {u}");
        }
        assert_eq!(from16(up16(f32::NAN)), 0.0);
    }
}
