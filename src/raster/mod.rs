//! The reference rasteriser: clip-space triangles in, a depth buffer and a
//! per-pixel triangle id (a visibility buffer) out, following
//! `docs/reference/raster-rules.md` so that it is bit-identical to lavapipe.
//!
//! Stages: `setup` (viewport, snap, planes), `clip` (Mesa's clipper),
//! `bin` (64×64 tiles), `tile` (the scalar reference: three edge tests and a
//! depth test per pixel) and `simd` (the fast path: exact covered spans per
//! row, depth-tested 8 pixels at a time). Shading is not done here:
//! [`Raster::interpolate`] and [`Raster::interpolate_run`] evaluate a visible
//! triangle's varyings, so the shading stage pays only for pixels that
//! survive the depth test.
//!
//! Determinism: triangles are set up in parallel but collected in submission
//! order; tiles are independent and each walks its triangles in that order;
//! so the result does not depend on the thread count or on the path.

pub(crate) mod bin;
pub(crate) mod clip;
pub mod setup;
pub(crate) mod simd;
pub(crate) mod tile;

use clip::ClipVertex;
pub use clip::MAX_VARYINGS;
use rayon::prelude::*;
use setup::{Edge, Plane, PlaneSetup, Viewport, WinVertex};

/// Pixels per step of [`Raster::interpolate_run`].
pub const RUN_LANES: usize = 8;

/// Triangle id of a pixel that nothing covered.
pub const NONE: u32 = u32::MAX;

/// Triangles in clip space with per-vertex varyings.
#[derive(Clone, Copy, Debug)]
pub struct Mesh<'a> {
    /// Clip-space position per vertex.
    pub clip: &'a [[f32; 4]],
    /// `linear.len()` varyings per vertex, vertex-major.
    pub attrs: &'a [f32],
    /// Per varying: true = screen-linear (noperspective), false =
    /// perspective-correct.
    pub linear: &'a [bool],
    /// Vertex indices, three per triangle.
    pub triangles: &'a [[u32; 3]],
    /// A flat value per triangle (the clipmap level, say).
    pub flat: &'a [u32],
}

/// Which inner loop to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Path {
    /// One pixel at a time.
    Scalar,
    /// Eight pixels at a time, as AVX2 + FMA code when the CPU has them.
    Simd,
    /// Eight pixels at a time, always built for the x86-64 baseline: what
    /// [`Path::Simd`] runs on a CPU without AVX2 + FMA, selectable on one
    /// with them so that every machine checks that build too.
    Portable,
}

impl Path {
    /// The names `TERRACLIP_SIMD` takes: `0`, `off` or `scalar` select
    /// [`Path::Scalar`]; `portable` [`Path::Portable`]; `1`, `on`, `simd`
    /// or an empty value [`Path::Simd`]. Anything else is `None`.
    pub fn parse(s: &str) -> Option<Path> {
        match s {
            "0" | "off" | "scalar" => Some(Path::Scalar),
            "portable" => Some(Path::Portable),
            "" | "1" | "on" | "simd" => Some(Path::Simd),
            _ => None,
        }
    }

    /// The path `TERRACLIP_SIMD` selects ([`Path::parse`]); unset or
    /// unrecognised, [`Path::Simd`]. The CLI refuses an unrecognised value
    /// before it renders ([`Path::check_env`]).
    pub fn from_env() -> Self {
        std::env::var("TERRACLIP_SIMD")
            .ok()
            .and_then(|v| Path::parse(&v))
            .unwrap_or(Path::Simd)
    }

    /// An error naming the variable and its value when `TERRACLIP_SIMD` is
    /// set to something [`Path::parse`] does not know.
    pub fn check_env() -> std::result::Result<(), String> {
        match std::env::var("TERRACLIP_SIMD") {
            Ok(v) if Path::parse(&v).is_none() => Err(format!(
                "TERRACLIP_SIMD={v:?} is not one of 0, off, scalar, portable, 1, on, simd"
            )),
            _ => Ok(()),
        }
    }

    /// Whether this path runs the AVX2 + FMA builds of the raster and
    /// shading loops on this CPU.
    pub fn uses_avx2_fma(self) -> bool {
        self == Path::Simd && crate::cpu::has_avx2_fma()
    }

