//! Image metrics against a reference render of the same view: colour RMSE
//! and largest channel difference (8-bit, as ATLOD measured), depth error in
//! metres, crack pixels, popping along a path, and box downsampling for
//! supersampled renders.

use crate::render::Image;
use crate::scene::camera::Camera;
use serde::Serialize;

/// Error of an image against a reference of the same view.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct ImageError {
    /// Root mean square of the RGB channel differences (0–255 units).
    pub rmse: f64,
    /// Largest RGB channel difference.
    pub max_abs: u8,
    /// Mean |distance difference| (metres) over pixels both images cover.
    pub depth_m: f64,
}

/// Distance along the view axis of a Depth32Float value (wgpu's 0..1
/// range with the camera's near and far).
pub fn linear_depth(d: f32, cam: &Camera) -> f64 {
    let (n, f) = (cam.near, cam.far);
    f * n / (f - d as f64 * (f - n))
}

pub fn image_error(img: &Image, reference: &Image, cam: &Camera) -> ImageError {
    assert_eq!(img.rgba.len(), reference.rgba.len(), "same image size");
    let mut sum = 0.0f64;
    let mut max_abs = 0u8;
    for (a, b) in img.rgba.chunks(4).zip(reference.rgba.chunks(4)) {
        for k in 0..3 {
            let d = a[k].abs_diff(b[k]);
            max_abs = max_abs.max(d);
            sum += (d as f64) * (d as f64);
        }
    }
    let n = (img.rgba.len() / 4 * 3).max(1) as f64;
    let (mut dsum, mut dn) = (0.0, 0usize);
    for (&a, &b) in img.depth.iter().zip(&reference.depth) {
        if a < 1.0 && b < 1.0 {
            dsum += (linear_depth(a, cam) - linear_depth(b, cam)).abs();
            dn += 1;
        }
    }
    ImageError {
        rmse: (sum / n).sqrt(),
        max_abs,
        depth_m: if dn > 0 { dsum / dn as f64 } else { 0.0 },
    }
}

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

/// The pixels of `bg` (a `w`×`h` mask, row-major) that no path of `bg`
/// pixels through their 4-neighbours joins to the image border: background
/// enclosed by surface, as a hole shows it, where sky past a silhouette
/// reaches the border.
pub fn enclosed(bg: &[bool], w: usize, h: usize) -> Vec<bool> {
    let mut outside = vec![false; w * h];
    let mut stack: Vec<usize> = (0..w * h)
        .filter(|&i| bg[i] && (i % w == 0 || i % w == w - 1 || i / w == 0 || i / w == h - 1))
        .collect();
    for &i in &stack {
        outside[i] = true;
    }
    while let Some(i) = stack.pop() {
        let (x, y) = (i % w, i / w);
        let mut next = Vec::with_capacity(4);
        if x > 0 {
            next.push(i - 1);
        }
        if x + 1 < w {
            next.push(i + 1);
        }
        if y > 0 {
            next.push(i - w);
        }
        if y + 1 < h {
            next.push(i + w);
        }
        for j in next {
            if bg[j] && !outside[j] {
                outside[j] = true;
                stack.push(j);
            }
        }
    }
    (0..w * h).map(|i| bg[i] && !outside[i]).collect()
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
    fn rmse_and_max_of_a_known_difference() {
        let a = img(4, 4, |_, _| [10, 10, 10]);
        let b = img(
            4,
            4,
            |x, _| if x == 0 { [14, 10, 10] } else { [10, 10, 10] },
        );
        let cam = Camera {
            eye: glam::DVec3::ZERO,
            target: glam::DVec3::X,
            fov_y_deg: 60.0,
            near: 1.0,
            far: 100.0,
            aspect: 1.0,
        };
        let e = image_error(&a, &b, &cam);
        // 4 of 48 channel values differ by 4: sqrt(4 * 16 / 48).
        assert!((e.rmse - (64.0f64 / 48.0).sqrt()).abs() < 1e-12);
        assert_eq!(e.max_abs, 4);
        assert_eq!(e.depth_m, 0.0);
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
