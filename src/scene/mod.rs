//! Scenes: TOML files that say which terrain to load, how to filter and LOD
//! it, where the camera is, the image size and the effects. Unknown keys and
//! bad values are errors that name the file, line and column.

/// The camera, re-exported where the scene's `[camera]` is read.
pub use crate::camera;
mod frame;

pub use frame::frame_terrain;

/// The named choices a scene makes, declared by the stages that own them.
pub use crate::lod::LodScheme;
/// The scene's `[lod]`, owned by the LOD stage.
pub use crate::lod::Spec as Lod;
pub use crate::shade::Effect;
/// The scene's `[terrain]`, owned by the terrain stage.
pub use crate::terrain::{CellSize, Spec as Terrain};

use crate::camera::Camera;
use crate::clipmap::Layout;
use crate::error::{Error, Result};
use crate::lod::LodConfig;
use crate::pyramid::Filter;
use crate::shade::Effects;
/// The shading constants a scene's `[shading]` table sets.
pub use crate::shade::ShadeParams;
use glam::DVec3;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The embedded default scene (procedural, no files needed).
pub const DEFAULT_SCENE: &str = include_str!("default.toml");

/// The benchmark's scene (`benches/scenes/bench.toml`): the speed figures
/// are measured on it and the tests build on it, so it stays fixed while
/// the default scene is free to show what terraclip does.
pub const BENCH_SCENE: &str = include_str!("../../benches/scenes/bench.toml");

/// Largest world coordinate accepted (metres).
pub const MAX_COORDINATE: f64 = 1e12;

/// Largest image side accepted.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// The scene's `[pyramid]`: how the coarser levels are made, and when.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PyramidSpec {
    /// Downsampling filter (`point`, `box`, `sinc-blackman[:TAPS]`; default sinc-Blackman).
    #[serde(default, deserialize_with = "filter_from_name")]
    pub filter: Filter,
    /// Build the pyramid in tiles around the viewer as frames need them
    /// (clipmap only), instead of whole before the first frame.
    #[serde(default)]
    pub lazy: bool,
    /// Lazy pyramid: samples one frame may build (all levels counted); the
    /// coarser levels that do not fit are drawn in later frames.
    #[serde(default = "default_lazy_budget")]
    pub budget: u64,
}

/// About 0.5 s of procedural generation and filtering on 2 cores.
pub const DEFAULT_LAZY_BUDGET: u64 = 16 << 20;

fn default_lazy_budget() -> u64 {
    DEFAULT_LAZY_BUDGET
}

/// A filter by its name (`point`, `box`, `sinc-blackman[:TAPS]`).
fn filter_from_name<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> std::result::Result<Filter, D::Error> {
    let s = String::deserialize(d)?;
    Filter::parse(&s).map_err(serde::de::Error::custom)
}

/// The scene's `[camera]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// World position (metres): x east, y north, z up.
    pub position: [f64; 3],
    /// Either a point to look at, or a heading (`yaw`, degrees clockwise
    /// from north) and `pitch` (degrees above the horizon).
    pub look_at: Option<[f64; 3]>,
    /// Heading in degrees clockwise from north (with `pitch`, instead of `look_at`).
    pub yaw: Option<f64>,
    /// Degrees above the horizon.
    pub pitch: Option<f64>,
    /// Vertical field of view in degrees (default 60).
    #[serde(default = "default_fov")]
    pub fov: f64,
    /// Near plane distance in metres (default 1).
    #[serde(default = "default_near")]
    pub near: f64,
    /// Far plane distance in metres (default 100 km).
    #[serde(default = "default_far")]
    pub far: f64,
}

fn default_fov() -> f64 {
    60.0
}
fn default_near() -> f64 {
    1.0
}
fn default_far() -> f64 {
    100_000.0
}

/// The scene's `[image]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ImageSpec {
    /// Width in pixels, 1..=16384.
    pub width: u32,
    /// Height in pixels, 1..=16384.
    pub height: u32,
    /// Clear colour, linear RGB in 0..=1.
    #[serde(default = "default_background")]
    pub background: [f32; 3],
}

fn default_background() -> [f32; 3] {
    [0.55, 0.7, 0.9]
}

