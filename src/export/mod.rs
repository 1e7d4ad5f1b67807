//! The export stage: a frame written out so that another renderer can draw
//! exactly what terraclip drew and be compared with it, and read back, by
//! `compare` and by the tests that prove the files are the frame.
//!
//! A frame's folder holds:
//!
//! | file | what |
//! | --- | --- |
//! | `frame.glb` | the triangles as glTF 2.0 binary: camera-relative f32 positions and the listed effects' varyings, bit for bit the vertex stage's ([`glb`]) |
//! | `camera.json` | view and projection (f64, camera-relative), the f32 view-projection the clip positions were made with, viewport, near and far, the depth convention, the floating origin |
//! | `frame.json` | what shading needs besides the mesh: effects, shading constants, varyings, drawn levels, and what the EXR files hold |
//! | `terrain.vert`, `terrain.frag` | the shading as GLSL 4.50 for an outside OpenGL renderer ([`glsl`]) |
//! | `terrain-es.vert`, `terrain-es.frag` | the same as GLSL ES 3.00, for WebGL 2 and OpenGL ES |
//! | `terrain.wgsl` | the same as WGSL, for WebGPU ([`wgsl`]) |
//! | `colour.png` | the reference colour, RGBA8 |
//! | `depth.exr`, `depth.f32` | the reference Depth32Float, as OpenEXR and as raw little-endian f32 rows, top row first |
//! | `clipmap.exr` | each clipmap level's toroid of heights, one layer a level (clipmap scenes only) |
//! | `effects.exr` | the lightmap pyramid and normal maps (scenes with `shadows` or `normal-map` only) |
//! | `scene.toml` | the scene the frame came from |
//! | `manifest.json` | format and version, terraclip's version, the rules followed, and each file's length and SHA-256 |
//!
//! A folder is written whole beside its destination and renamed into
//! place, so a reader never sees half an export.

pub mod exr;
pub mod glb;
pub mod glsl;
pub mod wgsl;

use crate::camera::Camera;
use crate::clipmap::Clipmap;
use crate::error::{temp_path, Error, Result};
use crate::frame::vertex::VertexUniforms;
use crate::frame::Frame;
use crate::lod::{LevelInfo, LodMesh};
use crate::pyramid::{Filter, Pyramid, PyramidLevel};
use crate::render::Image;
use crate::scene::Effect;
use crate::shade::normal_map::NormalMap;
use crate::shade::shadows::Lightmap;
use crate::shade::{Effects, Layout, Resources, ShadeParams};
use crate::shard::Shard;
use crate::terrain::world::WorldMap;
use exr::FloatLayer;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// `manifest.json`'s `format`.
pub const FORMAT: &str = "terraclip-export";
/// `manifest.json`'s `version`: bumped whenever a file's meaning changes.
pub const VERSION: u32 = 1;
/// Where the rules a conforming rasteriser follows are stated.
pub const RULES: &str = "docs/reference/raster-rules.md";

/// `camera.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CameraFile {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Viewport x, y, width, height in pixels (y down, origin top left).
    pub viewport: [u32; 4],
    /// The view-projection the clip positions were made with: f32 columns,
    /// applied to `frame.glb`'s POSITION as
    /// `((m3 + m2·z) + m1·y) + m0·x` per component, without FMA.
    pub view_proj: [[f32; 4]; 4],
    /// Camera-relative view matrix (f64 columns; right-handed, looking down −z).
    pub view: [[f64; 4]; 4],
    /// Projection matrix (f64 columns; depth 0 at near, 1 at far).
    pub projection: [[f64; 4]; 4],
    /// The eye relative to the floating origin, f32 metres.
    pub eye_relative: [f32; 3],
    /// The eye in world metres.
    pub eye: [f64; 3],
    /// The point looked at, world metres.
    pub target: [f64; 3],
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
    /// Width over height.
    pub aspect: f64,
    /// Near plane distance, metres.
    pub near: f64,
    /// Far plane distance, metres.
    pub far: f64,
    /// World metres of the floating origin that POSITION is relative to.
    pub floating_origin: [f64; 3],
    /// The same origin as a base-grid vertex (column, row).
    pub floating_origin_grid: [i64; 2],
    /// The depth buffer: `Depth32Float`, cleared to 1, test LESS, 0 at the
    /// near plane.
    pub depth: DepthConvention,
}

/// How the reference depth was made; `compare` names a mismatch.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DepthConvention {
    /// Texture format.
    pub format: String,
    /// Clear value.
    pub clear: f32,
    /// Depth test.
    pub compare: String,
    /// Depth at the near plane (0: not reversed).
    pub near_value: f32,
}

impl DepthConvention {
    /// terraclip's: Depth32Float cleared to 1, LESS, 0 at near.
    pub fn terraclip() -> Self {
        DepthConvention {
            format: "Depth32Float".into(),
            clear: 1.0,
            compare: "less".into(),
            near_value: 0.0,
        }
    }
}

