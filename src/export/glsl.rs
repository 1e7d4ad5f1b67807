//! The shading as GLSL 4.50 source an outside OpenGL renderer can compile
//! as it is (`terrain.vert`, `terrain.frag` in an export): the arithmetic
//! of docs/tutorials/verify-your-renderer.md, "The shading, exactly", written out
//! for the frame's effects and varyings, each step `precise` so that no
//! compiler fuses or reorders it. `examples/outside-gl` draws every golden
//! with these files and matches the reference bit for bit on llvmpipe
//! (`.ci/outside-gl`).
//!
//! Written by hand rather than translated from the wgpu back end's WGSL
//! with naga: that shader pulls vertices from clipmap textures and
//! storage buffers bound terraclip's way, which an outside renderer drawing
//! `frame.glb` does not have. Its texture reads are the same arithmetic:
//! `effects.exr`'s maps are read with `texelFetch` and blended in the
//! shader, because a sampler's own bilinear filter rounds its weights to
//! a few bits (8 on most hardware) and would not match.
//!
//! Each glTF primitive is one level, so the textures and window origin of
//! that level (and the next coarser one, which the morph blends toward)
//! are per-draw uniforms; the fragment shader's comment says where each
//! comes from.

use super::VaryingFile;
use crate::shade::Effect;

/// Which GLSL the shaders are written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dialect {
    /// Desktop GLSL 4.50: `precise` and `noperspective`, exact on llvmpipe.
    Desktop,
    /// GLSL ES 3.00 (WebGL 2, OpenGL ES 3.0), which has neither
    /// qualifier. A screen-linear varying is passed multiplied by clip w
    /// and perspective-interpolated, then multiplied by `gl_FragCoord.w`
    /// (1/w, interpolated screen-linearly): Σλᵢvᵢwᵢ/wᵢ ÷ Σλᵢ/wᵢ · Σλᵢ/wᵢ =
    /// Σλᵢvᵢ, the screen-linear value, in two more roundings. Without
    /// `precise` a compiler may fuse a product and a sum, and round once
    /// where terraclip rounds twice.
    Es300,
}

/// The vertex and fragment shaders for a frame with `effects` and
/// `varyings` (in `frame.json`'s order).
pub fn shaders(effects: &[Effect], varyings: &[VaryingFile]) -> (String, String) {
    shaders_in(Dialect::Desktop, effects, varyings)
}