/// Without an `[image]` table: 960 × 540, the default scene's size.
impl Default for ImageSpec {
    fn default() -> Self {
        ImageSpec {
            width: 960,
            height: 540,
            background: default_background(),
        }
    }
}

/// Without a `[camera]` table: a placeholder that validates, which
/// [`Scene::parse`] replaces by framing the map ([`frame_terrain`]).
impl Default for CameraSpec {
    fn default() -> Self {
        CameraSpec {
            position: [0.0, -1.0, 1.0],
            look_at: Some([0.0, 0.0, 0.0]),
            yaw: None,
            pitch: None,
            fov: default_fov(),
            near: default_near(),
            far: default_far(),
        }
    }
}

/// A parsed, validated scene.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// `[terrain]`.
    pub terrain: Terrain,
    /// `[pyramid]`.
    #[serde(default = "default_pyramid")]
    pub pyramid: PyramidSpec,
    /// `[lod]` (default: the clipmap, n = 63).
    #[serde(default)]
    pub lod: Lod,
    /// `[camera]` (default: the map framed from the south, as
    /// `render --heightmap` frames it).
    #[serde(default)]
    pub camera: CameraSpec,
    /// `[image]` (default: 960 × 540).
    #[serde(default)]
    pub image: ImageSpec,
    /// The effects to simulate; anything not listed is not computed.
    /// Without the key, `lambert`, `fog` and `morph` (the morph closes the
    /// seams between clipmap levels); `effects = []` asks for none.
    #[serde(default = "default_effects")]
    pub effects: Vec<Effect>,
    /// `[shading]`: sun, fog and material constants.
    #[serde(default)]
    pub shading: ShadeParams,
    /// `[gpu]`: how the wgpu back end updates the clipmap.
    #[serde(default)]
    pub gpu: GpuSpec,
    /// Folder that relative paths are resolved against.
    #[serde(skip)]
    pub base_dir: PathBuf,
    /// Where the scene came from, for error messages.
    #[serde(skip)]
    pub origin: String,
}

crate::names::named! {
    /// Who fills the GPU's toroids: `[gpu] update`.
    pub enum GpuUpdate ("GPU update") {
        /// The CPU's finished texels, uploaded (the reference).
        Cpu => "cpu",
        /// A compute pass on the GPU for synthesised levels (GPU Gems 2
        /// ch. 2); the map's own levels are uploaded as with `cpu`.
        Gpu => "gpu",
    }
}

/// The scene's `[gpu]`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GpuSpec {
    /// `cpu` (default) or `gpu`.
    #[serde(default = "default_update")]
    pub update: GpuUpdate,
}

fn default_update() -> GpuUpdate {
    GpuUpdate::Cpu
}

impl Default for GpuSpec {
    fn default() -> Self {
        GpuSpec {
            update: GpuUpdate::Cpu,
        }
    }
}

fn default_effects() -> Vec<Effect> {
    vec![Effect::Lambert, Effect::Fog, Effect::Morph]
}

fn default_pyramid() -> PyramidSpec {
    PyramidSpec {
        filter: Filter::default(),
        lazy: false,
        budget: DEFAULT_LAZY_BUDGET,
    }
}

/// The scene files (`*.toml`) of a folder, sorted: a golden set, or any
/// folder of scenes a sweep runs.
pub fn files_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    v.sort();
    if v.is_empty() {
        return Err(Error::file(dir, "no golden scenes (*.toml) found"));
    }
    Ok(v)
}

impl Scene {
    /// Parses scene text; `origin` names the source in errors.
    /// A scene without a `[camera]` gets its map framed, which reads the
    /// map's size and relief (a pack's header, or the whole file). Without
    /// a `fog_density`, the fog follows the far plane
    /// ([`Scene::fog_from_far`]).
    pub fn parse(text: &str, origin: &str, base_dir: &Path) -> Result<Self> {
        Self::parse_framing(text, origin, base_dir, true)
    }

    /// [`Scene::parse`], but a scene without a `[camera]` is left unframed
    /// (its camera the default) for a caller that replaces the terrain and
    /// frames the new one: framing reads the whole map, which for a large
    /// raw file is most of the time a render takes.
    pub fn parse_unframed(text: &str, origin: &str, base_dir: &Path) -> Result<Self> {
        Self::parse_framing(text, origin, base_dir, false)
    }

