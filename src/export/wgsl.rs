//! The shading as WGSL a WebGPU renderer can use as it is
//! (`terrain.wgsl` in an export): the arithmetic of [`super::glsl`]'s
//! shaders, in the same order, for the frame's effects and varyings.
//!
//! WGSL has no `precise`: it cannot forbid a compiler to fuse a product
//! and a sum. terraclip's own back end relies on the same WGSL arithmetic
//! and is exact on lavapipe (naga writes SPIR-V without fused operations,
//! and lavapipe does not contract them); other drivers may fuse, which
//! `compare --mode tiered` allows for.
//!
//! Every uniform lives in one buffer, `Frame`, because WebGPU has no loose
//! uniforms: a renderer writes one per glTF primitive (each primitive is
//! one level, and the level's palette colour, window origin and maps
//! differ). Its layout is fixed whatever the effects, so a renderer packs
//! it one way; the comment in the shader gives each field's byte offset.

use super::VaryingFile;
use crate::shade::Effect;

/// The `Frame` uniform buffer's fields, with their WGSL types and byte
/// offsets (WGSL's uniform layout rules: a `vec3` aligns to 16 and a
/// scalar after it fills its fourth slot). 160 bytes in all.
const FRAME_FIELDS: [(&str, &str, usize, &str); 14] = [
    (
        "view_proj",
        "mat4x4<f32>",
        0,
        "camera.json's view_proj, 4 columns of 4",
    ),
    (
        "albedo_tint",
        "vec3<f32>",
        64,
        "level-tint: level_palette[level mod 8] / 255",
    ),
    ("ambient", "f32", 76, "shading.ambient"),
    ("sun", "vec3<f32>", 80, "sun_direction"),
    ("specular_strength", "f32", 92, "shading.specular_strength"),
    (
        "fog_colour",
        "vec3<f32>",
        96,
        "shading.fog_colour, or background when null",
    ),
    (
        "specular_squarings",
        "i32",
        108,
        "shading.specular_squarings",
    ),
    ("wire_colour", "vec3<f32>", 112, "shading.wire_colour"),
    ("light_scale", "i32", 124, "lightmap.scale"),
    (
        "window_origin",
        "vec2<i32>",
        128,
        "levels[l].origin of this primitive's level l",
    ),
    (
        "normal_fine_origin",
        "vec2<i32>",
        136,
        "normal_maps[] origin of level l",
    ),
    (
        "normal_coarse_origin",
        "vec2<i32>",
        144,
        "normal_maps[] origin of level l + 1",
    ),
    (
        "light_blend",
        "u32",
        152,
        "1 if l + 1 < lightmap.levels count",
    ),
    (
        "normal_blend",
        "u32",
        156,
        "1 if level l + 1 has a normal map",
    ),
];

/// The size of the `Frame` uniform buffer, bytes.
pub const FRAME_BYTES: usize = 160;

