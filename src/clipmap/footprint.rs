//! Index generation, in the two layouts the literature uses.
//!
//! (a) **Strips over the toroid** (Losasso & Hoppe 2004; Brettell ch. 4):
//! the level's vertex buffer *is* its toroid (vertex i = texel i), and each
//! frame emits one triangle strip per row of cells of each render rectangle,
//! joined by degenerate triangles. The wrap is handled by mapping every
//! world vertex through the toroid's Euclidean modulo, so a strip crosses the
//! toroid seam without being split.
//!
//! (b) **Static footprints** (GPU Gems 2 ch. 2): shapes built once per n and
//! placed per frame by offset only: 12 m×m blocks per ring (m = (n+1)/4),
//! 4 m×3 ring fix-ups, an L-shaped interior trim in one of 4 positions, a
//! full centre for the finest level.
//!
//! Every mesh splits a cell along its main diagonal (x, y)–(x+1, y+1), and
//! every non-degenerate triangle has positive orientation in (column, row)
//! space. Where a level meets a coarser one, the vertex stage collapses the
//! odd boundary vertices onto their even neighbours
//! ([`super::morph::MorphParams::stitch`]), so the two levels share whole
//! edges. GPU Gems 2 closes those T-junctions with an outer ring of
//! zero-area triangles instead; we measured why we do not: once snapped,
//! such a triangle can cover a pixel with attribute planes extrapolated
//! from a near-zero area (a colour of 3.2 on a 0–1 ramp), and it cannot be
//! culled, because the clipper keeps it.

use super::region::{block_size, Rect};
use super::toroid::Toroid;
use std::collections::HashMap;

/// Level-local triangle list of a static footprint shape.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Shape {
    /// Vertex positions in level texels, relative to the instance offset.
    pub vertices: Vec<[i32; 2]>,
    pub triangles: Vec<[u32; 3]>,
}

impl Shape {
    /// A shape covering the given cells (lower-left corners), each split along
    /// its main diagonal.
    pub fn from_cells(cells: impl IntoIterator<Item = (i32, i32)>) -> Shape {
        let mut s = Shape::default();
        let mut index: HashMap<[i32; 2], u32> = HashMap::new();
        let mut vid = |s: &mut Shape, p: [i32; 2]| {
            *index.entry(p).or_insert_with(|| {
                s.vertices.push(p);
                (s.vertices.len() - 1) as u32
            })
        };
        for (x, y) in cells {
            let a = vid(&mut s, [x, y]);
            let b = vid(&mut s, [x + 1, y]);
            let c = vid(&mut s, [x, y + 1]);
            let d = vid(&mut s, [x + 1, y + 1]);
            s.triangles.push([c, a, d]);
            s.triangles.push([d, a, b]);
        }
        s
    }
    fn rect(x0: i32, y0: i32, w: i32, h: i32) -> Shape {
        Shape::from_cells((y0..y0 + h).flat_map(move |y| (x0..x0 + w).map(move |x| (x, y))))
    }
}

/// Layout (a): strip indices into the level's toroid for the given render
/// rectangles (level texels, closed), joined by degenerate triangles.
pub fn strip_indices(toroid: &Toroid<f32>, rects: &[[i64; 4]]) -> Vec<u32> {
    let mut out: Vec<u32> = Vec::new();
    for &[x0, y0, x1, y1] in rects {
        for y in y0..y1 {
            let first = toroid.index(x0, y + 1) as u32;
            if let Some(&last) = out.last() {
                // Two repeats keep the next strip starting on an even index,
                // so its winding is preserved.
                out.push(last);
                out.push(first);
            }
            for x in x0..=x1 {
                out.push(toroid.index(x, y + 1) as u32);
                out.push(toroid.index(x, y) as u32);
            }
        }
    }
    out
}

