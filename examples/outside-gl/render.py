#!/usr/bin/env python3
"""An outside renderer for terraclip exports: OpenGL 4.5 through moderngl,
on whatever EGL offers (Mesa's llvmpipe on a machine without a GPU).

It is written from the docs alone: docs/tutorials/verify-your-renderer.md, the
export's files and "The shading, exactly" (docs/reference/export-format.md), and
"Settings per graphics API" (docs/how-to/graphics-apis.md). It reads nothing
of terraclip's code and links nothing of it. Usage:

    render.py EXPORT_DIR OUT_PREFIX

writes OUT_PREFIX.png (RGBA8, top row first) and OUT_PREFIX.f32 (raw
little-endian float depth, top row first), which

    terraclip compare EXPORT_DIR --image OUT_PREFIX.png --depth OUT_PREFIX.f32

judges. It compiles the export's terrain.vert and terrain.frag when the
export has them; with SHADERS=es the export's GLSL ES 3.00 pair,
terrain-es.vert and terrain-es.frag (a GL 4.3+ context compiles ES 3.00
as WebGL 2 would); and with OWN_SHADERS=1, or without them, its own
shader written from the docs' arithmetic. MISTAKE=no-clip-control, last-vertex, d24 or (with OWN_SHADERS=1)
hardware-filter in the environment
leaves out one of the settings the docs name, to see what `compare` says.
It draws every effect: lambert, phong, fog, level-tint, wireframe, morph
(a geometry effect: nothing to draw), and normal-map and shadows, whose
maps it reads from effects.exr with the OpenEXR package (PyPI).
"""

import ctypes
import json
import os
import struct
import sys
import zlib

import moderngl

GL_UPPER_LEFT = 0x8CA2
GL_ZERO_TO_ONE = 0x935F
GL_TEXTURE_2D = 0x0DE1
GL_DEPTH_COMPONENT32F = 0x8CAC
GL_DEPTH_ATTACHMENT = 0x8D00


def read_glb(path):
    """The GLB's JSON and binary chunks (glTF 2.0, section 4.4)."""
    data = open(path, "rb").read()
    magic, _version, length = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67 or length != len(data):
        sys.exit(f"{path}: not a GLB")
    jlen, _ = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20 : 20 + jlen])
    blen, _ = struct.unpack_from("<II", data, 20 + jlen)
    start = 28 + jlen
    return doc, data[start : start + blen]


def accessor_bytes(doc, binary, index):
    a = doc["accessors"][index]
    v = doc["bufferViews"][a["bufferView"]]
    if a["componentType"] != 5126:
        sys.exit("only float accessors are expected")
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
    off = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    return binary[off : off + 4 * n * a["count"]], n, a["count"]


VERTEX = """
#version 450
in vec3 POSITION;
{inputs}
uniform mat4 view_proj;
{outputs}
void main() {{
    // camera.json: ((m3 + m2 z) + m1 y) + m0 x, without fused operations.
    precise vec4 p = ((view_proj[3] + view_proj[2] * POSITION.z)
        + view_proj[1] * POSITION.y) + view_proj[0] * POSITION.x;
    gl_Position = p;
{copies}
}}
"""

