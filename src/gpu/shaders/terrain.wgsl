// terraclip's wgpu terrain pipeline. Every floating-point step repeats the CPU
// reference in the same order (docs/reference/raster-rules.md rule 7): the vertex stage of
// src/frame/vertex.rs and src/clipmap/morph.rs, the varyings of src/frame/mod.rs and the
// per-pixel shading of src/shade/. lavapipe lowers `fma` to a multiply and an
// add and does not fuse, so plain `a * b + c` here equals the CPU's unfused
// f32 ops. It does factor `a * b + a * c` into `a * (b + c)`, so no
// expression here has that shape.

struct Level {
    // Window origin (level texels), normal-map origin (half-texels).
    origin: vec4<i32>,
    // Normal-map size x, y, atlas row, present (0/1).
    nm: vec4<i32>,
    // Lightmap level: atlas row, width, height.
    lm: vec4<i32>,
    // Albedo under level-tint.
    tint: vec4<f32>,
};

struct Globals {
    view_proj: mat4x4<f32>,
    // eye xyz, and w = 1.0 (see the vertex normals).
    eye: vec4<f32>,
    // cell x, cell y, vertical scale, fog rate (log2(e) · density).
    cell: vec4<f32>,
    // height-ramp low, span, ambient, specular strength.
    ramp: vec4<f32>,
    sun: vec4<f32>,
    fog_colour: vec4<f32>,
    wire_colour: vec4<f32>,
    // target width, height.
    size: vec4<f32>,
    // n, lightmap levels, lightmap scale, specular squarings.
    ints: vec4<i32>,
    levels: array<Level, 32>,
};

struct Draw {
    // level, spacing g, n, mode (MODE_*).
    level: vec4<i32>,
    // window origin x, y (level texels); toroid phase x, y (origin mod n).
    origin: vec4<i32>,
    // origin·g − floating origin (x, and y flipped); instance offset x, y.
    rel: vec4<i32>,
    // viewer x, y (level texels from the origin), half, width.
    morph: vec4<f32>,
    boundary: vec4<i32>,
    stitched: vec4<i32>,
    // morph enabled, morph toward l + 1 in the normals (0/1).
    flags: vec4<i32>,
};

override LIT: bool = false;
override PHONG: bool = false;
override FOG: bool = false;
override SHADOWS: bool = false;
override NORMAL_MAP: bool = false;
override VERTEX_NORMALS: bool = false;
override LEVEL_TINT: bool = false;
override WIREFRAME: bool = false;

@group(0) @binding(0) var<uniform> G: Globals;
@group(0) @binding(1) var heights: texture_2d_array<f32>;
@group(0) @binding(2) var gradients: texture_2d_array<f32>;
@group(0) @binding(3) var lightmap: texture_2d<f32>;
@group(0) @binding(4) var normal_maps: texture_2d<f32>;

@group(1) @binding(0) var<uniform> D: Draw;
@group(1) @binding(1) var<storage, read> strips: array<u32>;
@group(1) @binding(2) var<storage, read> footprints: array<vec2<i32>>;
@group(1) @binding(3) var<storage, read> passthrough: array<f32>;
@group(1) @binding(4) var<storage, read> mesh: array<u32>;

// What a draw's vertices are (D.level.w; gpu::uniforms::MODE_*).
const MODE_PASSTHROUGH: i32 = 0;
const MODE_STRIPS: i32 = 1;
const MODE_FOOTPRINT: i32 = 2;
const MODE_MESH: i32 = 3;

// Record of a passthrough vertex (gpu::uniforms::PassVertex): float
// offsets of the fields read here, and the record's length.
const PT_CLIP: u32 = 0u;
const PT_ALBEDO: u32 = 4u;
const PT_NORMAL: u32 = 7u;
const PT_UV: u32 = 10u;
const PT_ALPHA: u32 = 12u;
const PT_FOG: u32 = 13u;
const PT_VIEW: u32 = 14u;
const PT_EDGE: u32 = 20u;
const PT: u32 = 24u;

