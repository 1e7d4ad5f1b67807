// Shared by terrain.wgsl and update.wgsl, which are compiled with this
// file in front of them (gpu::TERRAIN_WGSL, gpu::update).

// v mod n in 0..n (n > 0), taking `%` only of operands that are not
// negative. WGSL defines `%` of a negative i32, but GLSL leaves it
// undefined and naga's GL back end writes WGSL's `%` as GLSL's: on
// llvmpipe's GL a negative toroid coordinate fetched the wrong texel.
fn wrap(v: i32, n: i32) -> i32 {
    if (v >= 0) {
        return v % n;
    }
    // -(v + 1) cannot overflow, even for the most negative i32.
    return n - 1 - (-(v + 1)) % n;
}