    /// What ran, as `render --json` reports it (`raster_path`): `scalar`,
    /// `portable` (8 lanes, baseline build) or `avx2+fma`.
    pub fn label(self) -> &'static str {
        match self {
            Path::Scalar => "scalar",
            _ if self.uses_avx2_fma() => "avx2+fma",
            _ => "portable",
        }
    }
}

/// A set-up triangle: edges, pixel bounds, depth and 1/w planes.
#[derive(Clone, Copy, Debug)]
pub struct Tri {
    /// The three edge functions, in 16.8 fixed point (rule 2), top-left rule applied.
    pub edges: [Edge; 3],
    /// Inclusive pixel bounds (x0, y0, x1, y1), inside the target.
    pub bbox: [i32; 4],
    /// Depth as a plane over the pixel grid.
    pub z: Plane,
    /// 1/w as a plane, for perspective-correct varyings.
    pub oow: Plane,
    /// The triangle's flat value.
    pub flat: u32,
}

/// What the rasteriser saw.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RasterStats {
    /// Triangles handed to the rasteriser.
    pub input_triangles: usize,
    /// Vertices with a NaN or infinite clip coordinate (their triangles are
    /// dropped).
    pub non_finite_vertices: usize,
    /// Triangles wholly outside one clip plane.
    pub rejected: usize,
    /// Triangles that needed the clipper.
    pub clipped: usize,
    /// Vertices the clipper made with a non-finite coordinate.
    pub non_finite_clipped: usize,
    /// Set-up triangles whose depth or 1/w plane is not finite.
    pub non_finite_planes: usize,
    /// Covered pixels whose depth is not finite.
    pub non_finite_depth: usize,
    /// Triangles after clipping that reached setup with non-zero area.
    pub setup: usize,
    /// Pixels covered in the end.
    pub covered_pixels: usize,
}

/// The rasteriser's output: depth, visibility and the planes to shade with.
#[derive(Clone, Debug)]
pub struct Raster {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Depth32Float, cleared to 1.0, tested LESS.
    pub depth: Vec<f32>,
    /// Index into `tris` per pixel, or [`NONE`].
    pub prim: Vec<u32>,
    /// The set-up triangles that `prim` indexes.
    pub tris: Vec<Tri>,
    /// `linear.len()` planes per triangle in `tris`.
    pub planes: Vec<Plane>,
    /// Per varying, whether it is screen-linear.
    pub linear: Vec<bool>,
    /// What the rasteriser saw.
    pub stats: RasterStats,
}

impl Raster {
    /// Rule 5: the varyings of triangle `id` at pixel (px, py), perspective
    /// correct as `plane(a·oow) · (1 / plane(oow))` unless screen-linear.
    #[inline(always)]
    pub fn interpolate(&self, id: u32, px: u32, py: u32, out: &mut [f32]) {
        let n = self.linear.len();
        let t = &self.tris[id as usize];
        let (x, y) = (px as f32, py as f32);
        let w = 1.0 / t.oow.eval(x, y);
        let planes = &self.planes[id as usize * n..id as usize * n + n];
        for k in 0..n {
            let v = planes[k].eval(x, y);
            out[k] = if self.linear[k] { v } else { v * w };
        }
    }