// Record of a resident mesh vertex (gpu::uniforms::MeshVertex): word
// offsets of the fields read here, and the record's length.
const MV_GRID: u32 = 0u;
const MV_OFFSET: u32 = 2u;
const MV_Z: u32 = 4u;
const MV_ZC: u32 = 5u;
const MV_ALPHA: u32 = 6u;
const MV_NORMAL: u32 = 7u;
const MV_UV: u32 = 10u;
const MV: u32 = 12u;

struct VOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) albedo: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) alpha: f32,
    @location(4) fog: f32,
    @location(5) view: vec3<f32>,
    @location(6) @interpolate(linear) bary: vec3<f32>,
    @location(7) @interpolate(linear) edge: vec3<f32>,
    @location(8) @interpolate(flat) level: i32,
};

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

fn normalize3(a: vec3<f32>) -> vec3<f32> {
    let l = sqrt(dot3(a, a));
    if (l > 0.0) {
        return vec3<f32>(a.x / l, a.y / l, a.z / l);
    }
    return a;
}

// shade::height_albedo
fn height_albedo(t_in: f32) -> vec3<f32> {
    let t = clamp(t_in, 0.0, 1.0);
    var a = vec3<f32>(0.22, 0.38, 0.16);
    var b = vec3<f32>(0.47, 0.42, 0.27);
    var t0 = 0.0;
    var t1 = 0.45;
    if (t > 0.45) {
        a = b;
        b = vec3<f32>(0.52, 0.50, 0.47);
        t0 = 0.45;
        t1 = 0.75;
        if (t > 0.75) {
            a = b;
            b = vec3<f32>(0.95, 0.95, 0.97);
            t0 = 0.75;
            t1 = 1.0;
        }
    }
    let k = (t - t0) / (t1 - t0);
    return vec3<f32>(a.x + (b.x - a.x) * k, a.y + (b.y - a.y) * k, a.z + (b.z - a.z) * k);
}

// shade::fog::exp2
fn fog_exp2(x_in: f32) -> f32 {
    if (!(x_in > -126.0)) {
        return 0.0;
    }
    let x = min(x_in, 0.0);
    let i = floor(x);
    let f = x - i;
    let p = 1.0 + f * (0.6931472 + f * (0.2402265 + f * (0.05550411 + f * (0.009618129
        + f * (0.0013333558 + f * (0.0001540353 + f * 0.000015252734))))));
    return p * bitcast<f32>(u32(i32(i) + 127) << 23u);
}

fn height(x: i32, y: i32, l: i32) -> f32 {
    let n = D.level.z;
    return textureLoad(heights, vec2<i32>(wrap(x, n), wrap(y, n)), l, 0).x;
}

fn gradient(x: i32, y: i32, l: i32) -> vec2<f32> {
    let n = D.level.z;
    return textureLoad(gradients, vec2<i32>(wrap(x, n), wrap(y, n)), l, 0).xy;
}

// clipmap::morph::coarse_sample over heights of level l + 1.
fn coarse_height(x: i32, y: i32, l: i32) -> f32 {
    let hx = x >> 1u;
    let hy = y >> 1u;
    let rx = x & 1;
    let ry = y & 1;
    let a = height(hx, hy, l);
    if (rx == 0 && ry == 0) {
        return a;
    }
    if (rx == 1 && ry == 0) {
        return (a + height(hx + 1, hy, l)) * 0.5;
    }
    if (rx == 0) {
        return (a + height(hx, hy + 1, l)) * 0.5;
    }
    return (a + height(hx + 1, hy + 1, l)) * 0.5;
}

fn coarse_gradient(x: i32, y: i32, l: i32) -> vec2<f32> {
    let hx = x >> 1u;
    let hy = y >> 1u;
    let rx = x & 1;
    let ry = y & 1;
    let a = gradient(hx, hy, l);
    var b = a;
    if (rx == 0 && ry == 0) {
        return a;
    }
    if (rx == 1 && ry == 0) {
        b = gradient(hx + 1, hy, l);
    } else if (rx == 0) {
        b = gradient(hx, hy + 1, l);
    } else {
        b = gradient(hx + 1, hy + 1, l);
    }
    return vec2<f32>((a.x + b.x) * 0.5, (a.y + b.y) * 0.5);
}

