//! The geometry clipmap behind the [`Lod`] trait: the toroidal update is the
//! "lod" pass, the level meshes (strips or footprints, culled) the "mesh"
//! pass. The level meshes are kept for a GPU back end that draws them from
//! its own textures.

use super::{LevelInfo, Lod, LodMesh, LodUpdate, LodVertex, View};
use crate::clipmap::{Clipmap, LevelMesh, UpdateStats};
use crate::lod::LodScheme;
use crate::pyramid::Pyramid;

/// The clipmap state a frame was made from, for a back end that draws from
/// its own copy of the toroidal levels.
pub struct ClipFrame {
    /// The level meshes of the frame.
    pub meshes: Vec<LevelMesh>,
    /// What the frame's update rewrote.
    pub update: UpdateStats,
}

/// Where a clipmap's levels nest (`lod.centre`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Centre {
    /// Around the eye's ground point (LH04): detail by distance alone.
    #[default]
    Eye,
    /// Each level over the terrain the view sees that needs it
    /// ([`super::focus`]), for texels of at most `tau` pixels (`lod.tau`),
    /// so that a narrow field of view looking far gets the fine levels.
    View {
        /// Pixels a texel may cover.
        tau: f64,
    },
}

/// The geometry clipmap as a LOD scheme: the nested toroidal levels, updated to the
/// viewer each frame and meshed as strips or footprints.
pub struct ClipmapLod {
    cm: Clipmap,
    centre: Centre,
    meshes: Vec<LevelMesh>,
    update: UpdateStats,
}

impl ClipmapLod {
    /// The scheme over `cm`, nested around the eye.
    pub fn new(cm: Clipmap) -> Self {
        ClipmapLod {
            cm,
            centre: Centre::Eye,
            meshes: Vec::new(),
            update: UpdateStats::default(),
        }
    }

    /// The same, with its levels nested around `centre`.
    pub fn centred(self, centre: Centre) -> Self {
        ClipmapLod { centre, ..self }
    }
}

impl Lod for ClipmapLod {
    fn scheme(&self) -> LodScheme {
        LodScheme::Clipmap
    }

    fn update(&mut self, view: &View) -> LodUpdate {
        // clone_from keeps this frame's lists in last frame's memory.
        let eye = view.world.to_grid(view.camera.eye);
        let stats = match self.centre {
            Centre::Eye => self.cm.update(eye),
            Centre::View { tau } => {
                let levels = self.cm.levels().len();
                let wants = super::focus::wants(view, self.cm.pyramid(), levels, tau);
                self.cm.update_placed(eye, &wants)
            }
        };
        self.update.clone_from(stats);
        LodUpdate {
            texels_updated: self.update.texels_total,
            changes: self
                .update
                .rects_per_level
                .iter()
                .map(|r| r.len() as u64)
                .sum(),
        }
    }

    fn mesh(&mut self, view: &View) -> LodMesh {
        self.meshes = self.cm.meshes(Some((view.frustum, view.world)));
        from_level_meshes(&self.cm, &self.meshes)
    }

    fn pyramid(&self) -> &Pyramid {
        self.cm.pyramid()
    }

    fn clipmap(&self) -> Option<&Clipmap> {
        Some(&self.cm)
    }

    fn take_clip_frame(&mut self) -> Option<ClipFrame> {
        Some(ClipFrame {
            meshes: std::mem::take(&mut self.meshes),
            update: std::mem::take(&mut self.update),
        })
    }
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
                offset: [0.0; 2],
                z: v.z,
                zc: v.zc,
                alpha: v.alpha,
            }));
        }
    }
    out
}