    /// [`Raster::interpolate`] for the pixels `xs` of row `py`, all covered
    /// by triangle `id`: varying k of pixel x lands at `out[k * stride + x]`
    /// (1/w at `winv[x]`). The same operations per pixel; with one plane per
    /// varying for the whole run, the loops run [`RUN_LANES`] pixels at a
    /// time. They write whole groups, so up to `RUN_LANES - 1` values past
    /// `xs.end` are overwritten too: callers go left to right (a later run
    /// overwrites them) and size each row of `out` to the width plus
    /// `RUN_LANES`.
    #[inline(always)]
    pub fn interpolate_run(
        &self,
        id: u32,
        xs: std::ops::Range<usize>,
        py: u32,
        winv: &mut [f32],
        out: &mut [f32],
        stride: usize,
    ) {
        const L: usize = RUN_LANES;
        let n = self.linear.len();
        let t = &self.tris[id as usize];
        let y = py as f32;
        let groups = (xs.end - xs.start).div_ceil(L);
        let span = xs.start..xs.start + groups * L;
        // Each group is computed into a local array, then stored: with all
        // loads before any store, and the planes copied into locals, the
        // compiler needs no alias checks and runs the 8 lanes as one.
        // Pixel indices go to f32 through i32, which converts 8 lanes at once.
        let xf = |g: usize| -> [f32; L] {
            let x0 = (xs.start + g * L) as i32;
            std::array::from_fn(|l| (x0 + l as i32) as f32)
        };
        let winv = &mut winv[span.clone()];
        let oow = t.oow;
        for (g, w) in winv.chunks_exact_mut(L).enumerate() {
            let x = xf(g);
            let v: [f32; L] = std::array::from_fn(|l| 1.0 / oow.eval(x[l], y));
            w.copy_from_slice(&v);
        }
        let planes = &self.planes[id as usize * n..id as usize * n + n];
        for (k, &p) in planes.iter().enumerate() {
            let o = &mut out[k * stride + span.start..k * stride + span.end];
            let lin = self.linear[k];
            for (g, (o, w)) in o.chunks_exact_mut(L).zip(winv.chunks_exact(L)).enumerate() {
                let x = xf(g);
                let w: [f32; L] = w.try_into().expect("whole group");
                let v: [f32; L] = std::array::from_fn(|l| {
                    let v = p.eval(x[l], y);
                    if lin {
                        v
                    } else {
                        v * w[l]
                    }
                });
                o.copy_from_slice(&v);
            }
        }
    }

    /// Asks the CPU to bring triangle `id`'s set-up and planes into cache
    /// (nothing for [`NONE`], or off x86-64): a hint, which changes no
    /// result.
    #[inline(always)]
    pub fn prefetch(&self, id: u32) {
        #[cfg(target_arch = "x86_64")]
        if let Some(t) = self.tris.get(id as usize) {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let n = self.linear.len();
            let planes = &self.planes[id as usize * n..id as usize * n + n];
            let line = |p: *const u8, bytes: usize| {
                for off in (0..bytes).step_by(64) {
                    // SAFETY: a prefetch reads nothing and cannot fault;
                    // the address lies inside (or one line past) a live
                    // borrow.
                    unsafe { _mm_prefetch(p.wrapping_add(off) as *const i8, _MM_HINT_T0) };
                }
                // The last byte's line, where the span straddles one more.
                unsafe { _mm_prefetch(p.wrapping_add(bytes - 1) as *const i8, _MM_HINT_T0) };
            };
            line(t as *const Tri as *const u8, std::mem::size_of::<Tri>());
            if n > 0 {
                line(planes.as_ptr() as *const u8, std::mem::size_of_val(planes));
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = id;
    }

    /// Plane `k` of triangle `id` (its screen gradient, for wireframe width).
    pub fn plane(&self, id: u32, k: usize) -> Plane {
        self.planes[id as usize * self.linear.len() + k]
    }
}

/// Rasterisation settings.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Which rasteriser path runs (scalar, portable or AVX2 + FMA); all agree bit for bit.
    pub path: Path,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            path: Path::from_env(),
        }
    }
}

/// A rendered image with its depth buffer.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA8, row-major, top row first.
    pub rgba: Vec<u8>,
    /// Depth32Float as the rasteriser left it (1.0 where nothing drew).
    pub depth: Vec<f32>,
}

impl Image {
    /// PNG bytes of the colour image.
    pub fn png(&self) -> crate::error::Result<Vec<u8>> {
        use image::ImageEncoder;
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(
                &self.rgba,
                self.width,
                self.height,
                image::ExtendedColorType::Rgba8,
            )
            .map_err(|e| crate::error::Error::value("png", e.to_string()))?;
        Ok(out)
    }
}

/// Depths are ≥ 0, so their bit patterns order like the values.
/// Units in the last place between two f32 of any sign: their distance on
/// the line of representable values (0 and −0 are 0 apart).
pub fn ulp_distance(a: f32, b: f32) -> u64 {
    let ordered = |v: f32| {
        let b = v.to_bits();
        if b >> 31 == 1 {
            -((b & 0x7fff_ffff) as i64)
        } else {
            b as i64
        }
    };
    (ordered(a) - ordered(b)).unsigned_abs()
}