// MorphParams::alpha
fn morph_alpha(x: i32, y: i32) -> f32 {
    if (D.flags.x == 0) {
        return 0.0;
    }
    let b = D.boundary;
    let s = D.stitched;
    if ((s.x != 0 && x == b.x) || (s.y != 0 && y == b.y) || (s.z != 0 && x == b.z) || (s.w != 0 && y == b.w)) {
        return 1.0;
    }
    let t = D.morph.z - D.morph.w - 1.0;
    let ax = clamp((abs(f32(x) - D.morph.x) - t) / D.morph.w, 0.0, 1.0);
    let ay = clamp((abs(f32(y) - D.morph.y) - t) / D.morph.w, 0.0, 1.0);
    return max(ax, ay);
}

// Level-window coordinates of the vertex a clipmap draw pulls, after
// stitching (MorphParams::stitch).
fn local_coords(vid: u32) -> vec2<i32> {
    let n = D.level.z;
    var c: vec2<i32>;
    if (D.level.w == MODE_STRIPS) {
        // Window-local indices (the CPU took the toroid origin off).
        let idx = strips[vid];
        c = vec2<i32>(i32(idx % u32(n)), i32(idx / u32(n)));
    } else {
        c = footprints[vid] + D.rel.zw;
    }
    return stitch(c);
}

// Odd vertices on a stitched side move onto their even neighbour below.
fn stitch(c: vec2<i32>) -> vec2<i32> {
    if (D.flags.x == 0) {
        return c;
    }
    let b = D.boundary;
    let s = D.stitched;
    let row = (s.y != 0 && c.y == b.y) || (s.w != 0 && c.y == b.w);
    if (row && ((c.x - b.x) & 1) == 1) {
        return vec2<i32>(c.x - 1, c.y);
    }
    let col = (s.x != 0 && c.x == b.x) || (s.z != 0 && c.x == b.z);
    if (col && ((c.y - b.y) & 1) == 1) {
        return vec2<i32>(c.x, c.y - 1);
    }
    return c;
}

struct Morphed {
    p: vec3<f32>,
    local: vec2<i32>,
    alpha: f32,
};

// Height fetch, morph and camera-relative position (VertexUniforms::position).
fn morphed(vid: u32) -> Morphed {
    let l = D.level.x;
    let g = D.level.y;
    let lc = local_coords(vid);
    let x = D.origin.x + lc.x;
    let y = D.origin.y + lc.y;
    let z = height(x, y, l);
    let alpha = morph_alpha(lc.x, lc.y);
    var zc = z;
    if (D.flags.x != 0) {
        zc = coarse_height(x, y, l + 1);
    }
    let keep = 1.0 - alpha;
    let zm = clamp(keep * z + alpha * zc, min(z, zc), max(z, zc));
    let p = vec3<f32>(
        f32(D.rel.x + lc.x * g) * G.cell.x,
        f32(D.rel.y - lc.y * g) * G.cell.y,
        zm * G.cell.z,
    );
    return Morphed(p, lc, alpha);
}

fn clip_of(p: vec3<f32>) -> vec4<f32> {
    return G.view_proj * vec4<f32>(p, 1.0);
}