/// The shader module (entry points `vs_main` and `fs_main`) for a frame
/// with `effects` and `varyings` (in `frame.json`'s order).
pub fn shader(effects: &[Effect], varyings: &[VaryingFile]) -> String {
    let ty = |v: &VaryingFile| match v.components {
        1 => "f32".to_string(),
        n => format!("vec{n}<f32>"),
    };
    let interp = |v: &VaryingFile| {
        if v.interpolation == "linear" {
            " @interpolate(linear)"
        } else {
            ""
        }
    };
    let has = |e: Effect| effects.contains(&e);
    let (shadows, mapped) = (has(Effect::Shadows), has(Effect::NormalMap));
    let mut s = String::from(
        "// terraclip export: the shading of docs/reference/export-format.md in WGSL.\n\
         // Draw frame.glb's primitives in order as unindexed triangle lists, no\n\
         // culling, no blending, into a depth32float attachment cleared to 1 with\n\
         // the LESS test; vertex attributes at @location(0) POSITION, then\n\
         // frame.json's varyings in order from @location(1).\n\
         //\n\
         // @group(0) @binding(0): Frame, 160 bytes, one buffer per primitive.\n\
         // Byte offsets and where each value comes from (frame.json unless named):\n",
    );
    for (name, t, at, from) in FRAME_FIELDS {
        s += &format!("//   {at:3} {name}: {t} = {from}\n");
    }
    s += "struct Frame {\n";
    for (name, t, _, _) in FRAME_FIELDS {
        s += &format!("    {name}: {t},\n");
    }
    s += "}\n\n@group(0) @binding(0) var<uniform> u: Frame;\n\n";
    s += "struct VertexIn {\n    @location(0) POSITION: vec3<f32>,\n";
    for (i, v) in varyings.iter().enumerate() {
        s += &format!("    @location({}) {}: {},\n", i + 1, v.attribute, ty(v));
    }
    s += "}\n\nstruct Varyings {\n    @builtin(position) clip: vec4<f32>,\n";
    for (i, v) in varyings.iter().enumerate() {
        s += &format!(
            "    @location({i}){} v{}: {},\n",
            interp(v),
            v.attribute,
            ty(v)
        );
    }
    s += "}\n\n\
          @vertex\n\
          fn vs_main(i: VertexIn) -> Varyings {\n\
          \x20   var o: Varyings;\n\
          \x20   // ((m3 + m2 z) + m1 y) + m0 x, as the clip positions were made.\n\
          \x20   let m = u.view_proj;\n\
          \x20   o.clip = ((m[3] + m[2] * i.POSITION.z) + m[1] * i.POSITION.y) + m[0] * i.POSITION.x;\n";
    for v in varyings {
        s += &format!("    o.v{0} = i.{0};\n", v.attribute);
    }
    s += "    return o;\n}\n\n\
          fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {\n\
          \x20   return a.x * b.x + a.y * b.y + a.z * b.z;\n\
          }\n\n\
          fn normalize3(a: vec3<f32>) -> vec3<f32> {\n\
          \x20   let l = sqrt(dot3(a, a));\n\
          \x20   if (l > 0.0) {\n\
          \x20       return a / l;\n\
          \x20   }\n\
          \x20   return a;\n\
          }\n";
    if shadows {
        s += LIGHTMAP;
    }
    if mapped {
        s += NORMAL_MAP;
    }
    let has_varying = |name: &str| varyings.iter().any(|v| v.attribute == name);
    let albedo = if has_varying("_ALBEDO") {
        "v.v_ALBEDO"
    } else {
        "u.albedo_tint"
    };
    let alpha = if has_varying("_MORPH_ALPHA") {
        "v.v_MORPH_ALPHA"
    } else {
        "0.0"
    };
    s += &format!(
        "\n@fragment\n\
         fn fs_main(v: Varyings) -> @location(0) vec4<f32> {{\n\
         \x20   let alpha = {alpha};\n\
         \x20   var c = {albedo};\n\
         \x20   var s = 1.0;\n"
    );
    if shadows {
        s += "    s = shadow_at(v.v_LEVEL_UV, alpha);\n";
    }
    if has(Effect::Lambert) || has(Effect::Phong) {
        s += if mapped {
            "    let n = pixel_normal(v.v_LEVEL_UV, alpha);\n"
        } else {
            "    let n = normalize3(v.v_NORMAL);\n"
        };
        s += "    let light = max(dot3(n, u.sun), 0.0) * s;\n\
              \x20   c = c * (u.ambient + (1.0 - u.ambient) * light);\n";
        if has(Effect::Phong) {
            s += "    let view = normalize3(-v.v_VIEW);\n\
                  \x20   let half = normalize3(u.sun + view);\n\
                  \x20   var p = max(dot3(n, half), 0.0);\n\
                  \x20   for (var k = 0; k < u.specular_squarings; k++) {\n\
                  \x20       p = p * p;\n\
                  \x20   }\n\
                  \x20   let spec = u.specular_strength * p * s;\n\
                  \x20   c = c + vec3<f32>(spec);\n";
        }
    } else if shadows {
        s += "    c = c * (u.ambient + (1.0 - u.ambient) * s);\n";
    }
    if has(Effect::Fog) {
        s += "    let g = 1.0 - v.v_FOG;\n\
              \x20   c = c * v.v_FOG + u.fog_colour * g;\n";
    }
    if has(Effect::Wireframe) {
        s += "    if (v.v_BARY.x < v.v_EDGE.x || v.v_BARY.y < v.v_EDGE.y || v.v_BARY.z < v.v_EDGE.z) {\n\
              \x20       c = c * 0.2 + u.wire_colour * 0.8;\n\
              \x20   }\n";
    }
    s += "    return vec4<f32>(c, 1.0);\n}\n";
    s
}

/// [`super::glsl`]'s lightmap reads: `effects.exr`'s lightmap{min(l, K −
/// 1)} and lightmap{l + 1} (K levels) as r32float textures, read with
/// `textureLoad` only.
const LIGHTMAP: &str = "
// shadows: @binding(1) light_fine = effects.exr's lightmap{min(l, K - 1)},
// @binding(2) light_coarse = lightmap{l + 1} (K = frame.json's
// lightmap.levels count; any lightmap when light_blend is 0): r32float.
@group(0) @binding(1) var light_fine: texture_2d<f32>;
@group(0) @binding(2) var light_coarse: texture_2d<f32>;