/// A drawn level's texture addressing.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct LevelFile {
    /// Level, 0 the finest.
    pub level: usize,
    /// Window origin in level texels.
    pub origin: [i64; 2],
    /// Window size in level texels.
    pub size: [usize; 2],
    /// Whether it morphs toward the next coarser level.
    pub morph: bool,
}

/// A clipmap level's toroid in `clipmap.exr`.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct ToroidFile {
    /// Level, 0 the finest; its layer is `level{level}`, channel `H`.
    pub level: usize,
    /// Texels per side (n).
    pub size: usize,
    /// World origin of the window in level texels; texel (x, y) of the
    /// window is sample `(y mod n)·n + (x mod n)` of the layer (Euclidean
    /// modulo). `None` for a level never filled.
    pub origin: Option<[i64; 2]>,
    /// Whether the level is drawn this frame.
    pub active: bool,
}

/// A normal map in `effects.exr` (layer `normal{level}`, channels X, Y, Z).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct NormalMapFile {
    /// The level it shades.
    pub level: usize,
    /// First sample in half-texels of the level.
    pub origin: [i64; 2],
    /// Samples across and down.
    pub size: [usize; 2],
}

/// The lightmap in `effects.exr` (layers `lightmap{k}`, channel `L`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LightmapFile {
    /// Samples per heightmap texel along each axis.
    pub scale: u32,
    /// Rays traced to make it.
    pub rays: usize,
    /// The filter of its pyramid.
    pub filter: Filter,
    /// Each level's width and height.
    pub levels: Vec<[usize; 2]>,
}

/// One varying in `frame.glb`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct VaryingFile {
    /// The attribute's name.
    pub attribute: String,
    /// Components.
    pub components: usize,
    /// `perspective` or `linear` (screen-linear).
    pub interpolation: String,
}

/// `frame.json`: what drawing the frame needs besides the mesh and camera.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FrameFile {
    /// The scene's name.
    pub scene: String,
    /// The LOD scheme that made the mesh.
    pub lod: String,
    /// Triangles in `frame.glb`.
    pub triangles: usize,
    /// The listed effects.
    pub effects: Vec<Effect>,
    /// The scene's shading constants.
    pub shading: ShadeParams,
    /// Clear colour, linear RGB.
    pub background: [f32; 3],
    /// Height-ramp low end and span, metres.
    pub height_ramp: [f32; 2],
    /// Metres per base-grid cell.
    pub cell: [f32; 2],
    /// Metres per height unit.
    pub vertical_scale: f32,
    /// The varyings each vertex carries, in order.
    pub varyings: Vec<VaryingFile>,
    /// The drawn levels' texture addressing.
    pub levels: Vec<LevelFile>,
    /// The clipmap's toroids in `clipmap.exr` (empty for other schemes).
    pub toroids: Vec<ToroidFile>,
    /// The normal maps in `effects.exr`.
    pub normal_maps: Vec<NormalMapFile>,
    /// The lightmap in `effects.exr`.
    pub lightmap: Option<LightmapFile>,
    /// The unit vector toward the sun as the shaders take it (f32, x east,
    /// y north, z up): `shading.sun`'s azimuth and elevation through f64
    /// sines and cosines, rounded once.
    #[serde(default)]
    pub sun_direction: [f32; 3],
    /// `level-tint`'s albedo: level l's colour is entry l mod 8, each
    /// channel divided by 255 (linear, as every colour here).
    #[serde(default)]
    pub level_palette: Vec<[u8; 3]>,
}

/// One file's entry in the manifest.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FileEntry {
    /// Path inside the export folder.
    pub name: String,
    /// Length in bytes.
    pub bytes: u64,
    /// SHA-256, lower-case hex.
    pub sha256: String,
}

/// `manifest.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// The terraclip that wrote it.
    pub terraclip: String,
    /// The scene's name.
    pub scene: String,
    /// The rasterisation rules the reference follows ([`RULES`]).
    pub rules: String,
    /// Frame folders, for an export of a path (`frame-0000`, ...); empty
    /// when this folder is one frame.
    #[serde(default)]
    pub frames: Vec<String>,
    /// Every other file, with its length and hash.
    pub files: Vec<FileEntry>,
}

/// An export's files: each path inside the folder and its bytes.
pub type Files = Vec<(String, Vec<u8>)>;

/// What one frame's export is made from.
pub struct Source<'a> {
    /// The scene's name.
    pub scene: &'a str,
    /// The scene's text, copied as `scene.toml`.
    pub scene_text: Option<&'a str>,
    /// The view, in world metres.
    pub camera: &'a Camera,
    /// The frame drawn.
    pub frame: &'a Frame,
    /// The CPU's image of it.
    pub image: &'a Image,
    /// Grid-to-world placement.
    pub world: &'a WorldMap,
    /// The clipmap, when the scene has one.
    pub clipmap: Option<&'a Clipmap>,
}

