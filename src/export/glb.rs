//! The frame's triangles as glTF 2.0 binary, through the `gltf` crate's
//! JSON types and GLB container: written for other renderers, and read back
//! by `compare` and the round-trip tests.
//!
//! The vertex data are the vertex stage's outputs, bit for bit: POSITION is
//! the camera-relative f32 position, and each varying the listed effects
//! use is an application-specific attribute (`_ALBEDO`, `_NORMAL`, ...).
//! Triangles are unindexed (three vertices each, as the CPU draws them) and
//! split into one primitive per run of triangles on one level, in draw
//! order, so drawing the primitives in order draws the frame's triangles in
//! its order, which decides depth ties.

use crate::error::{Error, Result};
use crate::shade::Layout;
use gltf::json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use std::collections::BTreeMap;
use std::path::Path;

/// One varying as an attribute: its glTF name, its offset among a vertex's
/// varyings and its number of components.
pub struct Varying {
    /// The attribute's name (with the leading underscore glTF asks of
    /// application-specific attributes).
    pub name: &'static str,
    /// Offset in `Layout` order.
    pub offset: usize,
    /// Components (1 to 3).
    pub components: usize,
    /// Screen-linear (true) or perspective-correct.
    pub linear: bool,
}

/// The varyings `layout` holds, in its order.
pub fn varyings(layout: &Layout) -> Vec<Varying> {
    let named = [
        ("_ALBEDO", layout.albedo, 3),
        ("_NORMAL", layout.normal, 3),
        ("_LEVEL_UV", layout.uv, 2),
        ("_MORPH_ALPHA", layout.alpha, 1),
        ("_FOG", layout.fog, 1),
        ("_VIEW", layout.view, 3),
        ("_BARY", layout.bary, 3),
        ("_EDGE", layout.edge, 3),
    ];
    let mut v: Vec<Varying> = named
        .iter()
        .filter_map(|&(name, at, components)| {
            at.map(|offset| Varying {
                name,
                offset,
                components,
                linear: layout.linear[offset],
            })
        })
        .collect();
    v.sort_by_key(|v| v.offset);
    v
}

/// What the GLB holds: per vertex a position and `layout.len()` varyings,
/// per triangle its level.
pub struct Triangles {
    /// Camera-relative positions, three a triangle.
    pub positions: Vec<[f32; 3]>,
    /// `layout.len()` varyings per vertex.
    pub attrs: Vec<f32>,
    /// The level of each triangle.
    pub levels: Vec<u32>,
}

fn extras(v: serde_json::Value) -> json::Extras {
    serde_json::value::to_raw_value(&v).ok()
}

/// Appends `data` to the binary chunk as one accessor of `components`-wide
/// f32 vectors (with its bounds, which glTF requires of POSITION).
fn push_accessor(
    root: &mut json::Root,
    buffer: json::Index<json::Buffer>,
    bin: &mut Vec<u8>,
    data: &[f32],
    components: usize,
) -> json::Index<json::Accessor> {
    let offset = bin.len();
    bin.extend(data.iter().flat_map(|v| v.to_le_bytes()));
    let view = root.push(json::buffer::View {
        buffer,
        byte_length: USize64::from(4 * data.len()),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: Some(Valid(json::buffer::Target::ArrayBuffer)),
        extensions: None,
        extras: None,
    });
    let mut lo = vec![f32::INFINITY; components];
    let mut hi = vec![f32::NEG_INFINITY; components];
    for v in data.chunks_exact(components) {
        for k in 0..components {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    let bound = |b: Vec<f32>| {
        let finite = b.iter().all(|v| v.is_finite());
        finite.then(|| serde_json::json!(b))
    };
    let type_ = match components {
        1 => json::accessor::Type::Scalar,
        2 => json::accessor::Type::Vec2,
        3 => json::accessor::Type::Vec3,
        _ => json::accessor::Type::Vec4,
    };
    root.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64::from(data.len() / components),
        component_type: Valid(json::accessor::GenericComponentType(
            json::accessor::ComponentType::F32,
        )),
        extensions: None,
        extras: None,
        type_: Valid(type_),
        min: bound(lo),
        max: bound(hi),
        name: None,
        normalized: false,
        sparse: None,
    })
}

