//! The floor under the incremental-update target (a walk costs at most
//! 1.2× its share of a rebuild; docs/explanation/performance.md), in a bare model:
//! 10 toroids of 256², level l stepping 2 texels every 2^(l+1) frames of a
//! one-texel walk, doing nothing but copy the exposed texels from a 16384²
//! source, against a rebuild that copies every texel in the same layout.
//! No planning, no regions, no stats, no column cache. Two layouts, for
//! source and toroid alike: row-major (the product's), and 4×4 tiles of one
//! cache line each, so a column touches as many lines as a row. If the bare
//! model misses `(walk ÷ rebuild) ÷ (texels ÷ all) ≤ 1.2` in a layout, the
//! product cannot meet it in that layout either.
//!
//! `cargo bench --bench update_bound [-- REPEATS]` (default 16).
use std::hint::black_box;
use std::time::Instant;

/// Toroid side; a power of two so wrapping is a mask (the product's 255
/// changes the texel counts by under 1 %).
const S: usize = 256;
const LEVELS: usize = 10;
/// Source side: 1 GiB of f32, far beyond the caches.
const W: usize = 16384;
/// Frames per walk: every level moves at least four times.
const FRAMES: usize = 4 << (LEVELS - 1);

#[derive(Clone, Copy, PartialEq)]
enum Layout {
    Rows,
    Tiles,
}

struct Model {
    layout: Layout,
    source: Vec<f32>,
    toroids: Vec<Vec<f32>>,
}

/// Level l's window origin for a viewer at `v`: even, as clipmap nesting
/// requires, and inside the source whatever the level.
fn origin(v: [usize; 2], l: usize) -> [usize; 2] {
    v.map(|c| (((c >> l) >> 1) << 1) + 2048 - S / 2)
}

/// Flat index of 4×4 tile (tx, ty) (in tiles) of a `w`-wide tiled array.
fn tile(w: usize, tx: usize, ty: usize) -> usize {
    (ty * (w / 4) + tx) * 16
}

impl Model {
    fn new(layout: Layout) -> Self {
        Model {
            layout,
            // Written, not zeroed: zero pages would read from one shared page.
            source: (0..W * W).map(|i| (i % 1013) as f32).collect(),
            toroids: vec![vec![0.0; S * S]; LEVELS],
        }
    }

    /// Copies world rectangle [x0, x1) × [y0, y1) of level l into its
    /// toroid. Levels read disjoint-ish parts of the one source.
    fn copy(&mut self, l: usize, [x0, x1]: [usize; 2], [y0, y1]: [usize; 2]) {
        let off = l * 64;
        let (t, s) = (&mut self.toroids[l], &self.source);
        match self.layout {
            Layout::Rows => {
                for y in y0..y1 {
                    let (dst, src) = ((y % S) * S, (y + off) * W + off);
                    let mut x = x0;
                    while x < x1 {
                        let run = (S - x % S).min(x1 - x);
                        t[dst + x % S..][..run].copy_from_slice(&s[src + x..][..run]);
                        x += run;
                    }
                }
            }
            Layout::Tiles => {
                // Tile grids of source and toroid line up (off and S are
                // multiples of 4), so whole tiles copy as runs of lines.
                for ty in (y0 & !3..y1).step_by(4) {
                    let (ry0, ry1) = (ty.max(y0), (ty + 4).min(y1));
                    let mut tx = x0 & !3;
                    while tx < x1 {
                        let d = tile(S, (tx % S) / 4, (ty % S) / 4);
                        let o = tile(W, (tx + off) / 4, (ty + off) / 4);
                        // Whole tiles up to x1 or the toroid's wrap.
                        let end = (x1 & !3).min(tx - tx % S + S);
                        if ry1 - ry0 == 4 && tx >= x0 && end > tx {
                            let n = (end - tx) * 4;
                            t[d..][..n].copy_from_slice(&s[o..][..n]);
                            tx = end;
                            continue;
                        }
                        let (dt, st) = (&mut t[d..][..16], &s[o..][..16]);
                        let (rx0, rx1) = (tx.max(x0), (tx + 4).min(x1));
                        if rx1 - rx0 == 4 {
                            // Full-width rows of a tile are contiguous.
                            let r = (ry0 % 4) * 4..(ry1 - ty) * 4;
                            dt[r.clone()].copy_from_slice(&st[r]);
                        } else {
                            for y in ry0..ry1 {
                                for x in rx0..rx1 {
                                    let i = (y % 4) * 4 + x % 4;
                                    dt[i] = st[i];
                                }
                            }
                        }
                        tx += 4;
                    }
                }
            }
        }
    }

