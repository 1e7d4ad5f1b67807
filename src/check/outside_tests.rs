//! The convention checks' thresholds and the error picture's colours,
//! each on a small buffer made to sit on one side of one threshold. The
//! goldens in tests/compare.rs reach these only as whole images, where a
//! threshold moved by one (`>` for `>=`, `9 + x` for `9 * x`) changes no
//! verdict.

use super::*;
use crate::check::compare::{Tier, TOLERANCE_DEPTH_ULP};

fn check(reference: &[f32], theirs: &[f32], w: usize) -> std::result::Result<(), String> {
    check_convention(Path::new("theirs.f32"), reference, theirs, w).map_err(|e| e.to_string())
}

/// The 24-bit grid's step.
const STEP: f64 = 1.0 / D24_MAX;

#[test]
fn an_empty_or_one_row_image_is_never_upside_down() {
    assert!(!rows_reversed(0, 2, |_, _| true));
    assert!(!rows_reversed(0, 0, |_, _| true));
    assert!(!rows_reversed(5, 1, |_, _| true));
}

#[test]
fn upside_down_takes_nine_in_ten_and_a_tenth_more_than_upright() {
    let (w, h) = (10, 10);
    let flip = |i: usize| (h - 1 - i / w) * w + i % w;
    // Every pixel matches upside down only.
    assert!(rows_reversed(w, h, |i, j| j == flip(i)));
    // Half of them: a tenth more than upright, but not nine in ten.
    assert!(!rows_reversed(w, h, |i, j| j == flip(i) && i < 50));
    // Every pixel both ways (a symmetric image): not a tenth more.
    assert!(!rows_reversed(w, h, |i, j| j == flip(i) || i == j));
}

#[test]
fn the_count_of_depths_outside_0_1_is_exact() {
    let reference = vec![0.5f32; 20];
    let mut theirs = reference.clone();
    theirs[4] = f32::NAN;
    theirs[7] = 2.0;
    theirs[9] = -0.1;
    let err = check(&reference, &theirs, 20).unwrap_err();
    assert!(
        err.contains("3 depths outside 0..1 (the first NaN at (4, 0))"),
        "{err}"
    );
}

/// Near the far plane 0.5 + 0.5 z is within 10⁻⁶ of z, so a buffer that
/// mostly matches ours there is not GL's range, however many of its
/// pixels also fit 0.5 + 0.5 z.
#[test]
fn gl_range_needs_most_pixels_unlike_ours() {
    let far = 0.999_999f32;
    assert!((0.5 + 0.5 * f64::from(far) - f64::from(far)).abs() <= 1e-6);
    // 60 pixels equal to ours near the far plane, 40 at 0.5 + 0.5 z.
    let reference: Vec<f32> = (0..100).map(|i| if i < 60 { far } else { 0.3 }).collect();
    let theirs: Vec<f32> = (0..100).map(|i| if i < 60 { far } else { 0.65 }).collect();
    assert_eq!(check(&reference, &theirs, 10), Ok(()));
    // The same with 40 equal and 60 at 0.5 + 0.5 z: GL's range.
    let reference: Vec<f32> = (0..100).map(|i| if i < 40 { far } else { 0.3 }).collect();
    let theirs: Vec<f32> = (0..100).map(|i| if i < 40 { far } else { 0.65 }).collect();
    let err = check(&reference, &theirs, 10).unwrap_err();
    assert!(err.contains("default depth range"), "{err}");
}

#[test]
fn cleared_to_0_takes_more_than_half_the_background() {
    let reference = [0.3, 0.3, 0.3, 0.3, 1.0, 1.0, 1.0, 1.0];
    let half = [0.3, 0.3, 0.3, 0.3, 1.0, 0.0, 1.0, 0.0];
    assert_eq!(check(&reference, &half, 4), Ok(()));
    let most = [0.3, 0.3, 0.3, 0.3, 0.0, 0.0, 1.0, 0.0];
    let err = check(&reference, &most, 4).unwrap_err();
    assert!(
        err.contains("cleared to 0") && err.contains("3 of 4"),
        "{err}"
    );
}

/// Zeros inside the surface (holes their renderer left cleared) are no
/// evidence of an order: only pixels both sides draw in (0, 1) are paired.
#[test]
fn reversed_z_pairs_only_pixels_drawn_on_both_sides() {
    let reference: Vec<f32> = (0..40)
        .map(|i| if i % 2 == 0 { 0.2 } else { 0.4 })
        .collect();
    let theirs: Vec<f32> = (0..40)
        .map(|i| if i % 2 == 0 { 0.2 } else { 0.0 })
        .collect();
    assert_eq!(check(&reference, &theirs, 40), Ok(()));
}

/// Pairs are neighbours along a row: never the last pixel of one row and
/// the first of the next, and never two pixels of equal reference depth.
#[test]
fn reversed_z_pairs_neighbours_along_a_row_whose_depths_differ() {
    // Two columns; the rows' depths rise downward in ours and fall in
    // theirs, equal along each row.
    let rows = 40;
    let reference: Vec<f32> = (0..2 * rows)
        .map(|i| 0.1 + 0.005 * (i / 2) as f32)
        .collect();
    let theirs: Vec<f32> = (0..2 * rows).map(|i| 0.9 - 0.01 * (i / 2) as f32).collect();
    assert_eq!(check(&reference, &theirs, 2), Ok(()));
    // One row of equal reference depth that theirs draws as a ramp.
    let reference = vec![0.3f32; 40];
    let theirs: Vec<f32> = (0..40).map(|i| 0.6 + 0.001 * i as f32).collect();
    assert_eq!(check(&reference, &theirs, 40), Ok(()));
}