/// Converts a colour channel to 8 bits: round half to even of clamp(c)·255,
/// and 0 for NaN. Written so that it vectorises: max/min turn NaN into 0
/// (clamp would keep it), and the integer in [0, 255] is read from the low
/// mantissa bits of v + 2²³, which is exact, instead of a saturating `as`
/// conversion that the compiler does one lane at a time.
#[inline(always)]
#[allow(clippy::manual_clamp)]
pub fn unorm8(c: f32) -> u8 {
    let v = (c.max(0.0).min(1.0) * 255.0).round_ties_even();
    ((v + 8_388_608.0).to_bits() & 0xff) as u8
}

/// A triangle's snapped corners in counter-clockwise order, that order,
/// and the pixel centres its box holds inside the target; None where the
/// snapped area is zero or the box holds no pixel centre, so that nothing
/// the triangle could do would reach a pixel.
struct Covered {
    order: [usize; 3],
    p: [[i64; 2]; 3],
    bbox: [i32; 4],
}

#[inline(always)]
fn covered(v: [&WinVertex; 3], vp: &Viewport) -> Option<Covered> {
    let snapped = v.map(|w| [setup::snap(w.x), setup::snap(w.y)]);
    let area = setup::area(&snapped);
    if area == 0 {
        return None;
    }
    let order = if area < 0 { [0, 2, 1] } else { [0, 1, 2] };
    let p = order.map(|i| snapped[i]);
    let min_x = p.iter().map(|q| q[0]).min().expect("3");
    let max_x = p.iter().map(|q| q[0]).max().expect("3");
    let min_y = p.iter().map(|q| q[1]).min().expect("3");
    let max_y = p.iter().map(|q| q[1]).max().expect("3");
    // Samples sit at multiples of 256; keep those within the box and target.
    let x0 = (min_x + 255).div_euclid(256).max(0);
    let y0 = (min_y + 255).div_euclid(256).max(0);
    let x1 = max_x.div_euclid(256).min(vp.width as i64 - 1);
    let y1 = max_y.div_euclid(256).min(vp.height as i64 - 1);
    if x0 > x1 || y0 > y1 {
        return None;
    }
    Some(Covered {
        order,
        p,
        bbox: [x0 as i32, y0 as i32, x1 as i32, y1 as i32],
    })
}

/// What [`rasterise`] would do with one triangle, judged from its clip
/// positions alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fate {
    /// It may reach a pixel (or is non-finite, or needs the clipper, which
    /// the rasteriser decides and counts).
    Draw,
    /// Wholly outside one clip plane: counted as rejected, drawn nowhere.
    Rejected,
    /// Inside the clip volume but with zero snapped area or no pixel
    /// centre in its box: set up to nothing, counted nowhere.
    Nothing,
}

/// The fate of the triangle at clip positions `c` in a `width`×`height`
/// target: the same tests, in the same arithmetic, as [`Target::draw`]
/// makes before it sets a triangle up, so that a caller may leave out the
/// triangles that cannot reach a pixel before computing their varyings
/// (what a tiled GPU's position-only pass does) and get the same image.
#[inline]
pub fn fate(c: [[f32; 4]; 3], vp: &Viewport) -> Fate {
    if !c.iter().flatten().all(|v| v.is_finite()) {
        return Fate::Draw;
    }
    let m = c.map(clip::outcode);
    if m[0] & m[1] & m[2] != 0 {
        return Fate::Rejected;
    }
    if m[0] | m[1] | m[2] != 0 {
        return Fate::Draw;
    }
    let w = c.map(|c| vp.map(c));
    match covered([&w[0], &w[1], &w[2]], vp) {
        Some(_) => Fate::Draw,
        None => Fate::Nothing,
    }
}