/// Expands a triangle strip into triangles, dropping those with a repeated
/// index (the joins); odd triangles swap their first two vertices.
pub fn strip_to_triangles(strip: &[u32]) -> Vec<[u32; 3]> {
    strip
        .windows(3)
        .enumerate()
        .filter(|(_, w)| w[0] != w[1] && w[1] != w[2] && w[0] != w[2])
        .map(|(k, w)| {
            if k % 2 == 0 {
                [w[0], w[1], w[2]]
            } else {
                [w[1], w[0], w[2]]
            }
        })
        .collect()
}

/// Which static shape an instance draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ShapeId {
    /// An m × m block, twelve per ring.
    Block,
    /// The fix-up 3 vertices wide and m tall, in the middle of a ring's top and bottom.
    FixupVertical,
    /// The fix-up m vertices wide and 3 tall, in the middle of a ring's left and right.
    FixupHorizontal,
    /// Trim variant: bit 0 set = trim column on the high-x side, bit 1 set =
    /// trim row on the high-y side.
    Trim(u8),
    /// The finest level's centre, which has no finer level inside it.
    Centre,
}

/// One placed footprint: shape plus offset in level texels (world).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// The shape drawn.
    pub shape: ShapeId,
    /// Where its first vertex goes, in level texels.
    pub offset: [i64; 2],
}

/// The static GPU Gems 2 footprints for one grid size n, built once.
#[derive(Clone, Debug)]
pub struct Footprints {
    /// Grid size.
    pub n: i64,
    /// Block size m = (n + 1) / 4.
    pub m: i64,
    /// The m × m block.
    pub block: Shape,
    /// The vertical fix-up.
    pub fixup_vertical: Shape,
    /// The horizontal fix-up.
    pub fixup_horizontal: Shape,
    /// The four L-shaped trims, by [`ShapeId::Trim`] variant.
    pub trims: [Shape; 4],
    /// The finest level's centre.
    pub centre: Shape,
}

impl Footprints {
    /// The footprints for grid size `n`.
    pub fn new(n: i64) -> Self {
        let m = block_size(n) as i32;
        let e = 2 * m; // interior width in cells: [m-1, 3m-1]
        let trim = |v: u8| {
            let col = if v & 1 == 0 { m - 1 } else { 3 * m - 2 };
            let row = if v & 2 == 0 { m - 1 } else { 3 * m - 2 };
            let cells = (m - 1..3 * m - 1).map(move |y| (col, y)).chain(
                (m - 1..3 * m - 1)
                    .filter(move |&x| x != col)
                    .map(move |x| (x, row)),
            );
            Shape::from_cells(cells)
        };
        Footprints {
            n,
            m: m as i64,
            block: Shape::rect(0, 0, m - 1, m - 1),
            fixup_vertical: Shape::rect(0, 0, 2, m - 1),
            fixup_horizontal: Shape::rect(0, 0, m - 1, 2),
            trims: [trim(0), trim(1), trim(2), trim(3)],
            centre: Shape::rect(m - 1, m - 1, e, e),
        }
    }

    /// The shape `id` names.
    pub fn shape(&self, id: ShapeId) -> &Shape {
        match id {
            ShapeId::Block => &self.block,
            ShapeId::FixupVertical => &self.fixup_vertical,
            ShapeId::FixupHorizontal => &self.fixup_horizontal,
            ShapeId::Trim(v) => &self.trims[v as usize & 3],
            ShapeId::Centre => &self.centre,
        }
    }

