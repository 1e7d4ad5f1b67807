#!/usr/bin/env python3
"""An outside renderer for terraclip exports: OpenGL 4.5 through moderngl,
on whatever EGL offers (Mesa's llvmpipe on a machine without a GPU).

It is written from docs/verify-your-renderer.md alone: the export's files,
"The shading, exactly" and "Settings per graphics API". It reads nothing
of terraclip's code and links nothing of it. Usage:

    render.py EXPORT_DIR OUT_PREFIX

writes OUT_PREFIX.png (RGBA8, top row first) and OUT_PREFIX.f32 (raw
little-endian float depth, top row first), which

    terraclip compare EXPORT_DIR --image OUT_PREFIX.png --depth OUT_PREFIX.f32

judges. It compiles the export's terrain.vert and terrain.frag when the
export has them, and with OWN_SHADERS=1, or without them, its own shader
written from the docs' arithmetic. MISTAKE=no-clip-control, last-vertex or d24 in the environment
leaves out one of the settings the docs name, to see what `compare` says.
It draws the effects lambert, phong, fog, level-tint, wireframe
and morph (a geometry effect: nothing to draw). normal-map and shadows
read textures from effects.exr, which this renderer does not decode; it
exits with status 3 on such an export.
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
TEXTURED = {"normal-map", "shadows"}


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

void main() {{
    precise vec3 c = {albedo};
    float s = 1.0;
#if LIT
    vec3 n = normalize3(v_NORMAL);
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


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    ref, out = sys.argv[1], sys.argv[2]
    frame = json.load(open(f"{ref}/frame.json"))
    camera = json.load(open(f"{ref}/camera.json"))
    effects = set(frame["effects"])
    if effects & TEXTURED:
        print(f"{ref}: {sorted(effects & TEXTURED)} need effects.exr: not drawn")
        sys.exit(3)
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
        ]
    )
    fs = FRAGMENT.format(
        inputs="\n".join(
            f"{qualifier(v)}in {glsl_type(v)} v{v['attribute']};" for v in varyings
        ),
        albedo="v_ALBEDO" if "_ALBEDO" in names else "albedo_tint",
    ).replace("#version 450", "#version 450\n" + defines, 1)
    # The export's own GLSL when it has it (terrain.vert, terrain.frag),
    # else the shader above, written from the docs' arithmetic.
    if os.path.exists(f"{ref}/terrain.vert") and not os.environ.get("OWN_SHADERS"):
        vs = open(f"{ref}/terrain.vert").read()
        fs = open(f"{ref}/terrain.frag").read()
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

    palette = frame["level_palette"]
    for prim in doc["meshes"][0]["primitives"]:
        attrs = prim["attributes"]
        level = prim["extras"]["level"]
        tint = palette[level % len(palette)]
        set_uniform("albedo_tint", tuple(c / 255.0 for c in tint))
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
