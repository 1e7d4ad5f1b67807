// The clipmap update on the GPU (GPU Gems 2 ch. 2; LH04): each texel of a
// dirty rectangle of level l's toroid is the four-point subdivision of
// level l + 1's toroid plus, for a synthesised level, the noise table's
// value times the level's amplitude, or, for a level of a pack coded
// against that subdivision, its uploaded residual times the pack's step;
// its slope is the central difference of two such samples. Every
// operation is the CPU's (src/pyramid/subdivide.rs, src/synthesis/mod.rs,
// src/pack/codec.rs, src/shade/normals.rs) in the same order and the same
// shapes, so lavapipe gives the same bits (docs/reference/raster-rules.md).

struct Synth {
    // Fine level: width, height; coarse level: width, height.
    dims: vec4<i32>,
    // Toroid side n, noise level index k, stretch numerator, denominator.
    grid: vec4<i32>,
    // The fine window's origin (level texels), and the rectangle's first
    // toroid texel.
    origin: vec4<i32>,
    // The rectangle's toroid texels past the last, and whether slopes are
    // written.
    rect_end: vec4<i32>,
    // Amplitude (or the pack's step), slope scale x, slope scale y.
    scale: vec4<f32>,
    // The box of level texels the rectangle reads (its own and, with
    // slopes, one around), which the residuals and the first pass cover:
    // first column, first row, columns, rows.
    res_box: vec4<i32>,
    // 0 synthesises, 1 adds residuals; escapes after the codes.
    res: vec4<i32>,
}

@group(0) @binding(0) var<uniform> s: Synth;
@group(0) @binding(1) var coarse: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> table: array<f32>;
@group(0) @binding(3) var fine: texture_storage_2d<r32float, write>;
@group(0) @binding(4) var slopes: texture_storage_2d<rg32float, write>;
// The residuals of the box, row-major, two i16 codes a word (the even
// sample in the low half); a code of -32768 is an escape, whose height's
// bits follow the codes as (sample index, bits) pairs sorted by index.
@group(0) @binding(5) var<storage, read> residuals: array<u32>;

// Coarse sample (i, j), clamped to the coarse level, from its toroid.
fn c(i: i32, j: i32) -> f32 {
    let n = s.grid.x;
    let ii = clamp(i, 0, s.dims.z - 1);
    let jj = clamp(j, 0, s.dims.w - 1);
    return textureLoad(coarse, vec2<i32>(wrap(ii, n), wrap(jj, n)), 0).r;
}

// (9 (v1 + v2) - (v0 + v3)) / 16, the CPU's shape.
fn four(v0: f32, v1: f32, v2: f32, v3: f32) -> f32 {
    return (9.0 * (v1 + v2) - (v0 + v3)) / 16.0;
}

// The four-point value between coarse (i, j) and (i + dx, j + dy).
fn line(i: i32, j: i32, dx: i32, dy: i32) -> f32 {
    return four(c(i - dx, j - dy), c(i, j), c(i + dx, j + dy), c(i + 2 * dx, j + 2 * dy));
}

// Synthesised sample (x, y) of the fine level, 0 <= x < width.
fn synth(x: i32, y: i32) -> f32 {
    let i = x / 2;
    let j = y / 2;
    var v: f32;
    if (x % 2 == 0 && y % 2 == 0) {
        v = c(i, j);
    } else if (y % 2 == 0) {
        v = line(i, j, 1, 0);
    } else if (x % 2 == 0) {
        v = line(i, j, 0, 1);
    } else {
        let a = four(line(i - 1, j, 0, 1), line(i, j, 0, 1), line(i + 1, j, 0, 1), line(i + 2, j, 0, 1));
        let b = four(line(i, j - 1, 1, 0), line(i, j, 1, 0), line(i, j + 1, 1, 0), line(i, j + 2, 1, 0));
        v = (a + b) * 0.5;
    }
    if (s.res.x == 1) {
        return with_residual(x, y, v);
    }
    let off = 17 * s.grid.y;
    let u = wrap((s.grid.z * x) / s.grid.w + off, 64);
    let t = wrap((s.grid.z * y) / s.grid.w + 3 * off, 64);
    return v + s.scale.x * table[t * 64 + u];
}

// Level sample (x, y), predicted as p, from its residual.
fn with_residual(x: i32, y: i32, p: f32) -> f32 {
    let i = (y - s.res_box.y) * s.res_box.z + (x - s.res_box.x);
    let w = bitcast<i32>(residuals[i / 2]);
    var q: i32;
    if (i % 2 == 0) {
        q = (w << 16u) >> 16u;
    } else {
        q = w >> 16u;
    }
    if (q != -32768) {
        return p + f32(q) * s.scale.x;
    }
    // The escape's pair: a binary search over the sorted indices.
    let base = (s.res_box.z * s.res_box.w + 1) / 2;
    var lo = 0;
    var hi = s.res.y;
    while (hi - lo > 1) {
        let mid = (lo + hi) / 2;
        if (i32(residuals[base + 2 * mid]) <= i) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return bitcast<f32>(residuals[base + 2 * lo + 1]);
}

// The box's samples as the first pass made them, row-major.
@group(0) @binding(6) var<storage, read_write> scratch: array<f32>;

// First pass: each sample of the box (the rectangle's level texels and
// one around them, clamped to the level) made once, where the slopes
// would otherwise make each five times.
@compute @workgroup_size(8, 8)
fn fill(@builtin(global_invocation_id) id: vec3<u32>) {
    let bx = i32(id.x);
    let by = i32(id.y);
    if (bx >= s.res_box.z || by >= s.res_box.w) {
        return;
    }
    scratch[by * s.res_box.z + bx] = synth(s.res_box.x + bx, s.res_box.y + by);
}

// Level sample (x, y), clamped to the level, as the first pass made it.
fn clamped(x: i32, y: i32) -> f32 {
    let cx = clamp(x, 0, s.dims.x - 1) - s.res_box.x;
    let cy = clamp(y, 0, s.dims.y - 1) - s.res_box.y;
    return scratch[cy * s.res_box.z + cx];
}

// Second pass: the rectangle's toroid texels and slopes from the box.
@compute @workgroup_size(8, 8)
fn update(@builtin(global_invocation_id) id: vec3<u32>) {
    let tx = s.origin.z + i32(id.x);
    let ty = s.origin.w + i32(id.y);
    if (tx >= s.rect_end.x || ty >= s.rect_end.y) {
        return;
    }
    let n = s.grid.x;
    // The level texel this toroid texel holds.
    let x = s.origin.x + wrap(tx - s.origin.x, n);
    let y = s.origin.y + wrap(ty - s.origin.y, n);
    textureStore(fine, vec2<i32>(tx, ty), vec4<f32>(clamped(x, y), 0.0, 0.0, 0.0));
    if (s.rect_end.z != 0) {
        let gx = (clamped(x + 1, y) - clamped(x - 1, y)) * s.scale.y;
        let gy = (clamped(x, y - 1) - clamped(x, y + 1)) * s.scale.z;
        textureStore(slopes, vec2<i32>(tx, ty), vec4<f32>(gx, gy, 0.0, 0.0));
    }
}
