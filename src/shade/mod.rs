//! Shading: the effects a scene lists, one per file, and nothing else.
//!
//! [`Effects`] says what the scene asked for; [`Layout`] derives the
//! varyings the vertex stage must produce for exactly those effects (no
//! normals without lighting, no texture coordinates without a map to read);
//! the render stage builds the [`Resources`] (normal maps, lightmap) only for
//! listed effects; [`shade`] then runs per visible pixel.
//!
//! Per-pixel maths is f32 in a fixed order without FMA, so a WGSL fragment
//! shader can repeat it.

pub mod fog;
pub mod lambert;
pub mod level_tint;
pub mod morph;
pub mod normal_map;
pub mod normals;
pub mod phong;
pub mod shadows;
pub mod vec3;
pub mod wireframe;

use crate::lod::LevelInfo;
use crate::raster::{unorm8, Path, Raster, NONE, RUN_LANES};
use normal_map::NormalMap;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use shadows::Lightmap;

crate::names::named! {
    /// An effect a scene may list. One the scene does not list costs
    /// nothing: its varyings are not computed and its shader code is
    /// compiled out.
    pub enum Effect ("effect") {
        /// Diffuse lighting from per-vertex normals.
        Lambert => "lambert",
        /// A Blinn–Phong highlight.
        Phong => "phong",
        /// Exponential fog, per vertex.
        Fog => "fog",
        /// Holkner's ray-traced lightmap.
        Shadows => "shadows",
        /// Per-level normal maps at twice the resolution.
        NormalMap => "normal-map",
        /// A colour per clipmap level.
        LevelTint => "level-tint",
        /// Triangle edges.
        Wireframe => "wireframe",
        /// Geomorphing across level boundaries.
        Morph => "morph",
    }
}

/// The effects a scene listed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Effects {
    pub lambert: bool,
    pub phong: bool,
    pub fog: bool,
    pub shadows: bool,
    pub normal_map: bool,
    pub level_tint: bool,
    pub wireframe: bool,
    pub morph: bool,
}

impl Effects {
    /// The flags for a scene's list; impossible combinations are errors.
    pub fn from_list(list: &[Effect]) -> Result<Self, String> {
        let mut e = Effects::default();
        for &n in list {
            let flag = match n {
                Effect::Lambert => &mut e.lambert,
                Effect::Phong => &mut e.phong,
                Effect::Fog => &mut e.fog,
                Effect::Shadows => &mut e.shadows,
                Effect::NormalMap => &mut e.normal_map,
                Effect::LevelTint => &mut e.level_tint,
                Effect::Wireframe => &mut e.wireframe,
                Effect::Morph => &mut e.morph,
            };
            *flag = true;
        }
        if e.normal_map && !e.lit() {
            return Err("'normal-map' needs a lighting effect ('lambert' or 'phong')".into());
        }
        Ok(e)
    }
    /// The list [`Effects::from_list`] takes back: what an export records.
    pub fn list(&self) -> Vec<Effect> {
        let flags = [
            (self.lambert, Effect::Lambert),
            (self.phong, Effect::Phong),
            (self.fog, Effect::Fog),
            (self.shadows, Effect::Shadows),
            (self.normal_map, Effect::NormalMap),
            (self.level_tint, Effect::LevelTint),
            (self.wireframe, Effect::Wireframe),
            (self.morph, Effect::Morph),
        ];
        flags.iter().filter(|f| f.0).map(|f| f.1).collect()
    }
    /// True if any effect needs surface normals.
    pub fn lit(&self) -> bool {
        self.lambert || self.phong
    }
    /// True if per-level texture coordinates and α reach the pixels.
    pub fn textured(&self) -> bool {
        self.normal_map || self.shadows
    }
}

