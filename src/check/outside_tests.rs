//! The convention checks' thresholds and the error picture's colours,
//! each on a small buffer made to sit on one side of one threshold. The
//! goldens in tests/compare.rs reach these only as whole images, where a
//! threshold moved by one (`>` for `>=`, `9 + x` for `9 * x`) changes no
//! verdict.
//!
//! Then what a comparison reports, the loaders and the reach, on a small
//! export ([`SMALL`]): a comparison of it takes milliseconds where a
//! golden's takes about a second, so these run with the unit tests, and a
//! mutant of the file costs a rebuild of the library and two seconds of
//! tests rather than a minute of `tests/compare.rs`.

use super::*;
use crate::check::compare::{self as cmp, Tier, TOLERANCE_DEPTH_ULP};
use crate::export::Exported;

fn check(reference: &[f32], theirs: &[f32], w: usize) -> std::result::Result<(), String> {
    check_convention(Path::new("theirs.f32"), reference, theirs, w).map_err(|e| e.to_string())
}

/// A fresh folder for one test's files, under the crate's `target/`.
fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("target/unit-tmp/outside")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A small scene for the comparisons below: 128 × 80 pixels of a 129²
/// procedural map seen from beyond its south edge, sky above, so that an
/// export takes milliseconds and holds surface, background, silhouettes
/// and level seams.
const SMALL: &str = r#"
effects = ["lambert", "fog", "morph"]

[terrain]
procedural = { seed = 7, width = 129, height = 129, amplitude = 300.0 }
cell_size = 10.0

[lod]
scheme = "clipmap"
n = 15

[camera]
position = [640.0, -1200.0, 250.0]
look_at = [640.0, -900.0, 120.0]
fov = 60.0
near = 1.0
far = 5000.0

[image]
width = 128
height = 80
"#;

/// [`SMALL`] exported once for the whole test binary.
fn small() -> &'static Exported {
    static E: std::sync::OnceLock<Exported> = std::sync::OnceLock::new();
    E.get_or_init(|| {
        let scene = crate::scene::Scene::parse(SMALL, "small.toml", Path::new(".")).unwrap();
        let dir = scratch("small");
        crate::export::scene(&scene, "small", Some(SMALL), 1, 0.0, &dir).unwrap();
        crate::export::read(&dir).unwrap()
    })
}

#[test]
fn the_small_scene_shows_surface_background_and_edges() {
    let e = small();
    let n = e.image.depth.len();
    let sky = e.image.depth.iter().filter(|&&z| z == 1.0).count();
    eprintln!(
        "small: {n} px, {sky} background, {} triangles",
        e.frame.positions.len() / 3
    );
    assert!(sky > n / 10 && sky < n / 2, "{sky} of {n}");
    let r = crate::render::raster(&e.frame, crate::raster::Path::from_env());
    let band = cmp::tie_band_for(&r, false, 4)
        .iter()
        .filter(|&&b| b)
        .count();
    eprintln!("tie band at 4 bits: {band} px");
    assert!(band > n / 100 && band < n / 4, "{band} of {n}");
}

/// The 24-bit grid's step.
const STEP: f64 = 1.0 / D24_MAX;

