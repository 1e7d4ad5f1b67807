//! The one comparison of two images, which golden, parity and the studies'
//! metrics all use: per-channel colour statistics, depth in ULP, the tiered
//! tolerance comparison (same, shifted, unmatched, hole) with the tie band
//! that bounds where a conforming rasteriser may differ, enclosed
//! background, and a difference picture.
//!
//! One module, so that "differs" means one thing everywhere: a golden that
//! passes, a parity frame that is exact and a tradeoff row with zero error
//! all count the same pixels.

use crate::camera::Camera;
use crate::render::Image;
use serde::Serialize;
/// Tolerance on adapters other than the pinned lavapipe (docs: README
/// "Tolerance mode"). A real GPU evaluates the same shader arithmetic in
/// another order and precision, snaps vertices to its own sub-pixel grid
/// and breaks pixel-centre ties its own way. Each pixel is "same", else
/// "shifted" (within the range of the other image's 3×3 neighbourhood, both
/// ways: the position-deviation comparison of the Khronos conformance tests,
/// dEQP's `intThresholdPositionDeviationCompare`), else "unmatched"; an
/// unmatched pixel that is enclosed background on one side and surface on
/// the other is a hole. Each threshold comes from a rule, not from the
/// worst value one GPU gave:
///
/// - [`TOLERANCE_CHANNEL`]: Vulkan's float → UNORM conversion may return
///   either of the two integers nearest to `f × 255` ("Conversion from
///   Floating-Point to Normalized Fixed-Point"). Shader arithmetic errors
///   are of the order of 1e-6 relative (SPIR-V precision: 3 ULP for
///   `exp2` near 0, 2.5 ULP for a division), far below a step, so they move
///   a value across at most one rounding boundary: 1 step per channel.
/// - [`TOLERANCE_DEPTH_ULP`]: the vertex shader's clip z and w are 4-term
///   dot products (each product and sum rounded, or fused: ≤ 4 ULP of the
///   result when the terms share a sign), the fixed-function divide adds
///   2.5 ULP (the SPIR-V bound for `/`), and interpolating z across the
///   triangle in f32 (a plane a + b·x + c·y: two products and two sums)
///   ≤ 4 ULP: 10.5 in all, taken as the next power of two, 16.
/// - [`TOLERANCE_SUBPIXEL`]: `subPixelPrecisionBits` ≥ 4 is all Vulkan
///   requires, so a vertex may move 1/16 px; depth may then change by the
///   local depth gradient over 1/16 px.
/// - [`TOLERANCE_HOLES`]: Vulkan's polygon rasterisation covers each sample
///   on an edge shared by two triangles exactly once, and the mesh is
///   watertight (`tests/cracks.rs`), so no legal difference shows the
///   background enclosed by surface where the other image has surface: 0.
/// - The tie band ([`tie_band`], used by `check-gpu`): a conforming
///   rasteriser can differ beyond "same" only where a pixel centre lies
///   within the vertex precision ([`TIE_DISTANCE`]) of an edge or of the
///   wire threshold, so no shifted or unmatched pixel may lie outside it,
///   as the Khronos CTS verifies rasterisation.
/// - No count of shifted or unmatched pixels is budgeted: the tie band
///   already bounds where, and so how many, pixels may differ, and a
///   budget inside it would be policy rather than derivation.
pub const TOLERANCE_CHANNEL: u8 = 1;
/// Depth may differ by this many ULP and still be "same" (derived above).
pub const TOLERANCE_DEPTH_ULP: u32 = 16;
/// How far in pixels a vertex may move: 2^-4, the least sub-pixel precision Vulkan allows.
pub const TOLERANCE_SUBPIXEL: f32 = 1.0 / 16.0;
/// Holes tolerance mode allows: none (derived above).
pub const TOLERANCE_HOLES: usize = 0;

/// Vulkan's least `subPixelPrecisionBits`, from which the default band and
/// depth tolerance are derived.
pub const MIN_SUBPIXEL_BITS: u32 = 4;

/// How far from an edge a pixel centre may lie and still be covered
/// differently by a conforming implementation with `bits` of sub-pixel
/// precision: each vertex may sit 2^-bits px from ours and ours from the
/// exact position by 1/256 px (rule 2), per axis.
pub fn tie_distance(bits: u32) -> f64 {
    (0.5f64.powi(bits as i32) + 1.0 / 256.0) * std::f64::consts::SQRT_2
}

/// [`tie_distance`] for Vulkan's minimum of 4 bits: 1/16 px.
pub const TIE_DISTANCE: f64 = (1.0 / 16.0 + 1.0 / 256.0) * std::f64::consts::SQRT_2;

/// [`tie_band_for`] with Vulkan's minimum sub-pixel precision.
pub fn tie_band(r: &crate::raster::Raster, wire: bool) -> Vec<bool> {
    tie_band_for(r, wire, MIN_SUBPIXEL_BITS)
}