    fn parse_framing(text: &str, origin: &str, base_dir: &Path, frame: bool) -> Result<Self> {
        let invalid = |e: toml::de::Error| {
            Error::file(origin, format!("invalid scene: {}", e.to_string().trim()))
        };
        // Parsed twice: as a table, to see which keys the text gives (serde's
        // defaults cannot tell), and as the schema, whose errors carry the
        // line and column, which a table's values have lost.
        let table: toml::Table = toml::from_str(text).map_err(invalid)?;
        let mut s: Scene = toml::from_str(text).map_err(invalid)?;
        s.base_dir = base_dir.to_path_buf();
        s.origin = origin.to_string();
        s.validate()?;
        if frame && !table.contains_key("camera") {
            frame_terrain(&mut s)?;
        }
        let fog_given = table
            .get("shading")
            .and_then(|t| t.get("fog_density"))
            .is_some();
        if !fog_given {
            s.fog_from_far();
        }
        Ok(s)
    }

    /// Sets the fog density the far plane implies, 0.4 / far: 67 % of a
    /// colour is left at the far plane, and 82 % at a framed map's far
    /// edge (the framing puts the far plane at twice that distance). What
    /// a scene without a `fog_density` gets, and a map framed on the command
    /// line, whose scene's fog was set for another terrain.
    pub fn fog_from_far(&mut self) {
        self.shading.fog_density = crate::shade::fog::density_for_far(self.camera.far);
    }

