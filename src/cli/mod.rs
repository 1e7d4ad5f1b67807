//! The commands, one file each: their arguments (clap) and their printing.
//! The work itself is the library's; a command only parses, calls and
//! prints.

#[cfg(feature = "gpu")]
pub mod bench;
#[cfg(feature = "gpu")]
pub mod check_gpu;
pub mod compare;
pub mod cracks;
pub mod diagram;
pub mod export;
pub mod fly;
pub mod golden;
pub mod height;
pub mod info;
pub mod merge;
pub mod pack;
pub mod render;
pub mod scaling;
pub mod synthesis;
pub mod tradeoff;
pub mod unpack;

use std::path::PathBuf;
use terraclip::scene::{Effect, LodScheme, Overrides, Scene};

/// Scene values the command line can replace.
#[derive(clap::Args, Debug, Default)]
pub struct SceneArgs {
    /// Heightmap file instead of the scene's terrain.
    #[arg(long)]
    pub heightmap: Option<PathBuf>,
    /// Camera position X,Y,Z (metres).
    #[arg(long, value_parser = Overrides::parse_xyz, allow_hyphen_values = true)]
    pub camera: Option<[f64; 3]>,
    /// Point to look at X,Y,Z (metres).
    #[arg(long, value_parser = Overrides::parse_xyz, allow_hyphen_values = true)]
    pub look_at: Option<[f64; 3]>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    pub fov: Option<f64>,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, value_parser = Overrides::parse_size)]
    pub size: Option<[u32; 2]>,
    /// LOD scheme (clipmap, brute-force, geomipmap, roam, annulus, cdlod, cbt).
    #[arg(long, value_enum, hide_possible_values = true)]
    pub lod: Option<LodScheme>,
    /// Comma-separated effects (empty for none).
    #[arg(long, value_parser = parse_effects)]
    pub effects: Option<EffectList>,
    /// The CRS of a map whose file names none, as EPSG:<code> (a
    /// geographic one converts its degrees to metres).
    #[arg(long)]
    pub crs: Option<String>,
    /// The variable of a netCDF file that holds the map, where its CF
    /// standard_names do not single one out.
    #[arg(long)]
    pub variable: Option<String>,
}

/// `--effects a,b,c`, empty for none.
#[derive(Clone, Debug)]
pub struct EffectList(pub Vec<Effect>);

fn parse_effects(s: &str) -> Result<EffectList, String> {
    s.split(',')
        .map(str::trim)
        .filter(|e| !e.is_empty())
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map(EffectList)
}

impl SceneArgs {
    pub fn overrides(&self) -> Overrides {
        Overrides {
            heightmap: self.heightmap.clone(),
            camera: self.camera,
            look_at: self.look_at,
            fov: self.fov,
            size: self.size,
            lod: self.lod,
            effects: self.effects.as_ref().map(|e| e.0.clone()),
            crs: self.crs.clone(),
            variable: self.variable.clone(),
        }
    }

    /// The scene at `path` and these overrides, in words: what every
    /// shard of one sweep must share (`shard.of`).
    pub fn describe(&self, path: &Option<PathBuf>) -> String {
        let scene = path
            .as_ref()
            .map_or("<default scene>".into(), |p| p.display().to_string());
        format!("{scene} {:?}", self.overrides())
    }

    /// The scene at `path` (else `embedded`: [`load_scene`]) with these
    /// overrides. A heightmap given without `--camera` or `--look-at` is
    /// framed: the scene's camera, far plane and fog were placed for its
    /// own terrain.
    pub fn scene(&self, path: &Option<PathBuf>, embedded: fn() -> Scene) -> anyhow::Result<Scene> {
        let reframe = self.heightmap.is_some() && self.camera.is_none() && self.look_at.is_none();
        // The scene's own map is not read when another replaces it.
        let mut s = match path {
            Some(p) if reframe => Scene::load_unframed(p)?,
            _ => load_scene(path, embedded)?,
        };
        s.apply(&self.overrides())?;
        warn_crs(&s.terrain, &s.base_dir);
        if reframe {
            terraclip::scene::frame_terrain(&mut s)?;
            s.fog_from_far();
        }
        Ok(s)
    }
}

/// Warns on stderr when a terrain's TIFF or netCDF grid names no CRS, none
/// is declared, and its numbers look like degrees (`terrain::crs`). Only
/// the tags or the header and coordinates are read; a file that cannot be
/// read is left to the command's own error.
pub fn warn_crs(spec: &terraclip::terrain::Spec, base_dir: &std::path::Path) {
    let Some(f) = spec.file.as_ref().filter(|_| spec.crs.is_none()) else {
        return;
    };
    let path = base_dir.join(f);
    let georeferenced = path.extension().is_some_and(|e| {
        ["tif", "tiff", "nc", "cdf"]
            .iter()
            .any(|x| e.eq_ignore_ascii_case(x))
    });
    if let Some(w) = georeferenced
        .then(|| terraclip::terrain::rows::open_var(&path, spec.variable.as_deref()).ok())
        .flatten()
        .and_then(|src| terraclip::terrain::rows::crs_warning(&*src, &path))
    {
        eprintln!("warning: {w}");
    }
}

/// Prints `value` as one JSON line with `--json`, else the sentence `text`
/// makes: every command reports this way.
pub fn report(json: bool, value: serde_json::Value, text: impl FnOnce() -> String) {
    if json {
        println!("{value}");
    } else {
        println!("{}", text());
    }
}

/// The scene at `path`, or without one the embedded scene `embedded`:
/// `Scene::default_scene` (the picture), or `Scene::bench_scene` for the
/// commands that measure (`bench`, `scaling`, `cracks`, `tradeoff`, `fly`),
/// so that their figures compare with the docs' whatever the default
/// picture shows.
pub fn load_scene(path: &Option<PathBuf>, embedded: fn() -> Scene) -> terraclip::Result<Scene> {
    match path {
        Some(p) => Scene::load(p),
        None => Ok(embedded()),
    }
}

/// A progress bar on stderr (drawn only when stderr is a terminal).
pub fn progress(len: usize, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len as u64);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta} left)")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_string());
    bar
}