/// The pixels where a conforming GPU with `bits` of sub-pixel precision
/// may legitimately differ from the CPU beyond the "same" tier: those whose
/// centre lies within [`tie_distance`] of an edge (and with `wire`, of the
/// wire's threshold half a pixel inside an edge) of
///
/// - a triangle drawn there or at a neighbour (the edge's whole line: an
///   edge one pixel over), or
/// - any other set-up triangle that could be in front there once its
///   vertices move by 2^-bits px: a sliver that covers no pixel centre, or
///   a triangle the reference hides by less than its depth change over
///   that move plus [`TOLERANCE_DEPTH_ULP`]. Here the distance is to the
///   edge segment, since nothing of the triangle lies beyond it.
///
/// This is how the Khronos CTS verifies rasterisation
/// (`tcuRasterizationVerifier`: pixels within the sub-pixel precision of
/// an edge may take either value, every other must match); anywhere else a
/// difference is a defect, however few pixels it has.
pub fn tie_band_for(r: &crate::raster::Raster, wire: bool, bits: u32) -> Vec<bool> {
    use crate::raster::NONE;
    let tie = tie_distance(bits);
    let half = crate::shade::wireframe::HALF_WIDTH as f64;
    let near_edge = |d: f64| d <= tie || (wire && (d - half).abs() <= tie);
    let (w, h) = (r.width as usize, r.height as usize);
    let mut band = vec![false; w * h];
    for py in 0..h {
        for px in 0..w {
            let (x0, x1) = (px.saturating_sub(1), (px + 1).min(w - 1));
            let (y0, y1) = (py.saturating_sub(1), (py + 1).min(h - 1));
            band[py * w + px] = (y0..=y1)
                .flat_map(|ny| (x0..=x1).map(move |nx| ny * w + nx))
                .filter(|&j| r.prim[j] != NONE)
                .map(|j| &r.tris[r.prim[j] as usize])
                .flat_map(|t| t.edges.iter())
                .any(|e| {
                    near_edge(
                        (e.at(px as i64, py as i64) as f64).abs() / (e.a as f64).hypot(e.b as f64),
                    )
                });
        }
    }
    let reach = tie + if wire { half } else { 0.0 };
    let step = 0.5f64.powi(bits as i32);
    for t in &r.tris {
        let ends = edge_ends(&t.edges);
        let slack = (t.z.dadx.abs() as f64 + t.z.dady.abs() as f64) * step;
        for [p, q] in ends {
            if !(p[0].is_finite() && p[1].is_finite() && q[0].is_finite() && q[1].is_finite()) {
                continue;
            }
            let lo = |a: f64, b: f64| (a.min(b) - reach).floor().max(0.0) as usize;
            let hi =
                |a: f64, b: f64, n: usize| ((a.max(b) + reach).ceil().max(0.0) as usize).min(n - 1);
            for py in lo(p[1], q[1])..=hi(p[1], q[1], h) {
                for px in lo(p[0], q[0])..=hi(p[0], q[0], w) {
                    let i = py * w + px;
                    if band[i] || !near_edge(segment_distance([px as f64, py as f64], p, q)) {
                        continue;
                    }
                    let z = t.z.eval(px as f32, py as f32) as f64;
                    let limit = r.depth[i] as f64 + slack;
                    // TOLERANCE_DEPTH_ULP ULPs of the reference's depth.
                    let ulps = f64::from(TOLERANCE_DEPTH_ULP) * f64::from(r.depth[i]) / 8_388_608.0;
                    // A plane that is not finite could be anywhere.
                    if z <= limit + ulps || !z.is_finite() {
                        band[i] = true;
                    }
                }
            }
        }
    }
    band
}

/// Each edge's two ends in pixel-index coordinates (pixel (x, y)'s centre
/// at (x, y), as [`crate::raster::setup::Edge::at`] takes them): where its
/// line meets the other two edges' lines.
pub fn edge_ends(e: &[crate::raster::setup::Edge; 3]) -> [[[f64; 2]; 2]; 3] {
    let meet = |e: &crate::raster::setup::Edge, f: &crate::raster::setup::Edge| {
        let (a1, b1, c1) = (e.a as f64, e.b as f64, e.c as f64);
        let (a2, b2, c2) = (f.a as f64, f.b as f64, f.c as f64);
        let det = a1 * b2 - a2 * b1;
        [(b1 * c2 - b2 * c1) / det, (a2 * c1 - a1 * c2) / det]
    };
    [0, 1, 2].map(|k| [meet(&e[k], &e[(k + 1) % 3]), meet(&e[k], &e[(k + 2) % 3])])
}

/// The distance from point `c` to the segment from `p` to `q`.
pub fn segment_distance(c: [f64; 2], p: [f64; 2], q: [f64; 2]) -> f64 {
    segment_nearest(c, p, q).1
}

