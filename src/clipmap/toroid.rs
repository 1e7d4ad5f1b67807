//! Toroidal arrays: an s×s window onto an unbounded grid, addressed by
//! Euclidean modulo so negative coordinates work. Moving the window rewrites
//! only the newly exposed L-shaped region, split into at most 4 rectangles that
//! do not wrap in toroid space (as Holkner splits `glTexSubImage2D` updates).

use rayon::prelude::*;
use serde::Serialize;

/// Texels below which an update is written on the calling thread.
pub const PARALLEL_TEXELS: usize = 16 * 1024;

/// A half-open rectangle `[x0, x1) × [y0, y1)` in toroid (texel) space.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TexRect {
    /// First column.
    pub x0: usize,
    /// First row.
    pub y0: usize,
    /// Column past the last.
    pub x1: usize,
    /// Row past the last.
    pub y1: usize,
}

impl TexRect {
    /// Texels covered.
    pub fn area(&self) -> usize {
        (self.x1 - self.x0) * (self.y1 - self.y0)
    }
    /// Whether the two share a texel.
    pub fn overlaps(&self, o: &TexRect) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }
    fn contains(&self, x: usize, y: usize) -> bool {
        x >= self.x0 && x < self.x1 && y >= self.y0 && y < self.y1
    }
}

/// The at most 4 rectangles of one update, held inline: an update runs
/// every frame for every level, and its cost should be the texels it
/// writes, not allocations.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TexRects {
    rects: [TexRect; 4],
    len: usize,
}

impl TexRects {
    /// A single rectangle (a whole window, for a first fill).
    pub fn one(r: TexRect) -> Self {
        std::iter::once(r).collect()
    }
    fn push(&mut self, r: TexRect) {
        self.rects[self.len] = r;
        self.len += 1;
    }
}

impl std::ops::Deref for TexRects {
    type Target = [TexRect];
    fn deref(&self) -> &[TexRect] {
        &self.rects[..self.len]
    }
}

impl<'a> IntoIterator for &'a TexRects {
    type Item = &'a TexRect;
    type IntoIter = std::slice::Iter<'a, TexRect>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl FromIterator<TexRect> for TexRects {
    fn from_iter<I: IntoIterator<Item = TexRect>>(iter: I) -> Self {
        let mut out = TexRects::default();
        iter.into_iter().for_each(|r| out.push(r));
        out
    }
}

impl Serialize for TexRects {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter())
    }
}

/// A window of `size`×`size` values over world cells `[origin, origin+size)`.
#[derive(Clone, Debug)]
pub struct Toroid<T> {
    size: usize,
    origin: Option<[i64; 2]>,
    data: Vec<T>,
}

/// Cyclic interval `[start, start+len)` on a circle of `s` texels, split into
/// at most two non-wrapping half-open pieces (held inline: updates run every
/// frame, and allocating for two pairs cost more than using them).
fn split_cyclic(start: usize, len: usize, s: usize) -> Cyclic {
    if len == 0 {
        Cyclic([(0, 0); 2], 0)
    } else if start + len <= s {
        Cyclic([(start, start + len), (0, 0)], 1)
    } else {
        Cyclic([(start, s), (0, start + len - s)], 2)
    }
}

/// The pieces of a cyclic interval, see [`split_cyclic`].
#[derive(Clone, Copy)]
struct Cyclic([(usize, usize); 2], usize);

impl Cyclic {
    fn pieces(&self) -> &[(usize, usize)] {
        &self.0[..self.1]
    }
}

/// The toroid-space rectangles to rewrite when a window of size `s` moves
/// from `old` to `new` (world origins). A first fill, or a jump of a full
/// window or more, rewrites everything as one rectangle.
pub fn update_rects(old: Option<[i64; 2]>, new: [i64; 2], s: usize) -> TexRects {
    let full = || {
        TexRects::one(TexRect {
            x0: 0,
            y0: 0,
            x1: s,
            y1: s,
        })
    };
    let Some(old) = old else { return full() };
    let d = [new[0] - old[0], new[1] - old[1]];
    if d == [0, 0] {
        return TexRects::default();
    }
    if d[0].unsigned_abs() as usize >= s || d[1].unsigned_abs() as usize >= s {
        return full();
    }
    // Per axis: the exposed cyclic interval N and the kept one K.
    let axis = |a: usize| {
        let len = d[a].unsigned_abs() as usize;
        let start_world = if d[a] > 0 { old[a] + s as i64 } else { new[a] };
        let start = start_world.rem_euclid(s as i64) as usize;
        let exposed = split_cyclic(start, len, s);
        let kept = split_cyclic((start + len) % s, s - len, s);
        (exposed, kept)
    };
    let (nx, kx) = axis(0);
    let (ny, ky) = axis(1);
    let (nx, kx, ny, ky) = (nx.pieces(), kx.pieces(), ny.pieces(), ky.pieces());
    let rect = |(x0, x1): (usize, usize), (y0, y1): (usize, usize)| TexRect { x0, y0, x1, y1 };
    // Either full-width rows of N_y plus N_x × K_y, or full-height columns of
    // N_x plus K_x × N_y; the cheaper split never needs more than 4.
    if ny.len() + nx.len() * ky.len() <= nx.len() + kx.len() * ny.len() {
        ny.iter()
            .map(|&y| rect((0, s), y))
            .chain(nx.iter().flat_map(|&x| ky.iter().map(move |&y| rect(x, y))))
            .collect()
    } else {
        nx.iter()
            .map(|&x| rect(x, (0, s)))
            .chain(kx.iter().flat_map(|&x| ny.iter().map(move |&y| rect(x, y))))
            .collect()
    }
}