/// [`shaders`] in `dialect`.
pub fn shaders_in(
    dialect: Dialect,
    effects: &[Effect],
    varyings: &[VaryingFile],
) -> (String, String) {
    let es = dialect == Dialect::Es300;
    let ty = |v: &VaryingFile| match v.components {
        1 => "float".to_string(),
        n => format!("vec{n}"),
    };
    let linear = |v: &VaryingFile| v.interpolation == "linear";
    let qual = |v: &VaryingFile| {
        if linear(v) && !es {
            "noperspective "
        } else {
            ""
        }
    };
    // The name a varying travels under between the stages: in ES a
    // screen-linear one travels multiplied by w.
    let wire_name = |v: &VaryingFile| {
        if linear(v) && es {
            format!("w{}", v.attribute)
        } else {
            format!("v{}", v.attribute)
        }
    };
    let lines =
        |f: &dyn Fn(&VaryingFile) -> String| varyings.iter().map(f).collect::<Vec<_>>().join("\n");
    let vert = format!(
        "#version 450\n\
         // terraclip export: draw frame.glb's triangles in order, no culling.\n\
         // view_proj is camera.json's (4 columns of 4).\n\
         in vec3 POSITION;\n{}\n\
         uniform mat4 view_proj;\n{}\n\
         void main() {{\n\
         \x20   // ((m3 + m2 z) + m1 y) + m0 x, unfused, as the clip positions were made.\n\
         \x20   precise vec4 p = ((view_proj[3] + view_proj[2] * POSITION.z)\n\
         \x20       + view_proj[1] * POSITION.y) + view_proj[0] * POSITION.x;\n\
         \x20   gl_Position = p;\n{}\n}}\n",
        lines(&|v| format!("in {} {};", ty(v), v.attribute)),
        lines(&|v| format!("{}out {} {};", qual(v), ty(v), wire_name(v))),
        lines(&|v| {
            if linear(v) && es {
                format!("    {} = {} * p.w;", wire_name(v), v.attribute)
            } else {
                format!("    v{0} = {0};", v.attribute)
            }
        }),
    );
    let has = |e: Effect| effects.contains(&e);
    let albedo = if varyings.iter().any(|v| v.attribute == "_ALBEDO") {
        "v_ALBEDO"
    } else {
        "albedo_tint"
    };
    let (shadows, mapped) = (has(Effect::Shadows), has(Effect::NormalMap));
    let mut body = format!("    precise vec3 c = {albedo};\n    float s = 1.0;\n");
    if shadows {
        body += "    s = shadow_at(v_LEVEL_UV, morph_alpha());\n";
    }
    let lit = has(Effect::Lambert) || has(Effect::Phong);
    if lit {
        body += if mapped {
            "    vec3 n = pixel_normal(v_LEVEL_UV, morph_alpha());\n"
        } else {
            "    vec3 n = normalize3(v_NORMAL);\n"
        };
        body += "\
                 \x20   precise float light = max(dot3(n, sun), 0.0) * s;\n\
                 \x20   c = c * (ambient + (1.0 - ambient) * light);\n";
        if has(Effect::Phong) {
            body += "    vec3 v = normalize3(-v_VIEW);\n\
                     \x20   vec3 h = normalize3(sun + v);\n\
                     \x20   precise float p = max(dot3(n, h), 0.0);\n\
                     \x20   for (int i = 0; i < specular_squarings; i++) {\n\
                     \x20       p = p * p;\n\
                     \x20   }\n\
                     \x20   precise float spec = specular_strength * p * s;\n\
                     \x20   c = c + vec3(spec);\n";
        }
    } else if shadows {
        body += "    c = c * (ambient + (1.0 - ambient) * s);\n";
    }
    if has(Effect::Fog) {
        body += "    precise float g = 1.0 - v_FOG;\n\
                 \x20   c = c * v_FOG + fog_colour * g;\n";
    }
    if has(Effect::Wireframe) {
        body += "    if (v_BARY.x < v_EDGE.x || v_BARY.y < v_EDGE.y || v_BARY.z < v_EDGE.z) {\n\
                 \x20       c = c * 0.2 + wire_colour * 0.8;\n\
                 \x20   }\n";
    }
    let frag = format!(
        "#version 450\n\
         // terraclip export: the shading of docs/tutorials/verify-your-renderer.md.\n\
         // Uniforms from frame.json: sun = sun_direction; ambient,\n\
         // specular_strength, specular_squarings, wire_colour from shading;\n\
         // fog_colour = shading.fog_colour, or background when null;\n\
         // albedo_tint = level_palette[level mod 8] / 255 per primitive\n\
         // (its extras' level), under level-tint.\n\
         {}\n\
         uniform vec3 albedo_tint;\n\
         uniform vec3 sun;\n\
         uniform float ambient;\n\
         uniform float specular_strength;\n\
         uniform int specular_squarings;\n\
         uniform vec3 fog_colour;\n\
         uniform vec3 wire_colour;\n\
         out vec4 colour;\n\
         \n\
         float dot3(vec3 a, vec3 b) {{\n\
         \x20   precise float d = a.x * b.x + a.y * b.y + a.z * b.z;\n\
         \x20   return d;\n\
         }}\n\
         \n\
         vec3 normalize3(vec3 a) {{\n\
         \x20   precise float l = sqrt(dot3(a, a));\n\
         \x20   return l > 0.0 ? a / l : a;\n\
         }}\n\
         {}\n\
         void main() {{\n{}{body}    colour = vec4(c, 1.0);\n}}\n",
        lines(&|v| {
            if linear(v) && es {
                format!("in {0} {1};\n{0} v{2};", ty(v), wire_name(v), v.attribute)
            } else {
                format!("{}in {} v{};", qual(v), ty(v), v.attribute)
            }
        }),
        textures(shadows, mapped, varyings),
        varyings
            .iter()
            .filter(|v| linear(v) && es)
            .map(|v| format!(
                "    v{} = {} * gl_FragCoord.w;\n",
                v.attribute,
                wire_name(v)
            ))
            .collect::<String>(),
    );
    match dialect {
        Dialect::Desktop => (vert, frag),
        Dialect::Es300 => (to_es(&vert), to_es(&frag)),
    }
}

/// Desktop GLSL 4.50 as GLSL ES 3.00: the version line, high precision
/// for every type that has a default, and no `precise` (ES 3.20 has it;
/// ES 3.00, which WebGL 2 is, does not). The linear varyings are written
/// for ES by [`shaders_in`] already.
fn to_es(src: &str) -> String {
    src.replacen(
        "#version 450\n",
        "#version 300 es\n\
         // GLSL ES 3.00: without `precise`, a compiler may fuse; expect\n\
         // `compare --mode tiered`, not exact.\n\
         precision highp float;\n\
         precision highp int;\n\
         precision highp sampler2D;\n",
        1,
    )
    .replace("precise ", "")
}

/// The texture-reading functions and their per-draw uniforms, for the
/// effects that read `effects.exr` (empty for neither).
fn textures(shadows: bool, mapped: bool, varyings: &[VaryingFile]) -> String {
    if !shadows && !mapped {
        return String::new();
    }
    let alpha = if varyings.iter().any(|v| v.attribute == "_MORPH_ALPHA") {
        "v_MORPH_ALPHA"
    } else {
        "0.0"
    };
    let mut t = format!(
        "\n// Per draw (one glTF primitive, one level l): window_origin is\n\
         // frame.json's levels[l].origin.\n\
         uniform ivec2 window_origin;\n\
         \n\
         float morph_alpha() {{\n\
         \x20   return {alpha};\n\
         }}\n"
    );
    if shadows {
        t += LIGHTMAP;
    }
    if mapped {
        t += NORMAL_MAP;
    }
    t
}

