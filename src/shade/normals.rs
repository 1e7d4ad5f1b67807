//! Surface normals from the heightmap by central differences, on the grid of
//! the level being drawn, blended toward the coarser level's normal by the
//! same α as the geometry so lighting does not pop across a transition band.
//! Only computed when a lighting effect is listed.

use super::vec3::normalize;
use crate::pyramid::PyramidLevel;
use crate::terrain::world::WorldMap;

/// World-space slope (dZ/dX, dZ/dY) at texel (x, y) of `p`, whose texels are
/// `spacing` base cells apart. Y points north, i.e. toward smaller rows.
#[inline]
pub fn gradient(p: &PyramidLevel, x: i64, y: i64, spacing: f64, world: &WorldMap) -> [f32; 2] {
    let [sx, sy] = slope_scale(world, spacing);
    let gx = (p.get_clamped(x + 1, y) - p.get_clamped(x - 1, y)) * sx;
    let gy = (p.get_clamped(x, y - 1) - p.get_clamped(x, y + 1)) * sy;
    [gx, gy]
}

/// The factors [`gradient`] multiplies its central differences by, for
/// samples `spacing` base cells apart: computed in f64, used as f32 (what
/// the GPU's update pass receives, so its slopes are the same bits).
pub fn slope_scale(world: &WorldMap, spacing: f64) -> [f32; 2] {
    let s = |cell: f64| (world.vertical_scale / (2.0 * spacing * cell)) as f32;
    [s(world.cell[0]), s(world.cell[1])]
}

/// Unit normal of a surface with slope `g`.
#[inline]
pub fn from_gradient(g: [f32; 2]) -> [f32; 3] {
    normalize([-g[0], -g[1], 1.0])
}

/// The coarser level's slope at fine texel (x, y), with the same averaging
/// as the coarse height (`clipmap::morph::coarse_height`).
pub fn coarse_gradient(c: &PyramidLevel, x: i64, y: i64, spacing: f64, w: &WorldMap) -> [f32; 2] {
    let g = |a: i64, b: i64| gradient(c, a, b, spacing, w);
    let avg = |p: [f32; 2], q: [f32; 2]| [(p[0] + q[0]) * 0.5, (p[1] + q[1]) * 0.5];
    crate::clipmap::morph::coarse_sample(x, y, g, avg)
}

/// The normal at level-`l` texel (x, y), morphed toward level l + 1 by α.
pub fn vertex_normal(
    levels: &[PyramidLevel],
    l: usize,
    x: i64,
    y: i64,
    alpha: f32,
    world: &WorldMap,
) -> [f32; 3] {
    let spacing = (1u64 << l) as f64;
    let f = gradient(&levels[l], x, y, spacing, world);
    if alpha <= 0.0 || l + 1 >= levels.len() {
        return from_gradient(f);
    }
    let c = coarse_gradient(&levels[l + 1], x, y, 2.0 * spacing, world);
    let k = 1.0 - alpha;
    from_gradient([k * f[0] + alpha * c[0], k * f[1] + alpha * c[1]])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn level(w: usize, h: usize, f: impl Fn(usize, usize) -> f32) -> PyramidLevel {
        let data: Vec<f32> = (0..w * h).map(|i| f(i % w, i / w)).collect();
        PyramidLevel {
            width: w,
            height: h,
            nodata: vec![false; w * h],
            min: 0.0,
            max: 0.0,
            data,
        }
    }

    #[test]
    fn a_plane_rising_east_tilts_the_normal_west() {
        // z = 2·col on 10 m cells: slope 0.2 east, so n ∝ (−0.2, 0, 1).
        let p = level(8, 8, |c, _| 2.0 * c as f32);
        let w = WorldMap::new([10.0, 10.0], 1.0);
        let n = from_gradient(gradient(&p, 3, 3, 1.0, &w));
        let l = (1.0f32 + 0.04).sqrt();
        assert!(
            (n[0] + 0.2 / l).abs() < 1e-6 && n[1].abs() < 1e-7 && (n[2] - 1.0 / l).abs() < 1e-6
        );
        // Rising toward larger rows means falling northward: n tilts north.
        let p = level(8, 8, |_, r| 2.0 * r as f32);
        let n = from_gradient(gradient(&p, 3, 3, 1.0, &w));
        assert!(n[1] > 0.19 / l);
    }
}
