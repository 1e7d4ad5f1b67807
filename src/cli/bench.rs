//! `terraclip bench`: CPU and GPU frames per second, side by side.

use super::load_scene;
use std::path::PathBuf;
use terraclip::scene::Overrides;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file; the benchmark's scene (benches/scenes/bench.toml) if omitted.
    pub scene: Option<PathBuf>,
    /// Frames per timed repeat.
    #[arg(long, default_value_t = 10)]
    pub frames: usize,
    /// Repeats; the median is reported.
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, default_value = "1920x1080", value_parser = Overrides::parse_size)]
    pub size: [u32; 2],
    /// Time the update of the levels the GPU can make instead (synthesised
    /// ones, and an upsampled pack's): the CPU's update and upload against
    /// the GPU's update pass, for a jump (the first frame) and a walk of
    /// --frames frames of --step metres.
    #[arg(long)]
    pub update: bool,
    /// Metres a frame, with --update.
    #[arg(long, default_value_t = 37.0)]
    pub step: f64,
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    use terraclip::check::parity;
    use terraclip::gpu::{Api, Gpu, GpuRenderer};
    if a.frames == 0 || a.repeats == 0 {
        anyhow::bail!("--frames and --repeats must be at least 1");
    }
    let mut s = load_scene(&a.scene, terraclip::scene::Scene::bench_scene)?;
    s.apply(&Overrides {
        size: Some(a.size),
        ..Default::default()
    })?;
    let mut r = GpuRenderer::new(Gpu::new(Api::Vulkan)?);
    if a.update {
        let b = parity::update_bench(&mut r, &s, a.frames, a.step)?;
        if a.json {
            println!("{}", serde_json::to_value(&b)?);
        } else {
            for (what, t) in [("jump", &b.jump), ("walk", &b.walk)] {
                println!(
                    "{what}: {} texels of {} levels made on the GPU (n = {}): CPU update {:.3} ms + upload {:.3} ms, GPU pass {:.3} ms ({})",
                    t.texels, b.levels, b.n, t.cpu_update_ms, t.upload_ms, t.gpu_pass_ms, b.adapter
                );
            }
        }
        return Ok(());
    }
    let b = parity::bench(&mut r, &s, a.frames, a.repeats)?;
    if a.json {
        println!("{}", serde_json::to_value(&b)?);
    } else {
        println!(
            "{}×{}, {} triangles, median of {} × {} frames: CPU {:.2} fps, GPU ({}) {:.2} fps, ratio {:.2}",
            b.size[0], b.size[1], b.triangles, b.repeats, b.frames, b.cpu_fps, b.adapter, b.gpu_fps, b.ratio
        );
    }
    Ok(())
}