/// The GLB bytes of the frame's triangles. `node_extras` go on the one node
/// (the floating origin); the node turns terraclip's z-up metres into
/// glTF's y-up for viewers, while the mesh data stay as the vertex stage
/// made them (camera.json's matrix applies to them directly).
pub fn write(t: &Triangles, layout: &Layout, node_extras: serde_json::Value) -> Result<Vec<u8>> {
    let k = layout.len();
    let vary = varyings(layout);
    let mut root = json::Root::default();
    root.asset.generator = Some(format!("terraclip {}", env!("CARGO_PKG_VERSION")));
    let buffer = root.push(json::Buffer {
        byte_length: USize64(0),
        name: None,
        uri: None,
        extensions: None,
        extras: None,
    });
    let mut bin = vec![];
    let mut primitives = vec![];
    for (l, t0, t1) in crate::lod::LodMesh::level_runs(&t.levels) {
        let (v0, v1) = (3 * t0, 3 * t1);
        let pos: Vec<f32> = t.positions[v0..v1].iter().flatten().copied().collect();
        let mut attributes = BTreeMap::new();
        let p = push_accessor(&mut root, buffer, &mut bin, &pos, 3);
        attributes.insert(Valid(json::mesh::Semantic::Positions), p);
        for v in &vary {
            let data: Vec<f32> = t.attrs[v0 * k..v1 * k]
                .chunks_exact(k)
                .flat_map(|a| a[v.offset..v.offset + v.components].iter().copied())
                .collect();
            let a = push_accessor(&mut root, buffer, &mut bin, &data, v.components);
            let name = v.name.trim_start_matches('_').to_string();
            attributes.insert(Valid(json::mesh::Semantic::Extras(name)), a);
        }
        primitives.push(json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: extras(serde_json::json!({
                "name": format!("level {l}, triangles {t0}..{t1}"),
                "level": l,
                "first_triangle": t0,
            })),
            indices: None,
            material: None,
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        });
    }
    root.buffers[buffer.value()].byte_length = USize64::from(bin.len());
    let mesh = root.push(json::Mesh {
        extensions: None,
        extras: None,
        name: Some("terrain".into()),
        primitives,
        weights: None,
    });
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let node = root.push(json::Node {
        mesh: Some(mesh),
        name: Some("terrain (z-up metres, camera-relative)".into()),
        rotation: Some(json::scene::UnitQuaternion([-h, 0.0, 0.0, h])),
        extras: extras(node_extras),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: None,
        extras: None,
        name: Some("frame".into()),
        nodes: vec![node],
    });
    root.scene = Some(scene);
    let text = json::serialize::to_vec(&root).map_err(|e| Error::value("glTF", e.to_string()))?;
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // to_vec works the length out itself
        },
        json: text.into(),
        bin: Some(bin.into()),
    };
    glb.to_vec()
        .map_err(|e| Error::value("glTF", e.to_string()))
}

/// Reads `bytes` (the file `path`) back into triangles of `layout`; every
/// flaw is an error naming the file and the primitive or attribute.
pub fn read(path: &Path, bytes: &[u8], layout: &Layout) -> Result<Triangles> {
    let bad = |why: String| Error::file(path, why);
    // The crate subtracts the header from its stated length unchecked.
    let stated = bytes
        .get(8..12)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    if bytes.get(..4) != Some(b"glTF") || stated != Some(bytes.len()) {
        return Err(bad(format!(
            "not a glTF binary of its stated length ({} bytes, header says {})",
            bytes.len(),
            stated.map_or("nothing".into(), |s| s.to_string())
        )));
    }
    let g = gltf::Gltf::from_slice(bytes).map_err(|e| bad(format!("invalid glTF: {e}")))?;
    let blob = g.blob.as_deref().unwrap_or(&[]);
    let mesh = g.meshes().next().ok_or_else(|| bad("no mesh".into()))?;
    let k = layout.len();
    let vary = varyings(layout);
    let mut t = Triangles {
        positions: vec![],
        attrs: vec![],
        levels: vec![],
    };
    for prim in mesh.primitives() {
        let i = prim.index();
        if prim.mode() != gltf::mesh::Mode::Triangles || prim.indices().is_some() {
            return Err(bad(format!("primitive {i}: not unindexed triangles")));
        }
        let level = prim
            .extras()
            .as_ref()
            .and_then(|e| serde_json::from_str::<serde_json::Value>(e.get()).ok())
            .and_then(|v| v["level"].as_u64())
            .ok_or_else(|| bad(format!("primitive {i}: no level in its extras")))?;
        let get = |semantic: &gltf::Semantic, comps: usize, what: &str| {
            let a = prim
                .get(semantic)
                .ok_or_else(|| bad(format!("primitive {i}: no {what} attribute")))?;
            floats(&a, blob, comps).map_err(|why| bad(format!("primitive {i}, {what}: {why}")))
        };
        let pos = get(&gltf::Semantic::Positions, 3, "POSITION")?;
        let n = pos.len() / 3;
        if n % 3 != 0 {
            return Err(bad(format!(
                "primitive {i}: {n} vertices, not whole triangles"
            )));
        }
        let start = t.positions.len();
        t.positions
            .extend(pos.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        t.attrs.resize((start + n) * k, 0.0);
        for v in &vary {
            let name = v.name.trim_start_matches('_');
            let data = get(&gltf::Semantic::Extras(name.into()), v.components, v.name)?;
            if data.len() != n * v.components {
                return Err(bad(format!(
                    "primitive {i}, {}: {} values for {n} vertices",
                    v.name,
                    data.len()
                )));
            }
            for (j, c) in data.chunks_exact(v.components).enumerate() {
                let at = (start + j) * k + v.offset;
                t.attrs[at..at + v.components].copy_from_slice(c);
            }
        }
        let level =
            u32::try_from(level).map_err(|_| bad(format!("primitive {i}: level {level}")))?;
        t.levels.extend(std::iter::repeat_n(level, n / 3));
    }
    Ok(t)
}

/// An accessor's tightly packed f32 vectors of `comps` components.
fn floats(a: &gltf::Accessor, blob: &[u8], comps: usize) -> std::result::Result<Vec<f32>, String> {
    if a.data_type() != gltf::accessor::DataType::F32 || a.dimensions().multiplicity() != comps {
        return Err(format!("not {comps} f32 components"));
    }
    let view = a.view().ok_or("no buffer view")?;
    if view.stride().is_some_and(|s| s != 4 * comps) {
        return Err("interleaved (a stride) where terraclip writes none".into());
    }
    let start = view.offset() + a.offset();
    let len = 4 * comps * a.count();
    let end = start.checked_add(len).ok_or("length overflows")?;
    if end > view.offset() + view.length() || end > blob.len() {
        return Err(format!(
            "bytes {start}..{end} lie past its view or the binary chunk ({} bytes)",
            blob.len()
        ));
    }
    Ok(super::le_f32s(&blob[start..end]))
}
