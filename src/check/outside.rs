//! `compare`: another renderer's image of an exported frame (`export`)
//! against terraclip's reference, in one of three modes: exact, the tiered
//! tolerance `check-gpu` uses (with the tie band from the export's own
//! triangles), or NVIDIA's FLIP perceptual error (the `nv-flip` crate,
//! the comparison wgpu's own tests use).

use crate::check::compare::{Difference, PixelPair, Tier};
use crate::error::{write_atomic, Error, Result};
use crate::export::Exported;
use crate::render::Image;
use serde::Serialize;
use std::path::{Path, PathBuf};

crate::scene::names::named! {
    /// How `compare` judges an outside image.
    pub enum Mode ("comparison mode") {
        /// No pixel may differ, in colour or (when given) depth.
        Exact => "exact",
        /// `check-gpu`'s tolerance mode: nothing beyond "same" outside
        /// the tie band, and no hole.
        Tiered => "tiered",
        /// FLIP: mean and 99.99th-percentile perceptual error under
        /// [`FLIP_MEAN`] and [`FLIP_TAIL_MAX`].
        Flip => "flip",
    }
}

/// FLIP's largest mean error that passes. Tiered mode accepts every pixel
/// one 8-bit step off and no pixel two steps off; over the goldens, an
/// image one step off everywhere has a mean FLIP of 0.0336–0.0424 and one
/// two steps off 0.0549–0.0695 (docs/verify-your-renderer.md), so 0.05
/// passes the one and fails the other. (wgpu's image tests use 0.01 for
/// their own renderer; that fails a one-step difference, and every JPEG.)
pub const FLIP_MEAN: f32 = 0.05;
/// The percentile [`FLIP_TAIL_MAX`] bounds: 99.99 %, so that a defect of
/// one pixel in ten thousand (a crack along part of a level's edge) is
/// seen, which a mean is not.
pub const FLIP_PERCENTILE: f32 = 0.9999;
/// The largest error at [`FLIP_PERCENTILE`] that passes: above the largest
/// any uniform change of up to two steps reaches on the goldens (0.1192),
/// below what background showing through terrain scores (0.4 and more).
pub const FLIP_TAIL_MAX: f32 = 0.15;

/// Pixels per tier (check-gpu's tolerance mode).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Tiers {
    /// Within a step and the depth tolerance.
    pub same: usize,
    /// Matched by a neighbour only.
    pub shifted: usize,
    /// Matched nowhere near.
    pub unmatched: usize,
    /// Unmatched with background enclosed by surface on one side.
    pub holes: usize,
    /// Shifted or unmatched where no conforming rasteriser may differ.
    pub outside_band: usize,
}

/// FLIP's figures for the image (percentiles unweighted).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct FlipStats {
    /// Mean error over every pixel.
    pub mean: f32,
    /// Median error.
    pub p50: f32,
    /// 90th percentile.
    pub p90: f32,
    /// 99th percentile.
    pub p99: f32,
    /// 99.9th percentile.
    pub p999: f32,
    /// 99.99th percentile ([`FLIP_PERCENTILE`]).
    pub p9999: f32,
    /// Largest error.
    pub max: f32,
    /// The thresholds flip mode applies: [`FLIP_MEAN`] on the mean and
    /// [`FLIP_TAIL_MAX`] on `p9999`.
    pub mean_max: f32,
    /// (with `mean_max`)
    pub p9999_max: f32,
    /// The viewing condition FLIP was run for (its default: a 0.7 m wide
    /// 4K monitor seen from 0.7 m).
    pub pixels_per_degree: f32,
}

