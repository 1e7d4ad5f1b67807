//! `terraclip export`: a scene's frame (or a path of frames) as files
//! another renderer can draw and be compared with (`compare`).

use super::SceneArgs;
use serde_json::json;
use std::path::PathBuf;
use terraclip::studies::shard::{self, Shard};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The scene (the embedded default scene if none).
    pub scene: Option<PathBuf>,
    /// The export folder; an earlier export there is replaced, anything
    /// else there is refused.
    #[arg(long)]
    pub out: PathBuf,
    /// Frames along the camera path `check-gpu` flies (1 = the scene's view).
    #[arg(long, default_value_t = 1)]
    pub frames: usize,
    /// Camera step per frame along the path, metres.
    #[arg(long, default_value_t = 37.0)]
    pub step: f64,
    #[command(flatten)]
    pub args: SceneArgs,
    /// Export part i of N of the frames, a run of them in order, as
    /// frame folders (`merge --dir` joins the parts' folders).
    #[arg(long, value_parser = Shard::parse, default_value = "0/1", allow_hyphen_values = true)]
    pub shard: Shard,
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let scene = a
        .args
        .scene(&a.scene, terraclip::scene::Scene::default_scene)?;
    let (name, text) = match &a.scene {
        Some(p) => (
            p.file_stem()
                .map_or("scene".into(), |s| s.to_string_lossy().into_owned()),
            std::fs::read_to_string(p).ok(),
        ),
        None => (
            "default".to_string(),
            Some(terraclip::scene::DEFAULT_SCENE.to_string()),
        ),
    };
    if !a.step.is_finite() {
        anyhow::bail!("--step: must be a finite number of metres, not {}", a.step);
    }
    let w = terraclip::export::scene_part(
        &scene,
        &name,
        text.as_deref(),
        a.frames,
        a.step,
        a.shard,
        &a.out,
    )?;
    let of = format!(
        "{} --frames {} --step {}",
        a.args.describe(&a.scene),
        a.frames,
        a.step
    );
    super::report(a.json, shard::tag(json!(w), "export", a.shard, &of), || {
        let tris: usize = w.frames.iter().map(|f| f.triangles).sum();
        format!(
            "wrote {} ({} frame(s) of {}, {} triangles, {} files, {} bytes)",
            w.dir.display(),
            w.frames.len(),
            w.scene,
            tris,
            w.files,
            w.bytes
        )
    });
    Ok(())
}