/// `shade::shadows::Lightmap::sample`: bilinear reads clamped to the
/// level's edges, blended by α toward level l + 1 read at half the
/// coordinate.
const LIGHTMAP: &str = "
// shadows: light_fine is effects.exr's lightmap{min(l, K - 1)} and
// light_coarse its lightmap{l + 1}, K being frame.json's lightmap.levels
// count; light_blend is l + 1 < K; light_scale is lightmap.scale. R32F
// textures, read with texelFetch only.
uniform sampler2D light_fine;
uniform sampler2D light_coarse;
uniform bool light_blend;
uniform int light_scale;

float light_get(sampler2D t, int x, int y) {
    ivec2 size = textureSize(t, 0);
    return texelFetch(t, ivec2(clamp(x, 0, size.x - 1), clamp(y, 0, size.y - 1)), 0).x;
}

float light_bilinear(sampler2D t, int ix, int iy, float tx, float ty) {
    precise float top = (1.0 - tx) * light_get(t, ix, iy) + tx * light_get(t, ix + 1, iy);
    precise float bottom = (1.0 - tx) * light_get(t, ix, iy + 1) + tx * light_get(t, ix + 1, iy + 1);
    precise float r = (1.0 - ty) * top + ty * bottom;
    return r;
}

float shadow_at(vec2 uv, float alpha) {
    float sf = float(light_scale);
    precise vec2 h = vec2(uv.x * sf, uv.y * sf);
    vec2 f = floor(h);
    ivec2 b = window_origin * light_scale;
    precise float fine = light_bilinear(light_fine, b.x + int(f.x), b.y + int(f.y), h.x - f.x, h.y - f.y);
    if (alpha <= 0.0 || !light_blend) {
        return fine;
    }
    // Level l + 1 at the same point: half the level-l coordinate.
    precise vec2 hh = vec2((float(b.x & 1) + uv.x * sf) * 0.5, (float(b.y & 1) + uv.y * sf) * 0.5);
    vec2 ff = floor(hh);
    precise float coarse = light_bilinear(light_coarse, (b.x >> 1) + int(ff.x), (b.y >> 1) + int(ff.y), hh.x - ff.x, hh.y - ff.y);
    precise float r = (1.0 - alpha) * fine + alpha * coarse;
    return r;
}
";

/// `shade::normal_map::pixel_normal`: level l's map on its half-texel
/// grid, blended by α toward level l + 1's, then normalised.
const NORMAL_MAP: &str = "
// normal-map: normal_fine is effects.exr's normal{l} (channels X, Y, Z as
// an RGB32F texture) and normal_fine_origin its frame.json normal_maps[]
// origin; normal_coarse and normal_coarse_origin the same of level l + 1;
// normal_blend is whether level l + 1 has a normal map. Read with
// texelFetch only.
uniform sampler2D normal_fine;
uniform ivec2 normal_fine_origin;
uniform sampler2D normal_coarse;
uniform ivec2 normal_coarse_origin;
uniform bool normal_blend;

vec3 lerp3(vec3 a, vec3 b, float t) {
    precise float k = 1.0 - t;
    precise vec3 r = vec3(k * a.x + t * b.x, k * a.y + t * b.y, k * a.z + t * b.z);
    return r;
}

vec3 normal_sample(sampler2D t, vec2 h) {
    ivec2 size = textureSize(t, 0);
    int ix = clamp(int(floor(h.x)), 0, size.x - 2);
    int iy = clamp(int(floor(h.y)), 0, size.y - 2);
    precise float tx = clamp(h.x - float(ix), 0.0, 1.0);
    precise float ty = clamp(h.y - float(iy), 0.0, 1.0);
    vec3 top = lerp3(texelFetch(t, ivec2(ix, iy), 0).xyz, texelFetch(t, ivec2(ix + 1, iy), 0).xyz, tx);
    vec3 bottom = lerp3(texelFetch(t, ivec2(ix, iy + 1), 0).xyz, texelFetch(t, ivec2(ix + 1, iy + 1), 0).xyz, tx);
    return lerp3(top, bottom, ty);
}

vec3 pixel_normal(vec2 uv, float alpha) {
    ivec2 o = window_origin;
    precise vec2 hf = vec2(float(2 * o.x - normal_fine_origin.x) + 2.0 * uv.x,
                           float(2 * o.y - normal_fine_origin.y) + 2.0 * uv.y);
    vec3 n = normal_sample(normal_fine, hf);
    if (normal_blend && alpha > 0.0) {
        // Level l texel X is half-texel X of level l + 1.
        precise vec2 hc = vec2(float(o.x - normal_coarse_origin.x) + uv.x,
                               float(o.y - normal_coarse_origin.y) + uv.y);
        n = lerp3(n, normal_sample(normal_coarse, hc), alpha);
    }
    return normalize3(n);
}
";