/// Little-endian f32s, as `depth.f32` holds them (a trailing partial value
/// is dropped; callers check the length first).
pub fn le_f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn to_json(v: &impl Serialize) -> Result<Vec<u8>> {
    let mut s = serde_json::to_vec_pretty(v).map_err(|e| Error::value("export", e.to_string()))?;
    s.push(b'\n');
    Ok(s)
}

fn cols(m: glam::DMat4) -> [[f64; 4]; 4] {
    [0, 1, 2, 3].map(|i| m.col(i).to_array())
}

/// The camera file of `src`'s frame.
fn camera_file(src: &Source) -> CameraFile {
    let u = &src.frame.uniforms;
    let o = src
        .world
        .to_world(u.origin[0] as f64, u.origin[1] as f64, 0.0);
    let c = src.camera;
    let rel = Camera {
        eye: c.eye - o,
        target: c.target - o,
        ..*c
    };
    let (w, h) = (src.frame.width, src.frame.height);
    CameraFile {
        width: w,
        height: h,
        viewport: [0, 0, w, h],
        view_proj: u.view_proj,
        view: cols(rel.view()),
        projection: cols(rel.projection()),
        eye_relative: u.eye,
        eye: c.eye.to_array(),
        target: c.target.to_array(),
        fov_y_deg: c.fov_y_deg,
        aspect: c.aspect,
        near: c.near,
        far: c.far,
        floating_origin: o.to_array(),
        floating_origin_grid: u.origin,
        depth: DepthConvention::terraclip(),
    }
}

/// The files of one frame's export, in the order the manifest lists them
/// (the manifest itself last).
pub fn files(src: &Source) -> Result<Files> {
    let f = src.frame;
    let cam = camera_file(src);
    let mut out: Vec<(String, Vec<u8>)> = vec![];
    let tris = glb::Triangles {
        positions: f.positions.clone(),
        attrs: f.attrs.clone(),
        levels: f.mesh.levels.clone(),
    };
    let extras = serde_json::json!({
        "floating_origin": cam.floating_origin,
        "floating_origin_grid": cam.floating_origin_grid,
        "note": "POSITION is metres from the floating origin, x east, y north, z up; \
                 camera.json's view_proj applies to it as stored (the node's rotation \
                 only turns it y-up for viewers)",
    });
    out.push(("frame.glb".into(), glb::write(&tris, &f.layout, extras)?));
    out.push(("camera.json".into(), to_json(&cam)?));

    let res = &f.resources;
    let mut frame_file = FrameFile {
        scene: src.scene.into(),
        lod: f.lod.clone(),
        triangles: f.triangle_count(),
        effects: f.effects.list(),
        shading: f.params.clone(),
        background: f.background,
        height_ramp: [f.height_ramp.0, f.height_ramp.1],
        cell: f.uniforms.cell,
        vertical_scale: f.uniforms.vertical_scale,
        varyings: glb::varyings(&f.layout)
            .iter()
            .map(|v| VaryingFile {
                attribute: v.name.into(),
                components: v.components,
                interpolation: if v.linear { "linear" } else { "perspective" }.into(),
            })
            .collect(),
        sun_direction: f.params.sun_direction().map(|c| c as f32),
        level_palette: crate::shade::level_tint::PALETTE.to_vec(),
        levels: res
            .levels
            .iter()
            .flatten()
            .map(|i| LevelFile {
                level: i.level,
                origin: i.origin,
                size: i.size,
                morph: i.morph,
            })
            .collect(),
        toroids: vec![],
        normal_maps: vec![],
        lightmap: None,
    };
    let mut toroid_layers = vec![];
    if let Some(cm) = src.clipmap {
        for lv in cm.levels() {
            let t = &lv.heights;
            frame_file.toroids.push(ToroidFile {
                level: lv.level,
                size: t.size(),
                origin: t.origin(),
                active: lv.is_active(),
            });
            toroid_layers.push(FloatLayer::single(
                &format!("level{}", lv.level),
                "H",
                t.size(),
                t.size(),
                t.data().to_vec(),
            ));
        }
    }
    let mut effect_layers = vec![];
    for (l, m) in res.normal_maps.iter().enumerate() {
        if let Some(m) = m {
            frame_file.normal_maps.push(NormalMapFile {
                level: l,
                origin: m.origin,
                size: m.size,
            });
            let axis = |k: usize| m.data.iter().map(|n| n[k]).collect::<Vec<f32>>();
            effect_layers.push(FloatLayer {
                name: format!("normal{l}"),
                width: m.size[0],
                height: m.size[1],
                channels: vec![
                    ("X".into(), axis(0)),
                    ("Y".into(), axis(1)),
                    ("Z".into(), axis(2)),
                ],
            });
        }
    }
    if let Some(lm) = &res.lightmap {
        let levels = &lm.pyramid.levels;
        frame_file.lightmap = Some(LightmapFile {
            scale: lm.scale,
            rays: lm.rays,
            filter: lm.pyramid.filter,
            levels: levels.iter().map(|p| [p.width, p.height]).collect(),
        });
        for (k, p) in levels.iter().enumerate() {
            effect_layers.push(FloatLayer::single(
                &format!("lightmap{k}"),
                "L",
                p.width,
                p.height,
                p.data.clone(),
            ));
        }
    }
    out.push(("frame.json".into(), to_json(&frame_file)?));
    let (vert, frag) = glsl::shaders(&frame_file.effects, &frame_file.varyings);
    out.push(("terrain.vert".into(), vert.into_bytes()));
    out.push(("terrain.frag".into(), frag.into_bytes()));
    let (vert, frag) = glsl::shaders_in(
        glsl::Dialect::Es300,
        &frame_file.effects,
        &frame_file.varyings,
    );
    out.push(("terrain-es.vert".into(), vert.into_bytes()));
    out.push(("terrain-es.frag".into(), frag.into_bytes()));
    let wgsl = wgsl::shader(&frame_file.effects, &frame_file.varyings);
    out.push(("terrain.wgsl".into(), wgsl.into_bytes()));
    out.push(("colour.png".into(), src.image.png()?));
    let (w, h) = (src.image.width as usize, src.image.height as usize);
    out.push((
        "depth.exr".into(),
        exr::write(&[FloatLayer::single(
            "depth",
            "Z",
            w,
            h,
            src.image.depth.clone(),
        )])?,
    ));
    out.push((
        "depth.f32".into(),
        src.image
            .depth
            .iter()
            .flat_map(|d| d.to_le_bytes())
            .collect(),
    ));
    if !toroid_layers.is_empty() {
        out.push(("clipmap.exr".into(), exr::write(&toroid_layers)?));
    }
    if !effect_layers.is_empty() {
        out.push(("effects.exr".into(), exr::write(&effect_layers)?));
    }
    if let Some(text) = src.scene_text {
        out.push(("scene.toml".into(), text.as_bytes().to_vec()));
    }
    let manifest = manifest(src.scene, vec![], &out);
    out.push(("manifest.json".into(), to_json(&manifest)?));
    Ok(out)
}

