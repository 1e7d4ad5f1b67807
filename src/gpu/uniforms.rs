//! The data the CPU hands the shader, as `#[repr(C)]` structs that mirror
//! `shaders/terrain.wgsl` field for field: the `Globals` and `Draw`
//! uniform blocks, and the record of a passed-through vertex. Every field
//! is a 16-byte vector (or an array of such structs), so `repr(C)` puts each
//! where WGSL's uniform layout does; a test reads the shader with naga and
//! checks every name, offset and size.

use bytemuck::{Pod, Zeroable};

/// Levels the uniform block describes.
pub const MAX_LEVELS: usize = 32;

/// One clipmap level's entry in [`Globals`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct Level {
    /// Window origin (level texels), normal-map origin (half-texels).
    pub origin: [i32; 4],
    /// Normal-map size x, y, atlas row, present (0/1).
    pub nm: [i32; 4],
    /// Lightmap level: atlas row, width, height.
    pub lm: [i32; 4],
    /// Albedo under level-tint.
    pub tint: [f32; 4],
}

/// What every draw of a frame shares.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct Globals {
    /// Column-major, camera-relative.
    pub view_proj: [[f32; 4]; 4],
    /// Eye x, y, z and 1.0 (see the vertex normals).
    pub eye: [f32; 4],
    /// Cell x, cell y, vertical scale, fog rate (log2(e) · density).
    pub cell: [f32; 4],
    /// Height-ramp low, span, ambient, specular strength.
    pub ramp: [f32; 4],
    pub sun: [f32; 4],
    pub fog_colour: [f32; 4],
    pub wire_colour: [f32; 4],
    /// Target width, height.
    pub size: [f32; 4],
    /// n, lightmap levels, lightmap scale, specular squarings.
    pub ints: [i32; 4],
    pub levels: [Level; MAX_LEVELS],
}

/// One draw: a level's strips or one footprint instance, or a run of
/// passed-through triangles.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct Draw {
    /// Level, spacing g, n, mode (0 passthrough, 1 strips, 2 footprint).
    pub level: [i32; 4],
    /// Window origin x, y (level texels); toroid phase x, y (origin mod n).
    pub origin: [i32; 4],
    /// origin·g − floating origin (x, and y flipped); instance offset x, y.
    pub rel: [i32; 4],
    /// Viewer x, y (level texels from the origin), half, width.
    pub morph: [f32; 4],
    pub boundary: [i32; 4],
    pub stitched: [i32; 4],
    /// Morph enabled, morph toward l + 1 in the normals (0/1).
    pub flags: [i32; 4],
}

/// Draw modes (`Draw::level[3]`).
pub const MODE_PASSTHROUGH: i32 = 0;
pub const MODE_STRIPS: i32 = 1;
pub const MODE_FOOTPRINT: i32 = 2;
pub const MODE_MESH: i32 = 3;

/// A vertex the CPU vertex stage made, read by the shader as floats at the
/// `PT_*` offsets: what a frame without grid places (an exported one) or
/// drawn on GL is drawn from.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct PassVertex {
    pub clip: [f32; 4],
    pub albedo: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    pub alpha: f32,
    pub fog: f32,
    pub view: [f32; 3],
    pub bary: [f32; 3],
    pub edge: [f32; 3],
    pub pad: f32,
}

/// A vertex of a mesh no clipmap made (brute force, ROAM, CBT, …), as a
/// GPU renderer keeps it resident: its grid place, heights and morph
/// weight, and the attributes that do not depend on the view. The shader
/// makes the camera-relative position, the clip position, fog and the
/// view vector from it each frame, in the CPU vertex stage's order, so the
/// buffer changes only where the mesh does. Read as 32-bit words at the
/// `MV_*` offsets.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct MeshVertex {
    /// Base-grid column and row (`LodVertex::col`, `row`).
    pub grid: [i32; 2],
    /// Sub-texel offset (`LodVertex::offset`).
    pub offset: [f32; 2],
    /// Own height, morph target and morph weight.
    pub z: f32,
    pub zc: f32,
    pub alpha: f32,
    /// The CPU's vertex normal (zero unless lit without a normal map).
    pub normal: [f32; 3],
    /// The CPU's level texel coordinates (zero unless the layout has them).
    pub uv: [f32; 2],
}

#[cfg(test)]
mod tests {
    use super::*;
    use naga::{Expression, Literal, TypeInner};
    use std::mem::{offset_of, size_of};

