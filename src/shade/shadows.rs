//! `shadows`: Holkner's ray-traced lightmap. From every texel (or every
//! half-texel at scale 2) a ray is marched toward the sun over the
//! heightmap; the light value is how far the ray stays above the terrain,
//! divided by an epsilon, clamped to [0, 1], which softens shadow edges.
//! The lightmap is then filtered into a pyramid with the scene's filter, and
//! a pixel blends levels l and l + 1 by the geometry's α.
//!
//! Built only when a scene lists `shadows`.

use crate::error::{Error, Result};
use crate::pyramid::{Filter, Pyramid, PyramidLevel};
use crate::terrain::world::WorldMap;
use crate::terrain::Heightmap;
use rayon::prelude::*;

/// The lightmap pyramid and its resolution relative to the heightmap.
#[derive(Clone, Debug)]
pub struct Lightmap {
    /// 1: one sample per heightmap texel; 2: one per half-texel.
    pub scale: u32,
    pub pyramid: Pyramid,
    /// Rays traced.
    pub rays: usize,
}

/// Bilinear height (metres) at fractional base-grid (col, row).
fn height_at(b: &PyramidLevel, col: f64, row: f64, vs: f64) -> f64 {
    let (c0, r0) = (col.floor(), row.floor());
    let (tx, ty) = (col - c0, row - r0);
    let (c, r) = (c0 as i64, r0 as i64);
    let g = |x: i64, y: i64| b.get_clamped(x, y) as f64;
    let top = g(c, r) * (1.0 - tx) + g(c + 1, r) * tx;
    let bottom = g(c, r + 1) * (1.0 - tx) + g(c + 1, r + 1) * tx;
    (top * (1.0 - ty) + bottom * ty) * vs
}

/// Light reaching base-grid point (col, row) from direction `sun` (unit
/// world vector toward the sun).
fn trace(b: &PyramidLevel, world: &WorldMap, col: f64, row: f64, sun: [f64; 3], eps: f64) -> f32 {
    let horiz = (sun[0] * sun[0] + sun[1] * sun[1]).sqrt();
    if horiz < 1e-9 {
        return 1.0;
    }
    let vs = world.vertical_scale;
    let top = b.max as f64 * vs;
    let step = 0.5 * world.cell[0].min(world.cell[1]);
    // Per step: grid movement (world y is −row) and ray rise.
    let dc = sun[0] / horiz * step / world.cell[0];
    let dr = -sun[1] / horiz * step / world.cell[1];
    let rise = sun[2] / horiz * step;
    let (w, h) = ((b.width - 1) as f64, (b.height - 1) as f64);
    let mut z = height_at(b, col, row, vs);
    let (mut c, mut r) = (col, row);
    let mut clearance = f64::INFINITY;
    loop {
        c += dc;
        r += dr;
        z += rise;
        if c < 0.0 || r < 0.0 || c > w || r > h || z > top {
            break;
        }
        clearance = clearance.min(z - height_at(b, c, r, vs));
        if clearance <= 0.0 {
            return 0.0;
        }
    }
    (clearance / eps).clamp(0.0, 1.0) as f32
}

impl Lightmap {
    /// Traces the lightmap of `base` and filters it into `levels` levels.
    pub fn build(
        base: &PyramidLevel,
        world: &WorldMap,
        sun: [f64; 3],
        epsilon: f64,
        scale: u32,
        filter: Filter,
        levels: usize,
    ) -> Result<Self> {
        let s = scale as usize;
        let (w, h) = (s * (base.width - 1) + 1, s * (base.height - 1) + 1);
        let mut light = vec![0.0f32; w * h];
        light.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
            for (i, out) in row.iter_mut().enumerate() {
                let (c, r) = (i as f64 / s as f64, j as f64 / s as f64);
                *out = trace(base, world, c, r, sun, epsilon);
            }
        });
        let cell = [world.cell[0] / s as f64, world.cell[1] / s as f64];
        let map = Heightmap::from_values(w, h, light, None, cell, "lightmap")
            .map_err(|r| Error::value("shadows", r))?;
        Ok(Lightmap {
            scale,
            pyramid: Pyramid::build(&map, filter, levels),
            rays: w * h,
        })
    }

    /// Bilinear light of pyramid level `l` at level-`l` texel `o + uv`
    /// (`half` = true samples level l at half resolution, i.e. level l + 1's
    /// grid at the same point).
    fn sample_level(&self, l: usize, o: [i64; 2], uv: [f32; 2]) -> f32 {
        let p = &self.pyramid.levels[l.min(self.pyramid.levels.len() - 1)];
        let s = self.scale as i64;
        let coord = |k: usize| {
            let h = uv[k] * s as f32;
            let f = h.floor();
            (o[k] * s + f as i64, h - f)
        };
        let ((ix, tx), (iy, ty)) = (coord(0), coord(1));
        bilinear(p, ix, iy, tx, ty)
    }

    /// The light at level-`l` texel `o + uv`, blended by α toward level l+1.
    pub fn sample(&self, l: usize, o: [i64; 2], uv: [f32; 2], alpha: f32) -> f32 {
        let f = self.sample_level(l, o, uv);
        if alpha <= 0.0 || l + 1 >= self.pyramid.levels.len() {
            return f;
        }
        // Level l + 1 at the same point: half the level-l coordinate.
        let s = self.scale as i64;
        let coord = |k: usize| {
            let b = o[k] * s;
            let h = ((b.rem_euclid(2)) as f32 + uv[k] * s as f32) * 0.5;
            let f = h.floor();
            (b.div_euclid(2) + f as i64, h - f)
        };
        let ((ix, tx), (iy, ty)) = (coord(0), coord(1));
        let c = bilinear(&self.pyramid.levels[l + 1], ix, iy, tx, ty);
        (1.0 - alpha) * f + alpha * c
    }
}

#[inline]
fn bilinear(p: &PyramidLevel, ix: i64, iy: i64, tx: f32, ty: f32) -> f32 {
    let g = |x: i64, y: i64| p.get_clamped(x, y);
    let top = (1.0 - tx) * g(ix, iy) + tx * g(ix + 1, iy);
    let bottom = (1.0 - tx) * g(ix, iy + 1) + tx * g(ix + 1, iy + 1);
    (1.0 - ty) * top + ty * bottom
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_shadows_the_ground_behind_it() {
        // A 1-texel wall 100 m high at column 20 of a flat 0 m map; sun in
        // the east at 45°: ground west of the wall is dark for 100 m (10
        // texels), ground east of it is lit.
        let (w, h) = (32usize, 8usize);
        let data: Vec<f32> = (0..w * h)
            .map(|i| if i % w == 20 { 100.0 } else { 0.0 })
            .collect();
        let base = PyramidLevel {
            width: w,
            height: h,
            nodata: vec![false; w * h],
            min: 0.0,
            max: 100.0,
            data,
        };
        let world = WorldMap::new([10.0, 10.0], 1.0);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let sun = [s, 0.0, s];
        let lm = Lightmap::build(&base, &world, sun, 1.0, 1, Filter::Point, 1).unwrap();
        let l = &lm.pyramid.levels[0];
        let at = |c: usize| l.data[4 * w + c];
        assert_eq!(at(14), 0.0);
        assert_eq!(at(18), 0.0);
        assert_eq!(at(22), 1.0);
        assert_eq!(at(5), 1.0, "beyond the shadow's length");
        assert_eq!(lm.rays, w * h);
    }
}