/// The manifest of `files` (names and bytes).
pub fn manifest(scene: &str, frames: Vec<String>, files: &[(String, Vec<u8>)]) -> Manifest {
    Manifest {
        format: FORMAT.into(),
        version: VERSION,
        terraclip: env!("CARGO_PKG_VERSION").into(),
        scene: scene.into(),
        rules: RULES.into(),
        frames,
        files: files
            .iter()
            .map(|(name, bytes)| FileEntry {
                name: name.clone(),
                bytes: bytes.len() as u64,
                sha256: hex(&Sha256::digest(bytes)),
            })
            .collect(),
    }
}

/// Writes `files` (paths relative to `dir`) as the folder `dir`: first into
/// a temporary folder beside it, then renamed into place. An existing
/// export at `dir` is replaced; anything else there is left alone and is
/// an error.
pub fn write_dir(dir: &Path, files: &[(String, Vec<u8>)]) -> Result<()> {
    if dir.exists() {
        let is_export = dir.join("manifest.json").is_file();
        let empty = std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .next()
            .is_none();
        if !is_export && !empty {
            return Err(Error::file(
                dir,
                "exists and is not a terraclip export (no manifest.json): not overwritten",
            ));
        }
    }
    // One temporary per call: threads of one process share its id.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = temp_path(dir, &format!("-{call}"))?;
    let result = (|| -> std::io::Result<()> {
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp)?;
        }
        std::fs::create_dir_all(&tmp)?;
        for (name, bytes) in files {
            let p = tmp.join(name);
            if let Some(parent) = p.parent() {
                std::fs::create_dir_all(parent)?;
            }
            std::fs::write(&p, bytes)?;
        }
        if dir.exists() {
            let old = temp_path(dir, &format!("-{call}-old")).map_err(std::io::Error::other)?;
            std::fs::rename(dir, &old)?;
            std::fs::rename(&tmp, dir)?;
            std::fs::remove_dir_all(&old)
        } else {
            std::fs::rename(&tmp, dir)
        }
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_dir_all(&tmp);
        Error::io(dir, e)
    })
}

/// An export read back: the frame as a plain mesh (positions and
/// varyings, no LOD vertices), with everything needed to draw and compare
/// it.
pub struct Exported {
    /// The folder.
    pub dir: PathBuf,
    /// `manifest.json`.
    pub manifest: Manifest,
    /// `camera.json`.
    pub camera: CameraFile,
    /// `frame.json`.
    pub info: FrameFile,
    /// The frame, ready for either back end.
    pub frame: Frame,
    /// The reference colour and depth.
    pub image: Image,
    /// Each toroid's heights (`clipmap.exr`), in `info.toroids` order.
    pub toroids: Vec<Vec<f32>>,
}

