//! `terraclip fly`: a straight flight, its frames and update statistics.

use super::{progress, SceneArgs};
use std::path::PathBuf;
use terraclip::error::write_atomic;
use terraclip::frame::stats::Rusage;
use terraclip::studies::fly;
use terraclip::studies::shard::{self, Shard};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file; the benchmark's scene (benches/scenes/bench.toml) if omitted.
    pub scene: Option<PathBuf>,
    #[arg(long, default_value_t = 60)]
    pub frames: usize,
    /// Metres per frame (forward, plus 0.37× sideways).
    #[arg(long, default_value_t = 5.0)]
    pub step: f64,
    /// Frames held at the path's last camera after it (a budget-limited
    /// update catches up there).
    #[arg(long, default_value_t = 0)]
    pub still: usize,
    /// Where frame_NNNN.png go; no images if omitted.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also write OUT/fly.gif.
    #[arg(long)]
    pub gif: bool,
    /// Skip the brute-force renders popping needs.
    #[arg(long)]
    pub no_popping: bool,
    #[command(flatten)]
    pub args: SceneArgs,
    /// Fly part i of N of the frames, a run of them in order (`merge
    /// --dir` joins the parts' JSON and draws the charts).
    #[arg(long, value_parser = Shard::parse, default_value = "0/1", allow_hyphen_values = true)]
    pub shard: Shard,
    /// Also draw every frame with the wgpu back end (Vulkan) and report
    /// each frame's upload bytes, draw calls and GPU time.
    #[arg(long)]
    pub gpu: bool,
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let start = Rusage::now();
    if a.frames == 0 || a.frames > 100_000 {
        anyhow::bail!("--frames must be within 1..=100000, got {}", a.frames);
    }
    if a.still > 100_000 {
        anyhow::bail!("--still must be within 0..=100000, got {}", a.still);
    }
    if !a.step.is_finite() {
        anyhow::bail!("--step must be finite");
    }
    if a.gif && a.out.is_none() {
        anyhow::bail!("--gif needs --out DIR");
    }
    if a.gif && !a.shard.is_whole() {
        anyhow::bail!("--gif is of the whole flight: it does not take --shard (each part writes its frames' PNGs)");
    }
    let s = a
        .args
        .scene(&a.scene, terraclip::scene::Scene::bench_scene)?;
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).map_err(|e| terraclip::Error::io(dir, e))?;
    }
    let bar = progress(a.shard.run_of(a.frames + a.still).len(), "fly");
    let mut kept = Vec::new();
    let flight = (a.frames, a.still);
    let popping = !a.no_popping;
    let report = fly::fly_with(&s, flight, a.step, popping, a.shard, a.gpu, |i, img| {
        bar.inc(1);
        if let Some(dir) = &a.out {
            write_atomic(&dir.join(format!("frame_{i:04}.png")), &img.png()?)?;
            if a.gif {
                kept.push(img.clone());
            }
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    if let (Some(dir), true) = (&a.out, a.gif) {
        write_atomic(&dir.join("fly.gif"), &fly::gif(&kept)?)?;
    }
    // A part's charts would show only its frames: the merge draws them.
    if let (Some(dir), true) = (&a.out, a.shard.is_whole()) {
        fly::write_charts(&report, dir)?;
    }
    if a.json {
        let of = format!(
            "{} --frames {} --still {} --step {} --no-popping {} --gpu {}",
            a.args.describe(&a.scene),
            a.frames,
            a.still,
            a.step,
            a.no_popping,
            a.gpu
        );
        let mut v = shard::tag(serde_json::to_value(&report)?, "fly", a.shard, &of);
        v["rusage"] = serde_json::to_value(Rusage::since(&start))?;
        println!("{v}");
    } else {
        println!(
            "{} frames of {}: mean update {:.3} ms, {} texels rewritten, popping max {:.3}",
            report.frames.len(),
            report.lod,
            report.mean_update_ms,
            report.texels_updated,
            report.popping_max
        );
        if let Some(u) = report.mean_upload_bytes {
            let ms: Vec<f64> = report
                .frames
                .iter()
                .filter(|f| f.frame > 0)
                .filter_map(|f| f.gpu.and_then(|g| g.ms))
                .collect();
            println!(
                "on the GPU: {u:.0} bytes uploaded a frame after the first, {}",
                match ms.len() {
                    0 => "no timestamp queries".to_string(),
                    n => format!(
                        "{:.3} ms a frame on its clock",
                        ms.iter().sum::<f64>() / n as f64
                    ),
                }
            );
        }
        if let Some(b) = &report.update_budget {
            println!(
                "decoding feeds {:.0} level-0 texels a frame in the whole frame, {:.1} in 10 % of it                  ({:.0} samples/ms, {:.0} samples a texel, {:.1} ms frames{})",
                b.texels_per_frame,
                b.texels_per_frame_at_10_percent,
                b.samples_per_ms,
                b.samples_per_texel,
                b.frame_ms,
                if b.every_level_drawn { "" } else { "; levels were dropped" }
            );
        }
    }
    Ok(())
}