/// Effect settings (the scene's `[shading]` table).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ShadeParams {
    /// Sun azimuth, degrees clockwise from north, and elevation, degrees.
    pub sun: [f64; 2],
    /// Light that reaches surfaces facing away from the sun.
    pub ambient: f32,
    /// Exponential fog density, 1/m.
    pub fog_density: f64,
    /// Fog colour; the image background if absent.
    pub fog_colour: Option<[f32; 3]>,
    /// Blinn–Phong exponent 2^k is given as k squarings.
    pub specular_squarings: u32,
    /// Weight of the specular highlight (`phong`).
    pub specular_strength: f32,
    /// Clearance (m) over which a ray fades from shadow to light.
    pub shadow_epsilon: f64,
    /// Lightmap samples per heightmap texel along each axis: 1 or 2.
    pub lightmap_scale: u32,
    /// Line colour of `wireframe`, linear RGB.
    pub wire_colour: [f32; 3],
    /// Heights (metres, before vertical scale) the colour ramp spans; the
    /// map's own range if absent. A lazy pyramid needs it: it has not seen
    /// the whole map.
    pub height_range: Option<[f32; 2]>,
}

impl Default for ShadeParams {
    fn default() -> Self {
        ShadeParams {
            sun: [315.0, 40.0],
            ambient: 0.25,
            fog_density: 1.0 / 12000.0,
            fog_colour: None,
            specular_squarings: 5,
            specular_strength: 0.25,
            shadow_epsilon: 20.0,
            lightmap_scale: 1,
            wire_colour: [0.05, 0.05, 0.08],
            height_range: None,
        }
    }
}

impl ShadeParams {
    /// Checks ranges; `Err` holds (field, reason).
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let [az, el] = self.sun;
        if !(az.is_finite() && el > 0.0 && el <= 90.0) {
            return Err((
                "shading.sun",
                format!("need a finite azimuth and 0 < elevation <= 90, got [{az}, {el}]"),
            ));
        }
        if !(0.0..=1.0).contains(&self.ambient) {
            return Err(("shading.ambient", "must be in [0, 1]".into()));
        }
        if !(self.fog_density.is_finite() && self.fog_density >= 0.0) {
            return Err(("shading.fog_density", "must be finite and >= 0".into()));
        }
        if self.specular_squarings > 10 {
            return Err((
                "shading.specular_squarings",
                "at most 10 (exponent 1024)".into(),
            ));
        }
        if !(self.specular_strength.is_finite() && self.specular_strength >= 0.0) {
            return Err((
                "shading.specular_strength",
                "must be finite and >= 0".into(),
            ));
        }
        if !(self.shadow_epsilon.is_finite() && self.shadow_epsilon > 0.0) {
            return Err(("shading.shadow_epsilon", "must be finite and > 0".into()));
        }
        if !matches!(self.lightmap_scale, 1 | 2) {
            return Err(("shading.lightmap_scale", "must be 1 or 2".into()));
        }
        if let Some([lo, hi]) = self.height_range {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err((
                    "shading.height_range",
                    format!("need finite low < high, got [{lo}, {hi}]"),
                ));
            }
        }
        let colours = self.fog_colour.iter().chain([&self.wire_colour]);
        if colours.flatten().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(("shading", "colours must be in [0, 1]".into()));
        }
        Ok(())
    }

    /// Unit vector toward the sun (x east, y north, z up).
    pub fn sun_direction(&self) -> [f64; 3] {
        let (az, el) = (self.sun[0].to_radians(), self.sun[1].to_radians());
        [el.cos() * az.sin(), el.cos() * az.cos(), el.sin()]
    }
}

/// Where each varying sits among a vertex's attributes; `None` = not made.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Layout {
    pub albedo: Option<usize>,
    pub normal: Option<usize>,
    pub uv: Option<usize>,
    pub alpha: Option<usize>,
    pub fog: Option<usize>,
    pub view: Option<usize>,
    pub bary: Option<usize>,
    /// Per-triangle wireframe thresholds (constant over a triangle).
    pub edge: Option<usize>,
    /// Per attribute: screen-linear (true) or perspective-correct.
    pub linear: Vec<bool>,
}

