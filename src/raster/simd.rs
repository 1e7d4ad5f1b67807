//! The fast path: per row of a triangle inside a tile, the exact run of
//! covered pixels from the three integer edge functions (one division each,
//! no per-pixel edge test), then the depth test over that run in a loop the
//! compiler runs 8 pixels at a time, as AVX2 + FMA code when the CPU has
//! them (runtime detection below) and as plain code otherwise. Per pixel it
//! computes exactly what `tile::draw` computes, so both paths give the same
//! bits (`tests/raster_rules.rs` and the goldens check it).

use super::tile::{span, TileBuf, STRIDE};
use super::Tri;

/// The pixels d ∈ [0, len) with e + a·d > 0, as an inclusive range (empty
/// when lo > hi): where one edge function, e at the row's first pixel and
/// rising by a per pixel, covers the row. Exact integer arithmetic, so it
/// picks the very pixels the per-pixel test picks.
#[inline(always)]
fn edge_span(e: i64, a: i64, len: i64) -> (i64, i64) {
    use std::cmp::Ordering::*;
    match a.cmp(&0) {
        // e + a·d > 0 ⇔ d > −e/a ⇔ d ≥ ⌊−e/a⌋ + 1.
        Greater => ((-e).div_euclid(a) + 1, len - 1),
        // e + a·d > 0 ⇔ d < e/|a| ⇔ d ≤ ⌈e/|a|⌉ − 1 = −⌊−e/|a|⌋ − 1.
        Less => (0, -(-e).div_euclid(-a) - 1),
        Equal if e > 0 => (0, len - 1),
        Equal => (0, -1),
    }
}

/// Per row: the covered span from the three edge functions, then the depth
/// test over that span only, in a loop with one plane that the compiler
/// runs 8 pixels at a time.
#[inline(always)]
fn draw_lanes(t: &Tri, id: u32, tx0: i64, ty0: i64, buf: &mut TileBuf) {
    let Some([x0, y0, x1, y1]) = span(t, tx0, ty0) else {
        return;
    };
    let len = x1 - x0 + 1;
    // A local copy, so stores to the tile cannot make it reload the plane.
    let zp = t.z;
    for py in y0..=y1 {
        let (mut lo, mut hi) = (0, len - 1);
        for e in &t.edges {
            let (l, h) = edge_span(e.at(x0, py), e.a, len);
            lo = lo.max(l);
            hi = hi.min(h);
        }
        if lo > hi {
            continue;
        }
        let row = (py - ty0) as usize * STRIDE;
        let at = row + (x0 + lo - tx0) as usize;
        let n = (hi - lo + 1) as usize;
        let depth = &mut buf.depth[at..at + n];
        let prim = &mut buf.prim[at..at + n];
        // Pixel indices as f32 through i32, which converts 8 lanes at once.
        let first = (x0 + lo) as i32;
        let pyf = py as f32;
        for (i, (d, p)) in depth.iter_mut().zip(prim.iter_mut()).enumerate() {
            let z = zp.eval((first + i as i32) as f32, pyf);
            let hit = z < *d;
            *d = if hit { z } else { *d };
            *p = if hit { id } else { *p };
        }
    }
}

crate::cpu::avx2_fma_twin! {
    /// 8-lane rasterisation of triangle `id` into the tile, in the AVX2 +
    /// FMA build when `fast` (and the CPU has them).
    pub fn draw(t: &Tri, id: u32, tx0: i64, ty0: i64, buf: &mut TileBuf) => draw_lanes
}

#[cfg(test)]
mod tests {
    use super::edge_span;
    use proptest::prelude::*;

    proptest! {
        /// The span is exactly the pixels the per-pixel test accepts, for
        /// edge values and slopes far beyond a 1920-wide target.
        #[test]
        fn edge_span_is_the_per_pixel_test(
            e in -(1i64 << 40)..(1i64 << 40),
            a in prop_oneof![-(1i64 << 28)..(1i64 << 28), -300i64..300, Just(0i64)],
            len in 1i64..80,
            near in any::<bool>(),
        ) {
            // Half the cases put the crossing inside the row.
            let e = if near && a != 0 { -a * (len / 2) + e % a.abs().max(1) } else { e };
            let (lo, hi) = edge_span(e, a, len);
            for d in 0..len {
                let inside = e + a * d > 0;
                prop_assert_eq!(inside, lo <= d && d <= hi, "d = {}, span {}..={}", d, lo, hi);
            }
        }
    }
}
