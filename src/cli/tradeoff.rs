//! `terraclip tradeoff`: error against brute force and time, per scheme and
//! setting.

use super::{progress, SceneArgs};
use std::path::PathBuf;
use terraclip::frame::stats::Rusage;
use terraclip::studies::shard::{self, Shard};
use terraclip::studies::tradeoff;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file; the benchmark's scene (benches/scenes/bench.toml) if omitted.
    pub scene: Option<PathBuf>,
    #[arg(long, default_value = "target/tradeoff")]
    pub out: PathBuf,
    /// Scene overrides (--size defaults to 320x180 here).
    #[command(flatten)]
    pub args: SceneArgs,
    /// Frames along the popping path.
    #[arg(long, default_value_t = 8)]
    pub path_frames: usize,
    /// Fewer settings per scheme.
    #[arg(long)]
    pub quick: bool,
    /// Measure part i of N of the settings (`merge --dir` joins the
    /// parts' JSON and writes the CSV and charts).
    #[arg(long, value_parser = Shard::parse, default_value = "0/1", allow_hyphen_values = true)]
    pub shard: Shard,
    /// Also draw every setting with the wgpu back end (Vulkan) and report
    /// what a GPU renderer pays: bytes uploaded per frame, draw calls and
    /// the render pass's GPU time (timestamp queries, where the adapter
    /// has them).
    #[arg(long)]
    pub gpu: bool,
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let start = Rusage::now();
    if a.path_frames < 2 {
        anyhow::bail!("--path-frames must be at least 2");
    }
    let size = a.args.size.unwrap_or([320, 180]);
    if size[0] == 0 || size[1] == 0 || size[0] > 2048 || size[1] > 2048 {
        anyhow::bail!(
            "--size must be within 1..=2048 per side (64× supersampling multiplies it by 8)"
        );
    }
    let s = a
        .args
        .scene(&a.scene, terraclip::scene::Scene::bench_scene)?;
    let opts = tradeoff::Options {
        size,
        path_frames: a.path_frames,
        quick: a.quick,
        shard: a.shard,
        gpu: a.gpu,
    };
    let count = tradeoff::settings(&s, a.quick)?.len();
    let mine = (0..count).filter(|&k| a.shard.owns(k)).count();
    let bar = progress(mine, "tradeoff");
    let mut report = tradeoff::run(&s, &opts, |label| {
        bar.set_message(label.to_string());
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    report.title = match &a.args.heightmap {
        Some(h) => format!("{} at {}x{}", h.display(), size[0], size[1]),
        None => format!("{} at {}x{}", s.origin, size[0], size[1]),
    };
    // A part's front and budget are its own rows': its CSV and charts
    // would mislead, so only the merge writes them.
    if a.shard.is_whole() {
        tradeoff::write(&report, &a.out)?;
    }
    if a.json {
        let of = format!(
            "{} --path-frames {} --quick {} --gpu {}",
            a.args.describe(&a.scene),
            a.path_frames,
            a.quick,
            a.gpu
        );
        let mut v = shard::tag(serde_json::to_value(&report)?, "tradeoff", a.shard, &of);
        v["rusage"] = serde_json::to_value(Rusage::since(&start))?;
        println!("{v}");
        return Ok(());
    }
    println!(
        "{:<12} {:<26} {:>9} {:>8} {:>4} {:>9} {:>10} {:>8}",
        "lod", "config", "ms", "rmse", "max", "depth m", "triangles", "popping"
    );
    for r in &report.rows {
        println!(
            "{:<12} {:<26} {:>9.2} {:>8.3} {:>4} {:>9.2} {:>10.0} {:>8.3}{}",
            r.lod,
            r.config,
            r.ms,
            r.rmse,
            r.max_abs,
            r.depth_m,
            r.triangles,
            r.popping,
            if r.pareto { "  *" } else { "" }
        );
    }
    if let Some(g) = report.rows.iter().find_map(|r| r.gpu.as_ref()) {
        println!("\non {}:", g.adapter);
        println!(
            "{:<12} {:<26} {:>10} {:>14} {:>7} {:>9}",
            "lod", "config", "cpu lod ms", "upload B/frame", "draws", "gpu ms"
        );
        for r in &report.rows {
            let Some(g) = &r.gpu else { continue };
            let f = |v: Option<f64>, d: usize| v.map_or("-".into(), |v| format!("{v:.d$}"));
            println!(
                "{:<12} {:<26} {:>10.3} {:>14} {:>7} {:>9}  {}",
                r.lod,
                r.config,
                r.ms_cpu_lod(),
                f(g.upload_bytes, 0),
                f(g.draw_calls, 1),
                f(g.ms, 3),
                g.note.as_deref().unwrap_or("")
            );
        }
    }
    match &report.best_in_budget {
        Some(b) => println!(
            "within 1/10 of brute force ({:.2} ms): {} {} has the lowest RMSE, {:.3}",
            report.budget_ms, b.lod, b.config, b.rmse
        ),
        None => println!(
            "no setting ran within 1/10 of brute force ({:.2} ms)",
            report.budget_ms
        ),
    }
    if a.shard.is_whole() {
        println!(
            "wrote {0}/tradeoff.{{csv,svg,png}}, {0}/tradeoff-low-fov.{{svg,png}} and the per-cost charts {1}",
            a.out.display(),
            tradeoff::cost_charts(&report)
                .iter()
                .map(|(stem, _)| format!("{stem}.{{svg,png}}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    } else {
        println!(
            "part {}/{}: the front and budget above are this part's; `terraclip merge` the parts' --json output with --dir for the sweep's CSV and charts",
            a.shard.index, a.shard.count
        );
    }
    Ok(())
}
