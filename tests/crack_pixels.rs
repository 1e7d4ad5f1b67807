//! Cracks in screen space, for every LOD scheme: renders over a red
//! background from random viewpoints show 0 background pixels enclosed by
//! terrain where a brute-force render covers them
//! (`terraclip::studies::metrics::crack_pixels`; a silhouette difference is connected
//! to the sky, a crack is enclosed). The detector must be able to fail: the
//! draping annulus (T-junctions between rings) and clipmaps or CDLOD with
//! morph off show cracks.

mod common;
use terraclip::scene::{Effect, Scene};
use terraclip::studies::cracks::{survey, CrackReport};
use terraclip::studies::shard::Shard;

fn scene(morph: bool) -> Scene {
    let mut s = common::small_scene();
    s.effects = if morph { vec![Effect::Morph] } else { vec![] };
    s
}

fn run(morph: bool, schemes: &[&str], views: usize) -> CrackReport {
    let list: Vec<String> = schemes.iter().map(|s| s.to_string()).collect();
    survey(&scene(morph), &list, views, [96, 64], Shard::WHOLE, || {}).unwrap()
}

#[test]
fn no_crack_pixels_in_any_scheme_but_the_annulus() {
    let schemes = [
        "clipmap/strips",
        "clipmap/footprints",
        "clipmap/view",
        "geomipmap",
        "roam",
        "cdlod",
        "cbt",
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

/// Longest-edge bisection is conforming by construction (each split takes
/// its hypotenuse neighbour with it), so a thousand views show no hole.
#[test]
fn cbt_has_no_holes_in_a_thousand_views() {
    let r = run(true, &["cbt"], 1000);
    let c = &r.schemes[0];
    assert!(
        c.triangles > 1000 * 500,
        "{} triangles over 1000 views",
        c.triangles
    );
    assert_eq!(c.crack_pixels, 0, "worst camera {:?}", c.worst_camera);
}

/// The view-dependent clipmap moves its levels furthest through narrow
/// lenses, where every level is pulled toward the terrain far off: 300
/// views at 4° show no hole either, and draw more than the eye-centred
/// clipmap does there (its levels sit in the view).
#[test]
fn the_view_dependent_clipmap_has_no_holes_through_narrow_lenses() {
    let mut s = scene(true);
    // At n = 15 the morph leaves a level all the slack the coarser
    // window does; at 31 it does not, so this n tests the placement.
    s.lod.n = 31;
    s.apply(&terraclip::scene::Overrides {
        fov: Some(4.0),
        ..Default::default()
    })
    .unwrap();
    let list = ["clipmap/strips".to_string(), "clipmap/view".to_string()];
    let r = survey(&s, &list, 300, [96, 64], Shard::WHOLE, || {}).unwrap();
    let (eye, view) = (&r.schemes[0], &r.schemes[1]);
    println!(
        "4°: eye {} triangles, view {} triangles, {} crack px",
        eye.triangles, view.triangles, view.crack_pixels
    );
    assert!(
        view.triangles > 2 * eye.triangles,
        "{} vs {}",
        view.triangles,
        eye.triangles
    );
    assert_eq!(view.crack_pixels, 0, "worst camera {:?}", view.worst_camera);
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

/// A real frame with triangles removed: every candidate the removal makes
/// is classified a hole, none LOD sky or far depth. The removed triangles
/// are one clipmap level's (a ring under the view), drawn with NaN
/// positions, which the rasteriser drops; the reference is the same frame
/// whole.
#[test]
fn removed_triangles_are_holes() {
    use terraclip::frame::stats::Passes;
    use terraclip::render::{draw, RenderOptions, Session};
    use terraclip::studies::cracks::{classify, Domain};
    let s = terraclip::studies::cracks::survey_scene(&scene(true), [160, 100]);
    let mut session = Session::new(&s, &mut Passes::default()).unwrap();
    let cam = s.camera();
    let (frame, _) = session.frame(&cam, &mut Passes::default()).unwrap();
    let opts = RenderOptions::default();
    let (whole, _) = draw(&frame, &opts, &mut Passes::default());
    let mut holed = frame.clone();
    // The triangles whose vertices all project within the middle fifth of
    // the frame: a hole the terrain around it encloses.
    let central = |i: usize| {
        let c = frame.uniforms.clip(frame.positions[i]);
        c[3] > 0.0 && (c[0] / c[3]).abs() < 0.2 && (c[1] / c[3]).abs() < 0.2
    };
    let mut removed = 0;
    for t in 0..frame.triangle_count() {
        if (3 * t..3 * t + 3).all(central) {
            removed += 1;
            for i in 3 * t..3 * t + 3 {
                holed.positions[i] = [f32::NAN; 3];
            }
        }
    }
    assert!(removed > 0);
    let (img, _) = draw(&holed, &opts, &mut Passes::default());
    let candidates = terraclip::studies::metrics::crack_candidates(&img, &whole, [255, 0, 0]);
    assert!(candidates.len() > 10, "{} candidates", candidates.len());
    let surface = terraclip::frame::surface::Surface::new(&holed, &session.world);
    let domain = Domain::of(&session);
    let size = [img.width, img.height];
    let mut kinds = std::collections::HashMap::new();
    for &p in &candidates {
        let (px, py) = (p % img.width as usize, p / img.width as usize);
        let dir = cam.ray_through(size, px as f64 + 0.5, py as f64 + 0.5);
        *kinds
            .entry(format!("{:?}", classify(&surface, &cam, dir, &domain)))
            .or_insert(0) += 1;
    }
    println!(
        "{removed} removed triangles: {} candidates, {kinds:?}",
        candidates.len()
    );
    assert_eq!(kinds.get("Hole"), Some(&candidates.len()), "{kinds:?}");
}

/// Over levels synthesised finer than the map (the clipmap's made a tile
/// at a time, the brute-force reference's whole), no scheme that
/// `docs/explanation/synthesis.md` names as crack-free cracks (clipmap strips and
/// footprints, GeoMipMapping, ROAM, CDLOD, CBT), the annulus does (it cracks
/// everywhere, by design), and with morph off the clipmap's synthesised
/// rings do: the detector still sees them.
#[test]
fn synthesised_levels_do_not_crack() {
    let mut s = Scene::load(std::path::Path::new("golden/synthesis-close.toml")).unwrap();
    // Two levels, so the brute-force reference draws 1025² samples, not 2049².
    s.terrain.synthesis.as_mut().unwrap().levels = 2;
    let list = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let r = survey(
        &s,
        &list(&[
            "clipmap/strips",
            "clipmap/footprints",
            "geomipmap",
            "roam",
            "cdlod",
            "annulus",
            "cbt",
        ]),
        24,
        [96, 64],
        Shard::WHOLE,
        || {},
    )
    .unwrap();
    assert_eq!(r.schemes.len(), 7);
    for c in &r.schemes {
        if c.lod.starts_with("annulus") {
            assert!(c.crack_pixels > 0, "the annulus cracks by design");
            continue;
        }
        assert_eq!(
            c.crack_pixels, 0,
            "{}: worst camera {:?}",
            c.lod, c.worst_camera
        );
    }
    s.effects.retain(|e| *e != Effect::Morph);
    let r = survey(
        &s,
        &list(&["clipmap/strips"]),
        24,
        [96, 64],
        Shard::WHOLE,
        || {},
    )
    .unwrap();
    assert!(r.crack_pixels > 0, "morph off must crack");
}
