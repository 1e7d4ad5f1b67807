//! `terraclip check-gpu`: both back ends on the same scenes, compared pixel
//! for pixel.

use serde_json::json;
use std::path::{Path, PathBuf};
use terraclip::gpu::Api;
use terraclip::scene::Scene;
use terraclip::studies::shard::{self, Shard};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene files; the golden scenes if none.
    pub scenes: Vec<PathBuf>,
    /// wgpu backend: vulkan or gl.
    #[arg(long, value_enum, default_value_t = Api::Vulkan, hide_possible_values = true)]
    pub api: Api,
    /// Where the -cpu, -gpu and -diff PNGs go.
    #[arg(long, default_value = "target/check-gpu")]
    pub out: PathBuf,
    /// Frames along a camera path (1 = the scene's view only).
    #[arg(long, default_value_t = 1)]
    pub frames: usize,
    /// Camera step per frame along the path, metres.
    #[arg(long, default_value_t = 37.0)]
    pub step: f64,
    /// Who fills the GPU's toroids, for every scene (`[gpu] update`):
    /// cpu uploads the CPU's texels, gpu makes synthesised levels' on the
    /// GPU and compares every level's texels after each update.
    #[arg(long, value_enum, hide_possible_values = true)]
    pub update: Option<terraclip::scene::GpuUpdate>,
    /// Check part i of N of the scenes (`merge` joins the parts' JSON).
    #[arg(long, value_parser = Shard::parse, default_value = "0/1", allow_hyphen_values = true)]
    pub shard: Shard,
    #[arg(long)]
    pub json: bool,
}

/// Scene paths given on the command line, or the goldens' scenes.
fn scene_list(scenes: &[PathBuf]) -> anyhow::Result<Vec<(String, Scene)>> {
    let paths = if scenes.is_empty() {
        terraclip::check::golden::scenes(Path::new("golden"))?
    } else {
        scenes.to_vec()
    };
    paths
        .iter()
        .map(|p| {
            let name = p
                .file_stem()
                .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
            Ok((name, Scene::load(p)?))
        })
        .collect()
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    use terraclip::check::parity;
    use terraclip::gpu::{Gpu, GpuRenderer};
    let list = scene_list(&a.scenes)?;
    let gpu = Gpu::new(a.api)?;
    let exact = gpu.exact_expected();
    let (adapter, driver) = (gpu.adapter(), gpu.info.driver_info.clone());
    let mut r = GpuRenderer::new(gpu);
    let mut results = vec![];
    let mine = list.iter().enumerate().filter(|(k, _)| a.shard.owns(*k));
    for (_, (name, scene)) in mine {
        let mut scene = scene.clone();
        if let Some(u) = a.update {
            scene.gpu.update = u;
        }
        let res = parity::check(&mut r, &scene, name, a.frames, a.step, &a.out, exact)?;
        if !a.json {
            println!(
                "{:<6} {:<22} {:>3} frame(s)  colour {} px  depth {} px  max channel {}  max depth {} ulp  shifted {} px  unmatched {} px",
                if res.pass { "ok" } else { "FAIL" },
                res.scene,
                res.frames,
                res.diff.colour_px_differ,
                res.diff.depth_px_differ,
                res.diff.max_channel_diff,
                res.diff.max_depth_ulp,
                res.diff.shifted_px,
                res.diff.unmatched_px
            );
        }
        results.push(res);
    }
    let mode = if exact { "exact" } else { "tolerance" };
    if a.json {
        let v = json!({"adapter": adapter, "driver_info": driver, "exact_expected": exact,
                       "mode": mode, "scenes": results});
        let names: Vec<&str> = list.iter().map(|(n, _)| n.as_str()).collect();
        let of = format!(
            "{} --frames {} --step {} --update {:?} --api {}",
            names.join(","),
            a.frames,
            a.step,
            a.update.map(|u| u.name()),
            a.api.name()
        );
        println!("{}", shard::tag(v, "check-gpu", a.shard, &of));
    } else {
        println!(
            "adapter {adapter}, driver {driver}: {mode} mode; images in {}",
            a.out.display()
        );
    }
    let failed = results.iter().filter(|r| !r.pass).count();
    if failed > 0 {
        anyhow::bail!("{failed} scene(s) differ between the CPU and GPU back ends ({mode} mode)");
    }
    Ok(())
}
