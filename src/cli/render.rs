//! `terraclip render`: one scene to a PNG, with its statistics.

use super::SceneArgs;
use serde_json::json;
use std::path::PathBuf;
use terraclip::frame::stats::Rusage;
use terraclip::render::{self, Backend, RenderOptions};
use terraclip::scene::Scene;

#[derive(clap::Args, Debug)]
pub struct Args {
    pub scene: Option<PathBuf>,
    #[arg(short, long, default_value = "terraclip.png")]
    pub out: PathBuf,
    /// Back end: cpu (the reference) or gpu.
    #[arg(long, value_enum, default_value_t = Backend::Cpu, hide_possible_values = true)]
    pub backend: Backend,
    #[command(flatten)]
    pub args: SceneArgs,
    #[arg(long)]
    pub json: bool,
}

impl Args {
    /// The main job, `terraclip` with no command: the embedded scene on the
    /// CPU to `terraclip.png`.
    pub fn main_job() -> Args {
        Args {
            scene: None,
            out: "terraclip.png".into(),
            backend: Backend::Cpu,
            args: SceneArgs::default(),
            json: false,
        }
    }
}

/// Renders the scene to `out` and prints its statistics.
pub fn run(a: &Args) -> anyhow::Result<()> {
    let start = Rusage::now();
    let s = a.args.scene(&a.scene, Scene::default_scene)?;
    let (image, stats) = match a.backend {
        Backend::Cpu => render::render(&s, &RenderOptions::default())?,
        Backend::Gpu => gpu_render(&s)?,
    };
    terraclip::error::write_atomic(&a.out, &image.png()?)?;
    let mut v = serde_json::to_value(&stats)?;
    v["output"] = json!(a.out);
    v["rusage"] = serde_json::to_value(Rusage::since(&start))?;
    if a.json {
        println!("{v}");
        return Ok(());
    }
    println!(
        "wrote {} ({}×{}, {} {} triangles, {:.1} ms)",
        a.out.display(),
        stats.width,
        stats.height,
        stats.triangles,
        stats.lod,
        stats.ms_total
    );
    for p in &stats.passes {
        println!("  {:<11} {:>9.2} ms", p.name, p.ms);
    }
    if stats.non_finite_vertices > 0 {
        println!(
            "  {} non-finite vertices dropped",
            stats.non_finite_vertices
        );
    }
    Ok(())
}

#[cfg(feature = "gpu")]
fn gpu_render(s: &Scene) -> anyhow::Result<(render::Image, render::RenderStats)> {
    use terraclip::gpu::{Api, Gpu, GpuRenderer};
    let mut r = GpuRenderer::new(Gpu::new(Api::Vulkan)?);
    Ok(terraclip::render::gpu::render(&mut r, s)?)
}

#[cfg(not(feature = "gpu"))]
fn gpu_render(_: &Scene) -> anyhow::Result<(render::Image, render::RenderStats)> {
    anyhow::bail!("--backend gpu: this build has no wgpu back end (cargo feature 'gpu')")
}
