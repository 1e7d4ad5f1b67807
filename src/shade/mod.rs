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
use crate::raster::{unorm8, Raster, NONE};
use normal_map::NormalMap;
use rayon::prelude::*;
use serde::Deserialize;
use shadows::Lightmap;

/// Effects a scene may list.
pub const EFFECTS: &[&str] = &[
    "lambert",
    "phong",
    "fog",
    "shadows",
    "normal-map",
    "level-tint",
    "wireframe",
    "morph",
];

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
    /// Parses effect names; unknown names and impossible combinations are
    /// errors.
    pub fn parse<S: AsRef<str>>(names: &[S]) -> Result<Self, String> {
        let mut e = Effects::default();
        for n in names {
            let flag = match n.as_ref() {
                "lambert" => &mut e.lambert,
                "phong" => &mut e.phong,
                "fog" => &mut e.fog,
                "shadows" => &mut e.shadows,
                "normal-map" => &mut e.normal_map,
                "level-tint" => &mut e.level_tint,
                "wireframe" => &mut e.wireframe,
                "morph" => &mut e.morph,
                other => {
                    return Err(format!(
                        "unknown effect '{other}' (known: {})",
                        EFFECTS.join(", ")
                    ))
                }
            };
            *flag = true;
        }
        if e.normal_map && !e.lit() {
            return Err("'normal-map' needs a lighting effect ('lambert' or 'phong')".into());
        }
        Ok(e)
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
#[derive(Clone, Debug, Deserialize, PartialEq)]
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
    pub specular_strength: f32,
    /// Clearance (m) over which a ray fades from shadow to light.
    pub shadow_epsilon: f64,
    /// Lightmap samples per heightmap texel along each axis: 1 or 2.
    pub lightmap_scale: u32,
    pub wire_colour: [f32; 3],
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

/// The colour of one visible pixel.
fn shade_pixel(s: &ShadeInputs, r: &Raster, id: u32, px: u32, py: u32, v: &mut [f32]) -> [f32; 3] {
    r.interpolate(id, px, py, v);
    let e = s.effects;
    let lay = s.layout;
    let level = r.tris[id as usize].flat;
    let at3 = |k: Option<usize>| k.map(|k| [v[k], v[k + 1], v[k + 2]]);
    let albedo = match lay.albedo {
        Some(_) => at3(lay.albedo).expect("albedo"),
        None => level_tint::albedo(level),
    };
    let sun = s.sun;
    let uv = lay.uv.map(|k| [v[k], v[k + 1]]);
    let alpha = lay.alpha.map_or(0.0, |k| v[k]);
    let info = s.resources.levels[level as usize].expect("drawn level");
    let shadow = match &s.resources.lightmap {
        Some(lm) => lm.sample(level as usize, info.origin, uv.expect("uv"), alpha),
        None => 1.0,
    };
    let mut c = albedo;
    if e.lit() {
        let n = match lay.normal {
            Some(_) => vec3::normalize(at3(lay.normal).expect("normal")),
            None => {
                let fine = s.resources.normal_maps[level as usize]
                    .as_ref()
                    .expect("normal map");
                let coarse = s
                    .resources
                    .normal_maps
                    .get(level as usize + 1)
                    .and_then(|m| m.as_ref());
                normal_map::pixel_normal(fine, coarse, info.origin, uv.expect("uv"), alpha)
            }
        };
        c = lambert::apply(albedo, s.params.ambient, lambert::diffuse(n, sun) * shadow);
        if e.phong {
            let view = at3(lay.view).expect("view");
            let to_eye = [-view[0], -view[1], -view[2]];
            let p = &s.params;
            let spec = phong::specular(n, sun, to_eye, p.specular_squarings, p.specular_strength);
            let spec = spec * shadow;
            c = [c[0] + spec, c[1] + spec, c[2] + spec];
        }
    } else if e.shadows {
        c = lambert::apply(albedo, s.params.ambient, shadow);
    }
    if let Some(k) = lay.fog {
        c = fog::apply(c, s.params.fog_colour.unwrap_or(s.background), v[k]);
    }
    if let Some(k) = lay.bary {
        let t = at3(lay.edge).expect("edge thresholds");
        if wireframe::on_edge([v[k], v[k + 1], v[k + 2]], t) {
            c = wireframe::apply(c, s.params.wire_colour);
        }
    }
    c
}

/// Shades every pixel of `r` into RGBA8 (background where nothing drew).
pub fn shade(s: &ShadeInputs, r: &Raster) -> Vec<u8> {
    let w = r.width as usize;
    let bg = s.background.map(unorm8);
    let mut out = vec![0u8; w * r.height as usize * 4];
    out.par_chunks_mut(w * 4).enumerate().for_each(|(py, row)| {
        let mut v = vec![0.0f32; s.layout.len()];
        for (px, rgba) in row.chunks_exact_mut(4).enumerate() {
            let id = r.prim[py * w + px];
            let c = if id == NONE {
                bg
            } else {
                shade_pixel(s, r, id, px as u32, py as u32, &mut v).map(unorm8)
            };
            rgba.copy_from_slice(&[c[0], c[1], c[2], 255]);
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_holds_only_what_effects_need() {
        let none = Layout::new(&Effects::default());
        assert_eq!(none.len(), 3, "albedo only");
        assert!(none.normal.is_none() && none.uv.is_none() && none.fog.is_none());
        let lit = Layout::new(&Effects::parse(&["lambert"]).unwrap());
        assert!(lit.normal.is_some() && lit.uv.is_none());
        let nm = Layout::new(&Effects::parse(&["lambert", "normal-map"]).unwrap());
        assert!(nm.normal.is_none() && nm.uv.is_some() && nm.alpha.is_some());
        let wire = Layout::new(&Effects::parse(&["wireframe", "level-tint"]).unwrap());
        assert_eq!(wire.linear, vec![true; 6]);
    }

    #[test]
    fn bad_effect_lists_are_errors() {
        assert!(Effects::parse(&["bloom"]).unwrap_err().contains("bloom"));
        assert!(Effects::parse(&["normal-map"])
            .unwrap_err()
            .contains("lighting"));
    }
}
