//! `normal-map`: per-level normal maps at twice the level's resolution, as in
//! GPU Gems 2 ch. 2. The map of level l is computed from the next finer
//! pyramid level (the base, upsampled, for level 0) over the level's window,
//! and a pixel blends the maps of levels l and l + 1 by the geometry's α.

use super::normals::{from_gradient, gradient};
use super::vec3::normalize;
use crate::pyramid::PyramidLevel;
use crate::terrain::world::WorldMap;
use rayon::prelude::*;

/// Normals on the half-texel grid of one level.
#[derive(Clone, Debug)]
pub struct NormalMap {
    /// First sample, in half-texels of the level (= texels of level l − 1).
    pub origin: [i64; 2],
    pub size: [usize; 2],
    pub data: Vec<[f32; 3]>,
}

/// The base level sampled at half-texel (X, Y): its own samples on even
/// points, midpoints along edges and along the main diagonal elsewhere.
fn half_base(b: &PyramidLevel) -> PyramidLevel {
    let (w, h) = (2 * b.width - 1, 2 * b.height - 1);
    let mut data = vec![0.0; w * h];
    data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            *out = crate::clipmap::morph::coarse_sample(
                x as i64,
                y as i64,
                |a, c| b.get_clamped(a, c),
                |p, q| (p + q) * 0.5,
            );
        }
    });
    PyramidLevel {
        width: w,
        height: h,
        nodata: vec![],
        min: b.min,
        max: b.max,
        data,
    }
}

/// Source heights for the normal maps: index l − 1 for level l ≥ 1, the
/// upsampled base for level 0.
pub struct Sources {
    base_half: Option<PyramidLevel>,
}

impl Sources {
    /// Builds the upsampled base only if level 0 needs a map.
    pub fn new(levels: &[PyramidLevel], need_level0: bool) -> Self {
        Sources {
            base_half: need_level0.then(|| half_base(&levels[0])),
        }
    }
    fn get<'a>(&'a self, levels: &'a [PyramidLevel], l: usize) -> &'a PyramidLevel {
        if l == 0 {
            self.base_half.as_ref().expect("level 0 source built")
        } else {
            &levels[l - 1]
        }
    }
}

impl NormalMap {
    /// The map of level `l` over level texels [o, o + n − 1]² (2n − 1
    /// samples a side).
    pub fn build(
        levels: &[PyramidLevel],
        src: &Sources,
        l: usize,
        o: [i64; 2],
        n: [usize; 2],
        world: &WorldMap,
    ) -> Self {
        let heights = src.get(levels, l);
        let spacing = (1u64 << l) as f64 / 2.0;
        let size = [2 * n[0] - 1, 2 * n[1] - 1];
        let origin = [2 * o[0], 2 * o[1]];
        let mut data = vec![[0.0; 3]; size[0] * size[1]];
        data.par_chunks_mut(size[0])
            .enumerate()
            .for_each(|(j, row)| {
                for (i, out) in row.iter_mut().enumerate() {
                    let (x, y) = (origin[0] + i as i64, origin[1] + j as i64);
                    *out = from_gradient(gradient(heights, x, y, spacing, world));
                }
            });
        NormalMap { origin, size, data }
    }

    /// Bilinear sample at half-texel position `h` relative to `origin`.
    #[inline]
    pub fn sample(&self, h: [f32; 2]) -> [f32; 3] {
        let fx = h[0].floor();
        let fy = h[1].floor();
        let ix = (fx as i64).clamp(0, self.size[0] as i64 - 2) as usize;
        let iy = (fy as i64).clamp(0, self.size[1] as i64 - 2) as usize;
        let tx = (h[0] - ix as f32).clamp(0.0, 1.0);
        let ty = (h[1] - iy as f32).clamp(0.0, 1.0);
        let at = |x: usize, y: usize| self.data[y * self.size[0] + x];
        let lerp = |a: [f32; 3], b: [f32; 3], t: f32| {
            let k = 1.0 - t;
            [
                k * a[0] + t * b[0],
                k * a[1] + t * b[1],
                k * a[2] + t * b[2],
            ]
        };
        let top = lerp(at(ix, iy), at(ix + 1, iy), tx);
        let bottom = lerp(at(ix, iy + 1), at(ix + 1, iy + 1), tx);
        lerp(top, bottom, ty)
    }
}

/// The pixel normal: level `l`'s map at level-local texel `uv` (relative to
/// the window origin `o`), blended by α toward level l + 1's map.
pub fn pixel_normal(
    fine: &NormalMap,
    coarse: Option<&NormalMap>,
    o: [i64; 2],
    uv: [f32; 2],
    alpha: f32,
) -> [f32; 3] {
    let f = fine.sample([
        (2 * o[0] - fine.origin[0]) as f32 + 2.0 * uv[0],
        (2 * o[1] - fine.origin[1]) as f32 + 2.0 * uv[1],
    ]);
    let n = match coarse {
        Some(c) if alpha > 0.0 => {
            // Level l texel X is half-texel X of level l + 1.
            let s = c.sample([
                (o[0] - c.origin[0]) as f32 + uv[0],
                (o[1] - c.origin[1]) as f32 + uv[1],
            ]);
            super::morph::blend3(f, s, alpha)
        }
        _ => f,
    };
    normalize(n)
}
