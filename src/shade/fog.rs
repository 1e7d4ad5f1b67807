//! `fog`: exponential fog, f = exp(−density · distance), as ATLOD uses. The
//! factor is computed per vertex and interpolated, so no transcendental runs
//! per pixel.
//!
//! `exp` itself differs between libm and a GPU's shader compiler (lavapipe
//! evaluates `exp2` with its own polynomial), so the factor uses [`exp2`]
//! below: plain f32 multiplies and adds in a fixed order plus an exponent
//! built from bits, which the WGSL vertex shader repeats operation for
//! operation (`src/gpu/shaders/terrain.wgsl`, `fog_exp2`).

/// The optical depth the default fog reaches at the far plane: exp(−0.4)
/// leaves 67 % of a colour there, so the farthest terrain fades but stays
/// visible whatever the map's size. A fixed density (1/12 km, the old
/// default) turned a map seen from 14 km up into fog colour alone.
pub const DEPTH_AT_FAR: f64 = 0.4;

/// The fog density of a scene that gives none: [`DEPTH_AT_FAR`] over the
/// far plane's distance.
pub fn density_for_far(far: f64) -> f64 {
    DEPTH_AT_FAR / far
}

/// log2(e) · density: the per-metre exponent the shaders take as a uniform.
pub fn rate(density: f64) -> f32 {
    (density * std::f64::consts::LOG2_E) as f32
}

/// The fog factor at distance `d` metres for `rate` from [`rate`]
/// (1 = clear, 0 = fully fogged).
#[inline(always)]
pub fn factor(rate: f32, d: f32) -> f32 {
    exp2(-(rate * d))
}

/// 2^x for x ≤ 0 (larger x is clamped to 0), within 2e-6 relative: a degree-7
/// Taylor polynomial of 2^f on f ∈ [0, 1) in Horner form, times 2^⌊x⌋ built
/// from the exponent bits. Underflow and NaN give 0.
#[inline(always)]
pub fn exp2(x: f32) -> f32 {
    // NaN fails every comparison and lands here too.
    if x.is_nan() || x <= -126.0 {
        return 0.0;
    }
    let x = x.min(0.0);
    let i = x.floor();
    let f = x - i;
    let p = 1.0
        + f * (std::f32::consts::LN_2
            + f * (0.240_226_5
                + f * (0.055_504_11
                    + f * (0.009_618_129
                        + f * (0.001_333_355_8 + f * (0.000_154_035_3 + f * 0.000_015_252_734))))));
    p * f32::from_bits(((i as i32 + 127) as u32) << 23)
}

/// c · f + fog · (1 − f).
#[inline(always)]
pub fn apply(c: [f32; 3], fog: [f32; 3], f: f32) -> [f32; 3] {
    let g = 1.0 - f;
    [
        c[0] * f + fog[0] * g,
        c[1] * f + fog[1] * g,
        c[2] * f + fog[2] * g,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp2_is_close_to_libm_and_exact_at_integers() {
        for k in 0..=20_000 {
            let x = -(k as f32) * 0.006;
            let want = (x as f64).exp2();
            let got = exp2(x) as f64;
            assert!(
                (got - want).abs() <= 2e-6 * want + 1e-38,
                "x={x}: {got} vs {want}"
            );
        }
        assert_eq!(exp2(0.0), 1.0);
        assert_eq!(exp2(-3.0), 0.125);
        assert_eq!(exp2(-200.0), 0.0);
        assert_eq!(exp2(f32::NAN), 0.0);
        assert_eq!(exp2(5.0), 1.0);
    }
}