/// What `compare` found (its JSON).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Outcome {
    /// The export compared against.
    pub reference: PathBuf,
    /// The mode that decided `pass`.
    pub mode: Mode,
    /// Whether the image passes in that mode.
    pub pass: bool,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Whether a depth buffer was given and compared.
    pub depth_compared: bool,
    /// Pixels whose RGBA differ at all.
    pub colour_px_differ: usize,
    /// Pixels whose depth bits differ at all (0 without depth).
    pub depth_px_differ: usize,
    /// The largest channel difference, 8-bit steps.
    pub max_channel_diff: u8,
    /// The largest depth difference, ULP.
    pub max_depth_ulp: u32,
    /// Pixels per tolerance tier.
    pub tiers: Tiers,
    /// The pixel with the largest channel difference (the first such in
    /// scan order), `a` the reference; none when the colours are equal.
    pub worst: Option<PixelPair>,
    /// FLIP's error figures.
    pub flip: FlipStats,
    /// Pictures written (`diff.png`: reference | error mask | theirs;
    /// `flip.png`: FLIP's error as a heat map).
    pub outputs: Vec<PathBuf>,
}

/// Reads `path` as an image of `w`×`h` (any format the `image` crate
/// reads), as RGBA8.
pub fn load_image(path: &Path, w: u32, h: u32) -> Result<Vec<u8>> {
    let (iw, ih, rgba) = crate::check::golden::load_png(path)?;
    if (iw, ih) != (w, h) {
        return Err(Error::file(
            path,
            format!("{iw}x{ih} where the reference is {w}x{h}"),
        ));
    }
    Ok(rgba)
}

/// Reads a depth buffer of `w`×`h`: raw little-endian f32 rows (`.f32`,
/// top row first) or a float OpenEXR (its channel `Z`, `depth`, `Y` or
/// `R`, or its only channel).
pub fn load_depth(path: &Path, w: u32, h: u32) -> Result<Vec<f32>> {
    let n = w as usize * h as usize;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "f32" => {
            if bytes.len() != 4 * n {
                return Err(Error::file(
                    path,
                    format!(
                        "{} bytes; a {w}x{h} f32 depth buffer is {}",
                        bytes.len(),
                        4 * n
                    ),
                ));
            }
            Ok(crate::export::le_f32s(&bytes))
        }
        "exr" => {
            let layers = crate::export::exr::read(path, &bytes)?;
            let l = layers
                .first()
                .ok_or_else(|| Error::file(path, "no layer"))?;
            if (l.width, l.height) != (w as usize, h as usize) {
                return Err(Error::file(
                    path,
                    format!("{}x{} where the reference is {w}x{h}", l.width, l.height),
                ));
            }
            let by_name = ["Z", "depth", "Y", "R"].iter().find_map(|c| l.channel(c));
            let only = (l.channels.len() == 1).then(|| l.channels[0].1.as_slice());
            by_name.or(only).map(<[f32]>::to_vec).ok_or_else(|| {
                Error::file(path, "no channel named Z, depth, Y or R, and more than one")
            })
        }
        _ => Err(Error::file(
            path,
            "a depth buffer is .f32 (raw little-endian) or .exr",
        )),
    }
}

/// Refuses a depth buffer made to another convention than the reference's
/// (Depth32Float in 0..1, cleared to 1, LESS, 0 at the near plane), with
/// an error that names the convention, rather than a flood of differing
/// pixels.
pub fn check_convention(path: &Path, reference: &[f32], theirs: &[f32], w: usize) -> Result<()> {
    let bad = |why: String| {
        Err(Error::file(
            path,
            format!(
                "{why}; the reference is Depth32Float in 0..1, cleared to 1, test LESS, \
                 0 at the near plane"
            ),
        ))
    };
    if let Some(i) = theirs
        .iter()
        .position(|z| !z.is_finite() || !(0.0..=1.0).contains(z))
    {
        let n = theirs
            .iter()
            .filter(|z| !z.is_finite() || !(0.0..=1.0).contains(*z))
            .count();
        return bad(format!(
            "{n} depths outside 0..1 (the first {} at ({}, {})): not window depth in 0..1 \
             (OpenGL's -1..1, or distances?)",
            theirs[i],
            i % w,
            i / w
        ));
    }
    let background: Vec<usize> = (0..reference.len())
        .filter(|&i| reference[i] == 1.0)
        .collect();
    let zeros = background.iter().filter(|&&i| theirs[i] == 0.0).count();
    if !background.is_empty() && 2 * zeros > background.len() {
        return bad(format!(
            "cleared to 0 where the reference shows background ({zeros} of {} pixels): \
             a reversed-Z or 0-cleared depth buffer",
            background.len()
        ));
    }
    // Along each row, neighbouring surface pixels whose reference depths
    // differ: a reversed buffer orders almost all of them the other way.
    let (mut agree, mut disagree) = (0usize, 0usize);
    for i in 1..reference.len() {
        let j = i - 1;
        let surface = |k: usize| reference[k] < 1.0 && theirs[k] > 0.0 && theirs[k] < 1.0;
        if i % w == 0 || !surface(i) || !surface(j) || reference[i] == reference[j] {
            continue;
        }
        let up = reference[i] > reference[j];
        if theirs[i] == theirs[j] {
            continue;
        }
        if (theirs[i] > theirs[j]) == up {
            agree += 1;
        } else {
            disagree += 1;
        }
    }
    if disagree >= 16 && disagree > 9 * agree {
        return bad(format!(
            "depth grows toward the camera ({disagree} of {} neighbouring pixel pairs are \
             ordered the other way): reversed Z",
            agree + disagree
        ));
    }
    Ok(())
}

