//! `compare`: another renderer's image of an exported frame (`export`)
//! against terraclip's reference, in one of three modes: exact, the tiered
//! tolerance `check-gpu` uses (with the tie band from the export's own
//! triangles), or NVIDIA's FLIP perceptual error (the `nv-flip` crate,
//! the comparison wgpu's own tests use).

use crate::check::compare::{
    Difference, PixelPair, Reach, Tier, MIN_SUBPIXEL_BITS, TOLERANCE_CHANNEL, TOLERANCE_DEPTH_ULP,
};
use crate::error::{write_atomic, Error, Result};
use crate::export::Exported;
use crate::render::Image;
use serde::Serialize;
use std::path::{Path, PathBuf};

crate::names::named! {
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

crate::names::named! {
    /// What `compare` compares.
    pub enum Only ("comparison subject") {
        /// Colour, and depth when given.
        Both => "both",
        /// Depth alone: a renderer that checks its geometry.
        Depth => "depth",
        /// Colour alone, even when depth is given.
        Colour => "colour",
    }
}

/// FLIP's largest mean error that passes. Tiered mode accepts every pixel
/// one 8-bit step off and no pixel two steps off; over the goldens, an
/// image one step off everywhere has a mean FLIP of 0.0317–0.0406 and one
/// two steps off 0.0521–0.0665 over the pixels outside the tie band
/// (docs/tutorials/verify-your-renderer.md), so 0.05
/// passes the one and fails the other. (wgpu's image tests use 0.01 for
/// their own renderer; that fails a one-step difference, and every JPEG.)
pub const FLIP_MEAN: f32 = 0.05;
/// The percentile [`FLIP_TAIL_MAX`] bounds: 99.99 %, so that a defect of
/// one pixel in ten thousand (a crack along part of a level's edge) is
/// seen, which a mean is not.
pub const FLIP_PERCENTILE: f32 = 0.9999;
/// The largest error at [`FLIP_PERCENTILE`] that passes: above the largest
/// any uniform change of up to two steps reaches on the goldens (0.1106),
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
    /// What was compared: `both`, `depth` or `colour`.
    pub only: Only,
    /// The other renderer's sub-pixel precision the band was drawn for.
    pub subpixel_bits: u32,
    /// The tie band's half-width in pixels for those bits.
    pub tie_distance_px: f64,
    /// Whether the image passes in that mode.
    pub pass: bool,
    /// Why it fails, in a line (null when it passes).
    pub reason: Option<String>,
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
    /// Pixels in the tie band.
    pub band_px: usize,
    /// Up to [`FAILING_LISTED`] pixels that make it fail, in scan order.
    pub failing: Vec<FailingPixel>,
    /// FLIP's figures over the pixels outside the tie band: what flip
    /// mode judges.
    pub flip: FlipStats,
    /// FLIP's figures over every pixel.
    pub flip_all: FlipStats,
    /// Pictures written (`diff.png`: reference | error mask | theirs, and
    /// with depth | depth difference; `flip.png`: FLIP's error as a heat
    /// map).
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
/// top row first) or a float OpenEXR. From an EXR, `channel` when given
/// (`Z`, or `layer.Z` where several layers have one), else the first of
/// the channels [`depth_candidates`] lists.
pub fn load_depth(path: &Path, w: u32, h: u32, channel: Option<&str>) -> Result<Vec<f32>> {
    Ok(depth_candidates(path, w, h, channel)?.swap_remove(0).1)
}

/// A depth buffer's candidate channels, the one to use first: one for a
/// `.f32` file or a chosen channel; for an EXR, every channel of the
/// reference's size, the first chosen as
///
/// 1. layer `depth`, channel `Z` (the reference's own layout);
/// 2. else the first channel named `Z`, `depth`, `Y` or `R`, in that
///    order of names (layer `depth` first, then the file's order);
/// 3. else the only channel.
///
/// The rest let [`run`] say which channel holds the depth when the chosen
/// one does not.
pub fn depth_candidates(
    path: &Path,
    w: u32,
    h: u32,
    channel: Option<&str>,
) -> Result<Vec<(String, Vec<f32>)>> {
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
            let z = crate::export::le_f32s(&bytes);
            let depth = |v: &f32| v.is_finite() && (0.0..=1.0).contains(v);
            let bad = z.iter().filter(|v| !depth(v)).count();
            let swapped = || {
                bytes
                    .chunks_exact(4)
                    .all(|b| depth(&f32::from_be_bytes([b[0], b[1], b[2], b[3]])))
            };
            if bad > 0 && swapped() {
                return Err(Error::file(
                    path,
                    format!(
                        "{bad} of {n} depths are outside 0..1 read little-endian, and every one \
                         is in 0..1 read big-endian: big-endian floats; write them little-endian"
                    ),
                ));
            }
            Ok(vec![(String::new(), z)])
        }
        "exr" => {
            let layers = crate::export::exr::read(path, &bytes)?;
            let mut named: Vec<(String, &str, &str, &[f32])> = vec![];
            // Layer `depth` first, then the file's order.
            for l in layers
                .iter()
                .filter(|l| l.name == "depth")
                .chain(layers.iter().filter(|l| l.name != "depth"))
            {
                if (l.width, l.height) != (w as usize, h as usize) {
                    continue;
                }
                for (c, v) in &l.channels {
                    let full = if l.name.is_empty() {
                        c.clone()
                    } else {
                        format!("{}.{c}", l.name)
                    };
                    named.push((full, &l.name, c, v));
                }
            }
            let sizes = || {
                layers
                    .iter()
                    .map(|l| format!("'{}' {}x{}", l.name, l.width, l.height))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            if named.is_empty() {
                return Err(Error::file(
                    path,
                    format!(
                        "no layer is {w}x{h}, the reference's size (layers: {})",
                        sizes()
                    ),
                ));
            }
            let list = || {
                named
                    .iter()
                    .map(|c| c.0.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            let pick = |i: usize| {
                let mut out = vec![(named[i].0.clone(), named[i].3.to_vec())];
                out.extend(
                    (0..named.len())
                        .filter(|&j| j != i)
                        .map(|j| (named[j].0.clone(), named[j].3.to_vec())),
                );
                out
            };
            if let Some(want) = channel {
                let hits: Vec<usize> = (0..named.len())
                    .filter(|&i| named[i].0 == want || named[i].2 == want)
                    .collect();
                return match hits[..] {
                    [i] => Ok(vec![(named[i].0.clone(), named[i].3.to_vec())]),
                    [] => Err(Error::file(
                        path,
                        format!("no {w}x{h} channel '{want}' (channels: {})", list()),
                    )),
                    _ => Err(Error::file(
                        path,
                        format!(
                            "{} channels are called '{want}': name one as layer.channel \
                             (channels: {})",
                            hits.len(),
                            list()
                        ),
                    )),
                };
            }
            let own = named.iter().position(|c| c.1 == "depth" && c.2 == "Z");
            let by_name = ["Z", "depth", "Y", "R"]
                .iter()
                .find_map(|want| named.iter().position(|c| c.2 == *want));
            let only = (named.len() == 1).then_some(0);
            match own.or(by_name).or(only) {
                Some(i) => Ok(pick(i)),
                None => Err(Error::file(
                    path,
                    format!(
                        "no channel named Z, depth, Y or R, and more than one ({}): choose one \
                         with --depth-channel",
                        list()
                    ),
                )),
            }
        }
        _ => Err(Error::file(
            path,
            "a depth buffer is .f32 (raw little-endian) or .exr",
        )),
    }
}

/// Whether the 8-bit-per-channel or depth buffer `theirs` read top row
/// first matches `reference` at most pixels only with its rows reversed: a
/// buffer read back bottom row first, as `glReadPixels` returns it.
/// `same` says whether pixel i of one matches pixel j of the other.
fn rows_reversed(w: usize, h: usize, same: impl Fn(usize, usize) -> bool) -> bool {
    let n = w * h;
    if h < 2 || n == 0 {
        return false;
    }
    let direct = (0..n).filter(|&i| same(i, i)).count();
    let flipped = (0..n)
        .filter(|&i| same(i, (h - 1 - i / w) * w + i % w))
        .count();
    // Nine in ten match upside down, and a tenth of the image more than
    // the right way up (a sky above and terrain below match in part
    // either way).
    10 * flipped >= 9 * n && 10 * flipped.saturating_sub(direct) >= n
}

/// A colour image read bottom row first is refused with an error that
/// says so, rather than a flood of differing pixels.
pub fn check_colour_rows(path: &Path, reference: &[u8], theirs: &[u8], w: usize) -> Result<()> {
    let h = reference.len() / 4 / w.max(1);
    if reference.len() == theirs.len()
        && rows_reversed(w, h, |i, j| {
            channel_step(&reference[4 * i..4 * i + 4], &theirs[4 * j..4 * j + 4])
                <= TOLERANCE_CHANNEL
        })
    {
        return Err(Error::file(
            path,
            "matches the reference only upside down: its rows are bottom first (glReadPixels \
             order); write the top row first",
        ));
    }
    Ok(())
}

fn channel_step(p: &[u8], q: &[u8]) -> u8 {
    p.iter()
        .zip(q)
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap_or(0)
}

/// The depth that a 24-bit fixed-point buffer holds for `z`, read back
/// as float: the nearest k / (2^24 − 1).
fn d24(z: f32) -> f32 {
    ((f64::from(z) * D24_MAX).round() / D24_MAX) as f32
}

/// The largest 24-bit fixed-point depth, 2^24 − 1: one grid step is its
/// reciprocal.
const D24_MAX: f64 = 16_777_215.0;

/// Refuses a depth buffer made to another convention than the reference's
/// (Depth32Float in 0..1, cleared to 1, LESS, 0 at the near plane, top row
/// first), with an error that names the convention, rather than a flood
/// of differing pixels.
pub fn check_convention(path: &Path, reference: &[f32], theirs: &[f32], w: usize) -> Result<()> {
    let bad = |why: String| {
        Err(Error::file(
            path,
            format!(
                "{why}; the reference is Depth32Float in 0..1, cleared to 1, test LESS, \
                 0 at the near plane, top row first"
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
    let n = reference.len().min(theirs.len());
    let h = n / w.max(1);
    let close = |a: f32, b: f32| {
        crate::check::compare::ulp_distance(a, b) <= u64::from(TOLERANCE_DEPTH_ULP)
    };
    let surface: Vec<usize> = (0..n).filter(|&i| reference[i] < 1.0).collect();
    // GL's default glDepthRange with a 0..1 projection: window depth is
    // 0.5 + 0.5 z, computed in f32 (a few ULP of 0.5..1 either way).
    let gl = surface
        .iter()
        .filter(|&&i| (f64::from(theirs[i]) - (0.5 + 0.5 * f64::from(reference[i]))).abs() <= 1e-6)
        .count();
    let own = surface
        .iter()
        .filter(|&&i| close(reference[i], theirs[i]))
        .count();
    if surface.len() >= 16 && 10 * gl >= 9 * surface.len() && 2 * own < surface.len() {
        return bad(format!(
            "{gl} of {} surface pixels hold 0.5 + 0.5 × the reference's depth: OpenGL's default \
             depth range (clip z in -1..1); call glClipControl(GL_UPPER_LEFT, GL_ZERO_TO_ONE) \
             (EXT_clip_control in GLES)",
            surface.len()
        ));
    }
    if rows_reversed(w, h, |i, j| close(reference[i], theirs[j])) {
        return bad(
            "matches the reference only upside down: rows bottom first (glReadPixels order); \
             write the top row first"
                .into(),
        );
    }
    let background: Vec<usize> = (0..n).filter(|&i| reference[i] == 1.0).collect();
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
    for i in 1..n {
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
    // Below 0.5 a float has finer steps than 24-bit fixed point, so a D24
    // buffer shows there: every differing depth on the 24-bit grid, within
    // a step of ours. A float buffer lands on that grid at most half the
    // time per pixel, so 16 such pixels happen by chance with odds 2^-16.
    let fine: Vec<usize> = surface
        .iter()
        .copied()
        .filter(|&i| reference[i] < 0.5 && theirs[i] != reference[i])
        .collect();
    let on_grid = fine
        .iter()
        .filter(|&&i| {
            d24(theirs[i]) == theirs[i]
                && (f64::from(theirs[i]) - f64::from(reference[i])).abs() <= 1.0 / D24_MAX
        })
        .count();
    if fine.len() >= 16 && on_grid == fine.len() {
        return bad(format!(
            "all {on_grid} differing depths below 0.5 lie on the 24-bit fixed-point grid \
             (k / (2^24 − 1)) within a step of the reference: a 24-bit depth buffer \
             (D24); use a 32-bit float depth attachment"
        ));
    }
    Ok(())
}

/// The error mask's colour for a pixel of `t`: a dimmed copy of the
/// reference where it is the same, and a colour per way of differing;
/// outside the tie band, where no conforming rasteriser may differ, cyan.
fn tier_colour(t: Tier, in_band: bool, reference: &[u8]) -> [u8; 4] {
    match t {
        Tier::Same => [reference[0] / 3, reference[1] / 3, reference[2] / 3, 255],
        Tier::Hole => [255, 0, 255, 255],
        _ if !in_band => [0, 255, 255, 255],
        Tier::Shifted => [255, 200, 0, 255],
        Tier::Unmatched => [255, 0, 0, 255],
    }
}

/// The depth panel's colour: grey where the depth bits are equal, and by
/// how far they differ: blue within [`TOLERANCE_DEPTH_ULP`], yellow within
/// 2^16 ULP, red beyond, magenta where one side is background.
fn depth_colour(a: f32, b: f32) -> [u8; 4] {
    if a.to_bits() == b.to_bits() {
        let g = (255.0 * (1.0 - a.clamp(0.0, 1.0).powi(8))) as u8 / 2;
        return [g, g, g, 255];
    }
    if (a == 1.0) != (b == 1.0) {
        return [255, 0, 255, 255];
    }
    match crate::check::compare::ulp_distance(a, b) {
        u if u <= u64::from(TOLERANCE_DEPTH_ULP) => [60, 120, 255, 255],
        u if u <= 1 << 16 => [255, 220, 0, 255],
        _ => [255, 0, 0, 255],
    }
}

/// FLIP's figures over `values` (one per pixel compared).
fn flip_stats(values: &[f32], ppd: f32) -> FlipStats {
    let mut f = FlipStats {
        mean: 0.0,
        p50: 0.0,
        p90: 0.0,
        p99: 0.0,
        p999: 0.0,
        p9999: 0.0,
        max: 0.0,
        mean_max: FLIP_MEAN,
        p9999_max: FLIP_TAIL_MAX,
        pixels_per_degree: ppd,
    };
    if values.is_empty() {
        return f;
    }
    let row = nv_flip::FlipImageFloat::with_data(values.len() as u32, 1, values);
    let mut pool = nv_flip::FlipPool::from_image(&row);
    f.mean = pool.mean();
    f.p50 = pool.get_percentile(0.5, false);
    f.p90 = pool.get_percentile(0.9, false);
    f.p99 = pool.get_percentile(0.99, false);
    f.p999 = pool.get_percentile(0.999, false);
    f.p9999 = pool.get_percentile(FLIP_PERCENTILE, false);
    f.max = pool.max_value();
    f
}

/// The distance in pixels from pixel (x, y)'s centre to the nearest edge
/// of a set-up triangle whose box, grown by a pixel, holds it; none when
/// no box does. Only those: a pixel's own triangle is among them, and no
/// triangle further out has an edge nearer than its own. (Two triangles
/// sharing an edge hold it a fixed-point unit apart after the top-left
/// rule, so a neighbour's copy can be nearer by about 10⁻⁶ px.)
fn nearest_edge(r: &crate::raster::Raster, x: usize, y: usize) -> Option<f64> {
    let (x, y) = (x as i32, y as i32);
    r.tris
        .iter()
        .filter(|t| {
            x >= t.bbox[0] - 1 && x <= t.bbox[2] + 1 && y >= t.bbox[1] - 1 && y <= t.bbox[3] + 1
        })
        .flat_map(|t| crate::check::compare::edge_ends(&t.edges))
        .map(|[p, q]| crate::check::compare::segment_distance([x as f64, y as f64], p, q))
        .filter(|d| d.is_finite())
        .min_by(f64::total_cmp)
}

/// One pixel that makes a comparison fail, with what it takes to judge it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FailingPixel {
    /// Column, from the left.
    pub x: usize,
    /// Row, from the top.
    pub y: usize,
    /// `differs` (exact mode), else `shifted`, `unmatched` or `hole`.
    pub tier: &'static str,
    /// Whether the pixel lies in the tie band.
    pub in_band: bool,
    /// The reference's colour.
    pub reference_rgba: [u8; 4],
    /// The compared image's colour.
    pub theirs_rgba: [u8; 4],
    /// The reference's depth (null without depth).
    pub reference_depth: Option<f32>,
    /// The compared depth (null without depth).
    pub theirs_depth: Option<f32>,
    /// Their distance in ULP.
    pub depth_ulp: Option<u64>,
    /// The distance from the pixel's centre to the nearest triangle edge,
    /// in pixels: within the tie distance, a rasteriser may differ there.
    pub nearest_edge_px: Option<f64>,
}

/// How many failing pixels `--json` lists.
pub const FAILING_LISTED: usize = 20;

/// How `compare` runs: the mode, what it compares, and the precision the
/// other renderer claims.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The mode that decides `pass`.
    pub mode: Mode,
    /// Colour and depth, or one of them.
    pub only: Only,
    /// The other renderer's sub-pixel precision (Vulkan's least is 4;
    /// D3D and most desktop GPUs have 8): sets the tie band's width and
    /// the depth change over a vertex move that counts as "same".
    pub subpixel_bits: u32,
    /// The EXR channel holding the depth (`Z` or `layer.Z`), when the
    /// file has several.
    pub depth_channel: Option<String>,
}

impl Options {
    /// `mode` on colour and depth, with Vulkan's least precision.
    pub fn new(mode: Mode) -> Options {
        Options {
            mode,
            only: Only::Both,
            subpixel_bits: MIN_SUBPIXEL_BITS,
            depth_channel: None,
        }
    }
}

/// The sub-pixel precisions `compare` accepts: 4 (Vulkan's least) up to
/// 8 of ours (rule 2), beyond which a band narrower than our own snapping
/// would blame us.
pub const SUBPIXEL_BITS: std::ops::RangeInclusive<u32> = MIN_SUBPIXEL_BITS..=8;

/// The reference's [`Reach`] for a renderer with `bits` of sub-pixel
/// precision: the frame drawn with every vertex shifted to each corner of
/// the square its centre may move in, (±s, ±s) px with s = 2^-bits +
/// 1/256, through the view-projection (the varyings do not depend on it).
fn reach(e: &Exported, bits: u32) -> Reach {
    let s = 0.5f32.powi(bits as i32) + 1.0 / 256.0;
    let mut r = Reach::of(&e.image);
    for (dx, dy) in [(-s, -s), (s, -s), (-s, s), (s, s)] {
        let mut f = e.frame.clone();
        // Window x moves by dx where clip x moves by 2 dx / width · w.
        let (sx, sy) = (2.0 * dx / f.width as f32, 2.0 * dy / f.height as f32);
        for c in &mut f.uniforms.view_proj {
            c[0] += sx * c[3];
            c[1] -= sy * c[3];
        }
        let opts = crate::render::RenderOptions::default();
        let (img, _) = crate::render::draw(&f, &opts, &mut Default::default());
        r.widen(&img);
    }
    r
}

/// Compares `theirs` (colour, and depth when not empty) with the export's
/// reference as `opts` says, and with `out` writes `diff.png` and
/// `flip.png` there.
pub fn compare(
    e: &Exported,
    theirs: &Image,
    opts: &Options,
    out: Option<&Path>,
) -> Result<Outcome> {
    let (w, h) = (e.image.width, e.image.height);
    let n = w as usize * h as usize;
    // Both images whole and the same size, so that no comparison below
    // meets a missing pixel (`Difference`'s size mismatch cannot happen).
    let whole = |img: &Image| img.rgba.len() == 4 * n && img.depth.len() == n;
    if n == 0 || !whole(&e.image) {
        return Err(Error::file(
            &e.dir,
            format!(
                "a {w}x{h} reference with {} colour bytes and {} depths: not a whole image",
                e.image.rgba.len(),
                e.image.depth.len()
            ),
        ));
    }
    if (theirs.width, theirs.height) != (w, h) {
        return Err(Error::value(
            "compare",
            format!(
                "a {}x{} image where the reference is {w}x{h}",
                theirs.width, theirs.height
            ),
        ));
    }
    if theirs.rgba.len() != 4 * n || !(theirs.depth.is_empty() || theirs.depth.len() == n) {
        return Err(Error::value(
            "compare",
            format!(
                "a {w}x{h} image with {} colour bytes and {} depths; {w}x{h} takes {} bytes \
                 and {n} depths (or none)",
                theirs.rgba.len(),
                theirs.depth.len(),
                4 * n
            ),
        ));
    }
    if !SUBPIXEL_BITS.contains(&opts.subpixel_bits) {
        return Err(Error::value(
            "--subpixel-bits",
            format!(
                "{}: a renderer has {} to {} bits here (Vulkan requires at least 4; terraclip \
                 snaps to 8)",
                opts.subpixel_bits,
                SUBPIXEL_BITS.start(),
                SUBPIXEL_BITS.end()
            ),
        ));
    }
    if opts.only == Only::Depth && theirs.depth.is_empty() {
        return Err(Error::value(
            "--only",
            "depth: no depth buffer to compare (give --depth)",
        ));
    }
    // What is not compared is made equal: their colour is the reference's
    // with --only depth, and neither side has depth with --only colour.
    let theirs = &Image {
        rgba: if opts.only == Only::Depth {
            e.image.rgba.clone()
        } else {
            theirs.rgba.clone()
        },
        depth: if opts.only == Only::Colour {
            vec![]
        } else {
            theirs.depth.clone()
        },
        ..theirs.clone()
    };
    let depth = !theirs.depth.is_empty();
    let reference = Image {
        depth: if depth { e.image.depth.clone() } else { vec![] },
        ..e.image.clone()
    };
    let raster = crate::render::raster(&e.frame, crate::raster::Path::from_env());
    let band =
        crate::check::compare::tie_band_for(&raster, e.frame.effects.wireframe, opts.subpixel_bits);
    let subpixel = 0.5f32.powi(opts.subpixel_bits as i32);
    // What the reference shows where a pixel centre may move to; exact
    // mode does not look.
    let reach = (opts.mode != Mode::Exact).then(|| reach(e, opts.subpixel_bits));
    let (mut d, mut tier) =
        Difference::tiers_with(&reference, theirs, Some(&band), subpixel, reach.as_ref());
    // A crack the mesh itself has may open or close by a sub-pixel move.
    if depth {
        let open = crate::check::compare::open_band(&e.frame, &reference.depth, opts.subpixel_bits);
        crate::check::compare::excuse_open_holes(&mut d, &mut tier, &open);
    }
    let mut worst: Option<(u8, usize)> = None;
    for (i, (p, q)) in reference
        .rgba
        .chunks_exact(4)
        .zip(theirs.rgba.chunks_exact(4))
        .enumerate()
    {
        let m = channel_step(p, q);
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
    let errors = map.to_vec();
    let flip_all = flip_stats(&errors, ppd);
    // FLIP filters over several pixels, so a silhouette a sub-pixel away
    // would spread error past the band: judged, FLIP sees their image
    // with the band's pixels taken from the reference, over the pixels
    // outside the band.
    let mut masked = theirs.clone();
    for i in (0..n).filter(|&i| band[i]) {
        masked.rgba[4 * i..4 * i + 4].copy_from_slice(&reference.rgba[4 * i..4 * i + 4]);
    }
    let judged = nv_flip::flip(
        nv_flip::FlipImageRgb8::with_data(w, h, &rgb(&reference)),
        nv_flip::FlipImageRgb8::with_data(w, h, &rgb(&masked)),
        ppd,
    )
    .to_vec();
    let off_band: Vec<f32> = (0..n).filter(|&i| !band[i]).map(|i| judged[i]).collect();
    let flip = flip_stats(&off_band, ppd);
    // Flip mode judges colour by FLIP away from the edges, and geometry as
    // tiered does: no hole, and (with depth) no depth unmatched outside the
    // band.
    let geometry = if depth {
        let same_colour = Image {
            rgba: reference.rgba.clone(),
            ..theirs.clone()
        };
        Difference::tiers_with(
            &reference,
            &same_colour,
            Some(&band),
            subpixel,
            reach.as_ref(),
        )
        .0
    } else {
        Difference::default()
    };
    let flip_colour = flip.mean <= FLIP_MEAN && flip.p9999 <= FLIP_TAIL_MAX;
    let pass = match opts.mode {
        Mode::Exact => d.passes(true),
        Mode::Tiered => d.passes(false),
        Mode::Flip => flip_colour && d.holes_px == 0 && geometry.outside_band_px == 0,
    };
    let fails_at = |i: usize| match opts.mode {
        Mode::Exact => {
            reference.rgba[4 * i..4 * i + 4] != theirs.rgba[4 * i..4 * i + 4]
                || (depth && reference.depth[i].to_bits() != theirs.depth[i].to_bits())
        }
        Mode::Tiered => tier[i] == Tier::Hole || (tier[i] != Tier::Same && !band[i]),
        Mode::Flip => tier[i] == Tier::Hole || (!band[i] && judged[i] > FLIP_TAIL_MAX),
    };
    let failing: Vec<FailingPixel> = if pass {
        vec![]
    } else {
        (0..n)
            .filter(|&i| fails_at(i))
            .take(FAILING_LISTED)
            .map(|i| {
                let (x, y) = (i % w as usize, i / w as usize);
                let ((a_rgba, a_z), (b_rgba, b_z)) = (at(&reference, i), at(theirs, i));
                let z = |v: f32| depth.then_some(v);
                FailingPixel {
                    x,
                    y,
                    tier: match (opts.mode, tier[i]) {
                        (_, Tier::Hole) => "hole",
                        (Mode::Exact, _) => "differs",
                        (_, Tier::Shifted) => "shifted",
                        (_, Tier::Unmatched) => "unmatched",
                        (_, Tier::Same) => "same",
                    },
                    in_band: band[i],
                    reference_rgba: a_rgba,
                    theirs_rgba: b_rgba,
                    reference_depth: z(a_z),
                    theirs_depth: z(b_z),
                    depth_ulp: depth.then(|| crate::check::compare::ulp_distance(a_z, b_z)),
                    nearest_edge_px: nearest_edge(&raster, x, y),
                }
            })
            .collect()
    };
    let reason = (!pass).then(|| match opts.mode {
        Mode::Exact => format!(
            "{} px differ in colour (by up to {} steps) and {} in depth (by up to {} ULP)",
            d.colour_px_differ, d.max_channel_diff, d.depth_px_differ, d.max_depth_ulp
        ),
        Mode::Tiered => format!(
            "{} px differ outside the tie band ({:.3} px of an edge, {} sub-pixel bits), where \
             no conforming rasteriser may differ; {} holes",
            d.outside_band_px,
            crate::check::compare::tie_distance(opts.subpixel_bits),
            opts.subpixel_bits,
            d.holes_px
        ),
        Mode::Flip => {
            let mut why = vec![];
            if !flip_colour {
                why.push(format!(
                    "FLIP over the {} px outside the tie band: mean {:.4} (at most {FLIP_MEAN}), \
                     99.99th percentile {:.4} (at most {FLIP_TAIL_MAX})",
                    off_band.len(),
                    flip.mean,
                    flip.p9999
                ));
            }
            if d.holes_px > 0 {
                why.push(format!("{} holes", d.holes_px));
            }
            if geometry.outside_band_px > 0 {
                why.push(format!(
                    "{} px of depth differ outside the tie band",
                    geometry.outside_band_px
                ));
            }
            why.join("; ")
        }
    });
    let mut outputs = vec![];
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let (wu, hu) = (w as usize, h as usize);
        let count = if depth { 4 } else { 3 };
        let mut panels = vec![0u8; 4 * count * wu * hu];
        for y in 0..hu {
            for x in 0..wu {
                let i = y * wu + x;
                let r = &reference.rgba[4 * i..4 * i + 4];
                let t = &theirs.rgba[4 * i..4 * i + 4];
                let mask = match opts.mode {
                    Mode::Exact if fails_at(i) => [255, 0, 0, 255],
                    Mode::Exact => tier_colour(Tier::Same, true, r),
                    _ => tier_colour(tier[i], band[i], r),
                };
                let dz = if depth {
                    depth_colour(reference.depth[i], theirs.depth[i])
                } else {
                    [0; 4]
                };
                let row = 4 * count * wu * y;
                for (panel, px) in [r, &mask[..], t, &dz[..]].iter().take(count).enumerate() {
                    let at = row + 4 * (panel * wu + x);
                    panels[at..at + 4].copy_from_slice(px);
                }
            }
        }
        let diff = Image {
            width: count as u32 * w,
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
        mode: opts.mode,
        only: opts.only,
        subpixel_bits: opts.subpixel_bits,
        tie_distance_px: crate::check::compare::tie_distance(opts.subpixel_bits),
        pass,
        reason,
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
        band_px: band.iter().filter(|&&b| b).count(),
        worst,
        failing,
        flip,
        flip_all,
        outputs,
    })
}

/// Reads the export at `reference`, then `image` (and `depth`) as the
/// outside renderer's, and compares them: what the command runs. Without
/// an image (`--only depth`), the reference's colour stands in for it.
pub fn run(
    reference: &Path,
    image: Option<&Path>,
    depth: Option<&Path>,
    opts: &Options,
    out: Option<&Path>,
) -> Result<Outcome> {
    let e = crate::export::read(reference)?;
    let (w, h) = (e.image.width, e.image.height);
    let rgba = match image {
        Some(p) => {
            let rgba = load_image(p, w, h)?;
            if opts.only != Only::Depth {
                check_colour_rows(p, &e.image.rgba, &rgba, w as usize)?;
            }
            rgba
        }
        None if opts.only == Only::Depth => e.image.rgba.clone(),
        None => {
            return Err(Error::value(
                "--image",
                format!(
                    "no image to compare in {} mode (only --only depth needs none)",
                    opts.mode
                ),
            ))
        }
    };
    let depth = match depth {
        Some(p) if opts.only != Only::Colour => {
            let mut candidates = depth_candidates(p, w, h, opts.depth_channel.as_deref())?;
            let (name, z) = candidates.remove(0);
            if let Err(err) = check_convention(p, &e.image.depth, &z, w as usize) {
                // Another channel of the file that passes: say so.
                if let Some((other, _)) = candidates
                    .iter()
                    .find(|(_, v)| check_convention(p, &e.image.depth, v, w as usize).is_ok())
                {
                    return Err(Error::file(
                        p,
                        format!(
                            "channel {name} is not the depth ({err}); channel {other} looks like \
                             it: pass --depth-channel {other}"
                        ),
                    ));
                }
                return Err(err);
            }
            z
        }
        _ => vec![],
    };
    let theirs = Image {
        width: w,
        height: h,
        rgba,
        depth,
    };
    compare(&e, &theirs, opts, out)
}

#[cfg(test)]
#[path = "outside_tests.rs"]
mod tests;