/// Where on the segment from `p` to `q` point `c` is nearest (0 at `p`,
/// 1 at `q`), and how far it is from there.
fn segment_nearest(c: [f64; 2], p: [f64; 2], q: [f64; 2]) -> (f64, f64) {
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((c[0] - p[0]) * dx + (c[1] - p[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (t, (c[0] - p[0] - t * dx).hypot(c[1] - p[1] - t * dy))
}

/// The pixels where a hole may open legally: those whose centre lies
/// within [`tie_distance`] of an *open* edge of `frame`'s mesh, one that
/// no other triangle shares (compared by the exact bits of its two ends).
///
/// [`TOLERANCE_HOLES`] is 0 because coverage is continuous across an edge
/// two triangles share. An open edge inside the picture is a crack the
/// mesh itself has (`morph-off` draws them on purpose); moving its ends by
/// 2^-bits px moves the crack's border, and a pixel centre that close to it
/// may be background in one image and surface in the other with both
/// renderers conforming. A watertight mesh has open edges only on its
/// rim, where the background is not enclosed and no hole is counted, so
/// this excuses nothing there. The clipmap's level seams are closed by
/// degenerate triangles, whose edges pair up the T-junctions.
///
/// Only where the edge can be seen: its depth at the nearest point is at
/// most the farthest of `depth` (the reference's) over the pixel's 3×3
/// neighbourhood, plus [`TOLERANCE_DEPTH_ULP`]. So the rim of a level
/// hidden behind a hill excuses no hole in the hill.
pub fn open_band(frame: &crate::frame::Frame, depth: &[f32], bits: u32) -> Vec<bool> {
    use std::collections::HashMap;
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut band = vec![false; w * h];
    let key = |v: [f32; 3]| v.map(f32::to_bits);
    // Each edge (its ends' bits, in order) -> how many triangles use it,
    // and its two ends.
    type Ends = ([u32; 3], [u32; 3]);
    let mut uses: HashMap<Ends, (usize, [[f32; 3]; 2])> = HashMap::new();
    for t in frame.positions.chunks_exact(3) {
        for k in 0..3 {
            let (p, q) = (t[k], t[(k + 1) % 3]);
            let (a, b) = (key(p), key(q));
            if a == b {
                continue;
            }
            let e = if a < b { (a, b) } else { (b, a) };
            uses.entry(e).or_insert((0, [p, q])).0 += 1;
        }
    }
    let m = frame.uniforms.view_proj.map(|c| c.map(f64::from));
    let clip = |p: [f32; 3]| -> [f64; 4] {
        let v = [p[0] as f64, p[1] as f64, p[2] as f64, 1.0];
        [0, 1, 2, 3].map(|r| (0..4).map(|c| m[c][r] * v[c]).sum())
    };
    // Pixel-index coordinates: pixel (x, y)'s centre at (x, y).
    let window = |c: [f64; 4]| {
        [
            (c[0] / c[3] + 1.0) / 2.0 * w as f64 - 0.5,
            (1.0 - c[1] / c[3]) / 2.0 * h as f64 - 0.5,
            c[2] / c[3],
        ]
    };
    // The farthest reference depth over a pixel's 3×3 neighbourhood.
    let farthest = |px: usize, py: usize| {
        let (x0, x1) = (px.saturating_sub(1), (px + 1).min(w - 1));
        let (y0, y1) = (py.saturating_sub(1), (py + 1).min(h - 1));
        (y0..=y1)
            .flat_map(|y| (x0..=x1).map(move |x| depth[y * w + x]))
            .fold(0f32, f32::max)
    };
    let tie = tie_distance(bits);
    for &(n, [p, q]) in uses.values() {
        if n != 1 {
            continue;
        }
        // Cut at the near plane (clip z = 0, depth 0..1), as the
        // rasteriser clips, so that both ends have w > 0.
        let (mut a, mut b) = (clip(p), clip(q));
        if a[2] < 0.0 && b[2] < 0.0 {
            continue;
        }
        if a[2] < 0.0 || b[2] < 0.0 {
            let t = a[2] / (a[2] - b[2]);
            let cut = [0, 1, 2, 3].map(|k| a[k] + t * (b[k] - a[k]));
            if a[2] < 0.0 {
                a = cut;
            } else {
                b = cut;
            }
        }
        if a[3] <= 0.0 || b[3] <= 0.0 {
            continue;
        }
        let (p, q) = (window(a), window(b));
        if !(p.iter().chain(&q).all(|v| v.is_finite())) {
            continue;
        }
        let lo = |a: f64, b: f64, n: usize| ((a.min(b) - tie).floor().max(0.0) as usize).min(n);
        let hi =
            |a: f64, b: f64, n: usize| (((a.max(b) + tie).ceil().max(-1.0) + 1.0) as usize).min(n);
        let (p2, q2) = ([p[0], p[1]], [q[0], q[1]]);
        for py in lo(p[1], q[1], h)..hi(p[1], q[1], h) {
            for px in lo(p[0], q[0], w)..hi(p[0], q[0], w) {
                let (t, dist) = segment_nearest([px as f64, py as f64], p2, q2);
                if band[py * w + px] || dist > tie {
                    continue;
                }
                // Window depth is linear along the edge in window space.
                let z = p[2] + t * (q[2] - p[2]);
                let far = farthest(px, py);
                let ulps = f64::from(TOLERANCE_DEPTH_ULP) * f64::from(far) / 8_388_608.0;
                if z <= f64::from(far) + ulps {
                    band[py * w + px] = true;
                }
            }
        }
    }
    band
}

/// Counts a hole at a pixel of `open` (see [`open_band`]) as the unmatched
/// pixel it also is, not as a hole.
pub fn excuse_open_holes(d: &mut Difference, tier: &mut [Tier], open: &[bool]) {
    for (t, _) in tier
        .iter_mut()
        .zip(open)
        .filter(|(t, o)| **t == Tier::Hole && **o)
    {
        *t = Tier::Unmatched;
        d.holes_px -= 1;
    }
}

/// How two images differ.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Difference {
    /// Pixels whose RGBA differ at all.
    pub colour_px_differ: usize,
    /// Pixels whose depth bits differ at all.
    pub depth_px_differ: usize,
    /// The largest difference of one channel, in 8-bit steps.
    pub max_channel_diff: u8,
    /// The largest depth difference, in ULP of the f32 values.
    pub max_depth_ulp: u32,
    /// Pixels that match within tolerance only at a neighbour.
    pub shifted_px: usize,
    /// Pixels that match within tolerance nowhere in their neighbourhood.
    pub unmatched_px: usize,
    /// Unmatched pixels where one image shows background (cleared depth)
    /// enclosed by surface and the other shows surface: a hole. Tolerance
    /// mode allows none (see [`TOLERANCE_HOLES`]).
    pub holes_px: usize,
    /// Shifted or unmatched pixels outside the tie band, where a
    /// conforming rasteriser cannot differ (see [`tie_band`]); counted only
    /// by [`Difference::within`], and tolerance mode allows none.
    pub outside_band_px: usize,
    /// The first unmatched pixel in scan order, to start debugging from.
    pub unmatched_example: Option<PixelPair>,
    /// The images are not comparable: other sizes, or a buffer (colour, or
    /// depth where either image has depth) shorter or longer than its size
    /// says, such as an empty or cut-off readback. Every pixel then counts
    /// as differing and unmatched, and the comparison fails in both modes.
    #[serde(skip)]
    pub size_mismatch: bool,
}

/// How one pixel compares in tolerance mode (see [`TOLERANCE_CHANNEL`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tier {
    /// Within a step of colour and the depth tolerance.
    Same,
    /// Matched only by a neighbour: an edge one pixel over.
    Shifted,
    /// Matched nowhere in its neighbourhood.
    Unmatched,
    /// Unmatched, and background enclosed by surface on one side.
    Hole,
}

/// What the reference shows, per pixel, where its centre may move to: the
/// least and greatest of each colour channel and of depth over the
/// reference drawn at the pixel centre and shifted by (±s, ±s) px, s the
/// renderer's vertex snap plus ours (2^-N + 1/256).
///
/// Why that is what a renderer may show: moving a triangle's vertices by
/// d_j (each within ±s per axis) and reading it at p gives, exactly, the
/// unmoved triangle read at q = p − Σ λ'_j d_j, λ' the barycentrics of p
/// in the moved triangle (screen-space barycentrics, which perspective
/// correction then weights by the unmoved 1/w_j). Inside it λ' ≥ 0 and
/// sums to 1, so q lies in the square p + [−s, s]². Every varying is
/// affine in screen space up to that weighting, so its extremes over the
/// square are at the corners; the colour, a smooth function of them, is
/// taken at the same corners. In a triangle a fraction of a pixel wide the
/// varyings change fast, and a 1/16 px move changes colour by more than
/// the step the "same" tier otherwise allows, while neighbouring pixels,
/// which lie in other triangles, do not show it.
#[derive(Clone, Debug, Default)]
pub struct Reach {
    /// Least colour per pixel.
    pub lo: Vec<[u8; 4]>,
    /// Greatest colour per pixel.
    pub hi: Vec<[u8; 4]>,
    /// Least depth per pixel.
    pub zlo: Vec<f32>,
    /// Greatest depth per pixel.
    pub zhi: Vec<f32>,
}

impl Reach {
    /// The reach of one image: each pixel its own value.
    pub fn of(img: &Image) -> Reach {
        let rgba: Vec<[u8; 4]> = img
            .rgba
            .chunks_exact(4)
            .map(|p| [p[0], p[1], p[2], p[3]])
            .collect();
        Reach {
            lo: rgba.clone(),
            hi: rgba,
            zlo: img.depth.clone(),
            zhi: img.depth.clone(),
        }
    }

    /// Widens each pixel's range to hold `img`'s value (same size).
    pub fn widen(&mut self, img: &Image) {
        for (i, p) in img.rgba.chunks_exact(4).enumerate() {
            for (k, &v) in p.iter().enumerate() {
                self.lo[i][k] = self.lo[i][k].min(v);
                self.hi[i][k] = self.hi[i][k].max(v);
            }
        }
        for (i, &z) in img.depth.iter().enumerate() {
            self.zlo[i] = self.zlo[i].min(z);
            self.zhi[i] = self.zhi[i].max(z);
        }
    }
}

/// One pixel as both back ends drew it (`a` is the reference).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct PixelPair {
    /// Column, from the left.
    pub x: usize,
    /// Row, from the top.
    pub y: usize,
    /// The reference's colour.
    pub a_rgba: [u8; 4],
    /// The other image's colour.
    pub b_rgba: [u8; 4],
    /// NaN where the image has no depth (GL).
    pub a_depth: f32,
    /// The other image's depth; NaN where it has none.
    pub b_depth: f32,
}