/// Reversed Z takes at least 16 pairs ordered the other way and more than
/// nine times as many as ordered our way.
#[test]
fn reversed_z_takes_nine_in_ten_pairs_ordered_the_other_way() {
    // A ramp with 20 neighbouring pairs swapped: 20 against 179.
    let reference: Vec<f32> = (0..200).map(|i| 0.1 + 0.001 * i as f32).collect();
    let mut theirs = reference.clone();
    for k in 0..20 {
        theirs.swap(10 * k, 10 * k + 1);
    }
    assert_eq!(check(&reference, &theirs, 200), Ok(()));
    // Rows of two pixels: 20 rows ordered the other way, 5 ours (20 is
    // more than 9 + 5, not more than 9 × 5).
    let row = |y: usize, other_way: bool| {
        let (a, b) = (0.1 + 0.002 * y as f32, 0.6 + 0.002 * y as f32);
        let theirs = if other_way {
            [b + 0.05, b]
        } else {
            [b, b + 0.05]
        };
        ([a, a + 0.05], theirs)
    };
    let (reference, theirs): (Vec<[f32; 2]>, Vec<[f32; 2]>) =
        (0..25).map(|y| row(y, y < 20)).unzip();
    let (reference, theirs) = (reference.concat(), theirs.concat());
    assert_eq!(check(&reference, &theirs, 2), Ok(()));
    // 40 rows ordered the other way, 4 ours: reversed Z.
    let (reference, theirs): (Vec<[f32; 2]>, Vec<[f32; 2]>) =
        (0..44).map(|y| row(y, y < 40)).unzip();
    let err = check(&reference.concat(), &theirs.concat(), 2).unwrap_err();
    assert!(
        err.contains("reversed Z") && err.contains("40 of 44"),
        "{err}"
    );
}

#[test]
fn d24_is_named_only_for_differing_depths_within_a_step_of_ours() {
    let off_grid: Vec<f32> = (0..100)
        .map(|i| 0.1 + 0.003 * i as f32)
        .filter(|&z| d24(z) != z)
        .take(40)
        .collect();
    assert_eq!(off_grid.len(), 40);
    // A D24 buffer: every depth the nearest grid value.
    let fixed: Vec<f32> = off_grid.iter().map(|&z| d24(z)).collect();
    let err = check(&off_grid, &fixed, 40).unwrap_err();
    assert!(err.contains("24-bit depth buffer (D24)"), "{err}");
    // Ours where our depths lie on the grid: equal, so nothing to see.
    assert_eq!(check(&fixed, &fixed, 40), Ok(()));
    // On the grid but five steps off: not a rounding of ours.
    let five: Vec<f32> = off_grid
        .iter()
        .map(|&z| ((f64::from(z) / STEP).round() * STEP + 5.0 * STEP) as f32)
        .collect();
    assert!(five.iter().all(|&z| d24(z) == z));
    assert_eq!(check(&off_grid, &five, 40), Ok(()));
}

#[test]
fn the_error_pictures_colours() {
    let r = [30, 60, 90, 255];
    for in_band in [false, true] {
        assert_eq!(tier_colour(Tier::Same, in_band, &r), [10, 20, 30, 255]);
        assert_eq!(tier_colour(Tier::Hole, in_band, &r), [255, 0, 255, 255]);
    }
    assert_eq!(tier_colour(Tier::Shifted, false, &r), [0, 255, 255, 255]);
    assert_eq!(tier_colour(Tier::Unmatched, false, &r), [0, 255, 255, 255]);
    assert_eq!(tier_colour(Tier::Shifted, true, &r), [255, 200, 0, 255]);
    assert_eq!(tier_colour(Tier::Unmatched, true, &r), [255, 0, 0, 255]);
    // Equal depths: grey, darker toward the far plane:
    // (255 · (1 − 0.9⁸)) as u8 / 2 = 145 / 2.
    assert_eq!(depth_colour(0.9, 0.9), [72, 72, 72, 255]);
    assert_eq!(depth_colour(0.0, 0.0), [127, 127, 127, 255]);
    assert_eq!(depth_colour(1.0, 1.0), [0, 0, 0, 255]);
    // Background on one side only: magenta.
    assert_eq!(depth_colour(1.0, 0.5), [255, 0, 255, 255]);
    assert_eq!(depth_colour(0.5, 1.0), [255, 0, 255, 255]);
    // By ULP: blue within the tolerance, yellow within 2^16, red beyond.
    let ulp = |k: u32| depth_colour(0.5, f32::from_bits(0.5f32.to_bits() + k));
    let blue = [60, 120, 255, 255];
    let yellow = [255, 220, 0, 255];
    assert_eq!(ulp(1), blue);
    assert_eq!(ulp(TOLERANCE_DEPTH_ULP), blue);
    assert_eq!(ulp(TOLERANCE_DEPTH_ULP + 1), yellow);
    assert_eq!(ulp(1 << 16), yellow);
    assert_eq!(ulp((1 << 16) + 1), [255, 0, 0, 255]);
}