    /// Reads a scene file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_framing(path, true)
    }

    /// [`Scene::load`] with [`Scene::parse_unframed`].
    pub fn load_unframed(path: &Path) -> Result<Self> {
        Self::load_framing(path, false)
    }

    fn load_framing(path: &Path, frame: bool) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        Self::parse_framing(&text, &path.display().to_string(), &dir, frame)
    }

    /// The embedded default scene.
    pub fn default_scene() -> Self {
        Self::parse(DEFAULT_SCENE, "<default scene>", Path::new("."))
            .expect("the embedded default scene is valid")
    }

    /// The benchmark's scene ([`BENCH_SCENE`]).
    pub fn bench_scene() -> Self {
        Self::parse(BENCH_SCENE, "benches/scenes/bench.toml", Path::new("."))
            .expect("the benchmark's scene is valid")
    }

    fn bad(&self, field: &str, reason: impl Into<String>) -> Error {
        Error::value(format!("{}: {field}", self.origin), reason)
    }

    /// Checks every value that serde's types cannot.
    pub fn validate(&self) -> Result<()> {
        match (&self.terrain.file, &self.terrain.procedural) {
            (Some(_), Some(_)) | (None, None) => {
                return Err(self.bad("terrain", "give exactly one of 'file' or 'procedural'"))
            }
            _ => {}
        }
        if !(self.terrain.vertical_scale.is_finite() && self.terrain.vertical_scale > 0.0) {
            return Err(self.bad("terrain.vertical_scale", "must be finite and > 0"));
        }
        // Beyond 10^12 m an f64 resolves only 0.1 mm: refuse rather than
        // round silently.
        let placeable = |v: &f64| v.is_finite() && v.abs() <= MAX_COORDINATE;
        if !self.terrain.origin.iter().all(placeable) {
            return Err(self.bad(
                "terrain.origin",
                format!("must be finite and within ±{MAX_COORDINATE:e} m"),
            ));
        }
        if let Some(c) = &self.terrain.crs {
            crate::terrain::crs::parse(c).map_err(|r| self.bad("terrain.crs", r))?;
        }
        if let Some(c) = &self.terrain.cell_size {
            let [x, y] = c.pair();
            if !(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0) {
                return Err(self.bad("terrain.cell_size", "must be finite and > 0"));
            }
        }
        if let Some(spec) = &self.terrain.synthesis {
            crate::synthesis::source::validate(spec).map_err(|(k, r)| self.bad(k, r))?;
            if self.pyramid.lazy {
                return Err(self.bad(
                    "terrain.synthesis",
                    "a lazy pyramid filters its coarser levels from tiles of the finest as frames need them, and synthesis makes finer levels from the coarser ones: they cannot both apply; remove pyramid.lazy",
                ));
            }
        }
        crate::clipmap::region::check_n(self.lod.n).map_err(|r| self.bad("lod.n", r))?;
        LodConfig::from_spec(&self.lod, self.has(Effect::Morph)).map_err(|e| self.named(e))?;
        let c = &self.camera;
        match (c.look_at, c.yaw, c.pitch) {
            (Some(t), None, None) => {
                if !t.iter().all(|v| v.is_finite()) {
                    return Err(self.bad("camera.look_at", "must be finite"));
                }
                if c.position == t {
                    return Err(self.bad("camera.look_at", "must differ from position"));
                }
            }
            (None, Some(y), Some(p)) => {
                if !(y.is_finite() && (-90.0..=90.0).contains(&p)) {
                    return Err(self.bad("camera", "need a finite yaw and -90 <= pitch <= 90"));
                }
            }
            _ => return Err(self.bad("camera", "give either 'look_at' or both 'yaw' and 'pitch'")),
        }
        if !c.position.iter().all(placeable) {
            return Err(self.bad(
                "camera.position",
                format!("must be finite and within ±{MAX_COORDINATE:e} m"),
            ));
        }
        if !(c.fov > 0.0 && c.fov < 180.0) {
            return Err(self.bad("camera.fov", format!("must be in (0, 180), got {}", c.fov)));
        }
        if !(c.near > 0.0 && c.far > c.near && c.far.is_finite()) {
            return Err(self.bad("camera", "need 0 < near < far < inf"));
        }
        let i = &self.image;
        if i.width == 0 || i.height == 0 || i.width > MAX_IMAGE_SIDE || i.height > MAX_IMAGE_SIDE {
            return Err(self.bad(
                "image",
                format!(
                    "size {}×{} must be within 1..={MAX_IMAGE_SIDE} per side",
                    i.width, i.height
                ),
            ));
        }
        let effects = Effects::from_list(&self.effects).map_err(|r| self.bad("effects", r))?;
        self.shading
            .validate()
            .map_err(|(field, reason)| self.bad(field, reason))?;
        if self.pyramid.lazy {
            self.check_lazy(&effects)?;
        }
        Ok(())
    }

    /// What a lazy pyramid cannot serve: schemes other than the clipmap
    /// read the whole map each frame, `shadows` and `normal-map` trace or
    /// filter the whole base level, and the height-ramp colours need the
    /// whole map's range unless the scene gives one.
    fn check_lazy(&self, e: &Effects) -> Result<()> {
        if self.lod.scheme != LodScheme::Clipmap {
            return Err(self.bad(
                "pyramid.lazy",
                format!(
                    "only the clipmap builds its pyramid lazily, not '{}'",
                    self.lod.scheme
                ),
            ));
        }
        if self.pyramid.budget == 0 {
            return Err(self.bad("pyramid.budget", "must be at least 1 sample"));
        }
        for (on, name) in [
            (e.shadows, Effect::Shadows),
            (e.normal_map, Effect::NormalMap),
        ] {
            if on {
                return Err(self.bad(
                    "pyramid.lazy",
                    format!(
                        "effect '{name}' reads the whole map, which a lazy pyramid has not built"
                    ),
                ));
            }
        }
        if !e.level_tint && self.shading.height_range.is_none() {
            return Err(self.bad(
                "shading.height_range",
                "a lazy pyramid cannot know the whole map's height range for the colour ramp: give [low, high] in metres",
            ));
        }
        Ok(())
    }

    /// The point the camera looks at (from look_at, or yaw and pitch).
    pub fn target(&self) -> DVec3 {
        let eye = DVec3::from_array(self.camera.position);
        match (self.camera.look_at, self.camera.yaw, self.camera.pitch) {
            (Some(t), _, _) => DVec3::from_array(t),
            (_, Some(y), Some(p)) => {
                let (y, p) = (y.to_radians(), p.to_radians());
                eye + DVec3::new(p.cos() * y.sin(), p.cos() * y.cos(), p.sin())
            }
            _ => eye - DVec3::Z,
        }
    }

    /// The camera the scene describes, its aspect from the image size.
    pub fn camera(&self) -> Camera {
        Camera {
            eye: DVec3::from_array(self.camera.position),
            target: self.target(),
            fov_y_deg: self.camera.fov,
            near: self.camera.near,
            far: self.camera.far,
            aspect: self.image.width as f64 / self.image.height as f64,
        }
    }

    /// Whether the scene lists effect `e`.
    pub fn has(&self, e: Effect) -> bool {
        self.effects.contains(&e)
    }

    /// `e` with this scene's name before the field it names: the stages
    /// report `lod.tau`, the user reads `golden/x.toml: lod.tau`.
    pub fn named(&self, e: Error) -> Error {
        match e {
            Error::BadValue { field, reason } => self.bad(&field, reason),
            other => other,
        }
    }
}