impl Layout {
    /// The varyings `e` needs, and only those.
    pub fn new(e: &Effects) -> Self {
        let mut l = Layout::default();
        let add = |n: usize, linear: bool, l: &mut Layout| {
            let at = l.linear.len();
            l.linear.extend(std::iter::repeat_n(linear, n));
            Some(at)
        };
        if !e.level_tint {
            l.albedo = add(3, false, &mut l);
        }
        if e.lit() && !e.normal_map {
            l.normal = add(3, false, &mut l);
        }
        if e.textured() {
            l.uv = add(2, false, &mut l);
            l.alpha = add(1, false, &mut l);
        }
        if e.fog {
            l.fog = add(1, false, &mut l);
        }
        if e.phong {
            l.view = add(3, false, &mut l);
        }
        if e.wireframe {
            l.bary = add(3, true, &mut l);
            l.edge = add(3, true, &mut l);
        }
        l
    }
    pub fn len(&self) -> usize {
        self.linear.len()
    }
    pub fn is_empty(&self) -> bool {
        self.linear.is_empty()
    }
}

/// Precomputed inputs of the listed effects.
#[derive(Clone, Debug, Default)]
pub struct Resources {
    /// Per level number: window origin and morph flag of drawn levels.
    pub levels: Vec<Option<LevelInfo>>,
    /// Per level number, with `normal-map`.
    pub normal_maps: Vec<Option<NormalMap>>,
    /// With `shadows`.
    pub lightmap: Option<Lightmap>,
}

/// The height-ramp albedo at normalised height t ∈ [0, 1]: lowland green,
/// brown slopes, grey rock, snow.
pub fn height_albedo(t: f32) -> [f32; 3] {
    const STOPS: [(f32, [f32; 3]); 4] = [
        (0.0, [0.22, 0.38, 0.16]),
        (0.45, [0.47, 0.42, 0.27]),
        (0.75, [0.52, 0.50, 0.47]),
        (1.0, [0.95, 0.95, 0.97]),
    ];
    let t = t.clamp(0.0, 1.0);
    for w in STOPS.windows(2) {
        let ((t0, a), (t1, b)) = (w[0], w[1]);
        if t <= t1 {
            let k = (t - t0) / (t1 - t0);
            return [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * k);
        }
    }
    STOPS[3].1
}

/// Everything the per-pixel shader reads besides the raster.
pub struct ShadeInputs<'a> {
    pub effects: &'a Effects,
    pub params: &'a ShadeParams,
    pub layout: &'a Layout,
    pub resources: &'a Resources,
    pub background: [f32; 3],
    /// Unit vector toward the sun, from [`ShadeParams::sun_direction`].
    pub sun: [f32; 3],
}

/// Pixels shaded together: one AVX2 register of f32.
const LANES: usize = 8;

/// Colour channels of [`LANES`] pixels.
type Rgb = [[f32; LANES]; 3];

/// A row's varyings in structure-of-arrays form: varying k of pixel x at
/// `vary[k * stride + x]`, with `stride` a multiple of [`LANES`] so every
/// group of pixels reads whole lanes.
struct Scratch {
    stride: usize,
    vary: Vec<f32>,
    winv: Vec<f32>,
    level: Vec<u32>,
    /// The row's runs of pixels that share a triangle: (first, end).
    runs: Vec<(usize, usize)>,
}

impl Scratch {
    fn new(width: usize, varyings: usize) -> Self {
        // Room for `interpolate_run`'s whole groups past the last pixel.
        let stride = (width + RUN_LANES).next_multiple_of(LANES);
        Scratch {
            stride,
            vary: vec![0.0; stride * varyings],
            winv: vec![0.0; stride],
            level: vec![0; stride],
            runs: Vec::with_capacity(width),
        }
    }
    #[inline(always)]
    fn lanes(&self, k: usize, x: usize) -> &[f32; LANES] {
        let at = k * self.stride + x;
        (&self.vary[at..at + LANES]).try_into().expect("padded row")
    }
    #[inline(always)]
    fn lanes3(&self, k: usize, x: usize) -> [[f32; LANES]; 3] {
        [
            *self.lanes(k, x),
            *self.lanes(k + 1, x),
            *self.lanes(k + 2, x),
        ]
    }
}