/// Sets up one triangle in window space (rules 2–5); None if it has zero
/// snapped area or covers no pixel centre's bounding box.
#[inline(always)]
fn setup_one(
    v: [&WinVertex; 3],
    attrs: [&[f32]; 3],
    linear: &[bool],
    flat: u32,
    vp: &Viewport,
    planes: &mut Vec<Plane>,
) -> Option<Tri> {
    let Covered { order, p, bbox } = covered(v, vp)?;
    let w = order.map(|i| *v[i]);
    let a = order.map(|i| attrs[i]);
    let ps = PlaneSetup::new(&w);
    for (k, &lin) in linear.iter().enumerate() {
        let vals = if lin {
            [a[0][k], a[1][k], a[2][k]]
        } else {
            [a[0][k] * w[0].oow, a[1][k] * w[1].oow, a[2][k] * w[2].oow]
        };
        planes.push(ps.plane(vals));
    }
    Some(Tri {
        edges: [
            Edge::new(p[0], p[1]),
            Edge::new(p[1], p[2]),
            Edge::new(p[2], p[0]),
        ],
        bbox,
        z: ps.plane([w[0].z, w[1].z, w[2].z]),
        oow: ps.plane([w[0].oow, w[1].oow, w[2].oow]),
        flat,
    })
}

/// Rasterises `mesh` into a `width`×`height` target.
///
/// # Panics
/// If `mesh` is inconsistent (index out of range, attribute count over
/// [`MAX_VARYINGS`], lengths that disagree): those are programming errors.
pub fn rasterise(mesh: &Mesh, width: u32, height: u32, opts: &Options) -> Raster {
    let mut target = Target::new(width, height, mesh.linear, *opts);
    target.draw(mesh);
    target.finish()
}

/// A target drawn in batches of triangles: each batch is set up, binned
/// and drawn after those before it, in submission order, so any split of
/// one mesh into consecutive batches leaves the depth and the pixels'
/// triangles exactly as one [`rasterise`] of the whole mesh. A mesh larger
/// than memory (brute force of a large map) then needs only a batch's
/// vertices at a time, and the buffers a batch uses are kept for the next
/// one rather than allocated (and faulted in by the kernel) again.
pub struct Target {
    width: u32,
    height: u32,
    opts: Options,
    linear: Vec<bool>,
    depth: Vec<f32>,
    prim: Vec<u32>,
    tris: Vec<Tri>,
    planes: Vec<Plane>,
    stats: RasterStats,
    /// Nothing drawn since the last reset: `depth` and `prim` hold no
    /// values yet, and the first draw writes every tile, cleared or drawn.
    fresh: bool,
    scratch: Scratch,
}

/// Per-batch working memory, kept between batches.
#[derive(Default)]
struct Scratch {
    finite: Vec<bool>,
    masks: Vec<u32>,
    wins: Vec<WinVertex>,
    chunks: Vec<Chunk>,
    bins: Vec<Vec<u32>>,
    keep: Vec<u32>,
}

impl Target {
    /// A cleared target (depth 1.0, no triangle) for meshes whose varyings
    /// are `linear`.
    pub fn new(width: u32, height: u32, linear: &[bool], opts: Options) -> Self {
        let mut t = Target {
            width: 0,
            height: 0,
            opts,
            linear: vec![],
            depth: vec![],
            prim: vec![],
            tris: vec![],
            planes: vec![],
            stats: RasterStats::default(),
            fresh: true,
            scratch: Scratch::default(),
        };
        t.reset(width, height, linear, opts);
        t
    }

    /// Cleared again for a new image, keeping the working memory that
    /// [`Target::finish`] did not hand over.
    pub fn reset(&mut self, width: u32, height: u32, linear: &[bool], opts: Options) {
        assert!(linear.len() <= MAX_VARYINGS, "too many varyings");
        let len = width as usize * height as usize;
        (self.width, self.height, self.opts) = (width, height, opts);
        self.linear = linear.to_vec();
        // The values are written by the first draw (or by `finish`, if
        // none comes), so the buffers are only sized here.
        self.depth.resize(len, 1.0);
        self.prim.resize(len, NONE);
        self.fresh = true;
        self.tris.clear();
        self.planes.clear();
        self.stats = RasterStats::default();
    }

