//! `terraclip diagram`: a top-down map of the clipmap's levels.

use super::load_scene;
use serde_json::json;
use std::path::PathBuf;
use terraclip::studies::diagram;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file; the embedded default scene if omitted.
    pub scene: Option<PathBuf>,
    #[arg(short, long, default_value = "diagram.png")]
    pub out: PathBuf,
    /// The map's side in pixels; the key adds a panel to its right.
    #[arg(long, default_value_t = 800)]
    pub size: u32,
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    if a.size == 0 || a.size > 16384 {
        anyhow::bail!("--size must be within 1..=16384, got {}", a.size);
    }
    let s = load_scene(&a.scene, terraclip::scene::Scene::default_scene)?;
    let session = diagram::session(&s)?;
    let cm = session
        .lod
        .clipmap()
        .ok_or_else(|| anyhow::anyhow!("the scene's LOD scheme has no clipmap"))?;
    let png = diagram::draw(cm, &session.world, Some(&s.camera()), a.size)?;
    terraclip::error::write_atomic(&a.out, &png)?;
    let active = cm.levels().iter().filter(|l| l.is_active()).count();
    if a.json {
        println!(
            "{}",
            json!({"output": a.out, "levels": cm.levels().len(), "active_levels": active, "n": cm.n()})
        );
    } else {
        println!(
            "wrote {} ({} levels, {active} active, n = {})",
            a.out.display(),
            cm.levels().len(),
            cm.n()
        );
    }
    Ok(())
}