    fn shader() -> naga::Module {
        naga::front::wgsl::parse_str(crate::gpu::SHADER).expect("WGSL parses")
    }

    /// (name, offset, size) of each member of WGSL struct `name`, and its
    /// size.
    fn members(m: &naga::Module, name: &str) -> (Vec<(String, u32, u32)>, u32) {
        let (_, ty) = m
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no struct {name} in terrain.wgsl"));
        let TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{name} is not a struct")
        };
        let out = members
            .iter()
            .map(|mm| {
                let size = m.types[mm.ty].inner.size(m.to_ctx());
                (mm.name.clone().unwrap(), mm.offset, size)
            })
            .collect();
        (out, *span)
    }

    macro_rules! layout {
        ($t:ty { $($f:ident),* $(,)? }) => {{
            let v: Vec<(String, u32, u32)> = vec![$((
                stringify!($f).to_string(),
                offset_of!($t, $f) as u32,
                {
                    fn size_of_field<T, F>(_: impl Fn(&T) -> &F) -> usize { size_of::<F>() }
                    size_of_field(|s: &$t| &s.$f) as u32
                },
            )),*];
            (v, size_of::<$t>() as u32)
        }};
    }

    #[test]
    fn uniform_structs_match_the_shader_field_for_field() {
        let m = shader();
        let level = layout!(Level {
            origin,
            nm,
            lm,
            tint
        });
        assert_eq!(members(&m, "Level"), level);
        let globals = layout!(Globals {
            view_proj,
            eye,
            cell,
            ramp,
            sun,
            fog_colour,
            wire_colour,
            size,
            ints,
            levels
        });
        assert_eq!(members(&m, "Globals"), globals);
        let draw = layout!(Draw {
            level,
            origin,
            rel,
            morph,
            boundary,
            stitched,
            flags
        });
        assert_eq!(members(&m, "Draw"), draw);
    }

    /// The shader's `PT_*` and `MV_*` constants are the word offsets of the
    /// [`PassVertex`] and [`MeshVertex`] fields it reads, `PT` and `MV`
    /// their lengths in words, and its `MODE_*` the draw modes [`Draw`]
    /// carries.
    #[test]
    fn vertex_record_offsets_match_the_shader() {
        let m = shader();
        // The literal a module-scope constant is set to.
        let literal = |name: &str| -> Literal {
            let (_, c) = m
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("no constant {name} in terrain.wgsl"));
            match m.global_expressions[c.init] {
                Expression::Literal(v) => v,
                ref e => panic!("{name} = {e:?}"),
            }
        };
        let constant = |name: &str| match literal(name) {
            Literal::U32(v) => v,
            v => panic!("{name} = {v:?}, not a u32"),
        };
        let float = |bytes: usize| (bytes / 4) as u32;
        for (name, mode) in [
            ("MODE_PASSTHROUGH", MODE_PASSTHROUGH),
            ("MODE_STRIPS", MODE_STRIPS),
            ("MODE_FOOTPRINT", MODE_FOOTPRINT),
            ("MODE_MESH", MODE_MESH),
        ] {
            assert_eq!(literal(name), Literal::I32(mode), "{name}");
        }
        assert_eq!(constant("PT"), float(size_of::<PassVertex>()));
        assert_eq!(constant("MV"), float(size_of::<MeshVertex>()));
        for (name, at) in [
            ("PT_CLIP", offset_of!(PassVertex, clip)),
            ("PT_ALBEDO", offset_of!(PassVertex, albedo)),
            ("PT_NORMAL", offset_of!(PassVertex, normal)),
            ("PT_UV", offset_of!(PassVertex, uv)),
            ("PT_ALPHA", offset_of!(PassVertex, alpha)),
            ("PT_FOG", offset_of!(PassVertex, fog)),
            ("PT_VIEW", offset_of!(PassVertex, view)),
            ("PT_EDGE", offset_of!(PassVertex, edge)),
            ("MV_GRID", offset_of!(MeshVertex, grid)),
            ("MV_OFFSET", offset_of!(MeshVertex, offset)),
            ("MV_Z", offset_of!(MeshVertex, z)),
            ("MV_ZC", offset_of!(MeshVertex, zc)),
            ("MV_ALPHA", offset_of!(MeshVertex, alpha)),
            ("MV_NORMAL", offset_of!(MeshVertex, normal)),
            ("MV_UV", offset_of!(MeshVertex, uv)),
        ] {
            assert_eq!(constant(name), float(at), "{name}");
        }
    }
}