// shade::wireframe::thresholds
fn edge_thresholds(c0: vec4<f32>, c1: vec4<f32>, c2: vec4<f32>) -> vec3<f32> {
    let hw = G.size.x * 0.5;
    let hh = G.size.y * 0.5;
    let o0 = 1.0 / c0.w;
    let o1 = 1.0 / c1.w;
    let o2 = 1.0 / c2.w;
    let p0 = vec2<f32>((c0.x * o0) * hw + hw, hh - (c0.y * o0) * hh);
    let p1 = vec2<f32>((c1.x * o1) * hw + hw, hh - (c1.y * o1) * hh);
    let p2 = vec2<f32>((c2.x * o2) * hw + hw, hh - (c2.y * o2) * hh);
    let a2 = (p1.x - p0.x) * (p2.y - p0.y) - (p2.x - p0.x) * (p1.y - p0.y);
    let aa = abs(a2);
    let d0 = p2 - p1;
    let d1 = p0 - p2;
    let d2 = p1 - p0;
    let l0 = sqrt(d0.x * d0.x + d0.y * d0.y);
    let l1 = sqrt(d1.x * d1.x + d1.y * d1.y);
    let l2 = sqrt(d2.x * d2.x + d2.y * d2.y);
    return vec3<f32>((0.5 * l0) / aa, (0.5 * l1) / aa, (0.5 * l2) / aa);
}

fn pt(vid: u32, k: u32) -> f32 {
    return passthrough[vid * PT + k];
}

fn mv(vid: u32, k: u32) -> f32 {
    return bitcast<f32>(mesh[vid * MV + k]);
}

// A resident mesh vertex's camera-relative position (VertexUniforms::position):
// the grid place less the floating origin (D.origin.xy) in integers, then
// f32, the offset, the cell; the height morphed as morph::blend does.
fn mesh_position(vid: u32) -> vec3<f32> {
    let col = bitcast<i32>(mesh[vid * MV + MV_GRID]);
    let row = bitcast<i32>(mesh[vid * MV + MV_GRID + 1u]);
    let z = mv(vid, MV_Z);
    let zc = mv(vid, MV_ZC);
    let alpha = mv(vid, MV_ALPHA);
    let keep = 1.0 - alpha;
    let zm = clamp(keep * z + alpha * zc, min(z, zc), max(z, zc));
    return vec3<f32>(
        (f32(col - D.origin.x) + mv(vid, MV_OFFSET)) * G.cell.x,
        (f32(D.origin.y - row) - mv(vid, MV_OFFSET + 1u)) * G.cell.y,
        zm * G.cell.z,
    );
}

// The camera-relative position of any vertex a draw pulls.
fn position_of(vid: u32) -> vec3<f32> {
    if (D.level.w == MODE_MESH) {
        return mesh_position(vid);
    }
    return morphed(vid).p;
}

