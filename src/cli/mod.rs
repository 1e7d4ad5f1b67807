//! The commands, one file each: their arguments (clap) and their printing.
//! The work itself is the library's; a command only parses, calls and
//! prints.

#[cfg(feature = "gpu")]
pub mod bench;
#[cfg(feature = "gpu")]
pub mod check_gpu;
pub mod cracks;
pub mod diagram;
pub mod fly;
pub mod golden;
pub mod height;
pub mod info;
pub mod render;
pub mod scaling;
pub mod tradeoff;

use std::path::PathBuf;
use terraclip::scene::{Overrides, Scene};

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
    /// LOD scheme (clipmap, brute-force, geomipmap, roam, annulus, cdlod).
    #[arg(long)]
    pub lod: Option<String>,
    /// Comma-separated effects (empty for none).
    #[arg(long)]
    pub effects: Option<String>,
}

impl SceneArgs {
    pub fn overrides(&self) -> Overrides {
        Overrides {
            heightmap: self.heightmap.clone(),
            camera: self.camera,
            look_at: self.look_at,
            fov: self.fov,
            size: self.size,
            lod: self.lod.clone(),
            effects: self.effects.as_ref().map(|e| {
                e.split(',')
                    .map(|s| s.trim().to_string())
                    .filter(|s| !s.is_empty())
                    .collect()
            }),
        }
    }

    /// The scene at `path` (the embedded one if none) with these overrides.
    pub fn scene(&self, path: &Option<PathBuf>) -> anyhow::Result<Scene> {
        let mut s = load_scene(path)?;
        s.apply(&self.overrides())?;
        Ok(s)
    }
}

/// The scene at `path`, or the embedded default scene.
pub fn load_scene(path: &Option<PathBuf>) -> terraclip::Result<Scene> {
    match path {
        Some(p) => Scene::load(p),
        None => Ok(Scene::default_scene()),
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