fn light_get(t: texture_2d<f32>, x: i32, y: i32) -> f32 {
    let size = vec2<i32>(textureDimensions(t));
    return textureLoad(t, vec2<i32>(clamp(x, 0, size.x - 1), clamp(y, 0, size.y - 1)), 0).x;
}

fn light_bilinear(t: texture_2d<f32>, ix: i32, iy: i32, tx: f32, ty: f32) -> f32 {
    let top = (1.0 - tx) * light_get(t, ix, iy) + tx * light_get(t, ix + 1, iy);
    let bottom = (1.0 - tx) * light_get(t, ix, iy + 1) + tx * light_get(t, ix + 1, iy + 1);
    return (1.0 - ty) * top + ty * bottom;
}

fn shadow_at(uv: vec2<f32>, alpha: f32) -> f32 {
    let sf = f32(u.light_scale);
    let h = vec2<f32>(uv.x * sf, uv.y * sf);
    let f = floor(h);
    let b = u.window_origin * u.light_scale;
    let fine = light_bilinear(light_fine, b.x + i32(f.x), b.y + i32(f.y), h.x - f.x, h.y - f.y);
    if (alpha <= 0.0 || u.light_blend == 0u) {
        return fine;
    }
    // Level l + 1 at the same point: half the level-l coordinate.
    let hh = vec2<f32>((f32(b.x & 1) + uv.x * sf) * 0.5, (f32(b.y & 1) + uv.y * sf) * 0.5);
    let ff = floor(hh);
    let coarse = light_bilinear(light_coarse, (b.x >> 1u) + i32(ff.x), (b.y >> 1u) + i32(ff.y), hh.x - ff.x, hh.y - ff.y);
    return (1.0 - alpha) * fine + alpha * coarse;
}
";

/// [`super::glsl`]'s normal-map reads: level l's map on its half-texel
/// grid, blended by α toward level l + 1's, then normalised.
const NORMAL_MAP: &str = "
// normal-map: @binding(3) normal_fine = effects.exr's normal{l}, @binding(4)
// normal_coarse = normal{l + 1} (normal{l} when normal_blend is 0), as
// rgba32float textures holding X, Y, Z (WebGPU has no three-channel float
// format; A is unused).
@group(0) @binding(3) var normal_fine: texture_2d<f32>;
@group(0) @binding(4) var normal_coarse: texture_2d<f32>;

fn lerp3(a: vec3<f32>, b: vec3<f32>, t: f32) -> vec3<f32> {
    let k = 1.0 - t;
    return vec3<f32>(k * a.x + t * b.x, k * a.y + t * b.y, k * a.z + t * b.z);
}

fn normal_sample(t: texture_2d<f32>, h: vec2<f32>) -> vec3<f32> {
    let size = vec2<i32>(textureDimensions(t));
    let ix = clamp(i32(floor(h.x)), 0, size.x - 2);
    let iy = clamp(i32(floor(h.y)), 0, size.y - 2);
    let tx = clamp(h.x - f32(ix), 0.0, 1.0);
    let ty = clamp(h.y - f32(iy), 0.0, 1.0);
    let top = lerp3(textureLoad(t, vec2<i32>(ix, iy), 0).xyz, textureLoad(t, vec2<i32>(ix + 1, iy), 0).xyz, tx);
    let bottom = lerp3(textureLoad(t, vec2<i32>(ix, iy + 1), 0).xyz, textureLoad(t, vec2<i32>(ix + 1, iy + 1), 0).xyz, tx);
    return lerp3(top, bottom, ty);
}

fn pixel_normal(uv: vec2<f32>, alpha: f32) -> vec3<f32> {
    let o = u.window_origin;
    let hf = vec2<f32>(f32(2 * o.x - u.normal_fine_origin.x) + 2.0 * uv.x,
                       f32(2 * o.y - u.normal_fine_origin.y) + 2.0 * uv.y);
    var n = normal_sample(normal_fine, hf);
    if (u.normal_blend != 0u && alpha > 0.0) {
        // Level l texel X is half-texel X of level l + 1.
        let hc = vec2<f32>(f32(o.x - u.normal_coarse_origin.x) + uv.x,
                           f32(o.y - u.normal_coarse_origin.y) + uv.y);
        n = lerp3(n, normal_sample(normal_coarse, hc), alpha);
    }
    return normalize3(n);
}
";
