//! LOD schemes turn the terrain and a view into triangles. Each scheme hands
//! the frame builder the same thing, a [`LodMesh`], so the back ends never
//! see which scheme made it.

pub mod brute_force;

use crate::camera::Frustum;
use crate::clipmap::{Clipmap, LevelMesh};
use crate::world::WorldMap;

/// One vertex as the LOD scheme emits it: base-grid position, own height,
/// the coarser surface's height there and the morph weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodVertex {
    pub col: i64,
    pub row: i64,
    pub z: f32,
    pub zc: f32,
    pub alpha: f32,
}

/// Per-level constants the effects need (texture addressing).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelInfo {
    pub level: usize,
    /// Window origin in level texels.
    pub origin: [i64; 2],
    /// Window size in level texels (n for a clipmap level).
    pub size: [usize; 2],
    /// Whether this level morphs toward the next.
    pub morph: bool,
}

/// Unshared triangles (three vertices each) with a level per triangle.
#[derive(Clone, Debug, Default)]
pub struct LodMesh {
    pub vertices: Vec<LodVertex>,
    pub levels: Vec<u32>,
    /// Indexed by level number; levels not drawn may be absent (`None`).
    pub level_info: Vec<Option<LevelInfo>>,
}

impl LodMesh {
    pub fn triangle_count(&self) -> usize {
        self.levels.len()
    }
}

/// The clipmap's meshes for a view, culled to `frustum`.
pub fn clipmap_mesh(cm: &Clipmap, frustum: &Frustum, world: &WorldMap) -> LodMesh {
    from_level_meshes(cm, &cm.meshes(Some((frustum, world))))
}

/// Expands this frame's level meshes (kept for a GPU back end that draws
/// them from its own textures) into the frame's triangles.
pub fn from_level_meshes(cm: &Clipmap, meshes: &[LevelMesh]) -> LodMesh {
    let mut out = LodMesh {
        level_info: vec![None; cm.levels().len()],
        ..Default::default()
    };
    for mesh in meshes {
        let lv = &cm.levels()[mesh.level];
        out.level_info[mesh.level] = Some(LevelInfo {
            level: mesh.level,
            origin: lv.regions.origin,
            size: [cm.n() as usize; 2],
            morph: lv.morph.enabled,
        });
        for t in cm.triangles(mesh) {
            out.levels.push(mesh.level as u32);
            out.vertices.extend(t.iter().map(|v| LodVertex {
                col: v.x,
                row: v.y,
                z: v.z,
                zc: v.zc,
                alpha: v.alpha,
            }));
        }
    }
    out
}
