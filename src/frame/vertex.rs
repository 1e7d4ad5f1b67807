//! The vertex stage: morph, camera-relative position, clip transform.
//!
//! World positions are f64; the stage subtracts a floating origin (a base-grid
//! vertex next to the eye) in integers before anything becomes f32, so a
//! view renders the same far from the world origin as near it. Each step is
//! written in the order a WGSL vertex shader will repeat (docs/reference/raster-rules.md
//! rule 7): no FMA, matrix columns summed from the last one.

use crate::camera::Camera;
use crate::clipmap::morph;
use crate::lod::LodVertex;
use crate::terrain::world::WorldMap;
use glam::DVec3;

/// The stage's constants (a GPU uniform block).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexUniforms {
    /// Floating origin: base-grid vertex nearest the eye.
    pub origin: [i64; 2],
    /// Metres per base-grid cell in x and y.
    pub cell: [f32; 2],
    /// Metres per height unit.
    pub vertical_scale: f32,
    /// Camera-relative view-projection, f32 columns.
    pub view_proj: [[f32; 4]; 4],
    /// The eye relative to the origin.
    pub eye: [f32; 3],
}

impl VertexUniforms {
    /// The constants for `cam` over `world`: the origin is the grid vertex nearest the eye,
    /// so camera-relative f32 positions stay exact far from the world origin.
    pub fn new(cam: &Camera, world: &WorldMap) -> Self {
        let g = world.to_grid(cam.eye);
        let origin = [g[0].round() as i64, g[1].round() as i64];
        let o = world.to_world(origin[0] as f64, origin[1] as f64, 0.0);
        let rel = Camera {
            eye: cam.eye - o,
            target: cam.target - o,
            ..*cam
        };
        let m = rel.view_projection();
        let col = |i: usize| m.col(i).to_array().map(|v| v as f32);
        let e: DVec3 = rel.eye;
        VertexUniforms {
            origin,
            cell: world.cell.map(|c| c as f32),
            vertical_scale: world.vertical_scale as f32,
            view_proj: [col(0), col(1), col(2), col(3)],
            eye: [e.x as f32, e.y as f32, e.z as f32],
        }
    }

    /// Height fetch result → morphed, camera-relative position (metres).
    /// The offset is 0 for on-grid vertices, and adding 0 is exact, so the
    /// clipmap's positions are what its WGSL shader computes.
    #[inline]
    pub fn position(&self, v: &LodVertex) -> [f32; 3] {
        let zm = morph::blend(v.z, v.zc, v.alpha);
        [
            ((v.col - self.origin[0]) as f32 + v.offset[0]) * self.cell[0],
            ((self.origin[1] - v.row) as f32 - v.offset[1]) * self.cell[1],
            zm * self.vertical_scale,
        ]
    }

    /// Clip-space position: ((m3·1 + m2·z) + m1·y) + m0·x per component.
    #[inline]
    pub fn clip(&self, p: [f32; 3]) -> [f32; 4] {
        let m = &self.view_proj;
        [0, 1, 2, 3].map(|k| ((m[3][k] * 1.0 + m[2][k] * p[2]) + m[1][k] * p[1]) + m[0][k] * p[0])
    }
}