/// Reads `name` in `dir`, checked against the manifest's length and hash.
/// The manifest of the export folder `dir`, in a format this terraclip
/// reads.
fn open_manifest(dir: &Path) -> Result<Manifest> {
    let mpath = dir.join("manifest.json");
    if !dir.is_dir() {
        return Err(Error::file(dir, "not a folder (an export is a folder)"));
    }
    let mbytes = std::fs::read(&mpath).map_err(|e| Error::io(&mpath, e))?;
    let manifest: Manifest = parse(dir, "manifest.json", &mbytes)?;
    if manifest.format != FORMAT || manifest.version != VERSION {
        return Err(Error::file(
            &mpath,
            format!(
                "format '{}' version {}, where this terraclip reads '{FORMAT}' version {VERSION}",
                manifest.format, manifest.version
            ),
        ));
    }
    // `merge --dir` copies every listed file into the joined folder: a
    // name that climbs out (`..`) or is absolute would read and write
    // outside both folders.
    let names = manifest
        .files
        .iter()
        .map(|e| &e.name)
        .chain(&manifest.frames);
    if let Some(bad) = names.into_iter().find(|n| !inside(n)) {
        return Err(Error::file(
            &mpath,
            format!("lists '{bad}', which is not a path inside the export's folder"),
        ));
    }
    // A name listed twice may carry two hashes, and `merge --dir` would
    // write it twice: the manifest is damaged.
    let mut seen = std::collections::HashSet::new();
    if let Some(twice) = manifest
        .files
        .iter()
        .map(|e| &e.name)
        .chain(&manifest.frames)
        .find(|n| !seen.insert(*n))
    {
        return Err(Error::file(&mpath, format!("lists '{twice}' twice")));
    }
    Ok(manifest)
}

/// Whether `name` is a relative path of plain names (no `.`, `..`, root or
/// drive), which stays inside the folder it is joined to.
fn inside(name: &str) -> bool {
    let mut parts = Path::new(name).components().peekable();
    parts.peek().is_some() && parts.all(|c| matches!(c, std::path::Component::Normal(_)))
}

fn checked(dir: &Path, m: &Manifest, name: &str) -> Result<Vec<u8>> {
    let path = dir.join(name);
    let entry = m
        .files
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| Error::file(&path, "not listed in manifest.json"))?;
    let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
    if bytes.len() as u64 != entry.bytes {
        return Err(Error::file(
            &path,
            format!(
                "{} bytes where manifest.json says {} (truncated or replaced)",
                bytes.len(),
                entry.bytes
            ),
        ));
    }
    if hex(&Sha256::digest(&bytes)) != entry.sha256 {
        return Err(Error::file(
            &path,
            "its SHA-256 differs from manifest.json's (the file was changed)",
        ));
    }
    Ok(bytes)
}

fn parse<T: serde::de::DeserializeOwned>(dir: &Path, name: &str, bytes: &[u8]) -> Result<T> {
    serde_json::from_slice(bytes)
        .map_err(|e| Error::file(dir.join(name), format!("invalid JSON: {e}")))
}

/// The layer named `name` of `layers` (read from `path`), `w`×`h`.
fn layer<'a>(
    path: &Path,
    layers: &'a [FloatLayer],
    name: &str,
    size: [usize; 2],
) -> Result<&'a FloatLayer> {
    let l = layers
        .iter()
        .find(|l| l.name == name)
        .ok_or_else(|| Error::file(path, format!("no layer '{name}'")))?;
    if [l.width, l.height] != size {
        return Err(Error::file(
            path,
            format!(
                "layer '{name}' is {}x{}, frame.json says {}x{}",
                l.width, l.height, size[0], size[1]
            ),
        ));
    }
    Ok(l)
}

fn channel<'a>(path: &Path, l: &'a FloatLayer, name: &str) -> Result<&'a [f32]> {
    l.channel(name)
        .ok_or_else(|| Error::file(path, format!("layer '{}' has no channel '{name}'", l.name)))
}