impl Scene {
    /// This scene with another LOD scheme: "NAME", or for the clipmap
    /// "clipmap/PART[/PART]" with a layout (strips, footprints) and where
    /// its levels nest (eye, view), as `cracks --lod` spells them.
    pub fn with_lod(&self, spec: &str) -> Result<Scene> {
        let mut parts = spec.split('/');
        let scheme = parts
            .next()
            .unwrap_or_default()
            .parse()
            .map_err(|r: String| self.bad("lod.scheme", r))?;
        let mut layout = None;
        let mut centre = None;
        for p in parts {
            match p {
                "eye" | "view" => centre = Some(p.to_string()),
                l => layout = Some(l.parse().map_err(|r: String| self.bad("lod.layout", r))?),
            }
        }
        let mut s = self.clone();
        if centre.is_some() {
            s.lod.centre = centre;
        }
        s.with_scheme(scheme, layout)
    }

    /// This scene with scheme `scheme` (and, if given, the clipmap layout
    /// `layout`), validated.
    pub fn with_scheme(&self, scheme: LodScheme, layout: Option<Layout>) -> Result<Scene> {
        let mut s = self.clone();
        s.lod.scheme = scheme;
        if let Some(l) = layout {
            s.lod.layout = l;
        }
        s.validate()?;
        Ok(s)
    }
}

/// Command-line replacements for scene values (`render` and friends).
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    /// `--heightmap`: replaces the terrain with this file.
    pub heightmap: Option<PathBuf>,
    /// `--camera`: the eye position.
    pub camera: Option<[f64; 3]>,
    /// `--look-at`: the point looked at.
    pub look_at: Option<[f64; 3]>,
    /// `--fov`: vertical field of view in degrees.
    pub fov: Option<f64>,
    /// `--size`: image width and height.
    pub size: Option<[u32; 2]>,
    /// `--lod`: the LOD scheme.
    pub lod: Option<LodScheme>,
    /// `--effects`: the effect list.
    pub effects: Option<Vec<Effect>>,
    /// `--crs`: the CRS of a map whose file names none (`terrain.crs`).
    pub crs: Option<String>,
    /// `--variable`: the netCDF variable that holds the map
    /// (`terrain.variable`).
    pub variable: Option<String>,
}

impl Overrides {
    /// Parses "X,Y,Z".
    pub fn parse_xyz(s: &str) -> std::result::Result<[f64; 3], String> {
        let v: Vec<f64> = s
            .split(',')
            .map(|p| p.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|e| format!("'{s}': {e}"))?;
        match v[..] {
            [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
            _ => Err(format!("'{s}': need three finite numbers X,Y,Z")),
        }
    }
    /// Parses "WxH".
    pub fn parse_size(s: &str) -> std::result::Result<[u32; 2], String> {
        let (w, h) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| format!("'{s}': need WIDTHxHEIGHT"))?;
        let p = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("'{s}': {e}"));
        Ok([p(w)?, p(h)?])
    }
}