    fn rebuild(&mut self, v: [usize; 2]) {
        for l in 0..LEVELS {
            let o = origin(v, l);
            self.copy(l, [o[0], o[0] + S], [o[1], o[1] + S]);
        }
    }

    /// One frame of a walk from `from` to `to` (one texel on one axis);
    /// returns the texels written.
    fn step(&mut self, from: [usize; 2], to: [usize; 2]) -> usize {
        let mut texels = 0;
        for l in 0..LEVELS {
            let (a, b) = (origin(from, l), origin(to, l));
            if b[0] > a[0] {
                self.copy(l, [a[0] + S, b[0] + S], [b[1], b[1] + S]);
                texels += (b[0] - a[0]) * S;
            } else if b[1] > a[1] {
                self.copy(l, [b[0], b[0] + S], [a[1] + S, b[1] + S]);
                texels += (b[1] - a[1]) * S;
            }
        }
        texels
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    // `cargo bench` passes `--bench`; a number is the repeat count.
    let repeats = std::env::args()
        .skip(1)
        .find_map(|a| a.parse::<usize>().ok())
        .unwrap_or(16)
        .max(1);
    println!("layout  walk   us/frame  texels/frame  rebuild us  overhead (target <= 1.2)");
    for layout in [Layout::Rows, Layout::Tiles] {
        let mut m = Model::new(layout);
        for (name, d) in [("east", [1, 0]), ("south", [0, 1])] {
            let (mut walks, mut rebuilds, mut texels) = (Vec::new(), Vec::new(), 0);
            for r in 0..repeats {
                // Each walk and each rebuild on terrain not read before.
                let start = [1000 + r * 977 % 7000, 1200 + r * 613 % 7000];
                m.rebuild(start);
                let at = |f: usize| [start[0] + f * d[0], start[1] + f * d[1]];
                let t = Instant::now();
                for f in 1..=FRAMES {
                    texels += m.step(at(f - 1), at(f));
                }
                walks.push(t.elapsed().as_secs_f64() * 1e6 / FRAMES as f64);
                // The model is only a bound if it writes what a rebuild
                // would: every toroid must equal one rebuilt where it ended.
                let walked = m.toroids.clone();
                m.rebuild(at(FRAMES));
                assert!(walked == m.toroids, "{name} walk differs from a rebuild");
                for k in 0..3 {
                    let i = r * 3 + k;
                    let t = Instant::now();
                    m.rebuild([9000 + i * 311 % 4000, 8000 + i * 419 % 4000]);
                    rebuilds.push(t.elapsed().as_secs_f64() * 1e6);
                }
                black_box(&m.toroids);
            }
            let (walk, rebuild) = (median(walks), median(rebuilds));
            let per_frame = texels as f64 / (repeats * FRAMES) as f64;
            let share = per_frame / (LEVELS * S * S) as f64;
            let label = if layout == Layout::Rows {
                "rows"
            } else {
                "tiles"
            };
            println!(
                "{label:6}  {name:5}  {walk:8.3}  {per_frame:12.1}  {rebuild:10.1}  {:.2}",
                walk / rebuild / share
            );
        }
    }
}