/// Reads the one-frame export in `dir`, checking every file against the
/// manifest first; a folder of frames is an error that names them.
pub fn read(dir: &Path) -> Result<Exported> {
    let manifest = open_manifest(dir)?;
    if let Some(first) = manifest.frames.first() {
        // The manifest is what says so: named, so that a damaged one is.
        return Err(Error::file(
            dir.join("manifest.json"),
            format!(
                "lists {} frame folders (an export of a path); name one of them, such as {}",
                manifest.frames.len(),
                dir.join(first).display()
            ),
        ));
    }
    let camera: CameraFile = parse(dir, "camera.json", &checked(dir, &manifest, "camera.json")?)?;
    let info: FrameFile = parse(dir, "frame.json", &checked(dir, &manifest, "frame.json")?)?;
    let fpath = dir.join("frame.json");
    let effects = Effects::from_list(&info.effects).map_err(|e| Error::file(&fpath, e))?;
    info.shading
        .validate()
        .map_err(|(field, why)| Error::file(&fpath, format!("{field}: {why}")))?;
    // Levels index per-level tables: a clipmap has at most 32.
    let levels = info.levels.iter().map(|l| l.level);
    let levels = levels.chain(info.normal_maps.iter().map(|m| m.level));
    if let Some(l) = levels
        .chain(info.toroids.iter().map(|t| t.level))
        .find(|&l| l >= 32)
    {
        return Err(Error::file(
            &fpath,
            format!("level {l}: levels are 0 to 31"),
        ));
    }
    let layout = Layout::new(&effects);
    let want: Vec<&str> = glb::varyings(&layout).iter().map(|v| v.name).collect();
    let have: Vec<&str> = info.varyings.iter().map(|v| v.attribute.as_str()).collect();
    if want != have {
        return Err(Error::file(
            dir.join("frame.json"),
            format!("varyings {have:?} are not what its effects make ({want:?})"),
        ));
    }
    let gpath = dir.join("frame.glb");
    let tris = glb::read(&gpath, &checked(dir, &manifest, "frame.glb")?, &layout)?;
    if tris.levels.len() != info.triangles {
        return Err(Error::file(
            &gpath,
            format!(
                "{} triangles where frame.json says {}",
                tris.levels.len(),
                info.triangles
            ),
        ));
    }

    let (w, h) = (camera.width as usize, camera.height as usize);
    let cpath = dir.join("colour.png");
    let (cw, ch, rgba) = {
        let bytes = checked(dir, &manifest, "colour.png")?;
        let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
            .map_err(|e| Error::file(&cpath, format!("unreadable PNG: {e}")))?
            .to_rgba8();
        (img.width(), img.height(), img.into_raw())
    };
    if (cw, ch) != (camera.width, camera.height) {
        return Err(Error::file(
            &cpath,
            format!("{cw}x{ch}, camera.json says {w}x{h}"),
        ));
    }
    let dpath = dir.join("depth.f32");
    let dbytes = checked(dir, &manifest, "depth.f32")?;
    if dbytes.len() != 4 * w * h {
        return Err(Error::file(
            &dpath,
            format!(
                "{} bytes, {w}x{h} Depth32Float is {}",
                dbytes.len(),
                4 * w * h
            ),
        ));
    }
    let depth = le_f32s(&dbytes);
    let epath = dir.join("depth.exr");
    let dl = exr::read(&epath, &checked(dir, &manifest, "depth.exr")?)?;
    let z = channel(&epath, layer(&epath, &dl, "depth", [w, h])?, "Z")?;
    if z.iter()
        .zip(&depth)
        .any(|(a, b)| a.to_bits() != b.to_bits())
    {
        return Err(Error::file(&epath, "differs from depth.f32"));
    }

    let mut toroids = vec![];
    if !info.toroids.is_empty() {
        let p = dir.join("clipmap.exr");
        let layers = exr::read(&p, &checked(dir, &manifest, "clipmap.exr")?)?;
        for t in &info.toroids {
            let l = layer(&p, &layers, &format!("level{}", t.level), [t.size, t.size])?;
            toroids.push(channel(&p, l, "H")?.to_vec());
        }
    }
    let mut resources = Resources::default();
    for l in &info.levels {
        if resources.levels.len() <= l.level {
            resources.levels.resize(l.level + 1, None);
        }
        resources.levels[l.level] = Some(LevelInfo {
            level: l.level,
            origin: l.origin,
            size: l.size,
            morph: l.morph,
        });
    }
    if !info.normal_maps.is_empty() || info.lightmap.is_some() {
        let p = dir.join("effects.exr");
        let layers = exr::read(&p, &checked(dir, &manifest, "effects.exr")?)?;
        for m in &info.normal_maps {
            let l = layer(&p, &layers, &format!("normal{}", m.level), m.size)?;
            let [x, y, z] = ["X", "Y", "Z"].map(|c| channel(&p, l, c));
            let (x, y, z) = (x?, y?, z?);
            if resources.normal_maps.len() <= m.level {
                resources.normal_maps.resize(m.level + 1, None);
            }
            resources.normal_maps[m.level] = Some(NormalMap {
                origin: m.origin,
                size: m.size,
                data: (0..x.len()).map(|i| [x[i], y[i], z[i]]).collect(),
            });
        }
        if let Some(lm) = &info.lightmap {
            let levels = lm
                .levels
                .iter()
                .enumerate()
                .map(|(k, &size)| {
                    let l = layer(&p, &layers, &format!("lightmap{k}"), size)?;
                    let data = channel(&p, l, "L")?.to_vec();
                    let n = data.len();
                    Ok(PyramidLevel::from_parts(
                        size[0],
                        size[1],
                        data,
                        vec![false; n],
                    ))
                })
                .collect::<Result<Vec<_>>>()?;
            resources.lightmap = Some(Lightmap {
                scale: lm.scale,
                pyramid: Pyramid::from_levels(levels, lm.filter),
                rays: lm.rays,
            });
        }
    }
    let (frame_w, frame_h) = (camera.width, camera.height);
    let frame = Frame {
        width: camera.width,
        height: camera.height,
        background: info.background,
        lod: info.lod.clone(),
        uniforms: VertexUniforms {
            origin: camera.floating_origin_grid,
            cell: info.cell,
            vertical_scale: info.vertical_scale,
            view_proj: camera.view_proj,
            eye: camera.eye_relative,
        },
        mesh: LodMesh {
            vertices: vec![],
            levels: tris.levels,
            level_info: resources.levels.clone(),
        },
        effects,
        params: info.shading.clone(),
        layout,
        positions: tris.positions,
        attrs: tris.attrs,
        resources,
        height_ramp: (info.height_ramp[0], info.height_ramp[1]),
    };
    Ok(Exported {
        dir: dir.to_path_buf(),
        manifest,
        camera,
        info,
        frame,
        image: Image {
            width: frame_w,
            height: frame_h,
            rgba,
            depth,
        },
        toroids,
    })
}