fn tier_colour(t: Tier, reference: &[u8]) -> [u8; 4] {
    match t {
        Tier::Same => [reference[0] / 3, reference[1] / 3, reference[2] / 3, 255],
        Tier::Shifted => [255, 200, 0, 255],
        Tier::Unmatched => [255, 0, 0, 255],
        Tier::Hole => [255, 0, 255, 255],
    }
}

/// Compares `theirs` (colour, and depth when not empty) with the export's
/// reference in `mode`, and with `out` writes `diff.png` and `flip.png`
/// there.
pub fn compare(e: &Exported, theirs: &Image, mode: Mode, out: Option<&Path>) -> Result<Outcome> {
    let (w, h) = (e.image.width, e.image.height);
    let n = w as usize * h as usize;
    if (theirs.width, theirs.height) != (w, h)
        || theirs.rgba.len() != 4 * n
        || !(theirs.depth.is_empty() || theirs.depth.len() == n)
    {
        return Err(Error::value(
            "compare",
            format!(
                "a {}x{} image where the reference is {w}x{h}",
                theirs.width, theirs.height
            ),
        ));
    }
    let depth = !theirs.depth.is_empty();
    let reference = Image {
        depth: if depth { e.image.depth.clone() } else { vec![] },
        ..e.image.clone()
    };
    let raster = crate::render::raster(&e.frame, crate::raster::Path::from_env());
    let band = crate::check::compare::tie_band(&raster, e.frame.effects.wireframe);
    let (d, tier) = Difference::tiers(&reference, theirs, Some(&band));
    let mut worst: Option<(u8, usize)> = None;
    for (i, (p, q)) in reference
        .rgba
        .chunks_exact(4)
        .zip(theirs.rgba.chunks_exact(4))
        .enumerate()
    {
        let m = (0..4).map(|k| p[k].abs_diff(q[k])).max().unwrap_or(0);
        if m > 0 && worst.is_none_or(|(best, _)| m > best) {
            worst = Some((m, i));
        }
    }
    let at = |img: &Image, i: usize| {
        (
            [0, 1, 2, 3].map(|k| img.rgba[4 * i + k]),
            img.depth.get(i).copied().unwrap_or(f32::NAN),
        )
    };
    let worst = worst.map(|(_, i)| {
        let ((a_rgba, a_depth), (b_rgba, b_depth)) = (at(&reference, i), at(theirs, i));
        PixelPair {
            x: i % w as usize,
            y: i / w as usize,
            a_rgba,
            b_rgba,
            a_depth,
            b_depth,
        }
    });

    let rgb = |img: &Image| -> Vec<u8> {
        img.rgba
            .chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect()
    };
    let ppd = nv_flip::DEFAULT_PIXELS_PER_DEGREE;
    let map = nv_flip::flip(
        nv_flip::FlipImageRgb8::with_data(w, h, &rgb(&reference)),
        nv_flip::FlipImageRgb8::with_data(w, h, &rgb(theirs)),
        ppd,
    );
    let mut pool = nv_flip::FlipPool::from_image(&map);
    let flip = FlipStats {
        mean: pool.mean(),
        p50: pool.get_percentile(0.5, false),
        p90: pool.get_percentile(0.9, false),
        p99: pool.get_percentile(0.99, false),
        p999: pool.get_percentile(0.999, false),
        p9999: pool.get_percentile(FLIP_PERCENTILE, false),
        max: pool.max_value(),
        mean_max: FLIP_MEAN,
        p9999_max: FLIP_TAIL_MAX,
        pixels_per_degree: ppd,
    };
    let pass = match mode {
        Mode::Exact => d.passes(true),
        Mode::Tiered => d.passes(false),
        Mode::Flip => flip.mean <= FLIP_MEAN && flip.p9999 <= FLIP_TAIL_MAX,
    };
    let mut outputs = vec![];
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let (wu, hu) = (w as usize, h as usize);
        let mut panels = vec![0u8; 4 * 3 * wu * hu];
        for y in 0..hu {
            for x in 0..wu {
                let i = y * wu + x;
                let r = &reference.rgba[4 * i..4 * i + 4];
                let t = &theirs.rgba[4 * i..4 * i + 4];
                let differs = r != t || (depth && reference.depth[i] != theirs.depth[i]);
                let mask = match mode {
                    Mode::Exact if differs => [255, 0, 0, 255],
                    Mode::Exact => tier_colour(Tier::Same, r),
                    _ => tier_colour(tier[i], r),
                };
                let row = 4 * 3 * wu * y;
                for (panel, px) in [r, &mask[..], t].iter().enumerate() {
                    let at = row + 4 * (panel * wu + x);
                    panels[at..at + 4].copy_from_slice(px);
                }
            }
        }
        let diff = Image {
            width: 3 * w,
            height: h,
            rgba: panels,
            depth: vec![],
        };
        let heat = map.apply_color_lut(&nv_flip::magma_lut()).to_vec();
        let heat = Image {
            width: w,
            height: h,
            rgba: heat
                .chunks_exact(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect(),
            depth: vec![],
        };
        for (name, img) in [("diff.png", diff), ("flip.png", heat)] {
            let p = dir.join(name);
            write_atomic(&p, &img.png()?)?;
            outputs.push(p);
        }
    }
    let count = |t: Tier| tier.iter().filter(|&&x| x == t).count();
    Ok(Outcome {
        reference: e.dir.clone(),
        mode,
        pass,
        width: w,
        height: h,
        depth_compared: depth,
        colour_px_differ: d.colour_px_differ,
        depth_px_differ: d.depth_px_differ,
        max_channel_diff: d.max_channel_diff,
        max_depth_ulp: d.max_depth_ulp,
        tiers: Tiers {
            same: count(Tier::Same),
            shifted: d.shifted_px,
            unmatched: d.unmatched_px,
            holes: d.holes_px,
            outside_band: d.outside_band_px,
        },
        worst,
        flip,
        outputs,
    })
}

/// Reads the export at `reference`, then `image` (and `depth`) as the
/// outside renderer's, and compares them: what the command runs.
pub fn run(
    reference: &Path,
    image: &Path,
    depth: Option<&Path>,
    mode: Mode,
    out: Option<&Path>,
) -> Result<Outcome> {
    let e = crate::export::read(reference)?;
    let (w, h) = (e.image.width, e.image.height);
    let rgba = load_image(image, w, h)?;
    let depth = match depth {
        Some(p) => {
            let z = load_depth(p, w, h)?;
            check_convention(p, &e.image.depth, &z, w as usize)?;
            z
        }
        None => vec![],
    };
    let theirs = Image {
        width: w,
        height: h,
        rgba,
        depth,
    };
    compare(&e, &theirs, mode, out)
}