FRAGMENT = """
#version 450
{inputs}
uniform vec3 albedo_tint;
uniform vec3 sun;
uniform float ambient;
uniform float specular_strength;
uniform int specular_squarings;
uniform vec3 fog_colour;
uniform vec3 wire_colour;
out vec4 colour;

float dot3(vec3 a, vec3 b) {{
    precise float d = a.x * b.x + a.y * b.y + a.z * b.z;
    return d;
}}

vec3 normalize3(vec3 a) {{
    precise float l = sqrt(dot3(a, a));
    return l > 0.0 ? a / l : a;
}}

// Texture reads ("Texture reads" in the docs): texelFetch and the
// bilinear blend written out, never the sampler's own filter.
uniform ivec2 window_origin;

#if SHADOWS
uniform sampler2D light_fine;
uniform sampler2D light_coarse;
uniform bool light_blend;
uniform int light_scale;

float texel(sampler2D t, int x, int y) {{
    ivec2 size = textureSize(t, 0);
    return texelFetch(t, ivec2(clamp(x, 0, size.x - 1), clamp(y, 0, size.y - 1)), 0).x;
}}

float bilinear(sampler2D t, int ix, int iy, float tx, float ty) {{
#if HW_FILTER
    // MISTAKE=hardware-filter: the sampler's bilinear filter instead.
    vec2 at = clamp(vec2(ix, iy) + vec2(tx, ty), vec2(0.0), vec2(textureSize(t, 0) - 1));
    return texture(t, (at + 0.5) / vec2(textureSize(t, 0))).x;
#endif
    precise float top = (1.0 - tx) * texel(t, ix, iy) + tx * texel(t, ix + 1, iy);
    precise float bottom = (1.0 - tx) * texel(t, ix, iy + 1) + tx * texel(t, ix + 1, iy + 1);
    precise float r = (1.0 - ty) * top + ty * bottom;
    return r;
}}

float light_at(vec2 uv, float alpha) {{
    precise vec2 h = uv * float(light_scale);
    vec2 f = floor(h);
    ivec2 b = window_origin * light_scale;
    precise float fine = bilinear(light_fine, b.x + int(f.x), b.y + int(f.y), h.x - f.x, h.y - f.y);
    if (alpha <= 0.0 || !light_blend) {{
        return fine;
    }}
    // The next level at half the coordinate, b split into b div 2 and b mod 2.
    precise vec2 g = (vec2(b & 1) + uv * float(light_scale)) * 0.5;
    vec2 gf = floor(g);
    precise float coarse = bilinear(light_coarse, (b.x >> 1) + int(gf.x), (b.y >> 1) + int(gf.y), g.x - gf.x, g.y - gf.y);
    precise float r = (1.0 - alpha) * fine + alpha * coarse;
    return r;
}}
#endif

#if NORMAL_MAP
uniform sampler2D normal_fine;
uniform ivec2 normal_fine_origin;
uniform sampler2D normal_coarse;
uniform ivec2 normal_coarse_origin;
uniform bool normal_blend;

vec3 mix3(vec3 a, vec3 b, float t) {{
    precise vec3 r = (1.0 - t) * a + t * b;
    return r;
}}

vec3 normal_at(sampler2D t, vec2 h) {{
    ivec2 size = textureSize(t, 0);
#if HW_FILTER
    return texture(t, (clamp(h, vec2(0.0), vec2(size - 1)) + 0.5) / vec2(size)).xyz;
#endif
    ivec2 i = clamp(ivec2(floor(h)), ivec2(0), size - 2);
    precise vec2 w = clamp(h - vec2(i), 0.0, 1.0);
    vec3 top = mix3(texelFetch(t, i, 0).xyz, texelFetch(t, i + ivec2(1, 0), 0).xyz, w.x);
    vec3 bottom = mix3(texelFetch(t, i + ivec2(0, 1), 0).xyz, texelFetch(t, i + ivec2(1, 1), 0).xyz, w.x);
    return mix3(top, bottom, w.y);
}}

vec3 mapped_normal(vec2 uv, float alpha) {{
    precise vec2 h = vec2(2 * window_origin - normal_fine_origin) + 2.0 * uv;
    vec3 n = normal_at(normal_fine, h);
    if (normal_blend && alpha > 0.0) {{
        precise vec2 hc = vec2(window_origin - normal_coarse_origin) + uv;
        n = mix3(n, normal_at(normal_coarse, hc), alpha);
    }}
    return normalize3(n);
}}
#endif

void main() {{
    precise vec3 c = {albedo};
    float s = 1.0;
#if SHADOWS
    s = light_at(v_LEVEL_UV, {alpha});
#endif
#if LIT
#if NORMAL_MAP
    vec3 n = mapped_normal(v_LEVEL_UV, {alpha});
#else
    vec3 n = normalize3(v_NORMAL);
#endif
    precise float light = max(dot3(n, sun), 0.0) * s;
    c = c * (ambient + (1.0 - ambient) * light);
#if PHONG
    vec3 v = normalize3(-v_VIEW);
    vec3 h = normalize3(sun + v);
    precise float p = max(dot3(n, h), 0.0);
    for (int i = 0; i < specular_squarings; i++) {{
        p = p * p;
    }}
    precise float spec = specular_strength * p * s;
    c = c + vec3(spec);
#endif
#elif SHADOWS
    c = c * (ambient + (1.0 - ambient) * s);
#endif
#if FOG
    precise float g = 1.0 - v_FOG;
    c = c * v_FOG + fog_colour * g;
#endif
#if WIRE
    if (v_BARY.x < v_EDGE.x || v_BARY.y < v_EDGE.y || v_BARY.z < v_EDGE.z) {{
        c = c * 0.2 + wire_colour * 0.8;
    }}
#endif
    colour = vec4(c, 1.0);
}}
"""