/// `session`'s frame for `camera`, drawn on the CPU, and its export's
/// files ([`files`]); the session's LOD scheme moves to `camera` as a
/// renderer's would.
fn view_files(
    session: &mut crate::render::Session,
    name: &str,
    text: Option<&str>,
    camera: &Camera,
) -> Result<(Frame, Files)> {
    let mut passes = crate::frame::stats::Passes::default();
    let (frame, _) = session.frame(camera, &mut passes)?;
    let opts = crate::render::RenderOptions::default();
    let (image, _) = crate::render::draw(&frame, &opts, &mut passes);
    let src = Source {
        scene: name,
        scene_text: text,
        camera,
        frame: &frame,
        image: &image,
        world: &session.world,
        clipmap: session.lod.clipmap(),
    };
    let files = files(&src)?;
    Ok((frame, files))
}

/// One exported frame, as `terraclip export --json` reports it.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FrameSummary {
    /// Its folder inside the export (`.` for a one-frame export).
    pub folder: String,
    /// Triangles in `frame.glb`.
    pub triangles: usize,
    /// Levels with triangles in the frame.
    pub levels_drawn: usize,
    /// SHA-256 of `colour.png`.
    pub colour_sha256: String,
    /// SHA-256 of `depth.f32`.
    pub depth_sha256: String,
}

/// What [`scene`] wrote.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Written {
    /// The export folder.
    pub dir: PathBuf,
    /// The scene's name.
    pub scene: String,
    /// Each frame written.
    pub frames: Vec<FrameSummary>,
    /// Files written, manifests included.
    pub files: usize,
    /// Their bytes.
    pub bytes: u64,
}

/// Exports `frames` views of `scene` along the path `check-gpu` flies
/// ([`crate::camera::path_camera`], `step` metres a frame) to
/// `dir`: one frame's files at its top, or with more than one frame a
/// folder `frame-NNNN` each and a manifest over them all. The scene's
/// LOD scheme is kept across frames, as a renderer's would be.
pub fn scene(
    scene: &crate::scene::Scene,
    name: &str,
    text: Option<&str>,
    frames: usize,
    step: f64,
    dir: &Path,
) -> Result<Written> {
    scene_part(scene, name, text, frames, step, Shard::WHOLE, dir)
}

/// [`scene`]'s part `shard` of the frames ([`Shard::run_of`]), always as
/// frame folders when there are several frames; `merge` joins the parts
/// ([`join`]).
pub fn scene_part(
    scene: &crate::scene::Scene,
    name: &str,
    text: Option<&str>,
    frames: usize,
    step: f64,
    shard: Shard,
    dir: &Path,
) -> Result<Written> {
    if frames == 0 {
        return Err(Error::value("--frames", "must be at least 1"));
    }
    if frames < shard.count {
        return Err(Error::value(
            "--shard",
            format!(
                "{} parts of {frames} frame(s) would leave parts with none: use at most {frames}",
                shard.count
            ),
        ));
    }
    // A part is a run of frame folders, even of one frame, so that `merge`
    // can put the parts' folders side by side.
    let folders_each = frames > 1;
    let mut session = crate::render::Session::new(scene, &mut Default::default())?;
    let base = scene.camera();
    let mut all: Vec<(String, Vec<u8>)> = vec![];
    let mut summaries = vec![];
    let mut folders = vec![];
    let mine = shard.run_of(frames);
    for i in 0..mine.end {
        let camera = crate::camera::path_camera(&base, i, step);
        // The scheme moves through the frames before this part's as it
        // would in one run.
        if i < mine.start {
            session.update(&camera, &mut Default::default());
            continue;
        }
        let (frame, files) = view_files(&mut session, name, text, &camera)?;
        let folder = if !folders_each {
            ".".to_string()
        } else {
            format!("frame-{i:04}")
        };
        let sha = |n: &str| {
            files
                .iter()
                .find(|f| f.0 == n)
                .map_or(String::new(), |f| hex(&Sha256::digest(&f.1)))
        };
        summaries.push(FrameSummary {
            folder: folder.clone(),
            triangles: frame.triangle_count(),
            levels_drawn: frame.mesh.level_info.iter().flatten().count(),
            colour_sha256: sha("colour.png"),
            depth_sha256: sha("depth.f32"),
        });
        if !folders_each {
            all = files;
        } else {
            all.extend(files.into_iter().map(|(n, b)| (format!("{folder}/{n}"), b)));
            folders.push(folder);
        }
    }
    written(name, folders_each.then_some(folders), all, summaries, dir)
}