#[inline(always)]
fn get(c: &Rgb, l: usize) -> [f32; 3] {
    [c[0][l], c[1][l], c[2][l]]
}

#[inline(always)]
fn set(c: &mut Rgb, l: usize, v: [f32; 3]) {
    (c[0][l], c[1][l], c[2][l]) = (v[0], v[1], v[2]);
}

/// The colour of [`LANES`] pixels from x, row `ids`. Lanes whose id is
/// [`NONE`] compute garbage that the caller discards; they never index a
/// per-level resource. The effects stay written for one pixel; the loops
/// over lanes (no closures, which the compiler may leave out of line and
/// so out of the AVX2 build) vectorise. Always inlined so it is compiled
/// into each build of [`shade_row`].
#[inline(always)]
#[allow(clippy::needless_range_loop)] // a lane indexes several arrays at once
fn shade_lanes(s: &ShadeInputs, sc: &Scratch, ids: &[u32], x: usize) -> Rgb {
    let e = s.effects;
    let lay = s.layout;
    let p = s.params;
    let mut c = match lay.albedo {
        Some(k) => sc.lanes3(k, x),
        None => {
            let mut a = [[0.0; LANES]; 3];
            for l in 0..LANES {
                set(&mut a, l, level_tint::albedo(sc.level[x + l]));
            }
            a
        }
    };
    let textured = e.textured().then(|| Texels::new(s, sc, ids, x));
    let mut shadow = [1.0f32; LANES];
    if let (Some(lm), Some(t)) = (&s.resources.lightmap, &textured) {
        for (l, sh) in shadow.iter_mut().enumerate() {
            if let Some((level, origin)) = t.level(l) {
                *sh = lm.sample(level, origin, t.uv(l), t.alpha(l));
            }
        }
    }
    if e.lit() {
        let mut n = [[0.0; LANES]; 3];
        match (lay.normal, &textured) {
            (Some(k), _) => {
                let v = sc.lanes3(k, x);
                for l in 0..LANES {
                    set(&mut n, l, vec3::normalize(get(&v, l)));
                }
            }
            (None, Some(t)) => {
                for l in 0..LANES {
                    if let Some(v) = t.normal(l) {
                        set(&mut n, l, v);
                    }
                }
            }
            (None, None) => unreachable!("lit without normals or a normal map"),
        }
        for l in 0..LANES {
            let light = lambert::diffuse(get(&n, l), s.sun) * shadow[l];
            let a = lambert::apply(get(&c, l), p.ambient, light);
            set(&mut c, l, a);
        }
        if let Some(k) = lay.view.filter(|_| e.phong) {
            let view = sc.lanes3(k, x);
            for l in 0..LANES {
                let v = get(&view, l);
                let to_eye = [-v[0], -v[1], -v[2]];
                let (sq, st) = (p.specular_squarings, p.specular_strength);
                let spec = phong::specular(get(&n, l), s.sun, to_eye, sq, st) * shadow[l];
                let a = get(&c, l);
                set(&mut c, l, [a[0] + spec, a[1] + spec, a[2] + spec]);
            }
        }
    } else if e.shadows {
        for l in 0..LANES {
            let a = lambert::apply(get(&c, l), p.ambient, shadow[l]);
            set(&mut c, l, a);
        }
    }
    if let Some(k) = lay.fog {
        let f = sc.lanes(k, x);
        let fog = p.fog_colour.unwrap_or(s.background);
        for l in 0..LANES {
            let a = fog::apply(get(&c, l), fog, f[l]);
            set(&mut c, l, a);
        }
    }
    if let (Some(k), Some(t)) = (lay.bary, lay.edge) {
        let (b, t) = (sc.lanes3(k, x), sc.lanes3(t, x));
        for l in 0..LANES {
            let a = get(&c, l);
            let edge = wireframe::on_edge(get(&b, l), get(&t, l));
            let w = wireframe::apply(a, p.wire_colour);
            set(&mut c, l, if edge { w } else { a });
        }
    }
    c
}