#[test]
fn an_empty_or_one_row_image_is_never_upside_down() {
    assert!(!rows_reversed(0, 2, |_, _| true));
    assert!(!rows_reversed(0, 0, |_, _| true));
    assert!(!rows_reversed(5, 1, |_, _| true));
    // Two rows are the fewest that can be upside down: pixel i matches
    // only the pixel in the same column of the other row.
    let other_row = |i: usize, j: usize| i % 5 == j % 5 && i / 5 != j / 5;
    assert!(rows_reversed(5, 2, other_row));
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
    // A finite depth outside 0..1 is as bad as a NaN, and named first
    // when it comes first.
    theirs[2] = 1.5;
    let err = check(&reference, &theirs, 20).unwrap_err();
    assert!(
        err.contains("4 depths outside 0..1 (the first 1.5 at (2, 0))"),
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
    // Exactly half equal to ours (and every pixel at 0.5 + 0.5 z): not
    // fewer than half, so not GL's range.
    let reference: Vec<f32> = (0..100).map(|i| if i < 50 { far } else { 0.3 }).collect();
    let theirs: Vec<f32> = (0..100).map(|i| if i < 50 { far } else { 0.65 }).collect();
    assert_eq!(check(&reference, &theirs, 10), Ok(()));
    // Half at 0.5 + 0.5 z and half elsewhere: not nine in ten.
    let reference = vec![0.3f32; 100];
    let theirs: Vec<f32> = (0..100)
        .map(|i| if i < 50 { 0.65 } else { 0.2 + 0.001 * i as f32 })
        .collect();
    assert_eq!(check(&reference, &theirs, 10), Ok(()));
    // Background is no evidence either way: GL's range on the surface
    // is named however much background (where both hold 1) there is.
    let reference: Vec<f32> = (0..100).map(|i| if i < 60 { 1.0 } else { 0.3 }).collect();
    let theirs: Vec<f32> = (0..100).map(|i| if i < 60 { 1.0 } else { 0.65 }).collect();
    let err = check(&reference, &theirs, 10).unwrap_err();
    assert!(err.contains("40 of 40 surface pixels"), "{err}");
}

/// Depth rows bottom first are named, as colour rows are.
#[test]
fn depth_rows_bottom_first_are_named() {
    let (w, h) = (10, 10);
    let reference: Vec<f32> = (0..w * h)
        .map(|i| 0.1 + 0.01 * (i / w) as f32 + 0.0001 * (i % w) as f32)
        .collect();
    let theirs: Vec<f32> = (0..w * h)
        .map(|i| reference[(h - 1 - i / w) * w + i % w])
        .collect();
    let err = check(&reference, &theirs, w).unwrap_err();
    assert!(err.contains("only upside down"), "{err}");
    assert_eq!(check(&reference, &reference, w), Ok(()));
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
    // Of 10 background pixels, 6 zeros are more than half, 5 are not.
    let reference: Vec<f32> = (0..20).map(|i| if i < 10 { 0.3 } else { 1.0 }).collect();
    let zeros = |k: usize| -> Vec<f32> {
        (0..20)
            .map(|i| match i {
                0..10 => 0.3,
                _ if i - 10 < k => 0.0,
                _ => 1.0,
            })
            .collect()
    };
    assert_eq!(check(&reference, &zeros(5), 20), Ok(()));
    let err = check(&reference, &zeros(6), 20).unwrap_err();
    assert!(err.contains("6 of 10"), "{err}");
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

/// A pair needs both pixels surface in ours (depth under 1) and drawn in
/// theirs (depth in (0, 1)): a row of surface pixels each beside a pixel
/// that is background in ours, or 1 in theirs, pairs nothing, however
/// those neighbours are ordered.
#[test]
fn reversed_z_pairs_need_surface_in_ours_and_theirs() {
    let alternate =
        |a: f32, b: f32| -> Vec<f32> { (0..40).map(|i| if i % 2 == 0 { a } else { b }).collect() };
    // Background in ours beside surface, drawn nearer than it in theirs.
    assert_eq!(
        check(&alternate(0.2, 1.0), &alternate(0.8, 0.5), 40),
        Ok(())
    );
    // Surface in ours, 1 in theirs beside a nearer pixel.
    assert_eq!(
        check(&alternate(0.2, 0.3), &alternate(1.0, 0.5), 40),
        Ok(())
    );
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
    // 36 rows ordered the other way, 4 ours: 9 times as many, not more.
    let (reference, theirs): (Vec<[f32; 2]>, Vec<[f32; 2]>) =
        (0..40).map(|y| row(y, y < 36)).unzip();
    assert_eq!(check(&reference.concat(), &theirs.concat(), 2), Ok(()));
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
    // Only depths under 0.5 are looked at: a pixel of ours at exactly
    // 0.5 that theirs holds far from it does not hide the D24 buffer.
    let (mut ours, mut theirs) = (off_grid.clone(), fixed.clone());
    ours.push(0.5);
    theirs.push(0.7);
    let err = check(&ours, &theirs, 41).unwrap_err();
    assert!(err.contains("all 40 differing depths"), "{err}");
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

/// A depth OpenEXR's channel, one case per fallback: `Z`, else `depth`,
/// else `Y`, else `R`, else the only channel; two unnamed channels are an
/// error naming the file. Each channel holds its own values, so the one
/// read is known.
#[test]
fn depth_exr_channels_are_read_in_their_documented_order() {
    use crate::export::exr::{write, FloatLayer};
    let dir = scratch("depth-channels");
    std::fs::create_dir_all(&dir).unwrap();
    let (w, h) = (3u32, 2u32);
    // Channel `name`'s values: distinct per channel.
    let values = |name: &str| -> Vec<f32> {
        let k = name.bytes().map(u32::from).sum::<u32>() as f32;
        (0..w * h).map(|i| k / 1000.0 + i as f32 / 100.0).collect()
    };
    for (channels, want) in [
        (&["Z", "depth", "Y", "R"][..], Some("Z")),
        (&["depth", "Y", "R"][..], Some("depth")),
        (&["Y", "R", "G"][..], Some("Y")),
        (&["R", "G", "B"][..], Some("R")),
        (&["G"][..], Some("G")),
        (&["G", "B"][..], None),
    ] {
        let layer = FloatLayer {
            name: "depth".into(),
            width: w as usize,
            height: h as usize,
            channels: channels
                .iter()
                .map(|c| (c.to_string(), values(c)))
                .collect(),
        };
        let path = dir.join(format!("{}.exr", channels.join("-")));
        std::fs::write(&path, write(&[layer]).unwrap()).unwrap();
        match (load_depth(&path, w, h, None), want) {
            (Ok(d), Some(c)) => {
                assert_eq!(d, values(c), "{channels:?}: read another channel than {c}")
            }
            (Err(e), None) => {
                let e = e.to_string();
                assert!(
                    e.contains("G-B.exr") && e.contains("no channel named Z, depth, Y or R"),
                    "{e}"
                );
            }
            (r, want) => panic!("{channels:?}: {r:?}, wanted {want:?}"),
        }
    }
}

/// A colour image bottom row first, an EXR with the depth in another
/// channel than the one read first, an EXR with the reference's layout
/// beside another layer with a `Z`, and `--depth-channel`.
#[test]
fn colour_rows_and_exr_channels_are_named() {
    use crate::export::exr::{write, FloatLayer};
    let dir = scratch("exr-channels");
    std::fs::create_dir_all(&dir).unwrap();
    let e = small();
    let (w, h) = (e.image.width as usize, e.image.height as usize);
    let png = dir.join("theirs.png");
    std::fs::write(&png, e.image.png().unwrap()).unwrap();
    let opts = |c: Option<&str>| Options {
        depth_channel: c.map(str::to_string),
        ..Options::new(Mode::Exact)
    };
    // Colour bottom row first.
    let mut flipped = e.image.clone();
    for y in 0..h {
        let src = (h - 1 - y) * w * 4;
        flipped.rgba[y * w * 4..(y + 1) * w * 4].copy_from_slice(&e.image.rgba[src..src + w * 4]);
    }
    let upside = dir.join("upside-down.png");
    std::fs::write(&upside, flipped.png().unwrap()).unwrap();
    let err = run(&e.dir, Some(&upside), None, &opts(None), None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("upside-down.png") && err.contains("bottom first"),
        "{err}"
    );
    // RGB with the depth in G: R is read first, and G is named.
    let layer = |name: &str, chans: &[(&str, Vec<f32>)]| FloatLayer {
        name: name.into(),
        width: w,
        height: h,
        channels: chans
            .iter()
            .map(|(c, v)| (c.to_string(), v.clone()))
            .collect(),
    };
    let zeros = vec![0.0f32; w * h];
    let rgb = dir.join("rgb.exr");
    let depth = e.image.depth.clone();
    std::fs::write(
        &rgb,
        write(&[layer(
            "",
            &[
                ("R", zeros.clone()),
                ("G", depth.clone()),
                ("B", zeros.clone()),
            ],
        )])
        .unwrap(),
    )
    .unwrap();
    let err = run(&e.dir, Some(&png), Some(&rgb), &opts(None), None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("channel R is not the depth") && err.contains("--depth-channel G"),
        "{err}"
    );
    let o = run(&e.dir, Some(&png), Some(&rgb), &opts(Some("G")), None).unwrap();
    assert!(o.pass && o.depth_compared, "{o:?}");
    // The reference's layout (layer depth, channel Z) after another layer
    // with a Z: the depth layer is read.
    let two = dir.join("two-layers.exr");
    std::fs::write(
        &two,
        write(&[
            layer("normal", &[("X", zeros.clone()), ("Z", zeros.clone())]),
            layer("depth", &[("Z", depth.clone())]),
        ])
        .unwrap(),
    )
    .unwrap();
    let o = run(&e.dir, Some(&png), Some(&two), &opts(None), None).unwrap();
    assert!(o.pass, "{o:?}");
    // Z is then ambiguous by name, not as layer.channel.
    let err = run(&e.dir, Some(&png), Some(&two), &opts(Some("Z")), None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("2 channels are called 'Z'") && err.contains("normal.Z"),
        "{err}"
    );
    let o = run(&e.dir, Some(&png), Some(&two), &opts(Some("depth.Z")), None).unwrap();
    assert!(o.pass, "{o:?}");
    let err = run(&e.dir, Some(&png), Some(&two), &opts(Some("W")), None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("no") && err.contains("channel 'W'") && err.contains("depth.Z"),
        "{err}"
    );
}

/// `--only depth` judges depth alone (no image needed), `--only colour`
/// colour alone, and the default both.
#[test]
fn only_depth_and_only_colour_compare_one_buffer() {
    let e = small();
    let mut recoloured = e.image.clone();
    for v in recoloured.rgba.iter_mut().step_by(4) {
        *v = v.wrapping_add(40);
    }
    let mut deeper = e.image.clone();
    for z in deeper.depth.iter_mut().filter(|z| **z < 1.0) {
        *z = f32::from_bits(z.to_bits() + 1000);
    }
    let opts = |only| Options {
        only,
        ..Options::new(Mode::Exact)
    };
    let pass = |img: &Image, only| compare(e, img, &opts(only), None).unwrap().pass;
    use Only::{Both, Colour, Depth};
    assert!(pass(&recoloured, Depth) && !pass(&recoloured, Colour) && !pass(&recoloured, Both));
    assert!(pass(&deeper, Colour) && !pass(&deeper, Depth) && !pass(&deeper, Both));
    // Depth alone with no image at all.
    let dir = scratch("only-depth");
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("d.f32");
    let bytes: Vec<u8> = e.image.depth.iter().flat_map(|z| z.to_le_bytes()).collect();
    std::fs::write(&f, bytes).unwrap();
    let o = run(&e.dir, None, Some(&f), &opts(Depth), None).unwrap();
    assert!(o.pass && o.depth_compared && o.only == Depth, "{o:?}");
    // Colour alone ignores a depth file given with it, however wrong.
    let png = dir.join("c.png");
    let (w, h) = (e.image.width, e.image.height);
    image::RgbaImage::from_raw(w, h, e.image.rgba.clone())
        .unwrap()
        .save(&png)
        .unwrap();
    let wrong = dir.join("deeper.f32");
    let bytes: Vec<u8> = deeper.depth.iter().flat_map(|z| z.to_le_bytes()).collect();
    std::fs::write(&wrong, bytes).unwrap();
    let o = run(&e.dir, Some(&png), Some(&wrong), &opts(Colour), None).unwrap();
    assert!(o.pass && !o.depth_compared && o.only == Colour, "{o:?}");
    assert!(
        !run(&e.dir, Some(&png), Some(&wrong), &opts(Both), None)
            .unwrap()
            .pass
    );
    // Not even read: three bytes are no depth buffer.
    std::fs::write(&wrong, [0u8; 3]).unwrap();
    let o = run(&e.dir, Some(&png), Some(&wrong), &opts(Colour), None).unwrap();
    assert!(o.pass && !o.depth_compared, "{o:?}");
    assert!(run(&e.dir, Some(&png), Some(&wrong), &opts(Both), None).is_err());
    let err = run(&e.dir, None, Some(&f), &opts(Both), None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("--image"), "{err}");
    let no_depth = Image {
        depth: vec![],
        ..e.image.clone()
    };
    let err = compare(e, &no_depth, &opts(Depth), None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("--depth"), "{err}");
    // Sub-pixel precision out of range.
    let bits = |b| Options {
        subpixel_bits: b,
        ..Options::new(Mode::Tiered)
    };
    for b in [3, 9] {
        let err = compare(e, &e.image, &bits(b), None)
            .unwrap_err()
            .to_string();
        assert!(err.contains("--subpixel-bits"), "{err}");
    }
}

/// Big-endian depths whose little-endian reading is finite but outside
/// 0..1 (not NaN or infinite) are still named as big-endian: 0.5000039
/// (bits 0x3F000042) reads as 32.00024 the other way round.
#[test]
fn big_endian_is_named_when_the_wrong_reading_is_finite() {
    let dir = scratch("depth-endian");
    std::fs::create_dir_all(&dir).unwrap();
    let z = f32::from_bits(0x3F00_0042);
    assert_eq!(f32::from_le_bytes(z.to_be_bytes()), 32.000_24);
    let path = dir.join("be.f32");
    std::fs::write(
        &path,
        [z; 6]
            .iter()
            .flat_map(|v| v.to_be_bytes())
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    let err = load_depth(&path, 3, 2, None).unwrap_err().to_string();
    assert!(
        err.contains("be.f32") && err.contains("big-endian floats"),
        "{err}"
    );
    // The same values little-endian read as they are.
    std::fs::write(
        &path,
        [z; 6]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    assert_eq!(load_depth(&path, 3, 2, None).unwrap(), vec![z; 6]);
    // Depths in 0..1 read either way round are little-endian, as given:
    // zeros, 2^-126 and 2^-149, whose bytes reversed are other tiny
    // positive floats.
    let both = [0.0, f32::MIN_POSITIVE, 0.0, 1.0e-45, 0.0, 0.0];
    assert!(both
        .iter()
        .all(|z| (0.0..=1.0).contains(&f32::from_le_bytes(z.to_be_bytes()))));
    std::fs::write(
        &path,
        both.iter()
            .flat_map(|v| v.to_le_bytes())
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    assert_eq!(load_depth(&path, 3, 2, None).unwrap(), both.to_vec());
}

/// What a failing comparison reports, pixel by pixel, in each mode: the
/// failing pixels in scan order with their place, tier, band and distance
/// to the nearest edge of the set-up triangles whose box, grown by a
/// pixel, holds the pixel;
/// the worst pixel (the first with the largest step); the reason; and the
/// error picture's panels.
#[test]
fn a_failing_comparison_lists_its_pixels_and_draws_them() {
    let e = small();
    let (w, h) = (e.image.width as usize, e.image.height as usize);
    let raster = crate::render::raster(&e.frame, crate::raster::Path::from_env());
    let band = cmp::tie_band_for(&raster, e.frame.effects.wireframe, cmp::MIN_SUBPIXEL_BITS);
    // Terrain pixels with no band and no background within 3 px, at
    // least 8 px apart; and one band pixel as far from them.
    let clear = |i: usize| {
        let (x, y) = (i % w, i / w);
        x >= 3
            && y >= 3
            && x + 3 < w
            && y + 3 < h
            && (y - 3..=y + 3).all(|v| {
                (x - 3..=x + 3).all(|u| !band[v * w + u] && e.image.depth[v * w + u] < 1.0)
            })
    };
    let apart = |picked: &[usize], i: usize| {
        picked
            .iter()
            .all(|&p| (p % w).abs_diff(i % w).max((p / w).abs_diff(i / w)) >= 8)
    };
    let mut picked: Vec<usize> = vec![];
    for i in (0..w * h).step_by(3) {
        if picked.len() < 4 && clear(i) && apart(&picked, i) {
            picked.push(i);
        }
    }
    let in_band = (0..w * h)
        .step_by(13)
        .find(|&i| band[i] && e.image.depth[i] < 1.0 && apart(&picked, i))
        .unwrap();
    assert_eq!(picked.len(), 4, "{picked:?}");
    let [early, far, far2, deep] = [picked[0], picked[1], picked[2], picked[3]];
    let mut theirs = e.image.clone();
    let nudge = |img: &mut Image, i: usize, by: u8| {
        for k in 0..3 {
            let c = &mut img.rgba[4 * i + k];
            *c = if *c < 128 { *c + by } else { *c - by };
        }
    };
    nudge(&mut theirs, early, 2);
    nudge(&mut theirs, in_band, 3);
    nudge(&mut theirs, far, 120);
    nudge(&mut theirs, far2, 120);
    theirs.depth[far] *= 0.5;
    theirs.depth[deep] = f32::from_bits(theirs.depth[deep].to_bits() + 1);
    let nearest = |x: usize, y: usize| {
        nearest_of(
            raster.tris.iter().filter(|t| {
                let [x0, y0, x1, y1] = t.bbox.map(|v| v as f64);
                let (x, y) = (x as f64, y as f64);
                (x0 - 1.0..=x1 + 1.0).contains(&x) && (y0 - 1.0..=y1 + 1.0).contains(&y)
            }),
            x,
            y,
        )
    };
    let dir = scratch("failing-pixels");
    let run = |mode: Mode| {
        let o = compare(e, &theirs, &Options::new(mode), Some(&dir)).unwrap();
        assert!(!o.pass, "{mode}");
        for f in &o.failing {
            let i = f.y * w + f.x;
            assert_eq!(f.in_band, band[i], "{mode} {f:?}");
            assert_eq!(
                f.reference_rgba[..],
                e.image.rgba[4 * i..4 * i + 4],
                "{f:?}"
            );
            assert_eq!(f.theirs_rgba[..], theirs.rgba[4 * i..4 * i + 4], "{f:?}");
            assert_eq!(f.nearest_edge_px, nearest(f.x, f.y), "{mode} {f:?}");
        }
        let worst = o.worst.unwrap();
        assert_eq!((worst.x, worst.y), (far % w, far / w), "{mode}");
        let diff = image::open(dir.join("diff.png")).unwrap().to_rgba8();
        assert_eq!(diff.dimensions(), (4 * w as u32, h as u32));
        let panel = |k: usize, i: usize| diff.get_pixel((k * w + i % w) as u32, (i / w) as u32).0;
        for i in 0..w * h {
            assert_eq!(
                panel(0, i)[..],
                e.image.rgba[4 * i..4 * i + 4],
                "{mode} {i}"
            );
            assert_eq!(panel(2, i)[..], theirs.rgba[4 * i..4 * i + 4], "{mode} {i}");
        }
        (
            o,
            panel(1, far),
            panel(1, early),
            panel(3, deep),
            panel(3, far),
        )
    };
    let listed = |o: &Outcome| -> Vec<(usize, &str)> {
        o.failing.iter().map(|f| (f.y * w + f.x, f.tier)).collect()
    };
    let mut all = [early, in_band, far, far2, deep];
    all.sort();

    let (o, mask_far, mask_early, dz_deep, dz_far) = run(Mode::Exact);
    assert_eq!(
        listed(&o),
        all.iter().map(|&i| (i, "differs")).collect::<Vec<_>>()
    );
    let reason = o.reason.unwrap();
    assert!(
        reason.starts_with("4 px differ in colour (by up to 120 steps) and 2 in depth"),
        "{reason}"
    );
    assert_eq!(mask_far, [255, 0, 0, 255]);
    assert_eq!(mask_early, [255, 0, 0, 255]);
    assert_eq!(dz_deep, [60, 120, 255, 255]);
    assert_eq!(dz_far, [255, 0, 0, 255]);
    let quiet = (0..w * h).find(|&i| !all.contains(&i)).unwrap();
    let dim = e.image.rgba[4 * quiet..4 * quiet + 3].iter().map(|c| c / 3);
    let diff = image::open(dir.join("diff.png")).unwrap().to_rgba8();
    let got = diff.get_pixel((w + quiet % w) as u32, (quiet / w) as u32).0;
    assert_eq!(got[..3], dim.collect::<Vec<u8>>()[..]);

    let (o, mask_far, mask_early, _, _) = run(Mode::Tiered);
    let tiered: Vec<usize> = listed(&o).iter().map(|&(i, _)| i).collect();
    let mut want = vec![early, far, far2];
    want.sort();
    assert_eq!(tiered, want, "{:?}", o.failing);
    assert!(o
        .failing
        .iter()
        .all(|f| f.tier != "same" && f.tier != "hole"));
    assert_eq!(mask_far, [0, 255, 255, 255]);
    assert_eq!(mask_early, [0, 255, 255, 255]);

    let (o, _, _, _, _) = run(Mode::Flip);
    let flipped: Vec<usize> = listed(&o).iter().map(|&(i, _)| i).collect();
    assert!(
        flipped.contains(&far) && flipped.contains(&far2),
        "{flipped:?}"
    );
    for &i in &flipped {
        assert!(!band[i]);
        let near = [early, far, far2]
            .iter()
            .any(|&p| (p % w).abs_diff(i % w).max((p / w).abs_diff(i / w)) <= 3);
        assert!(near, "{i} is listed in flip mode: {flipped:?}");
    }
    let reason = o.reason.unwrap();
    assert!(
        reason.contains("1 px of depth differ outside the tie band") && !reason.contains("holes"),
        "{reason}"
    );
}

/// A comparison of images that are not whole or not the same size is an
/// error, before any pixel is read.
#[test]
fn images_of_another_size_or_not_whole_are_refused() {
    let e = small();
    let (w, h) = (e.image.width, e.image.height);
    let opts = Options::new(Mode::Tiered);
    let turned = Image {
        width: h,
        height: w,
        ..e.image.clone()
    };
    let err = compare(e, &turned, &opts, None).unwrap_err().to_string();
    assert!(
        err.contains(&format!("a {h}x{w} image where the reference is {w}x{h}")),
        "{err}"
    );
    let mut short = e.image.clone();
    short.rgba.pop();
    let err = compare(e, &short, &opts, None).unwrap_err().to_string();
    assert!(err.contains("colour bytes"), "{err}");
    let mut short = e.image.clone();
    short.depth.pop();
    let err = compare(e, &short, &opts, None).unwrap_err().to_string();
    assert!(err.contains("depths"), "{err}");
    let mut no_depth = crate::export::read(&e.dir).unwrap();
    no_depth.image.depth.clear();
    let err = compare(&no_depth, &e.image, &opts, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("not a whole image"), "{err}");
}

/// A failing pixel's nearest edge is looked for only among the triangles
/// whose box, grown by a pixel, holds it. Over every pixel of the small
/// frame that gives the nearest of all the triangles' edges, within the
/// fixed-point unit by which two triangles' copies of a shared edge may
/// differ (2^-8 px of snapping, at most 10^-6 px between the copies,
/// `nearest_edge`'s comment): 10^-5 px here.
/// The distance from pixel (x, y)'s centre to the nearest edge of any of
/// `tris`, over every edge they have and with no box test: what the tests
/// check `nearest_edge` against.
fn nearest_of<'a>(
    tris: impl IntoIterator<Item = &'a crate::raster::Tri>,
    x: usize,
    y: usize,
) -> Option<f64> {
    tris.into_iter()
        .flat_map(|t| cmp::edge_ends(&t.edges))
        .map(|[p, q]| cmp::segment_distance([x as f64, y as f64], p, q))
        .filter(|d| d.is_finite())
        .min_by(f64::total_cmp)
}

#[test]
fn the_nearest_edge_is_the_nearest_of_every_triangle() {
    let e = small();
    let r = crate::render::raster(&e.frame, crate::raster::Path::from_env());
    let (w, h) = (r.width as usize, r.height as usize);
    let (mut some, mut near, mut none) = (0, 0, 0);
    for y in 0..h {
        for x in 0..w {
            let all = nearest_of(&r.tris, x, y);
            match (nearest_edge(&r, x, y), all) {
                (Some(d), Some(all)) => {
                    some += 1;
                    assert!(d >= all, "({x}, {y}): {d} against {all}");
                    if all <= 0.5 {
                        near += 1;
                        assert!(d - all <= 1e-5, "({x}, {y}): {d} against {all}");
                    }
                }
                (None, all) => {
                    none += 1;
                    assert!(all.is_none_or(|a| a > 0.5), "({x}, {y}): {all:?}");
                }
                (d, None) => panic!("({x}, {y}): {d:?} with no triangle"),
            }
        }
    }
    eprintln!(
        "{some} pixels with a triangle near ({near} within 0.5 px of an edge), {none} without"
    );
    assert!(
        some > w * h / 2 && near > 0 && none > 0,
        "{some} {near} {none}"
    );
}

/// A triangle alone: the pixels one past its box on every side still
/// find its edges. In a whole frame a neighbour's shared edge answers
/// there too, so only a frame of one triangle shows a box grown too
/// little on one side.
#[test]
fn a_lone_triangle_is_found_one_pixel_past_its_box() {
    let e = small();
    let mut r = crate::render::raster(&e.frame, crate::raster::Path::from_env());
    let (w, h) = (r.width as i32, r.height as i32);
    // The largest triangle with a pixel of room on every side.
    let tri = *r
        .tris
        .iter()
        .filter(|t| t.bbox[0] >= 1 && t.bbox[1] >= 1 && t.bbox[2] + 1 < w && t.bbox[3] + 1 < h)
        .max_by_key(|t| (t.bbox[2] - t.bbox[0]) * (t.bbox[3] - t.bbox[1]))
        .expect("a triangle inside the frame");
    r.tris = vec![tri];
    let [x0, y0, x1, y1] = tri.bbox;
    let ring = (x0 - 1..=x1 + 1)
        .flat_map(|x| [(x, y0 - 1), (x, y1 + 1)])
        .chain((y0..=y1).flat_map(|y| [(x0 - 1, y), (x1 + 1, y)]));
    let mut seen = 0;
    for (x, y) in ring {
        let (x, y) = (x as usize, y as usize);
        assert_eq!(
            nearest_edge(&r, x, y),
            nearest_of([&tri], x, y),
            "({x}, {y})"
        );
        seen += 1;
    }
    // Two pixels past the box: no box holds it.
    if x1 + 2 < w {
        assert_eq!(nearest_edge(&r, (x1 + 2) as usize, y0 as usize), None);
    }
    assert!(seen >= 8, "{seen}");
}

/// The reach for `bits` of sub-pixel precision holds the frame drawn with
/// every vertex moved by up to s = 2^-bits + 1/256 px: its four corners
/// and points inside the square (a depth within the comparison's
/// [`TOLERANCE_DEPTH_ULP`] of the reach's range, since a depth
/// interpolated at a move between two corners may round a few ULP past
/// both: 18 pixels here at 8 bits were more than 1 ULP out, none more
/// than 16). Moved by
/// 2.5 s, some pixel leaves it.
#[test]
fn the_reach_holds_a_move_within_the_square_and_not_beyond() {
    let e = small();
    for bits in [4, 8] {
        let s = 0.5f32.powi(bits as i32) + 1.0 / 256.0;
        let r = reach(e, bits);
        let outside = |img: &Image| {
            let beyond = |a: f32, z: f32| cmp::ulp_distance(a, z) > u64::from(TOLERANCE_DEPTH_ULP);
            (0..img.depth.len())
                .filter(|&i| {
                    let z = img.depth[i];
                    (0..4).any(|k| !(r.lo[i][k]..=r.hi[i][k]).contains(&img.rgba[4 * i + k]))
                        || (z < r.zlo[i] && beyond(r.zlo[i], z))
                        || (z > r.zhi[i] && beyond(r.zhi[i], z))
                })
                .count()
        };
        let inside = [
            (s, s),
            (-s, s),
            (s, -s),
            (-s, -s),
            (0.9 * s, -0.9 * s),
            (-0.5 * s, 0.0),
        ];
        for (dx, dy) in inside {
            assert_eq!(outside(&moved(e, dx, dy)), 0, "{bits} bits: ({dx}, {dy})");
        }
        for (dx, dy) in [(2.5 * s, 0.0), (0.0, -2.5 * s)] {
            let n = outside(&moved(e, dx, dy));
            eprintln!("{bits} bits: shifted ({dx}, {dy}): {n} px outside the reach");
            assert!(n > 0, "{bits} bits: ({dx}, {dy})");
        }
    }
}

/// The reference compared with itself: every figure of the outcome, and
/// with a folder the two pictures (four panels of the frame's size, the
/// error mask dimmed reference and the depth panel grey).
#[test]
fn the_reference_passes_every_mode_with_every_figure_zero() {
    let e = small();
    let (w, h) = (e.image.width as usize, e.image.height as usize);
    let r = crate::render::raster(&e.frame, crate::raster::Path::from_env());
    for mode in [Mode::Exact, Mode::Tiered, Mode::Flip] {
        for bits in [4, 8] {
            let opts = Options {
                subpixel_bits: bits,
                ..Options::new(mode)
            };
            let dir = scratch(&format!("itself-{mode}-{bits}"));
            let o = compare(e, &e.image, &opts, Some(&dir)).unwrap();
            let band = cmp::tie_band_for(&r, e.frame.effects.wireframe, bits);
            assert!(
                o.pass && o.reason.is_none() && o.failing.is_empty(),
                "{o:?}"
            );
            assert_eq!((o.mode, o.only, o.subpixel_bits), (mode, Only::Both, bits));
            assert_eq!(o.tie_distance_px, cmp::tie_distance(bits));
            assert_eq!((o.width, o.height), (w as u32, h as u32));
            assert!(o.depth_compared && o.worst.is_none());
            assert_eq!(
                (
                    o.colour_px_differ,
                    o.depth_px_differ,
                    o.max_channel_diff,
                    o.max_depth_ulp
                ),
                (0, 0, 0, 0)
            );
            assert_eq!(
                o.tiers,
                Tiers {
                    same: w * h,
                    ..Tiers::default()
                }
            );
            assert_eq!(o.band_px, band.iter().filter(|&&b| b).count());
            assert!(o.band_px > 0 && o.band_px < w * h / 2, "{}", o.band_px);
            for f in [o.flip, o.flip_all] {
                // FLIP's largest error starts at the least normal float.
                assert_eq!((f.mean, f.p9999), (0.0, 0.0));
                assert!(f.max <= f32::MIN_POSITIVE, "{f:?}");
                assert_eq!((f.mean_max, f.p9999_max), (FLIP_MEAN, FLIP_TAIL_MAX));
            }
            assert_eq!(o.outputs, vec![dir.join("diff.png"), dir.join("flip.png")]);
            let diff = image::open(dir.join("diff.png")).unwrap().to_rgba8();
            assert_eq!(diff.dimensions(), (4 * w as u32, h as u32));
            let heat = image::open(dir.join("flip.png")).unwrap().to_rgba8();
            assert_eq!(heat.dimensions(), (w as u32, h as u32));
            for i in 0..w * h {
                let px = |k: usize| diff.get_pixel((k * w + i % w) as u32, (i / w) as u32).0;
                let c = &e.image.rgba[4 * i..4 * i + 4];
                assert_eq!(px(0)[..], c[..]);
                assert_eq!(px(1), [c[0] / 3, c[1] / 3, c[2] / 3, 255]);
                assert_eq!(px(2)[..], c[..]);
                let z = e.image.depth[i];
                assert_eq!(px(3), depth_colour(z, z));
            }
        }
    }
    // Without depth, three panels.
    let dir = scratch("itself-colour");
    let opts = Options {
        only: Only::Colour,
        ..Options::new(Mode::Tiered)
    };
    let o = compare(e, &e.image, &opts, Some(&dir)).unwrap();
    assert!(o.pass && !o.depth_compared, "{o:?}");
    let diff = image::open(dir.join("diff.png")).unwrap().to_rgba8();
    assert_eq!(diff.dimensions(), (3 * w as u32, h as u32));
}

/// The worst pixel is the first in scan order with the largest channel
/// step, its colours and depths read at that pixel.
#[test]
fn the_worst_pixel_is_the_first_with_the_largest_step() {
    let e = small();
    let w = e.image.width as usize;
    let mut theirs = e.image.clone();
    let bump = |img: &mut Image, i: usize, k: usize, by: u8| {
        let c = &mut img.rgba[4 * i + k];
        *c = if *c < 128 { *c + by } else { *c - by };
    };
    // Steps of 9 at pixels 100 and 700 (the first of the two is the
    // worst), 5 before them at 50, and 9 again at 900.
    bump(&mut theirs, 50, 0, 5);
    bump(&mut theirs, 100, 1, 9);
    bump(&mut theirs, 700, 2, 9);
    bump(&mut theirs, 900, 0, 9);
    theirs.depth[100] = 0.25;
    let o = compare(e, &theirs, &Options::new(Mode::Exact), None).unwrap();
    let worst = o.worst.unwrap();
    assert_eq!((worst.x, worst.y), (100 % w, 100 / w));
    assert_eq!(worst.a_rgba[..], e.image.rgba[400..404]);
    assert_eq!(worst.b_rgba[..], theirs.rgba[400..404]);
    assert_eq!((worst.a_depth, worst.b_depth), (e.image.depth[100], 0.25));
    assert_eq!(o.max_channel_diff, 9);
    assert_eq!((o.colour_px_differ, o.depth_px_differ), (4, 1));
}

/// The frame drawn with every vertex moved by (dx, dy) px: a translation
/// of normalised device coordinates after the view-projection (y is up
/// there, down in the window).
fn moved(e: &Exported, dx: f32, dy: f32) -> Image {
    let mut f = e.frame.clone();
    let ndc = glam::Vec3::new(2.0 * dx / f.width as f32, -2.0 * dy / f.height as f32, 0.0);
    let vp = glam::Mat4::from_cols_array_2d(&f.uniforms.view_proj);
    f.uniforms.view_proj = (glam::Mat4::from_translation(ndc) * vp).to_cols_array_2d();
    crate::render::draw(&f, &Default::default(), &mut Default::default()).0
}

/// A renderer whose vertices land at a corner of the reach's square
/// (s = 2^-4 + 1/256 px each way) passes the tiered and FLIP modes, which
/// look up the reach, and fails the exact mode, which does not. Without
/// the reach the tiered mode fails it: 2,669 pixels shifted outside the
/// band, 88 unmatched.
#[test]
fn a_sub_pixel_move_passes_by_the_reach_and_fails_exact() {
    let e = small();
    let s = 0.5f32.powi(MIN_SUBPIXEL_BITS as i32) + 1.0 / 256.0;
    let theirs = moved(e, s, s);
    let o = compare(e, &theirs, &Options::new(Mode::Exact), None).unwrap();
    assert!(!o.pass && o.depth_px_differ > 0, "{o:?}");
    for mode in [Mode::Tiered, Mode::Flip] {
        let o = compare(e, &theirs, &Options::new(mode), None).unwrap();
        assert!(o.pass, "{mode}: {o:?}");
    }
}

/// FLIP mode judges colour away from the edges by both figures: five
/// inverted pixels there leave the mean far under [`FLIP_MEAN`] but put
/// the 99.99th percentile over [`FLIP_TAIL_MAX`], and fail it, though
/// the geometry (depth) is the reference's, and the reason gives FLIP's
/// figures alone. The same five as background are holes, and the reason
/// names them and the depth. The same five in the band are not judged by
/// FLIP.
#[test]
fn a_few_wrong_colours_away_from_edges_fail_flip_by_the_tail() {
    let e = small();
    let (w, h) = (e.image.width as usize, e.image.height as usize);
    let raster = crate::render::raster(&e.frame, crate::raster::Path::from_env());
    let band = cmp::tie_band_for(&raster, e.frame.effects.wireframe, MIN_SUBPIXEL_BITS);
    let invert = |img: &mut Image, at: &[usize]| {
        for &i in at {
            for k in 0..3 {
                img.rgba[4 * i + k] = 255 - img.rgba[4 * i + k];
            }
        }
    };
    // Surface pixels 9 px apart: in the band, or with neither band nor
    // background within R px.
    const R: usize = 3;
    let clear = |i: usize| {
        let (x, y) = (i % w, i / w);
        x >= R
            && y >= R
            && x + R < w
            && y + R < h
            && (y - R..=y + R).all(|v| {
                (x - R..=x + R).all(|u| !band[v * w + u] && e.image.depth[v * w + u] < 1.0)
            })
    };
    let pick = |in_band: bool| -> Vec<usize> {
        (0..w * h)
            .step_by(9)
            .filter(|&i| {
                if in_band {
                    band[i] && e.image.depth[i] < 1.0
                } else {
                    clear(i)
                }
            })
            .take(5)
            .collect()
    };
    let mut theirs = e.image.clone();
    let off = pick(false);
    assert_eq!(off.len(), 5, "{off:?}");
    invert(&mut theirs, &off);
    let o = compare(e, &theirs, &Options::new(Mode::Flip), None).unwrap();
    assert!(!o.pass, "{o:?}");
    assert!(o.flip.mean < FLIP_MEAN / 10.0, "{:?}", o.flip);
    assert!(o.flip.p9999 > FLIP_TAIL_MAX, "{:?}", o.flip);
    assert_eq!((o.depth_px_differ, o.tiers.holes), (0, 0), "{o:?}");
    // The reason names FLIP's figures and nothing else.
    let why = o.reason.clone().unwrap_or_default();
    assert!(
        why.starts_with("FLIP over the ") && !why.contains(';'),
        "{why}"
    );
    assert!(
        why.contains(&format!("99.99th percentile {:.4}", o.flip.p9999)),
        "{why}"
    );
    // The same pixels as background, their colour the reference's: holes,
    // named, and depth outside the band; FLIP's line only if its figures
    // fail.
    let mut theirs = e.image.clone();
    for &i in &off {
        theirs.depth[i] = 1.0;
    }
    let o = compare(e, &theirs, &Options::new(Mode::Flip), None).unwrap();
    let why = o.reason.clone().unwrap_or_default();
    assert!(!o.pass && o.tiers.holes > 0, "{o:?}");
    assert!(why.contains(&format!("{} holes", o.tiers.holes)), "{why}");
    assert!(
        why.contains("px of depth differ outside the tie band"),
        "{why}"
    );
    assert_eq!(
        why.contains("FLIP over the"),
        o.flip.mean > FLIP_MEAN || o.flip.p9999 > FLIP_TAIL_MAX,
        "{why}"
    );
    let mut theirs = e.image.clone();
    invert(&mut theirs, &pick(true));
    let o = compare(e, &theirs, &Options::new(Mode::Flip), None).unwrap();
    assert!(o.pass && o.flip.p9999 == 0.0, "{o:?}");
}