impl<T: Copy + Default + Send + Sync> Toroid<T> {
    /// An empty toroid of `size` × `size` texels; the first move fills it.
    pub fn new(size: usize) -> Self {
        Toroid {
            size,
            origin: None,
            data: vec![T::default(); size * size],
        }
    }
    /// Texels per side.
    pub fn size(&self) -> usize {
        self.size
    }
    /// World origin of the window, once filled.
    pub fn origin(&self) -> Option<[i64; 2]> {
        self.origin
    }
    /// Every texel in toroid order: world cell (x, y) at [`Toroid::index`].
    pub fn data(&self) -> &[T] {
        &self.data
    }
    /// Forgets the contents: the next move rewrites every texel.
    pub fn invalidate(&mut self) {
        self.origin = None;
    }
    /// Toroid texel index of world cell (x, y).
    #[inline]
    pub fn index(&self, x: i64, y: i64) -> usize {
        let s = self.size as i64;
        (y.rem_euclid(s) * s + x.rem_euclid(s)) as usize
    }
    /// Value at world cell (x, y); the cell must be inside the window.
    #[inline]
    pub fn get(&self, x: i64, y: i64) -> T {
        debug_assert!(
            self.in_window(x, y),
            "({x},{y}) outside window {:?}",
            self.origin
        );
        self.data[self.index(x, y)]
    }
    /// Whether world cell (x, y) is inside the window (false before the first fill).
    pub fn in_window(&self, x: i64, y: i64) -> bool {
        self.origin.is_some_and(|o| {
            let s = self.size as i64;
            x >= o[0] && x < o[0] + s && y >= o[1] && y < o[1] + s
        })
    }
    /// Raw texels in toroid order (row-major), e.g. for a texture upload.
    pub fn texels(&self) -> &[T] {
        &self.data
    }
    /// World coordinate held by toroid column/row `t` for window origin `o`.
    #[inline]
    pub fn world_of(t: usize, o: i64, s: usize) -> i64 {
        o + (t as i64 - o).rem_euclid(s as i64)
    }

    /// Moves the window to `new` and rewrites exactly the exposed texels with
    /// `fill(world_x, world_y)`. Returns the rectangles rewritten.
    pub fn move_to(&mut self, new: [i64; 2], fill: impl Fn(i64, i64) -> T + Sync) -> TexRects {
        let rects = update_rects(self.origin, new, self.size);
        self.move_from(new, &rects, &Cells(fill));
        rects
    }