@vertex
fn vs_main(@builtin(vertex_index) vid: u32) -> VOut {
    var o: VOut;
    o.level = D.level.x;
    let corner = vid % 3u;
    o.bary = vec3<f32>(0.0);
    o.bary[corner] = 1.0;
    if (D.level.w == MODE_PASSTHROUGH) {
        // Frames without grid places (exports), and every CPU-made mesh
        // on GL: the CPU vertex stage's output, passed through.
        o.pos = vec4<f32>(
            pt(vid, PT_CLIP), pt(vid, PT_CLIP + 1u), pt(vid, PT_CLIP + 2u), pt(vid, PT_CLIP + 3u)
        );
        o.albedo = vec3<f32>(pt(vid, PT_ALBEDO), pt(vid, PT_ALBEDO + 1u), pt(vid, PT_ALBEDO + 2u));
        o.normal = vec3<f32>(pt(vid, PT_NORMAL), pt(vid, PT_NORMAL + 1u), pt(vid, PT_NORMAL + 2u));
        o.uv = vec2<f32>(pt(vid, PT_UV), pt(vid, PT_UV + 1u));
        o.alpha = pt(vid, PT_ALPHA);
        o.fog = pt(vid, PT_FOG);
        o.view = vec3<f32>(pt(vid, PT_VIEW), pt(vid, PT_VIEW + 1u), pt(vid, PT_VIEW + 2u));
        o.edge = vec3<f32>(pt(vid, PT_EDGE), pt(vid, PT_EDGE + 1u), pt(vid, PT_EDGE + 2u));
        return o;
    }
    var p: vec3<f32>;
    if (D.level.w == MODE_MESH) {
        // Meshes no clipmap made: the view-independent attributes come
        // from the CPU, as a renderer would keep them resident.
        p = mesh_position(vid);
        o.uv = vec2<f32>(mv(vid, MV_UV), mv(vid, MV_UV + 1u));
        o.alpha = mv(vid, MV_ALPHA);
        o.normal = vec3<f32>(mv(vid, MV_NORMAL), mv(vid, MV_NORMAL + 1u), mv(vid, MV_NORMAL + 2u));
    } else {
        let m = morphed(vid);
        p = m.p;
        o.uv = vec2<f32>(f32(m.local.x), f32(m.local.y));
        o.alpha = m.alpha;
        if (VERTEX_NORMALS) {
            let l = D.level.x;
            let x = D.origin.x + m.local.x;
            let y = D.origin.y + m.local.y;
            var gr = gradient(x, y, l);
            if (D.flags.y != 0 && m.alpha > 0.0) {
                let c = coarse_gradient(x, y, l + 1);
                let k = 1.0 - m.alpha;
                gr = vec2<f32>(k * gr.x + m.alpha * c.x, k * gr.y + m.alpha * c.y);
            }
            // 1.0 from a uniform: with a literal, the compiler turns 1 / sqrt(d)
            // into an inverse square root, whose bits differ from the CPU's.
            o.normal = normalize3(vec3<f32>(-gr.x, -gr.y, G.eye.w));
        }
    }
    o.pos = clip_of(p);
    o.albedo = height_albedo((p.z - G.ramp.x) / G.ramp.y);
    let view = vec3<f32>(p.x - G.eye.x, p.y - G.eye.y, p.z - G.eye.z);
    o.view = view;
    if (FOG) {
        let d = sqrt(dot3(view, view));
        o.fog = fog_exp2(-(G.cell.w * d));
    }
    if (WIREFRAME) {
        let first = vid - corner;
        let c0 = clip_of(position_of(first));
        let c1 = clip_of(position_of(first + 1u));
        let c2 = clip_of(position_of(first + 2u));
        o.edge = edge_thresholds(c0, c1, c2);
    }
    return o;
}

// Lightmap (shade::shadows::Lightmap::sample)
fn lm_get(l: i32, x: i32, y: i32) -> f32 {
    let d = G.levels[l].lm;
    let cx = clamp(x, 0, d.y - 1);
    let cy = clamp(y, 0, d.z - 1);
    return textureLoad(lightmap, vec2<i32>(cx, d.x + cy), 0).x;
}

fn lm_bilinear(l: i32, ix: i32, iy: i32, tx: f32, ty: f32) -> f32 {
    let top = (1.0 - tx) * lm_get(l, ix, iy) + tx * lm_get(l, ix + 1, iy);
    let bottom = (1.0 - tx) * lm_get(l, ix, iy + 1) + tx * lm_get(l, ix + 1, iy + 1);
    return (1.0 - ty) * top + ty * bottom;
}

fn lm_sample(l: i32, o: vec2<i32>, uv: vec2<f32>, alpha: f32) -> f32 {
    let count = G.ints.y;
    let s = G.ints.z;
    let sf = f32(s);
    let h = vec2<f32>(uv.x * sf, uv.y * sf);
    let f = floor(h);
    let fv = lm_bilinear(min(l, count - 1), o.x * s + i32(f.x), o.y * s + i32(f.y), h.x - f.x, h.y - f.y);
    if (alpha <= 0.0 || l + 1 >= count) {
        return fv;
    }
    let b = o * s;
    let hh = vec2<f32>((f32(b.x & 1) + uv.x * sf) * 0.5, (f32(b.y & 1) + uv.y * sf) * 0.5);
    let ff = floor(hh);
    let c = lm_bilinear(l + 1, (b.x >> 1u) + i32(ff.x), (b.y >> 1u) + i32(ff.y), hh.x - ff.x, hh.y - ff.y);
    return (1.0 - alpha) * fv + alpha * c;
}

// Normal maps (shade::normal_map)
fn nm_get(l: i32, x: i32, y: i32) -> vec3<f32> {
    return textureLoad(normal_maps, vec2<i32>(x, G.levels[l].nm.z + y), 0).xyz;
}

