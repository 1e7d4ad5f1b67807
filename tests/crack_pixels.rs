//! Cracks in screen space: renders of the clipmap over a red background from
//! 200 random viewpoints per index layout, with morph on, show 0 background
//! pixels inside the terrain. "Inside" is defined so the test can fail: a
//! red pixel counts when a brute-force full-resolution render of the same
//! view covers it and it is not connected to the image border through other
//! red pixels (a silhouette difference between LOD and brute force is
//! connected to the sky; a crack is enclosed). With morph off the same test
//! finds cracks.

use std::path::Path;
use terraclip::render::{render, Image, RenderOptions};
use terraclip::scene::Scene;

const W: u32 = 96;
const H: u32 = 64;

fn scene(layout: &str, morph: bool, lod: &str, cam: [f64; 6]) -> Scene {
    let effects = if morph { r#"["morph"]"# } else { "[]" };
    let text = format!(
        r#"effects = {effects}
[terrain]
procedural = {{ seed = 5, width = 257, height = 257, amplitude = 500.0, wavelength = 64.0 }}
cell_size = 10.0
[lod]
scheme = "{lod}"
n = 15
layout = "{layout}"
[camera]
position = [{}, {}, {}]
look_at = [{}, {}, {}]
fov = 60.0
near = 1.0
far = 20000.0
[image]
width = {W}
height = {H}
background = [1.0, 0.0, 0.0]
"#,
        cam[0], cam[1], cam[2], cam[3], cam[4], cam[5]
    );
    Scene::parse(&text, "crack scene", Path::new(".")).unwrap()
}

fn background(img: &Image) -> Vec<bool> {
    img.rgba.chunks(4).map(|p| p == [255, 0, 0, 255]).collect()
}

/// Red pixels of `lod` covered in `brute` and enclosed by terrain.
fn crack_pixels(lod: &Image, brute: &Image) -> usize {
    let bg = background(lod);
    let covered: Vec<bool> = background(brute).iter().map(|b| !b).collect();
    let (w, h) = (W as usize, H as usize);
    // Flood the background from the border.
    let mut outside = vec![false; w * h];
    let mut stack: Vec<usize> = (0..w * h)
        .filter(|&i| bg[i] && (i % w == 0 || i % w == w - 1 || i / w == 0 || i / w == h - 1))
        .collect();
    for &i in &stack {
        outside[i] = true;
    }
    while let Some(i) = stack.pop() {
        let (x, y) = (i % w, i / w);
        let mut visit = |j: usize| {
            if bg[j] && !outside[j] {
                outside[j] = true;
                stack.push(j);
            }
        };
        if x > 0 {
            visit(i - 1);
        }
        if x + 1 < w {
            visit(i + 1);
        }
        if y > 0 {
            visit(i - w);
        }
        if y + 1 < h {
            visit(i + w);
        }
    }
    (0..w * h)
        .filter(|&i| bg[i] && covered[i] && !outside[i])
        .count()
}

/// Deterministic pseudo-random viewpoints above the terrain.
fn views(count: usize) -> Vec<[f64; 6]> {
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..count)
        .map(|_| {
            let (x, y) = (200.0 + 2160.0 * next(), -200.0 - 2160.0 * next());
            let z = 550.0 + 600.0 * next();
            let (tx, ty) = (2560.0 * next(), -2560.0 * next());
            [x, y, z, tx, ty, 500.0 * next()]
        })
        .collect()
}

fn cracks(layout: &str, morph: bool, views: &[[f64; 6]]) -> (usize, usize) {
    let opts = RenderOptions::default();
    let mut total = 0;
    let mut worst = (0, 0);
    for (i, v) in views.iter().enumerate() {
        let (lod, _) = render(&scene(layout, morph, "clipmap", *v), &opts).unwrap();
        let (brute, _) = render(&scene(layout, morph, "brute-force", *v), &opts).unwrap();
        let c = crack_pixels(&lod, &brute);
        total += c;
        if c > worst.1 {
            worst = (i, c);
        }
    }
    (total, worst.0)
}

#[test]
fn no_crack_pixels_with_morph_in_either_layout() {
    let v = views(200);
    for layout in ["strips", "footprints"] {
        let (n, worst) = cracks(layout, true, &v);
        assert_eq!(
            n, 0,
            "{layout}: {n} crack pixels, worst view {worst}: {:?}",
            v[worst]
        );
    }
}

#[test]
fn morph_off_shows_cracks_so_the_test_can_fail() {
    let v = views(40);
    for layout in ["strips", "footprints"] {
        let (n, _) = cracks(layout, false, &v);
        println!("{layout}, morph off: {n} crack pixels in 40 views");
        assert!(
            n > 0,
            "{layout}: the crack detector found nothing with morph off"
        );
    }
}