    /// Sets up `mesh`'s triangles and draws them over what earlier batches
    /// drew.
    ///
    /// # Panics
    /// If `mesh` is inconsistent with itself or with the target's varyings.
    pub fn draw(&mut self, mesh: &Mesh) {
        let n = mesh.linear.len();
        assert_eq!(mesh.linear, &self.linear[..], "varyings");
        assert_eq!(mesh.attrs.len(), mesh.clip.len() * n, "attribute count");
        assert_eq!(mesh.flat.len(), mesh.triangles.len(), "flat count");
        let vp = Viewport::new(self.width, self.height);
        let sc = &mut self.scratch;
        let fast = self.opts.path.uses_avx2_fma();
        let len = mesh.clip.len();
        sc.finite.resize(len, false);
        sc.masks.resize(len, 0);
        sc.wins.resize(len, WinVertex::default());
        sc.finite
            .par_chunks_mut(SETUP_CHUNK)
            .zip(sc.masks.par_chunks_mut(SETUP_CHUNK))
            .zip(sc.wins.par_chunks_mut(SETUP_CHUNK))
            .zip(mesh.clip.par_chunks(SETUP_CHUNK))
            .for_each(|(((f, m), w), c)| map_vertices(fast, c, &vp, f, m, w));
        let vertices = Vertices {
            mesh,
            finite: &sc.finite,
            masks: &sc.masks,
            wins: &sc.wins,
            vp: &vp,
        };

        // The chunks' buffers are kept too: a batch of the same size as the
        // last one reuses them (their order, not which one, decides where
        // the triangles go).
        let chunk_count = mesh.triangles.len().div_ceil(SETUP_CHUNK);
        sc.chunks
            .resize_with(chunk_count.max(sc.chunks.len()), Chunk::default);
        sc.chunks[..chunk_count]
            .par_iter_mut()
            .zip(mesh.triangles.par_chunks(SETUP_CHUNK))
            .zip(mesh.flat.par_chunks(SETUP_CHUNK))
            .for_each(|((c, tris), flats)| setup_chunk(fast, &vertices, tris, flats, c));
        let finite = &sc.finite;

        let stats = &mut self.stats;
        stats.input_triangles += mesh.triangles.len();
        stats.non_finite_vertices += finite.iter().filter(|f| !**f).count();
        let first = self.tris.len();
        let chunks = &sc.chunks[..chunk_count];
        let count: usize = chunks.iter().map(|c| c.tris.len()).sum();
        self.tris.reserve(count);
        self.planes.reserve(count * n);
        for c in chunks {
            stats.rejected += c.rejected;
            stats.clipped += c.clipped;
            stats.non_finite_clipped += c.non_finite_clipped;
            self.tris.extend_from_slice(&c.tris);
            self.planes.extend_from_slice(&c.planes);
        }
        let new = &self.tris[first..];
        stats.setup += new.len();
        let finite = |p: &Plane| p.dadx.is_finite() && p.dady.is_finite() && p.a00.is_finite();
        stats.non_finite_planes += new
            .iter()
            .filter(|t| !(finite(&t.z) && finite(&t.oow)))
            .count();

        bin::bin_into(&mut sc.bins, new, first as u32, self.width, self.height);
        let bins = &sc.bins;
        let tris = &self.tris;
        let (tiles_x, _) = bin::grid(self.width, self.height);
        let path = self.opts.path;
        let avx2 = path.uses_avx2_fma();
        let fresh = std::mem::replace(&mut self.fresh, false);
        // One band of 64 rows per task: each of its tiles with triangles
        // in this batch is read into a reused tile buffer (cleared, on a
        // fresh target), drawn and copied back, so the full-size buffers
        // are written once per batch where something is drawn (and once
        // everywhere by the first), in parallel.
        let w = self.width as usize;
        let band = w * bin::TILE as usize;
        self.depth
            .par_chunks_mut(band)
            .zip(self.prim.par_chunks_mut(band))
            .enumerate()
            .for_each_init(tile::TileBuf::new, |buf, (by, (depth, prim))| {
                let ty0 = by as u32 * bin::TILE;
                let h = depth.len() / w;
                for bx in 0..tiles_x {
                    let ids = &bins[(by as u32 * tiles_x + bx) as usize];
                    if ids.is_empty() && !fresh {
                        continue;
                    }
                    let tx0 = bx * bin::TILE;
                    let tw = (w - tx0 as usize).min(bin::TILE as usize);
                    if fresh {
                        buf.depth.fill(1.0);
                        buf.prim.fill(NONE);
                    } else {
                        for r in 0..h {
                            let at = r * w + tx0 as usize;
                            let to = r * tile::STRIDE;
                            buf.depth[to..to + tw].copy_from_slice(&depth[at..at + tw]);
                            buf.prim[to..to + tw].copy_from_slice(&prim[at..at + tw]);
                        }
                    }
                    for &id in ids {
                        let t = &tris[id as usize];
                        let (x, y) = (tx0 as i64, ty0 as i64);
                        match path {
                            Path::Scalar => tile::draw(t, id, x, y, buf),
                            Path::Simd | Path::Portable => simd::draw(avx2, t, id, x, y, buf),
                        }
                    }
                    for r in 0..h {
                        let at = r * w + tx0 as usize;
                        let from = r * tile::STRIDE;
                        depth[at..at + tw].copy_from_slice(&buf.depth[from..from + tw]);
                        prim[at..at + tw].copy_from_slice(&buf.prim[from..from + tw]);
                    }
                }
            });
    }