/// What texture-reading effects need per lane: the level and its window
/// origin (None for uncovered lanes), uv and α.
struct Texels<'a> {
    s: &'a ShadeInputs<'a>,
    sc: &'a Scratch,
    ids: &'a [u32],
    x: usize,
}

impl<'a> Texels<'a> {
    fn new(s: &'a ShadeInputs<'a>, sc: &'a Scratch, ids: &'a [u32], x: usize) -> Self {
        Texels { s, sc, ids, x }
    }
    fn level(&self, l: usize) -> Option<(usize, [i64; 2])> {
        let id = *self.ids.get(self.x + l)?;
        if id == NONE {
            return None;
        }
        let level = self.sc.level[self.x + l] as usize;
        let info = self.s.resources.levels[level].expect("drawn level");
        Some((level, info.origin))
    }
    fn uv(&self, l: usize) -> [f32; 2] {
        let k = self.s.layout.uv.expect("uv");
        [self.sc.lanes(k, self.x)[l], self.sc.lanes(k + 1, self.x)[l]]
    }
    fn alpha(&self, l: usize) -> f32 {
        self.s
            .layout
            .alpha
            .map_or(0.0, |k| self.sc.lanes(k, self.x)[l])
    }
    /// The normal-mapped normal of lane `l`, if covered.
    fn normal(&self, l: usize) -> Option<[f32; 3]> {
        let (level, origin) = self.level(l)?;
        let maps = &self.s.resources.normal_maps;
        let fine = maps[level].as_ref().expect("normal map");
        let coarse = maps.get(level + 1).and_then(|m| m.as_ref());
        let (uv, alpha) = (self.uv(l), self.alpha(l));
        Some(normal_map::pixel_normal(fine, coarse, origin, uv, alpha))
    }
}

/// Shades every pixel of `r` into RGBA8 (background where nothing drew).
///
/// Per row: the varyings of each run of pixels that share a triangle are
/// interpolated with that triangle's planes (see
/// [`Raster::interpolate_run`]), then the effects run over 8 pixels
/// at a time. Every pixel gets exactly the operations, in the same order,
/// that one-pixel-at-a-time shading would give it.
///
/// `path` picks the build of the per-row loop: [`Path::Simd`] runs one
/// compiled for AVX2 + FMA when the CPU has them, where `mul_add` and
/// rounding are single instructions instead of library calls; the scalar
/// and portable paths run the baseline build. IEEE 754 fixes the result of each
/// operation, so both give the same bits (the goldens check it).
pub fn shade(s: &ShadeInputs, r: &Raster, path: Path) -> Vec<u8> {
    let w = r.width as usize;
    let mut out = vec![0u8; w * r.height as usize * 4];
    let fast = path.uses_avx2_fma();
    out.par_chunks_mut(w * 4).enumerate().for_each_init(
        || Scratch::new(w, s.layout.len()),
        |sc, (py, row)| shade_row_in(fast, s, r, py, row, sc),
    );
    out
}

crate::cpu::avx2_fma_twin! {
    fn shade_row_in(s: &ShadeInputs, r: &Raster, py: usize, row: &mut [u8], sc: &mut Scratch) => shade_row
}

/// The end of the run of pixels from x that share `ids[x]`: 8 ids compared
/// per step (branch-free within a step, so it vectorises), then one at a
/// time.
#[inline(always)]
fn run_end(ids: &[u32], x: usize) -> usize {
    let id = ids[x];
    let mut e = x + 1;
    while let Some(c) = ids.get(e..e + LANES) {
        if !c.iter().fold(true, |all, &j| all & (j == id)) {
            break;
        }
        e += LANES;
    }
    while e < ids.len() && ids[e] == id {
        e += 1;
    }
    e
}