/// Writes `all` (with a manifest over the `folders` of a path's frames)
/// as the export `dir`, and says what it wrote.
fn written(
    name: &str,
    folders: Option<Vec<String>>,
    mut all: Files,
    frames: Vec<FrameSummary>,
    dir: &Path,
) -> Result<Written> {
    if let Some(folders) = folders {
        let m = manifest(name, folders, &all);
        all.push(("manifest.json".into(), to_json(&m)?));
    }
    write_dir(dir, &all)?;
    Ok(Written {
        dir: dir.to_path_buf(),
        scene: name.into(),
        frames,
        files: all.len(),
        bytes: all.iter().map(|f| f.1.len() as u64).sum(),
    })
}

/// Joins the folders the parts of a sharded export wrote (`parts`, their
/// JSON in part order, read from the files `names`) into the export one
/// run writes, at `dir`. Every file is checked against its part's manifest
/// first; where a folder disagrees with its part's JSON, the error names
/// both.
pub fn join(parts: &[Written], names: &[&str], dir: &Path) -> Result<Written> {
    let first = parts
        .first()
        .ok_or_else(|| Error::value("merge", "no parts"))?;
    let (mut all, mut folders, mut frames): (Files, Vec<String>, Vec<FrameSummary>) =
        (vec![], vec![], vec![]);
    for (p, name) in parts.iter().zip(names) {
        if p.scene != first.scene {
            return Err(Error::file(
                &p.dir,
                format!(
                    "an export of {}, where the first part's is of {} ({name})",
                    p.scene, first.scene
                ),
            ));
        }
        let m = open_manifest(&p.dir)?;
        let listed: Vec<&str> = p.frames.iter().map(|f| f.folder.as_str()).collect();
        if m.frames != listed {
            return Err(Error::file(
                p.dir.join("manifest.json"),
                format!(
                    "frames {:?}, where the part's JSON ({name}) says {listed:?}",
                    m.frames
                ),
            ));
        }
        for e in &m.files {
            all.push((e.name.clone(), checked(&p.dir, &m, &e.name)?));
        }
        folders.extend(m.frames);
        frames.extend(p.frames.iter().cloned());
    }
    for (k, f) in folders.iter().enumerate() {
        if *f != format!("frame-{k:04}") {
            return Err(Error::value(
                "merge",
                format!("{f} is where frame-{k:04} should be: parts missing or out of order"),
            ));
        }
    }
    written(&first.scene, Some(folders), all, frames, dir)
}

/// What [`conformance_pack`] wrote.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PackWritten {
    /// The pack's folder.
    pub dir: PathBuf,
    /// The scenes exported, one folder each, in name order.
    pub scenes: Vec<String>,
    /// Files written, manifests and README included.
    pub files: usize,
    /// Their bytes.
    pub bytes: u64,
}

/// The conformance pack's README: for the people who draw its frames.
const PACK_README: &str = include_str!("pack_readme.md");

/// Exports every scene of the golden folder `golden` into `out` (a folder
/// each, as `export` writes one frame), with a README for the pack's users
/// and a manifest over it all: a conformance pack another renderer is
/// checked against with `terraclip compare`. Written whole, then renamed
/// into place.
pub fn conformance_pack(golden: &Path, out: &Path) -> Result<PackWritten> {
    let mut all: Vec<(String, Vec<u8>)> = vec![];
    let mut scenes = vec![];
    for path in crate::scene::files_in(golden)? {
        let name = path
            .file_stem()
            .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let scene = crate::scene::Scene::load(&path)?;
        let mut session = crate::render::Session::new(&scene, &mut Default::default())?;
        let (_, files) = view_files(&mut session, &name, Some(&text), &scene.camera())?;
        all.extend(files.into_iter().map(|(n, b)| (format!("{name}/{n}"), b)));
        scenes.push(name);
    }
    all.push(("README.md".into(), PACK_README.as_bytes().to_vec()));
    let m = manifest("conformance pack", scenes.clone(), &all);
    all.push(("manifest.json".into(), to_json(&m)?));
    write_dir(out, &all)?;
    Ok(PackWritten {
        dir: out.to_path_buf(),
        scenes,
        files: all.len(),
        bytes: all.iter().map(|f| f.1.len() as u64).sum(),
    })
}
