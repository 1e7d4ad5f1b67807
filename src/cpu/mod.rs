//! The CPU features the fast paths use, detected in one place, and the one
//! way to run code in a build compiled for them.
//!
//! `f32::mul_add` compiled for the x86-64 baseline is a library call, and
//! `floor` one into libm; compiled with AVX2 + FMA each is one instruction.
//! IEEE 754 fixes every result either way, so the two builds give the same
//! bits, and the choice only moves time.

/// True when the CPU has AVX2 and FMA, what the fast builds need.
pub fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// True when the CPU fuses multiply-adds in hardware (the pinned lavapipe
/// stack needs it for exact parity).
pub fn has_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Declares `fn NAME(fast: bool, ARGS…)`, which runs `BODY(ARGS…)` in a
/// build compiled for AVX2 + FMA when `fast` is true and the CPU has them,
/// and in the baseline build otherwise. `BODY` must be `#[inline(always)]`,
/// so that each build compiles its own copy of it: the compiler inlines it
/// into the AVX2 + FMA function and compiles it there. (A closure passed to
/// a generic wrapper is not inlined that way: it stays a baseline function,
/// and the fast build loses its FMA instructions.)
macro_rules! avx2_fma_twin {
    (
        $(#[$meta:meta])*
        $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? => $body:path
    ) => {
        $(#[$meta])*
        $vis fn $name(fast: bool, $($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if fast && $crate::cpu::has_avx2_fma() {
                #[target_feature(enable = "avx2,fma")]
                unsafe fn compiled_for_avx2_fma($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                // SAFETY: the CPU has AVX2 and FMA (checked just above).
                return unsafe { compiled_for_avx2_fma($($arg),*) };
            }
            let _ = fast;
            $body($($arg),*)
        }
    };
}
pub(crate) use avx2_fma_twin;

#[cfg(test)]
mod tests {
    use super::*;

    #[inline(always)]
    fn fused(x: [f32; 5]) -> [u32; 5] {
        x.map(|v| v.mul_add(1.0 / 3.0, -v).to_bits())
    }

    avx2_fma_twin! {
        fn fused_either(x: [f32; 5]) -> [u32; 5] => fused
    }

    #[test]
    fn both_builds_give_the_same_bits() {
        let x = [1.1f32, -2.7, 3.3e7, 1e-30, f32::MAX / 3.0];
        assert_eq!(fused_either(true, x), fused_either(false, x));
        assert_eq!(has_avx2_fma(), has_avx2_fma() && has_fma());
    }
}