    /// Counts triangles a caller left out because their [`fate`] was
    /// `Rejected` or `Nothing`, so that the statistics are those of
    /// drawing them.
    pub fn left_out(&mut self, rejected: usize, nothing: usize) {
        self.stats.input_triangles += rejected + nothing;
        self.stats.rejected += rejected;
    }

    /// Drops the set-up triangles that no pixel shows any more and
    /// renumbers the rest (in their order) in the pixels: later batches
    /// can only hide a triangle, never show one again, so the target then
    /// holds at most one triangle per pixel however many were drawn.
    pub fn compact(&mut self) {
        if self.fresh {
            return;
        }
        let keep = &mut self.scratch.keep;
        keep.clear();
        keep.resize(self.tris.len(), NONE);
        for &p in &self.prim {
            if p != NONE {
                keep[p as usize] = 0;
            }
        }
        let n = self.linear.len();
        let mut next = 0u32;
        for (old, k) in keep.iter_mut().enumerate() {
            if *k == NONE {
                continue;
            }
            *k = next;
            let new = next as usize;
            self.tris[new] = self.tris[old];
            self.planes.copy_within(old * n..old * n + n, new * n);
            next += 1;
        }
        self.tris.truncate(next as usize);
        self.planes.truncate(next as usize * n);
        self.prim.par_iter_mut().for_each(|p| {
            if *p != NONE {
                *p = keep[*p as usize];
            }
        });
    }

    /// Takes back the buffers of a raster this target finished (all but
    /// the depth, which the image keeps), so the next image reuses them.
    pub fn recycle(&mut self, r: Raster) {
        let Raster {
            mut prim,
            mut tris,
            mut planes,
            ..
        } = r;
        if prim.capacity() > self.prim.capacity() {
            std::mem::swap(&mut prim, &mut self.prim);
        }
        tris.clear();
        planes.clear();
        if tris.capacity() > self.tris.capacity() {
            self.tris = tris;
            self.planes = planes;
        }
    }

    /// Set-up triangles held now.
    pub fn triangles_held(&self) -> usize {
        self.tris.len()
    }

    /// The finished raster; the target is empty until [`Target::reset`].
    pub fn finish(&mut self) -> Raster {
        if std::mem::replace(&mut self.fresh, false) {
            self.depth.fill(1.0);
            self.prim.fill(NONE);
        }
        let (covered, bad) = self
            .prim
            .par_iter()
            .zip(self.depth.par_iter())
            .map(|(&p, d)| (usize::from(p != NONE), usize::from(!d.is_finite())))
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        self.stats.covered_pixels = covered;
        self.stats.non_finite_depth = bad;
        Raster {
            width: self.width,
            height: self.height,
            depth: std::mem::take(&mut self.depth),
            prim: std::mem::take(&mut self.prim),
            tris: std::mem::take(&mut self.tris),
            planes: std::mem::take(&mut self.planes),
            linear: self.linear.clone(),
            stats: std::mem::take(&mut self.stats),
        }
    }
}

/// One batch's vertices as set-up reads them.
struct Vertices<'a> {
    mesh: &'a Mesh<'a>,
    finite: &'a [bool],
    masks: &'a [u32],
    wins: &'a [WinVertex],
    vp: &'a Viewport,
}