/// Re-exported for the depth comparisons here; it lives with the
/// rasteriser, whose f32 depths it measures, so the GPU back end reads it
/// from there.
pub use crate::raster::ulp_distance;

fn depth_ulp(p: f32, q: f32) -> u32 {
    let ulp = (p.to_bits() as i64 - q.to_bits() as i64).unsigned_abs();
    ulp.min(u32::MAX as u64) as u32
}

fn channel_diff(p: &[u8], q: &[u8]) -> u8 {
    p.iter()
        .zip(q)
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

impl Difference {
    /// Compares `b` with the reference `a` pixel by pixel (see the
    /// tolerance above) with an empty tie band: every shifted or unmatched
    /// pixel counts as outside it, so tolerance mode allows only "same".
    pub fn of(a: &Image, b: &Image) -> Difference {
        Difference::within(a, b, None)
    }

    /// [`Difference::of`], and with `band` (one flag per pixel, from
    /// [`tie_band`] of the reference's raster) counts the pixels that are
    /// not "same" outside it in `outside_band_px`, which tolerance mode
    /// allows none of. Without a band every such pixel is outside.
    pub fn within(a: &Image, b: &Image, band: Option<&[bool]>) -> Difference {
        Difference::tiers(a, b, band).0
    }

    /// [`Difference::within`], and each pixel's [`Tier`] (empty when the
    /// images are not comparable): what `compare`'s error mask shows.
    pub fn tiers(a: &Image, b: &Image, band: Option<&[bool]>) -> (Difference, Vec<Tier>) {
        Difference::tiers_with(a, b, band, TOLERANCE_SUBPIXEL, None)
    }

    /// [`Difference::tiers`] for a renderer whose vertices may move by
    /// `subpixel` px rather than Vulkan's least precision, 1/16 px: the
    /// depth change over that move still counts as "same". With `reach`,
    /// so does a colour or depth within a step (or the depth tolerance) of
    /// what the reference shows over the move (see [`Reach`]).
    pub fn tiers_with(
        a: &Image,
        b: &Image,
        band: Option<&[bool]>,
        subpixel: f32,
        reach: Option<&Reach>,
    ) -> (Difference, Vec<Tier>) {
        let mut d = Difference::default();
        let (w, h) = (a.width as usize, a.height as usize);
        let px = w * h;
        let whole = |img: &Image| {
            let n = img.width as usize * img.height as usize;
            img.rgba.len() == 4 * n && (img.depth.is_empty() || img.depth.len() == n)
        };
        if (b.width as usize, b.height as usize) != (w, h)
            || !whole(a)
            || !whole(b)
            || a.depth.is_empty() != b.depth.is_empty()
            || px == 0
        {
            let all = px.max(b.width as usize * b.height as usize).max(1);
            d.size_mismatch = true;
            d.colour_px_differ = all;
            d.depth_px_differ = all;
            d.unmatched_px = all;
            return (d, vec![]);
        }
        let mut tier = vec![Tier::Same; px];
        let colour = channels(&a.rgba, &b.rgba, 4);
        d.colour_px_differ = colour.px_differ;
        d.max_channel_diff = colour.max;
        for (p, q) in a.depth.iter().zip(&b.depth) {
            if p.to_bits() != q.to_bits() {
                d.depth_px_differ += 1;
                d.max_depth_ulp = d.max_depth_ulp.max(depth_ulp(*p, *q));
            }
        }
        // Images without depth (the GL back end's, on both sides) compare
        // colour alone.
        let depth = !a.depth.is_empty();
        // The largest depth step from pixel i to a 4-neighbour.
        let steep = |img: &Image, px: usize, py: usize| {
            let z = img.depth[py * w + px];
            let mut g = 0f32;
            for (nx, ny) in [
                (px.wrapping_sub(1), py),
                (px + 1, py),
                (px, py.wrapping_sub(1)),
                (px, py + 1),
            ] {
                if nx < w && ny < h {
                    g = g.max((img.depth[ny * w + nx] - z).abs());
                }
            }
            g
        };
        // A reach of another size is not this comparison's.
        let reached = reach.filter(|r| r.lo.len() == px && r.hi.len() == px);
        // The same pixel: colour within a step, depth within a few ULP, or
        // within the depth change over `subpixel` px (1/16 px, the coarsest
        // vertex snap Vulkan allows, subPixelPrecisionBits ≥ 4, unless the
        // caller knows better): a steep wall at the near plane changes
        // depth by a quarter per pixel.
        let same = |i: usize, px: usize, py: usize| {
            let in_reach = |r: &Reach| {
                (0..4).all(|k| {
                    let v = b.rgba[4 * i + k];
                    v >= r.lo[i][k].saturating_sub(TOLERANCE_CHANNEL)
                        && v <= r.hi[i][k].saturating_add(TOLERANCE_CHANNEL)
                })
            };
            if channel_diff(&a.rgba[4 * i..4 * i + 4], &b.rgba[4 * i..4 * i + 4])
                > TOLERANCE_CHANNEL
                && !reached.is_some_and(in_reach)
            {
                return false;
            }
            if !depth || depth_ulp(a.depth[i], b.depth[i]) <= TOLERANCE_DEPTH_ULP {
                return true;
            }
            if let Some((lo, hi)) = reached.and_then(|r| Some((r.zlo.get(i)?, r.zhi.get(i)?))) {
                let z = b.depth[i].to_bits();
                if z >= lo.to_bits().saturating_sub(TOLERANCE_DEPTH_ULP)
                    && z <= hi.to_bits().saturating_add(TOLERANCE_DEPTH_ULP)
                {
                    return true;
                }
            }
            let slope = steep(a, px, py).max(steep(b, px, py));
            (a.depth[i] - b.depth[i]).abs() <= slope * subpixel
        };
        // Within the range `y` spans over the 3×3 neighbourhood, widened by
        // the tolerance: an edge, wire or threshold one pixel over, and a
        // depth read a fraction of a pixel away where the surface is steep.
        let near = |x: &Image, y: &Image, px: usize, py: usize| {
            let (x0, x1) = (px.saturating_sub(1), (px + 1).min(w - 1));
            let (y0, y1) = (py.saturating_sub(1), (py + 1).min(h - 1));
            let (mut lo, mut hi) = ([u8::MAX; 4], [0u8; 4]);
            let (mut zlo, mut zhi) = (u32::MAX, 0u32);
            for j in (y0..=y1).flat_map(|ny| (x0..=x1).map(move |nx| ny * w + nx)) {
                for k in 0..4 {
                    lo[k] = lo[k].min(y.rgba[4 * j + k]);
                    hi[k] = hi[k].max(y.rgba[4 * j + k]);
                }
                if depth {
                    zlo = zlo.min(y.depth[j].to_bits());
                    zhi = zhi.max(y.depth[j].to_bits());
                }
            }
            let i = py * w + px;
            let colour = (0..4).all(|k| {
                let v = x.rgba[4 * i + k];
                v >= lo[k].saturating_sub(TOLERANCE_CHANNEL)
                    && v <= hi[k].saturating_add(TOLERANCE_CHANNEL)
            });
            let z = x.depth.get(i).map_or(0, |z| z.to_bits());
            let in_depth = !depth
                || (z >= zlo.saturating_sub(TOLERANCE_DEPTH_ULP)
                    && z <= zhi.saturating_add(TOLERANCE_DEPTH_ULP));
            colour && in_depth
        };
        // Background is the depth clear value; without depth there is no
        // telling it from a surface of the same colour, and no hole count.
        let enclosed = |img: &Image| {
            let bg: Vec<bool> = img.depth.iter().map(|&z| z == 1.0).collect();
            enclosed(&bg, w, h)
        };
        let holes = depth.then(|| (enclosed(a), enclosed(b)));
        for py in 0..h {
            for px in 0..w {
                let i = py * w + px;
                if same(i, px, py) {
                    continue;
                }
                tier[i] = Tier::Shifted;
                // No band: no pixel may differ beyond "same".
                if !band.is_some_and(|band| band.get(i).copied().unwrap_or(false)) {
                    d.outside_band_px += 1;
                }
                if near(a, b, px, py) && near(b, a, px, py) {
                    d.shifted_px += 1;
                } else {
                    d.unmatched_px += 1;
                    tier[i] = Tier::Unmatched;
                    if let Some((ha, hb)) = &holes {
                        let hole_a = ha[i] && b.depth[i] < 1.0;
                        let hole_b = hb[i] && a.depth[i] < 1.0;
                        if hole_a || hole_b {
                            d.holes_px += 1;
                            tier[i] = Tier::Hole;
                        }
                    }
                    let at = |img: &Image| {
                        let rgba = [0, 1, 2, 3].map(|k| img.rgba[4 * i + k]);
                        (rgba, img.depth.get(i).copied().unwrap_or(f32::NAN))
                    };
                    let ((a_rgba, a_depth), (b_rgba, b_depth)) = (at(a), at(b));
                    d.unmatched_example.get_or_insert(PixelPair {
                        x: px,
                        y: py,
                        a_rgba,
                        b_rgba,
                        a_depth,
                        b_depth,
                    });
                }
            }
        }
        (d, tier)
    }

    /// Exact: nothing differs. Otherwise the stated tolerance: no hole,
    /// and nothing beyond "same" outside the tie band.
    pub fn passes(&self, exact: bool) -> bool {
        if self.size_mismatch {
            return false;
        }
        if exact {
            return self.colour_px_differ == 0 && self.depth_px_differ == 0;
        }
        self.holes_px == TOLERANCE_HOLES && self.outside_band_px == 0
    }
}

impl Difference {
    /// Adds frame `d` to a path's running total: counts summed, the largest
    /// differences the largest. `unmatched_example` is left to the caller,
    /// which knows which frame was worst.
    pub fn add(&mut self, d: &Difference) {
        self.colour_px_differ += d.colour_px_differ;
        self.depth_px_differ += d.depth_px_differ;
        self.max_channel_diff = self.max_channel_diff.max(d.max_channel_diff);
        self.max_depth_ulp = self.max_depth_ulp.max(d.max_depth_ulp);
        self.shifted_px += d.shifted_px;
        self.unmatched_px += d.unmatched_px;
        self.holes_px += d.holes_px;
        self.outside_band_px += d.outside_band_px;
        self.size_mismatch |= d.size_mismatch;
    }
}

/// Per-channel colour statistics of two images of one size.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Channels {
    /// Pixels where any compared channel differs.
    pub px_differ: usize,
    /// The largest channel difference.
    pub max: u8,
    /// The sum of squared channel differences.
    pub sum_sq: u64,
    /// Channel values compared (pixels × channels).
    pub count: usize,
}