def png(path, width, height, rgba):
    """RGBA8 rows, top first, as a PNG (zlib and struct only)."""
    rows = b"".join(
        b"\x00" + rgba[y * 4 * width : (y + 1) * 4 * width] for y in range(height)
    )

    def chunk(kind, body):
        return (
            struct.pack(">I", len(body))
            + kind
            + body
            + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
        )

    head = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", head)
    data += chunk(b"IDAT", zlib.compress(rows, 6)) + chunk(b"IEND", b"")
    open(path, "wb").write(data)


def effect_textures(ctx, ref, frame):
    """effects.exr's layers as float textures, by layer name: lightmap{k}
    (channel L, R32F) and normal{l} (channels X, Y, Z, RGB32F)."""
    if not (frame["lightmap"] or frame["normal_maps"]):
        return {}
    import numpy
    import OpenEXR

    textures = {}
    for part in OpenEXR.File(f"{ref}/effects.exr").parts:
        names = ["L"] if part.name().startswith("lightmap") else ["X", "Y", "Z"]
        pixels = numpy.stack([part.channels[c].pixels for c in names], axis=-1)
        height, width = pixels.shape[:2]
        tex = ctx.texture(
            (width, height), len(names), pixels.astype("<f4").tobytes(), dtype="f4"
        )
        if os.environ.get("MISTAKE") == "hardware-filter":
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        else:
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        textures[part.name()] = tex
    return textures


