//! `phong`: Blinn–Phong specular highlight added to the diffuse term. The
//! exponent is a power of two applied by repeated squaring, so the GPU can
//! do the same multiplications instead of a `pow` whose bits differ.

use super::vec3::{dot, normalize};

/// Specular term for unit normal `n`, unit sun `l`, and `to_eye` (any
/// length): strength · max(0, n·h)^(2^squarings).
#[inline(always)]
pub fn specular(n: [f32; 3], l: [f32; 3], to_eye: [f32; 3], squarings: u32, strength: f32) -> f32 {
    let v = normalize(to_eye);
    let h = normalize([l[0] + v[0], l[1] + v[1], l[2] + v[2]]);
    let mut s = dot(n, h).max(0.0);
    for _ in 0..squarings {
        s *= s;
    }
    strength * s
}
