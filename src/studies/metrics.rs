//! The studies' measures built on [`crate::check::compare`]: crack pixels,
//! popping along a path, and box downsampling for supersampled references.
//! The error of one image against another is
//! [`compare::image_error`](crate::check::compare::image_error).

use crate::check::compare::enclosed;
use crate::render::Image;

/// Popping between two consecutive frames: the RMS (0–255 units) of the
/// part of the LOD image's change that the reference's change does not
/// share, per pixel and channel: ((L₁ − L₀) − (B₁ − B₀)).
pub fn popping(lod: [&Image; 2], reference: [&Image; 2]) -> f64 {
    let mut sum = 0.0f64;
    let px = lod[0].rgba.len() / 4;
    for i in 0..px {
        for k in 0..3 {
            let j = 4 * i + k;
            let dl = lod[1].rgba[j] as f64 - lod[0].rgba[j] as f64;
            let db = reference[1].rgba[j] as f64 - reference[0].rgba[j] as f64;
            sum += (dl - db) * (dl - db);
        }
    }
    (sum / (3 * px).max(1) as f64).sqrt()
}

/// Background pixels of `lod` that the brute-force render `brute` covers
/// and that are enclosed by terrain: not connected to the image border
/// through other background pixels. A silhouette that differs from brute
/// force is connected to the sky; a crack is enclosed.
pub fn crack_pixels(lod: &Image, brute: &Image, background: [u8; 3]) -> usize {
    crack_candidates(lod, brute, background).len()
}

/// The pixel indices [`crack_pixels`] counts, in scan order: the candidates
/// the crack survey classifies (`cracks`).
pub fn crack_candidates(lod: &Image, brute: &Image, background: [u8; 3]) -> Vec<usize> {
    let is_bg = |img: &Image| -> Vec<bool> {
        img.rgba
            .chunks(4)
            .map(|p| p[..3] == background[..])
            .collect()
    };
    let bg = is_bg(lod);
    let covered: Vec<bool> = is_bg(brute).iter().map(|b| !b).collect();
    let (w, h) = (lod.width as usize, lod.height as usize);
    let inside = enclosed(&bg, w, h);
    (0..w * h)
        .filter(|&i| inside[i] && covered[i])
        .collect::<Vec<_>>()
}

/// Box-filters an image rendered at `s`× the width and height down to
/// its target size (colour: rounded mean; depth: nearest sample).
pub fn downsample(img: &Image, s: u32) -> Image {
    let (w, h) = (img.width / s, img.height / s);
    let mut rgba = vec![0u8; (w * h * 4) as usize];
    let mut depth = vec![1.0f32; (w * h) as usize];
    let n = s * s;
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0u32; 4];
            let mut d = 1.0f32;
            for sy in 0..s {
                for sx in 0..s {
                    let i = ((y * s + sy) * img.width + x * s + sx) as usize;
                    for (k, a) in acc.iter_mut().enumerate() {
                        *a += img.rgba[4 * i + k] as u32;
                    }
                    d = d.min(img.depth[i]);
                }
            }
            let o = (y * w + x) as usize;
            for k in 0..4 {
                rgba[4 * o + k] = ((acc[k] + n / 2) / n) as u8;
            }
            depth[o] = d;
        }
    }
    Image {
        width: w,
        height: h,
        rgba,
        depth,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) -> Image {
        let mut rgba = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let c = f(x, y);
                rgba.extend([c[0], c[1], c[2], 255]);
            }
        }
        Image {
            width: w,
            height: h,
            rgba,
            depth: vec![0.5; (w * h) as usize],
        }
    }

    #[test]
    fn enclosed_background_is_a_crack_and_open_background_is_not() {
        let red = [255, 0, 0];
        let brute = img(7, 7, |_, y| if y == 0 { red } else { [9, 9, 9] });
        // A hole in the middle and a notch open to the sky.
        let lod = img(7, 7, |x, y| {
            if y == 0 || (x == 3 && y == 3) || (x == 5 && y == 1) {
                red
            } else {
                [9, 9, 9]
            }
        });
        assert_eq!(crack_pixels(&lod, &brute, red), 1);
    }

    #[test]
    fn popping_ignores_changes_the_reference_shares() {
        let a = img(2, 2, |_, _| [0, 0, 0]);
        let b = img(2, 2, |_, _| [30, 30, 30]);
        assert_eq!(popping([&a, &b], [&a, &b]), 0.0);
        assert_eq!(popping([&a, &b], [&a, &a]), 30.0);
    }

    #[test]
    fn downsample_averages_colour_and_keeps_nearest_depth() {
        let mut hi = img(4, 2, |x, _| {
            if x % 2 == 0 {
                [0, 0, 0]
            } else {
                [255, 255, 255]
            }
        });
        hi.depth[1] = 0.25;
        let lo = downsample(&hi, 2);
        assert_eq!((lo.width, lo.height), (2, 1));
        assert_eq!(&lo.rgba[..4], &[128, 128, 128, 255]);
        assert_eq!(lo.depth[0], 0.25);
    }
}
