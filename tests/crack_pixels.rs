//! Cracks in screen space, for every LOD scheme: renders over a red
//! background from random viewpoints show 0 background pixels enclosed by
//! terrain where a brute-force render covers them
//! (`terraclip::metrics::crack_pixels`; a silhouette difference is connected
//! to the sky, a crack is enclosed). The detector must be able to fail: the
//! draping annulus (T-junctions between rings) and clipmaps or CDLOD with
//! morph off show cracks.

mod common;
use terraclip::cracks::{survey, CrackReport};
use terraclip::scene::Scene;

fn scene(morph: bool) -> Scene {
    let mut s = common::small_scene();
    s.effects = if morph { vec!["morph".into()] } else { vec![] };
    s
}

fn run(morph: bool, schemes: &[&str], views: usize) -> CrackReport {
    let list: Vec<String> = schemes.iter().map(|s| s.to_string()).collect();
    survey(&scene(morph), &list, views, [96, 64], || {}).unwrap()
}

#[test]
fn no_crack_pixels_in_any_scheme_but_the_annulus() {
    let schemes = [
        "clipmap/strips",
        "clipmap/footprints",
        "geomipmap",
        "roam",
        "cdlod",
    ];
    let r = run(true, &schemes, 200);
    for s in &r.schemes {
        println!(
            "{}: {} crack px, {} lod-sky px",
            s.lod, s.crack_pixels, s.lod_sky_pixels
        );
        assert_eq!(
            s.crack_pixels, 0,
            "{}: {} crack pixels, worst view {} (camera {:?})",
            s.lod, s.crack_pixels, s.worst_view, s.worst_camera
        );
    }
}

#[test]
fn geomipmap_is_crack_free_without_morph_too() {
    // Its stitched sides, not the morph, close the seams.
    let r = run(false, &["geomipmap"], 100);
    assert_eq!(r.crack_pixels, 0, "{:?}", r.schemes[0].worst_camera);
}

#[test]
fn the_detector_sees_annulus_and_unmorphed_cracks() {
    let r = run(true, &["annulus"], 40);
    println!("annulus: {} crack px in 40 views", r.crack_pixels);
    assert!(r.crack_pixels > 0, "the annulus's T-junctions went unseen");
    let r = run(
        false,
        &["clipmap/strips", "clipmap/footprints", "cdlod"],
        40,
    );
    for s in &r.schemes {
        println!(
            "{}, morph off: {} crack px in 40 views",
            s.lod, s.crack_pixels
        );
        assert!(
            s.crack_pixels > 0,
            "{}: no cracks found with morph off",
            s.lod
        );
    }
}
