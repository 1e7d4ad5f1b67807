//! `lambert`: diffuse lighting from the sun, n·l clamped at zero, over an
//! ambient floor.

use super::vec3::dot;

/// Diffuse factor for unit normal `n` and unit sun direction `l`.
#[inline(always)]
pub fn diffuse(n: [f32; 3], l: [f32; 3]) -> f32 {
    dot(n, l).max(0.0)
}

/// Lit colour: albedo · (ambient + (1 − ambient) · light), where `light` is
/// the diffuse factor already darkened by any shadow.
#[inline(always)]
pub fn apply(albedo: [f32; 3], ambient: f32, light: f32) -> [f32; 3] {
    let k = ambient + (1.0 - ambient) * light;
    albedo.map(|a| a * k)
}