/// Compares the first `channels` channels (3: RGB, 4: RGBA) of each pixel
/// of two RGBA8 buffers of one length.
pub fn channels(a: &[u8], b: &[u8], channels: usize) -> Channels {
    let mut c = Channels::default();
    for (p, q) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        let mut m = 0u8;
        for k in 0..channels {
            let d = p[k].abs_diff(q[k]);
            m = m.max(d);
            c.sum_sq += u64::from(d) * u64::from(d);
        }
        c.px_differ += usize::from(m > 0);
        c.max = c.max.max(m);
        c.count += channels;
    }
    c
}

/// `a` with the pixels that differ from `expected` (RGBA8, same size) in
/// red and the rest dimmed to a third, so the differences stand out.
pub fn difference_image(a: &Image, expected: &[u8]) -> Image {
    let mut out = a.clone();
    for (px, q) in out.rgba.chunks_exact_mut(4).zip(expected.chunks_exact(4)) {
        if px != q {
            px.copy_from_slice(&[255, 0, 0, 255]);
        } else {
            for c in &mut px[..3] {
                *c /= 3;
            }
        }
    }
    out
}

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

/// The error of `img` against `reference` (the same view, rendered by
/// brute force or supersampled): RGB statistics in 8-bit units, as ATLOD
/// measured, and depth in metres through `cam`.
pub fn image_error(img: &Image, reference: &Image, cam: &Camera) -> ImageError {
    assert_eq!(img.rgba.len(), reference.rgba.len(), "same image size");
    let c = channels(&img.rgba, &reference.rgba, 3);
    let (mut dsum, mut dn) = (0.0, 0usize);
    for (&a, &b) in img.depth.iter().zip(&reference.depth) {
        if a < 1.0 && b < 1.0 {
            dsum += (linear_depth(a, cam) - linear_depth(b, cam)).abs();
            dn += 1;
        }
    }
    ImageError {
        rmse: (c.sum_sq as f64 / c.count.max(1) as f64).sqrt(),
        max_abs: c.max,
        depth_m: if dn > 0 { dsum / dn as f64 } else { 0.0 },
    }
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

#[cfg(test)]
mod tests {

    /// ULPs across zero count both sides' steps; equal values and ±0 are 0.
    #[test]
    fn ulp_distance_spans_signs() {
        use super::ulp_distance;
        assert_eq!(ulp_distance(1.0, 1.0), 0);
        assert_eq!(ulp_distance(0.0, -0.0), 0);
        assert_eq!(ulp_distance(1.0, f32::from_bits(1.0f32.to_bits() + 3)), 3);
        let tiny = f32::from_bits(1);
        assert_eq!(ulp_distance(tiny, -tiny), 2);
        assert_eq!(ulp_distance(-2.0, -2.0f32.next_down()), 1);
    }

    use super::*;

    fn flat(w: u32, h: u32) -> Image {
        let n = (w * h) as usize;
        Image {
            width: w,
            height: h,
            rgba: vec![7; 4 * n],
            depth: vec![0.5; n],
        }
    }

    /// Fails in exact mode and in tolerance mode, with every pixel counted.
    fn fails_both(a: &Image, b: &Image) -> Difference {
        let d = Difference::of(a, b);
        assert!(d.size_mismatch, "{d:?}");
        let px = (a.width * a.height) as usize;
        assert!(!d.passes(true) && !d.passes(false), "{d:?}");
        assert!(d.colour_px_differ >= px && d.unmatched_px >= px, "{d:?}");
        d
    }

    /// A pixel 5 steps and 1,000 ULP off is "same" only where the reach
    /// holds it, to within a step and 16 ULP; a reach of another size is
    /// not used.
    #[test]
    fn the_reach_makes_a_pixel_the_same_only_within_it() {
        let a = flat(4, 3);
        let mut b = flat(4, 3);
        b.rgba[4 * 5..4 * 5 + 3].copy_from_slice(&[12, 12, 12]);
        b.depth[5] = f32::from_bits(0.5f32.to_bits() + 1000);
        let same = |r: Option<&Reach>| {
            let (d, tier) = Difference::tiers_with(&a, &b, None, TOLERANCE_SUBPIXEL, r);
            (tier[5] == Tier::Same, d.outside_band_px)
        };
        assert_eq!(same(None), (false, 1));
        let mut reach = Reach::of(&a);
        let mut other = flat(4, 3);
        other.rgba[4 * 5..4 * 5 + 3].copy_from_slice(&[11, 11, 11]);
        other.depth[5] = f32::from_bits(0.5f32.to_bits() + 984);
        reach.widen(&other);
        assert_eq!((reach.lo[5], reach.hi[5]), ([7, 7, 7, 7], [11, 11, 11, 7]));
        assert_eq!(same(Some(&reach)), (true, 0));
        // One step short on colour, or 17 ULP short on depth: not same.
        let mut short = reach.clone();
        short.hi[5] = [10, 10, 10, 7];
        assert_eq!(same(Some(&short)), (false, 1));
        let mut short = reach.clone();
        short.zhi[5] = f32::from_bits(0.5f32.to_bits() + 983);
        assert_eq!(same(Some(&short)), (false, 1));
        // The low side counts the same way.
        let mut low = b.clone();
        low.rgba[4 * 5..4 * 5 + 3].copy_from_slice(&[2, 2, 2]);
        low.depth[5] = f32::from_bits(0.5f32.to_bits() - 1000);
        let mut below = Reach::of(&a);
        let mut other = flat(4, 3);
        other.rgba[4 * 5..4 * 5 + 3].copy_from_slice(&[3, 3, 3]);
        other.depth[5] = f32::from_bits(0.5f32.to_bits() - 984);
        below.widen(&other);
        let (_, tier) = Difference::tiers_with(&a, &low, None, TOLERANCE_SUBPIXEL, Some(&below));
        assert_eq!(tier[5], Tier::Same);
        let mut small = Reach::of(&flat(2, 2));
        small.widen(&flat(2, 2));
        assert_eq!(same(Some(&small)), (false, 1));
    }

    #[test]
    fn identical_images_pass_both_modes() {
        let d = Difference::of(&flat(4, 3), &flat(4, 3));
        assert_eq!(d, Difference::default());
        assert!(d.passes(true) && d.passes(false));
    }

    #[test]
    fn an_image_of_another_size_fails() {
        // Same pixel count, other shape: zipping the buffers would see no
        // difference at all.
        let d = fails_both(&flat(4, 3), &flat(3, 4));
        assert_eq!(d.unmatched_px, 12);
        // A smaller readback whose pixels all equal the reference's first.
        let d = fails_both(&flat(8, 8), &flat(4, 4));
        assert_eq!(d.unmatched_px, 64);
    }

    #[test]
    fn an_empty_readback_fails() {
        let mut b = flat(4, 3);
        b.rgba.clear();
        b.depth.clear();
        fails_both(&flat(4, 3), &b);
        // Zero by zero against zero by zero compares nothing: not a pass.
        fails_both(&flat(0, 0), &flat(0, 0));
    }

    #[test]
    fn a_short_readback_fails() {
        let a = flat(4, 3);
        let mut b = flat(4, 3);
        b.rgba.truncate(4 * 11);
        fails_both(&a, &b);
        let mut b = flat(4, 3);
        b.depth.truncate(5);
        fails_both(&a, &b);
        // Depth on one side only (a readback that lost it).
        let mut b = flat(4, 3);
        b.depth.clear();
        fails_both(&a, &b);
        fails_both(&b, &a);
    }

    #[test]
    fn rmse_and_max_of_a_known_difference() {
        let a = flat(4, 4);
        let mut b = flat(4, 4);
        // The red channel of column 0 brighter by 4, alpha far off (not
        // counted: the error is over RGB).
        for y in 0..4 {
            b.rgba[16 * y] += 4;
            b.rgba[16 * y + 7] = 200;
        }
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
        // Over RGBA the alpha counts.
        let c = channels(&a.rgba, &b.rgba, 4);
        assert_eq!((c.px_differ, c.max, c.count), (8, 193, 64));
    }
}