    /// [`Toroid::move_to`] with the rectangles already computed by
    /// [`update_rects`] for this move, and a [`Source`] that fills a run at
    /// a time.
    ///
    /// Each rectangle is cut where the window's world coordinates wrap, so
    /// every piece maps to consecutive world cells and needs one modulo, not
    /// one per texel. Rectangles at most [`NARROW`] texels wide (an east or
    /// west step) go to [`Source::narrow`] whole, the others a row at a
    /// time. Small updates (a one-texel step writes a row and a column) run
    /// on the calling thread, rectangle by rectangle; large ones in parallel
    /// over the rows they touch.
    pub fn move_from(&mut self, new: [i64; 2], rects: &[TexRect], src: &impl Source<T>) {
        let s = self.size;
        let wrap = new.map(|o| o.rem_euclid(s as i64) as usize);
        // Per rectangle: its column pieces as (x0, x1, world x of x0).
        let mut pieces = [[(0usize, 0usize, 0i64); 2]; 4];
        for (p, r) in pieces.iter_mut().zip(rects) {
            *p =
                consecutive(r.x0, r.x1, wrap[0]).map(|(a, b)| (a, b, Self::world_of(a, new[0], s)));
        }
        let write = |row: &mut [T], p: &[(usize, usize, i64); 2], wy: i64| {
            for &(a, b, wx) in p {
                if a < b {
                    src.row(wx, wy, &mut row[a..b]);
                }
            }
        };
        let area: usize = rects.iter().map(|r| r.area()).sum();
        if area < PARALLEL_TEXELS {
            for (r, p) in rects.iter().zip(&pieces) {
                for (ya, yb) in consecutive(r.y0, r.y1, wrap[1]) {
                    let wy = Self::world_of(ya, new[1], s);
                    if ya == yb {
                        continue;
                    }
                    if r.x1 - r.x0 <= NARROW {
                        for &(a, b, wx) in p {
                            if a < b {
                                let dst = Narrow {
                                    data: &mut self.data,
                                    at: ya * s + a,
                                    stride: s,
                                    width: b - a,
                                    rows: yb - ya,
                                };
                                src.narrow(wx, wy, dst);
                            }
                        }
                    } else {
                        for ty in ya..yb {
                            write(&mut self.data[ty * s..ty * s + s], p, wy + (ty - ya) as i64);
                        }
                    }
                }
            }
        } else {
            let y0 = rects.iter().map(|r| r.y0).min().unwrap_or(0);
            let y1 = rects.iter().map(|r| r.y1).max().unwrap_or(0);
            let band = &mut self.data[y0 * s..y1 * s];
            band.par_chunks_mut(s).enumerate().for_each(|(i, row)| {
                let ty = y0 + i;
                let wy = Self::world_of(ty, new[1], s);
                for (r, p) in rects.iter().zip(&pieces) {
                    if ty >= r.y0 && ty < r.y1 {
                        debug_assert!(r.contains(r.x0, ty));
                        write(row, p, wy);
                    }
                }
            });
        }
        self.origin = Some(new);
    }
}

/// Rectangles at most this wide go to [`Source::narrow`] whole.
pub const NARROW: usize = 3;

/// A toroid rectangle at most [`NARROW`] texels wide being rewritten:
/// `rows` runs of `width` texels, the first at `data[at..]`, each `stride`
/// after the last (the toroid's rows).
pub struct Narrow<'a, T> {
    /// The toroid's texels.
    pub data: &'a mut [T],
    /// Index of the rectangle's first texel.
    pub at: usize,
    /// Texels from one row's start to the next's.
    pub stride: usize,
    /// Texels per row (at most [`NARROW`]).
    pub width: usize,
    /// Rows.
    pub rows: usize,
}

/// Where a toroid's new texels come from.
pub trait Source<T>: Sync {
    /// Writes world cells `(wx + i, wy)` into `run[i]`.
    fn row(&self, wx: i64, wy: i64, run: &mut [T]);
    /// Writes world cells `(wx + i, wy + j)` into the j-th run of `dst`.
    /// By default a row at a time; a source laid out in long rows does
    /// better from a copy of the few columns (see `clipmap::columns`).
    fn narrow(&self, wx: i64, wy: i64, dst: Narrow<'_, T>) {
        narrow_by_rows(self, wx, wy, dst);
    }
}

/// [`Source::narrow`] a row at a time through [`Source::row`]: the default,
/// and what a source with a faster way falls back to where it has none.
pub fn narrow_by_rows<T, S: Source<T> + ?Sized>(src: &S, wx: i64, wy: i64, dst: Narrow<'_, T>) {
    for j in 0..dst.rows {
        let at = dst.at + j * dst.stride;
        src.row(wx, wy + j as i64, &mut dst.data[at..at + dst.width]);
    }
}

/// A source that computes each cell: `fill(world_x, world_y)`.
struct Cells<F>(F);

impl<T, F: Fn(i64, i64) -> T + Sync> Source<T> for Cells<F> {
    fn row(&self, wx: i64, wy: i64, run: &mut [T]) {
        for (i, v) in run.iter_mut().enumerate() {
            *v = (self.0)(wx + i as i64, wy);
        }
    }
}

/// Toroid interval [a, b) cut at texel `wrap`, where the window's world
/// coordinates jump back by s; an empty second piece when it does not wrap.
fn consecutive(a: usize, b: usize, wrap: usize) -> [(usize, usize); 2] {
    if a < wrap && wrap < b {
        [(a, wrap), (wrap, b)]
    } else {
        [(a, b), (b, b)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_move_rewrites_2ms_minus_m2() {
        let s = 31;
        for m in 1..s {
            let r = update_rects(Some([-5, 7]), [-5 + m as i64, 7 - m as i64], s);
            let area: usize = r.iter().map(|r| r.area()).sum();
            assert_eq!(area, 2 * m * s - m * m, "m = {m}");
            assert!(r.len() <= 4);
        }
    }

    #[test]
    fn negative_coordinates_address_correctly() {
        let mut t = Toroid::<i64>::new(7);
        t.move_to([-20, -3], |x, y| x * 1000 + y);
        for y in -3..4 {
            for x in -20..-13 {
                assert_eq!(t.get(x, y), x * 1000 + y);
            }
        }
    }
}