/// RGBA8 as one little-endian u32 (alpha 255).
#[inline(always)]
fn pack(r: u8, g: u8, b: u8) -> u32 {
    u32::from_le_bytes([r, g, b, 255])
}

/// One row of pixels; inlined into both builds.
#[inline(always)]
fn shade_row(s: &ShadeInputs, r: &Raster, py: usize, row: &mut [u8], sc: &mut Scratch) {
    let w = r.width as usize;
    let ids = &r.prim[py * w..py * w + w];
    let mut runs = std::mem::take(&mut sc.runs);
    runs.clear();
    let mut x = 0;
    while x < w {
        let end = run_end(ids, x);
        runs.push((x, end));
        x = end;
    }
    // A row's triangles lie anywhere in the set-up order, so each run's
    // planes are a cache miss; asking for the planes of the run after next
    // while this one is interpolated hides most of the wait.
    for (i, &(x, end)) in runs.iter().enumerate() {
        if let Some(&(ahead, _)) = runs.get(i + 2) {
            r.prefetch(ids[ahead]);
        }
        let id = ids[x];
        if id != NONE {
            let stride = sc.stride;
            r.interpolate_run(id, x..end, py as u32, &mut sc.winv, &mut sc.vary, stride);
            sc.level[x..end].fill(r.tris[id as usize].flat);
        }
    }
    sc.runs = runs;
    let [br, bgreen, bb] = s.background.map(unorm8);
    let bg = pack(br, bgreen, bb);
    for x in (0..w).step_by(LANES) {
        let n = (w - x).min(LANES);
        let out = row[x * 4..(x + n) * 4].chunks_exact_mut(4);
        if ids[x..x + n].iter().all(|&id| id == NONE) {
            out.for_each(|rgba| rgba.copy_from_slice(&bg.to_le_bytes()));
            continue;
        }
        let c = shade_lanes(s, sc, ids, x);
        // Packed in 8 lanes, background where nothing drew, then stored.
        let mut px = [0u32; LANES];
        for l in 0..LANES {
            let id = ids.get(x + l).copied().unwrap_or(NONE);
            let v = pack(unorm8(c[0][l]), unorm8(c[1][l]), unorm8(c[2][l]));
            px[l] = if id == NONE { bg } else { v };
        }
        for (rgba, p) in out.zip(px) {
            rgba.copy_from_slice(&p.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_holds_only_what_effects_need() {
        let none = Layout::new(&Effects::default());
        assert_eq!(none.len(), 3, "albedo only");
        assert!(none.normal.is_none() && none.uv.is_none() && none.fog.is_none());
        let lit = Layout::new(&Effects::from_list(&[Effect::Lambert]).unwrap());
        assert!(lit.normal.is_some() && lit.uv.is_none());
        let nm = Layout::new(&Effects::from_list(&[Effect::Lambert, Effect::NormalMap]).unwrap());
        assert!(nm.normal.is_none() && nm.uv.is_some() && nm.alpha.is_some());
        let wire =
            Layout::new(&Effects::from_list(&[Effect::Wireframe, Effect::LevelTint]).unwrap());
        assert_eq!(wire.linear, vec![true; 6]);
    }

    #[test]
    fn bad_effect_lists_are_errors() {
        assert!(Effects::from_list(&[Effect::NormalMap])
            .unwrap_err()
            .contains("lighting"));
    }

    /// The 8-at-a-time run search ends where the one-at-a-time one does.
    #[test]
    fn run_end_matches_a_linear_search() {
        let mut seed = 12345u64;
        for len in 1..60 {
            let ids: Vec<u32> = (0..len)
                .map(|_| {
                    seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                    // Long runs and short ones: few distinct values.
                    ((seed >> 60) % 3) as u32
                })
                .collect();
            for x in 0..len {
                let want = ids[x..]
                    .iter()
                    .position(|&j| j != ids[x])
                    .map_or(len, |d| x + d);
                assert_eq!(run_end(&ids, x), want, "{ids:?} from {x}");
            }
        }
    }
}