    /// Instances for a level whose window starts at `origin` (level texels).
    /// `finer_origin` is the finer level's origin in *its* texels (None for the
    /// finest level, which gets the full centre).
    pub fn instances(&self, origin: [i64; 2], finer_origin: Option<[i64; 2]>) -> Vec<Instance> {
        let m = self.m;
        let at = |shape, x: i64, y: i64| Instance {
            shape,
            offset: [origin[0] + x, origin[1] + y],
        };
        let pos = [0, m - 1, 2 * m, 3 * m - 1];
        let mut out = vec![];
        for (j, &y) in pos.iter().enumerate() {
            for (i, &x) in pos.iter().enumerate() {
                let interior = (1..=2).contains(&i) && (1..=2).contains(&j);
                if !interior {
                    out.push(at(ShapeId::Block, x, y));
                }
            }
        }
        for y in [0, 3 * m - 1] {
            out.push(at(ShapeId::FixupVertical, 2 * m - 2, y));
        }
        for x in [0, 3 * m - 1] {
            out.push(at(ShapeId::FixupHorizontal, x, 2 * m - 2));
        }
        match finer_origin {
            None => out.push(at(ShapeId::Centre, 0, 0)),
            Some(f) => {
                // The finer window starts m or m−1 coarse cells in; the trim
                // fills the one-cell gap on the other side.
                let off = [f[0] / 2 - origin[0], f[1] / 2 - origin[1]];
                debug_assert!(off.iter().all(|&o| o == m || o == m - 1), "{off:?}");
                let v = (off[0] == m - 1) as u8 | (((off[1] == m - 1) as u8) << 1);
                out.push(at(ShapeId::Trim(v), 0, 0));
            }
        }
        out
    }
}

/// Render rectangle in base units → closed level-texel bounds. A level's
/// regions lie on its own grid lines, so this is exact and a shift (a
/// 64-bit division per side cost a quarter of a still viewer's update).
pub fn to_level(r: &Rect, level: usize) -> [i64; 4] {
    let v = [r.x0, r.y0, r.x1, r.y1];
    debug_assert!(
        v.iter().all(|c| c & ((1 << level) - 1) == 0),
        "{r:?} is not on level {level}'s grid"
    );
    v.map(|c| c >> level)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area2(v: &[[i32; 2]], t: &[u32; 3]) -> i64 {
        let [a, b, c] = t.map(|i| v[i as usize]);
        (b[0] - a[0]) as i64 * (c[1] - a[1]) as i64 - (b[1] - a[1]) as i64 * (c[0] - a[0]) as i64
    }

    #[test]
    fn footprints_cover_the_ring_exactly() {
        for n in [15i64, 31, 63] {
            let f = Footprints::new(n);
            let m = f.m;
            let inst = f.instances([0, 0], Some([2 * m, 2 * m]));
            let mut cover = vec![0u32; ((n - 1) * (n - 1)) as usize];
            for i in &inst {
                let s = f.shape(i.shape);
                for t in &s.triangles {
                    let a = area2(&s.vertices, t);
                    assert!(a >= 0);
                    if a > 0 {
                        let xs = t.map(|k| s.vertices[k as usize][0] as i64 + i.offset[0]);
                        let ys = t.map(|k| s.vertices[k as usize][1] as i64 + i.offset[1]);
                        let (x, y) = (*xs.iter().min().unwrap(), *ys.iter().min().unwrap());
                        cover[(y * (n - 1) + x) as usize] += 1;
                    }
                }
            }
            // Finer window occupies coarse cells [m, 3m-1); trim at [m-1, m).
            for y in 0..n - 1 {
                for x in 0..n - 1 {
                    let inner = (m..3 * m - 1).contains(&x) && (m..3 * m - 1).contains(&y);
                    let want = if inner { 0 } else { 2 };
                    assert_eq!(
                        cover[(y * (n - 1) + x) as usize],
                        want,
                        "n={n} cell ({x},{y})"
                    );
                }
            }
        }
    }

    #[test]
    fn strip_triangles_are_positive() {
        let mut t = Toroid::<f32>::new(15);
        t.move_to([-3, 5], |_, _| 0.0);
        let strip = strip_indices(&t, &[[-3, 5, 2, 8], [4, 6, 8, 10]]);
        let tris = strip_to_triangles(&strip);
        assert_eq!(tris.len(), 2 * (5 * 3 + 4 * 4));
        let pos = |i: u32| {
            let (tx, ty) = ((i % 15) as usize, (i / 15) as usize);
            [
                Toroid::<f32>::world_of(tx, -3, 15),
                Toroid::<f32>::world_of(ty, 5, 15),
            ]
        };
        for tri in tris {
            let [a, b, c] = tri.map(pos);
            let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert_eq!(cross, 1);
        }
    }
}