impl Scene {
    /// Applies command-line overrides and validates the result again.
    pub fn apply(&mut self, o: &Overrides) -> Result<()> {
        if let Some(h) = &o.heightmap {
            let abs = std::env::current_dir()
                .map(|d| d.join(h))
                .unwrap_or_else(|_| h.clone());
            self.terrain.file = Some(abs);
            self.terrain.procedural = None;
            self.terrain.cell_size = None;
            self.terrain.crs = None;
            self.terrain.variable = None;
        }
        if let Some(c) = &o.crs {
            self.terrain.crs = Some(c.clone());
        }
        if let Some(v) = &o.variable {
            self.terrain.variable = Some(v.clone());
        }
        if let Some(p) = o.camera {
            self.camera.position = p;
        }
        if let Some(t) = o.look_at {
            self.camera.look_at = Some(t);
            self.camera.yaw = None;
            self.camera.pitch = None;
        }
        if let Some(f) = o.fov {
            self.camera.fov = f;
        }
        if let Some([w, h]) = o.size {
            self.image.width = w;
            self.image.height = h;
        }
        if let Some(l) = o.lod {
            self.lod.scheme = l;
        }
        if let Some(e) = &o.effects {
            self.effects = e.clone();
        }
        self.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_known_ones() {
        for e in Effect::ALL {
            assert_eq!(e.name().parse::<Effect>(), Ok(*e));
        }
        for s in LodScheme::ALL {
            assert_eq!(s.to_string().parse::<LodScheme>(), Ok(*s));
        }
        assert_eq!(Effect::ALL.len(), 8);
        assert_eq!(LodScheme::ALL.len(), 7);
        let e = "bloom".parse::<Effect>().unwrap_err();
        assert_eq!(
            e,
            "unknown effect 'bloom' (known: lambert, phong, fog, shadows, normal-map, \
             level-tint, wireframe, morph)"
        );
        assert!("Clipmap".parse::<LodScheme>().is_err(), "names are exact");
    }

    #[test]
    fn default_scene_parses() {
        let s = Scene::default_scene();
        assert_eq!(s.lod.n, 127);
        assert!(s.has(Effect::Shadows));
        assert_eq!(Scene::bench_scene().lod.n, 63);
    }

    /// A scene of only `[terrain]` is the clipmap at 960 × 540 with
    /// lambert, fog and morph, its camera framing the map from the south
    /// (looking at the map's centre, from outside it) and fog scaled to
    /// it; a density the scene gives is kept.
    #[test]
    fn a_terrain_only_scene_is_framed() {
        let only =
            "[terrain]\nprocedural = { seed = 3, width = 129, height = 65 }\ncell_size = 10.0\n";
        let s = Scene::parse(only, "only.toml", Path::new(".")).unwrap();
        assert_eq!(s.lod, Lod::default());
        assert_eq!((s.image.width, s.image.height), (960, 540));
        assert_eq!(s.effects, default_effects());
        let [x, y, z] = s.camera.look_at.unwrap();
        assert_eq!([x, y], [640.0, -320.0], "the map's centre");
        let eye = s.camera.position;
        assert!(
            eye[1] < -640.0 && eye[2] > z,
            "south of the map, above it: {eye:?}"
        );
        assert!(s.camera.far > 1280.0, "{}", s.camera.far);
        let framed_fog = s.shading.fog_density;
        assert_ne!(framed_fog, ShadeParams::default().fog_density);
        let kept = format!("{only}[shading]\nfog_density = 0.25\n");
        let s = Scene::parse(&kept, "kept.toml", Path::new(".")).unwrap();
        assert_eq!(s.shading.fog_density, 0.25);
        let none = format!("effects = []\n{only}");
        assert!(Scene::parse(&none, "n.toml", Path::new("."))
            .unwrap()
            .effects
            .is_empty());
    }

    #[test]
    fn unknown_key_reports_line_and_column() {
        let text = BENCH_SCENE.replace("fov = 60.0", "fov = 60.0\nzoom = 2");
        let e = Scene::parse(&text, "x.toml", Path::new("."))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.toml"), "{e}");
        assert!(e.contains("line"), "{e}");
        assert!(e.contains("zoom"), "{e}");
    }

    #[test]
    fn bad_n_and_unknown_effect_are_errors() {
        let t = BENCH_SCENE.replace("n = 63", "n = 64");
        assert!(Scene::parse(&t, "s", Path::new("."))
            .unwrap_err()
            .to_string()
            .contains("2^k"));
        let t = BENCH_SCENE.replace("\"fog\"", "\"bloom\"");
        assert!(Scene::parse(&t, "s", Path::new("."))
            .unwrap_err()
            .to_string()
            .contains("bloom"));
    }
}
