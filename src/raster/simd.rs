//! The 8-lane path: eight pixels of a row per step, branch-free, written so
//! the compiler turns it into AVX2 + FMA code when the CPU has them (runtime
//! detection below) and into plain code otherwise. Per pixel it computes
//! exactly what `tile::draw` computes, so both paths give the same bits.

use super::tile::{span, TileBuf, STRIDE};
use super::Tri;

const LANES: usize = 8;

#[inline(always)]
fn draw_lanes(t: &Tri, id: u32, tx0: i64, ty0: i64, buf: &mut TileBuf) {
    let Some([x0, y0, x1, y1]) = span(t, tx0, ty0) else {
        return;
    };
    let [e0, e1, e2] = &t.edges;
    let step = [
        e0.a * LANES as i64,
        e1.a * LANES as i64,
        e2.a * LANES as i64,
    ];
    for py in y0..=y1 {
        let row = (py - ty0) as usize * STRIDE;
        let start = [e0.at(x0, py), e1.at(x0, py), e2.at(x0, py)];
        let mut l0 = [0i64; LANES];
        let mut l1 = [0i64; LANES];
        let mut l2 = [0i64; LANES];
        for k in 0..LANES {
            l0[k] = start[0] + e0.a * k as i64;
            l1[k] = start[1] + e1.a * k as i64;
            l2[k] = start[2] + e2.a * k as i64;
        }
        let pyf = py as f32;
        let mut px = x0;
        while px <= x1 {
            let base = row + (px - tx0) as usize;
            let depth: &mut [f32; LANES] = (&mut buf.depth[base..base + LANES])
                .try_into()
                .expect("padded row");
            let prim: &mut [u32; LANES] = (&mut buf.prim[base..base + LANES])
                .try_into()
                .expect("padded row");
            for k in 0..LANES {
                let x = px + k as i64;
                let z = t.z.eval(x as f32, pyf);
                let hit = (x <= x1) & (l0[k] > 0) & (l1[k] > 0) & (l2[k] > 0) & (z < depth[k]);
                depth[k] = if hit { z } else { depth[k] };
                prim[k] = if hit { id } else { prim[k] };
                l0[k] += step[0];
                l1[k] += step[1];
                l2[k] += step[2];
            }
            px += LANES as i64;
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn draw_avx2(t: &Tri, id: u32, tx0: i64, ty0: i64, buf: &mut TileBuf) {
    draw_lanes(t, id, tx0, ty0, buf)
}

/// True when the CPU has what the fast 8-lane build needs.
pub fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// 8-lane rasterisation of triangle `id` into the tile.
pub fn draw(t: &Tri, id: u32, tx0: i64, ty0: i64, buf: &mut TileBuf, avx2: bool) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is only true when has_avx2_fma() said so.
        unsafe { draw_avx2(t, id, tx0, ty0, buf) };
        return;
    }
    let _ = avx2;
    draw_lanes(t, id, tx0, ty0, buf)
}
