//! The shading as GLSL 4.50 source an outside OpenGL renderer can compile
//! as it is (`terrain.vert`, `terrain.frag` in an export): the arithmetic
//! of docs/verify-your-renderer.md, "The shading, exactly", written out
//! for the frame's effects and varyings, each step `precise` so that no
//! compiler fuses or reorders it. `examples/outside-gl` draws every golden
//! it covers with these files and matches the reference bit for bit on
//! llvmpipe (`.ci/outside-gl`).
//!
//! Written by hand rather than translated from the wgpu back end's WGSL
//! with naga: that shader pulls vertices from clipmap textures and
//! storage buffers bound terraclip's way, which an outside renderer drawing
//! `frame.glb` does not have. Effects that read `effects.exr` (normal-map,
//! shadows) are not covered: their texture addressing is specified in the
//! docs, and no shader is written for such a frame.

use super::VaryingFile;
use crate::scene::names::Effect;

/// The vertex and fragment shaders for a frame with `effects` and
/// `varyings` (in `frame.json`'s order), or none when an effect reads
/// textures.
pub fn shaders(effects: &[Effect], varyings: &[VaryingFile]) -> Option<(String, String)> {
    if effects
        .iter()
        .any(|e| matches!(e, Effect::NormalMap | Effect::Shadows))
    {
        return None;
    }
    let ty = |v: &VaryingFile| match v.components {
        1 => "float".to_string(),
        n => format!("vec{n}"),
    };
    let qual = |v: &VaryingFile| {
        if v.interpolation == "linear" {
            "noperspective "
        } else {
            ""
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
        lines(&|v| format!("{}out {} v{};", qual(v), ty(v), v.attribute)),
        lines(&|v| format!("    v{0} = {0};", v.attribute)),
    );
    let has = |e: Effect| effects.contains(&e);
    let albedo = if varyings.iter().any(|v| v.attribute == "_ALBEDO") {
        "v_ALBEDO"
    } else {
        "albedo_tint"
    };
    let mut body = format!("    precise vec3 c = {albedo};\n    float s = 1.0;\n");
    if has(Effect::Lambert) || has(Effect::Phong) {
        body += "    vec3 n = normalize3(v_NORMAL);\n\
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
         // terraclip export: the shading of docs/verify-your-renderer.md.\n\
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
         \n\
         void main() {{\n{body}    colour = vec4(c, 1.0);\n}}\n",
        lines(&|v| format!("{}in {} v{};", qual(v), ty(v), v.attribute)),
    );
    Some((vert, frag))
}