fn lerp3(a: vec3<f32>, b: vec3<f32>, t: f32) -> vec3<f32> {
    let k = 1.0 - t;
    return vec3<f32>(k * a.x + t * b.x, k * a.y + t * b.y, k * a.z + t * b.z);
}

fn nm_sample(l: i32, h: vec2<f32>) -> vec3<f32> {
    let size = G.levels[l].nm.xy;
    let ix = clamp(i32(floor(h.x)), 0, size.x - 2);
    let iy = clamp(i32(floor(h.y)), 0, size.y - 2);
    let tx = clamp(h.x - f32(ix), 0.0, 1.0);
    let ty = clamp(h.y - f32(iy), 0.0, 1.0);
    let top = lerp3(nm_get(l, ix, iy), nm_get(l, ix + 1, iy), tx);
    let bottom = lerp3(nm_get(l, ix, iy + 1), nm_get(l, ix + 1, iy + 1), tx);
    return lerp3(top, bottom, ty);
}

fn pixel_normal(l: i32, o: vec2<i32>, uv: vec2<f32>, alpha: f32) -> vec3<f32> {
    let fo = G.levels[l].origin.zw;
    let f = nm_sample(l, vec2<f32>(f32(2 * o.x - fo.x) + 2.0 * uv.x, f32(2 * o.y - fo.y) + 2.0 * uv.y));
    var n = f;
    if (l + 1 < 32 && G.levels[l + 1].nm.w != 0 && alpha > 0.0) {
        let co = G.levels[l + 1].origin.zw;
        let s = nm_sample(l + 1, vec2<f32>(f32(o.x - co.x) + uv.x, f32(o.y - co.y) + uv.y));
        n = lerp3(f, s, alpha);
    }
    return normalize3(n);
}

fn lambert(albedo: vec3<f32>, light: f32) -> vec3<f32> {
    let ambient = G.ramp.z;
    let k = ambient + (1.0 - ambient) * light;
    return vec3<f32>(albedo.x * k, albedo.y * k, albedo.z * k);
}

@fragment
fn fs_main(i: VOut) -> @location(0) vec4<f32> {
    let l = i.level;
    var albedo = i.albedo;
    if (LEVEL_TINT) {
        albedo = G.levels[l].tint.xyz;
    }
    let sun = G.sun.xyz;
    let o = G.levels[l].origin.xy;
    var shadow = 1.0;
    if (SHADOWS) {
        shadow = lm_sample(l, o, i.uv, i.alpha);
    }
    var c = albedo;
    if (LIT) {
        var n: vec3<f32>;
        if (NORMAL_MAP) {
            n = pixel_normal(l, o, i.uv, i.alpha);
        } else {
            n = normalize3(i.normal);
        }
        c = lambert(albedo, max(dot3(n, sun), 0.0) * shadow);
        if (PHONG) {
            let v = normalize3(vec3<f32>(-i.view.x, -i.view.y, -i.view.z));
            let h = normalize3(vec3<f32>(sun.x + v.x, sun.y + v.y, sun.z + v.z));
            var s = max(dot3(n, h), 0.0);
            for (var k = 0; k < G.ints.w; k++) {
                s = s * s;
            }
            let spec = (G.ramp.w * s) * shadow;
            c = vec3<f32>(c.x + spec, c.y + spec, c.z + spec);
        }
    } else if (SHADOWS) {
        c = lambert(albedo, shadow);
    }
    if (FOG) {
        let f = i.fog;
        let g = 1.0 - f;
        let fc = G.fog_colour.xyz;
        c = vec3<f32>(c.x * f + fc.x * g, c.y * f + fc.y * g, c.z * f + fc.z * g);
    }
    if (WIREFRAME) {
        if (i.bary.x < i.edge.x || i.bary.y < i.edge.y || i.bary.z < i.edge.z) {
            let w = G.wire_colour.xyz;
            c = vec3<f32>(c.x * 0.2 + w.x * 0.8, c.y * 0.2 + w.y * 0.8, c.z * 0.2 + w.z * 0.8);
        }
    }
    return vec4<f32>(c, 1.0);
}