/// Per vertex: whether its clip position is finite, its outcode and its
/// window position.
#[inline(always)]
fn map_vertices_in(
    clip: &[[f32; 4]],
    vp: &Viewport,
    finite: &mut [bool],
    masks: &mut [u32],
    wins: &mut [WinVertex],
) {
    for (i, &c) in clip.iter().enumerate() {
        finite[i] = c.iter().all(|v| v.is_finite());
        masks[i] = clip::outcode(c);
        wins[i] = vp.map(c);
    }
}

/// Sets up the triangles `tris` into `c`, in submission order.
#[inline(always)]
fn setup_chunk_in(v: &Vertices, tris: &[[u32; 3]], flats: &[u32], c: &mut Chunk) {
    let Vertices {
        mesh,
        finite,
        masks,
        wins,
        vp,
    } = *v;
    let n = mesh.linear.len();
    let attrs_of = |i: u32| &mesh.attrs[i as usize * n..i as usize * n + n];
    c.clear();
    let mut fan = Vec::new();
    for (t, &flat) in tris.iter().zip(flats) {
        if !t.iter().all(|&i| finite[i as usize]) {
            continue;
        }
        let m = t.map(|i| masks[i as usize]);
        if m[0] & m[1] & m[2] != 0 {
            c.rejected += 1;
            continue;
        }
        let or = m[0] | m[1] | m[2];
        if or == 0 {
            let v = t.map(|i| &wins[i as usize]);
            let a = t.map(attrs_of);
            if let Some(s) = setup_one(v, a, mesh.linear, flat, vp, &mut c.planes) {
                c.tris.push(s);
            }
            continue;
        }
        c.clipped += 1;
        let cv = t.map(|i| {
            let mut a = [0.0; MAX_VARYINGS];
            a[..n].copy_from_slice(attrs_of(i));
            ClipVertex {
                clip: mesh.clip[i as usize],
                win: wins[i as usize],
                attrs: a,
            }
        });
        fan.clear();
        c.non_finite_clipped +=
            clip::clip_triangle([&cv[0], &cv[1], &cv[2]], or, n, mesh.linear, vp, &mut fan);
        for f in &fan {
            let v = [&f[0].win, &f[1].win, &f[2].win];
            let a = [&f[0].attrs[..n], &f[1].attrs[..n], &f[2].attrs[..n]];
            if let Some(s) = setup_one(v, a, mesh.linear, flat, vp, &mut c.planes) {
                c.tris.push(s);
            }
        }
    }
}

crate::cpu::avx2_fma_twin! {
    /// [`map_vertices_in`], in the AVX2 + FMA build when `fast`: the
    /// viewport's multiply-add and the snap's rounding are then
    /// instructions rather than calls into the maths library, with the
    /// same bits.
    fn map_vertices(
        clip: &[[f32; 4]],
        vp: &Viewport,
        finite: &mut [bool],
        masks: &mut [u32],
        wins: &mut [WinVertex],
    ) => map_vertices_in
}

crate::cpu::avx2_fma_twin! {
    /// [`setup_chunk_in`], in the AVX2 + FMA build when `fast`.
    fn setup_chunk(v: &Vertices, tris: &[[u32; 3]], flats: &[u32], c: &mut Chunk) => setup_chunk_in
}

/// Triangles per set-up task.
const SETUP_CHUNK: usize = 2048;

/// Per-chunk setup output, merged in order afterwards.
#[derive(Default)]
struct Chunk {
    tris: Vec<Tri>,
    planes: Vec<Plane>,
    rejected: usize,
    clipped: usize,
    non_finite_clipped: usize,
}

impl Chunk {
    fn clear(&mut self) {
        self.tris.clear();
        self.planes.clear();
        self.rejected = 0;
        self.clipped = 0;
        self.non_finite_clipped = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::unorm8;

    /// The vectorisable form equals the plain definition, NaN included.
    #[test]
    fn unorm8_matches_its_definition() {
        let plain = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round_ties_even() as u8;
        let specials = [
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            0.5 / 255.0,
        ];
        let halves = (0..=512).map(|k| k as f32 * 0.5 / 255.0);
        let sweep = (0..u32::MAX / 7919).map(|i| f32::from_bits(i * 7919));
        for c in specials.into_iter().chain(halves).chain(sweep) {
            assert_eq!(unorm8(c), plain(c), "{c:e} ({:#x})", c.to_bits());
        }
    }
}