def bind_level(prog, maps, frame, level, origin):
    """The per-draw uniforms of the level one glTF primitive draws: its
    window origin, and its maps and the next coarser level's."""
    if not maps:
        return
    prog["window_origin"].value = tuple(origin)
    if frame["lightmap"]:
        count = len(frame["lightmap"]["levels"])
        blend = level + 1 < count
        maps[f"lightmap{min(level, count - 1)}"].use(0)
        maps[f"lightmap{level + 1 if blend else min(level, count - 1)}"].use(1)
        prog["light_fine"].value, prog["light_coarse"].value = 0, 1
        prog["light_blend"].value = blend
        prog["light_scale"].value = frame["lightmap"]["scale"]
    if frame["normal_maps"]:
        by_level = {m["level"]: m for m in frame["normal_maps"]}
        fine, coarse = by_level[level], by_level.get(level + 1)
        maps[f"normal{level}"].use(2)
        maps[f"normal{level + 1 if coarse else level}"].use(3)
        prog["normal_fine"].value, prog["normal_coarse"].value = 2, 3
        prog["normal_fine_origin"].value = tuple(fine["origin"])
        prog["normal_coarse_origin"].value = tuple((coarse or fine)["origin"])
        prog["normal_blend"].value = coarse is not None


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    ref, out = sys.argv[1], sys.argv[2]
    frame = json.load(open(f"{ref}/frame.json"))
    camera = json.load(open(f"{ref}/camera.json"))
    effects = set(frame["effects"])
    width, height = camera["width"], camera["height"]
    doc, binary = read_glb(f"{ref}/frame.glb")
    varyings = [v for v in frame["varyings"]]

    ctx = moderngl.create_standalone_context(backend="egl", require=450)
    # Settings per graphics API, OpenGL: clip z in 0..1 with y down, and
    # the first vertex provoking.
    egl = ctypes.CDLL("libEGL.so.1")
    egl.eglGetProcAddress.restype = ctypes.c_void_p

    def gl(name, *args):
        return ctypes.CFUNCTYPE(None, *args)(egl.eglGetProcAddress(name.encode()))

    u, i = ctypes.c_uint, ctypes.c_int
    # MISTAKE leaves one setting out, to show what `compare` says then.
    mistake = os.environ.get("MISTAKE", "")
    if mistake != "no-clip-control":
        gl("glClipControl", u, u)(GL_UPPER_LEFT, GL_ZERO_TO_ONE)
    if mistake != "last-vertex":
        ctx.provoking_vertex = moderngl.FIRST_VERTEX_CONVENTION

    def qualifier(v):
        return "noperspective " if v["interpolation"] == "linear" else ""

    def glsl_type(v):
        return "float" if v["components"] == 1 else f"vec{v['components']}"

    vs = VERTEX.format(
        inputs="\n".join(f"in {glsl_type(v)} {v['attribute']};" for v in varyings),
        outputs="\n".join(
            f"{qualifier(v)}out {glsl_type(v)} v{v['attribute']};" for v in varyings
        ),
        copies="\n".join(f"    v{v['attribute']} = {v['attribute']};" for v in varyings),
    )
    names = {v["attribute"] for v in varyings}
    defines = "\n".join(
        [
            f"#define LIT {int(bool(effects & {'lambert', 'phong'}))}",
            f"#define PHONG {int('phong' in effects)}",
            f"#define FOG {int('fog' in effects)}",
            f"#define WIRE {int('wireframe' in effects)}",
            f"#define SHADOWS {int('shadows' in effects)}",
            f"#define NORMAL_MAP {int('normal-map' in effects)}",
            f"#define HW_FILTER {int(mistake == 'hardware-filter')}",
        ]
    )
    fs = FRAGMENT.format(
        inputs="\n".join(
            f"{qualifier(v)}in {glsl_type(v)} v{v['attribute']};" for v in varyings
        ),
        albedo="v_ALBEDO" if "_ALBEDO" in names else "albedo_tint",
        alpha="v_MORPH_ALPHA" if "_MORPH_ALPHA" in names else "0.0",
    ).replace("#version 450", "#version 450\n" + defines, 1)
    # The export's own GLSL when it has it (terrain.vert, terrain.frag),
    # else the shader above, written from the docs' arithmetic.
    stem = "terrain-es" if os.environ.get("SHADERS") == "es" else "terrain"
    if os.path.exists(f"{ref}/{stem}.vert") and not os.environ.get("OWN_SHADERS"):
        vs = open(f"{ref}/{stem}.vert").read()
        fs = open(f"{ref}/{stem}.frag").read()
    elif stem == "terrain-es":
        sys.exit(f"{ref}: no {stem}.vert and {stem}.frag in the export")
    prog = ctx.program(vertex_shader=vs, fragment_shader=fs)

    # 4 columns of 4, as GLSL stores a mat4.
    vp = [float(x) for col in camera["view_proj"] for x in col]
    prog["view_proj"].write(struct.pack("<16f", *vp))
    shading = frame["shading"]

    def set_uniform(name, value):
        if name in prog:
            prog[name].value = value

    set_uniform("sun", tuple(frame["sun_direction"]))
    set_uniform("ambient", shading["ambient"])
    set_uniform("specular_strength", shading["specular_strength"])
    set_uniform("specular_squarings", shading["specular_squarings"])
    set_uniform("fog_colour", tuple(shading["fog_colour"] or frame["background"]))
    set_uniform("wire_colour", tuple(shading["wire_colour"]))

    colour = ctx.renderbuffer((width, height), 4, dtype="f1")
    # A 32-bit float depth attachment. moderngl's depth textures are
    # GL_DEPTH_COMPONENT24, which `compare` names as a D24 buffer on
    # near-clip-cliff, so the framebuffer gets one made here instead.
    fbo = ctx.framebuffer(
        color_attachments=[colour], depth_attachment=ctx.depth_texture((width, height))
    )
    tex = ctypes.c_uint(0)
    if mistake == "d24":
        tex_format = 0x81A6  # GL_DEPTH_COMPONENT24
    else:
        tex_format = GL_DEPTH_COMPONENT32F
    gl("glCreateTextures", u, i, ctypes.POINTER(u))(GL_TEXTURE_2D, 1, ctypes.byref(tex))
    gl("glTextureStorage2D", u, i, u, i, i)(tex.value, 1, tex_format, width, height)
    gl("glNamedFramebufferTexture", u, u, u, i)(fbo.glo, GL_DEPTH_ATTACHMENT, tex.value, 0)
    fbo.use()
    ctx.viewport = (0, 0, width, height)
    bg = frame["background"]
    fbo.clear(bg[0], bg[1], bg[2], 1.0, depth=1.0)
    ctx.enable(moderngl.DEPTH_TEST)
    ctx.depth_func = "<"
    ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)

    maps = effect_textures(ctx, ref, frame)
    origins = {entry["level"]: entry["origin"] for entry in frame["levels"]}
    palette = frame["level_palette"]
    for prim in doc["meshes"][0]["primitives"]:
        attrs = prim["attributes"]
        level = prim["extras"]["level"]
        tint = palette[level % len(palette)]
        set_uniform("albedo_tint", tuple(c / 255.0 for c in tint))
        bind_level(prog, maps, frame, level, origins.get(level))
        buffers = []
        for name in ["POSITION"] + [v["attribute"] for v in varyings]:
            raw, n, count = accessor_bytes(doc, binary, attrs[name])
            buffers.append((ctx.buffer(raw), f"{n}f", name))
        vao = ctx.vertex_array(prog, buffers)
        vao.render(moderngl.TRIANGLES)
        vao.release()
        for b, _, _ in buffers:
            b.release()
    ctx.finish()

    # With GL_UPPER_LEFT the first row read is the image's top row.
    rgba = fbo.read(components=4, dtype="f1")
    png(f"{out}.png", width, height, rgba)
    z = fbo.read(components=1, attachment=-1, dtype="f4")
    open(f"{out}.f32", "wb").write(z)


if __name__ == "__main__":
    main()
