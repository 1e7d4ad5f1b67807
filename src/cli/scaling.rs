//! `terraclip scaling`: what grows with the terrain.

use super::{load_scene, progress};
use std::path::PathBuf;

/// `terraclip scaling`'s settings.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene whose camera, shading and seed are used; the benchmark's scene
    /// (benches/scenes/bench.toml) if omitted.
    pub scene: Option<PathBuf>,
    /// Square terrain sizes in texels per side, comma-separated, smallest
    /// first.
    #[arg(long, default_value = "1024,2048,4096,16384", value_delimiter = ',')]
    pub sizes: Vec<usize>,
    /// Packs to time instead of the procedural sizes, comma-separated,
    /// smallest first (their frames interleaved like the sizes').
    #[arg(long, value_delimiter = ',')]
    pub packs: Vec<PathBuf>,
    /// Clipmap n and levels of the size test.
    #[arg(long, default_value_t = 127)]
    pub n: i64,
    #[arg(long, default_value_t = 3)]
    pub levels: usize,
    /// Frames per size (median reported).
    #[arg(long, default_value_t = 40)]
    pub frames: usize,
    /// Largest size brute force renders.
    #[arg(long, default_value_t = 2048)]
    pub brute_max: usize,
    /// n and levels of the incremental-update test (on its own map, wide
    /// enough for that many levels).
    #[arg(long, default_value_t = 255)]
    pub update_n: i64,
    #[arg(long, default_value_t = 10)]
    pub update_levels: usize,
    /// Repeats of the update test (medians reported).
    #[arg(long, default_value_t = 5)]
    pub update_repeats: usize,
    /// n of the lazy first-frame test (largest size, every level).
    #[arg(long, default_value_t = 255)]
    pub first_n: i64,
    /// Lazy pyramid samples per frame in the first-frame test.
    #[arg(long, default_value_t = terraclip::scene::DEFAULT_LAZY_BUDGET)]
    pub first_budget: u64,
    #[arg(long)]
    pub json: bool,
}

impl Args {
    fn options(&self) -> terraclip::studies::scaling::Options {
        terraclip::studies::scaling::Options {
            sizes: self.sizes.clone(),
            packs: self.packs.clone(),
            n: self.n,
            levels: self.levels,
            frames: self.frames,
            brute_max: self.brute_max,
            update_n: self.update_n,
            update_levels: self.update_levels,
            update_repeats: self.update_repeats,
            first_n: self.first_n,
            first_budget: self.first_budget,
            ..Default::default()
        }
    }
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    use terraclip::studies::scaling;
    let s = load_scene(&args.scene, terraclip::scene::Scene::bench_scene)?;
    let opts = args.options();
    let bar = progress(0, "scaling");
    let r = scaling::run(&s, &opts, |label| bar.set_message(label.to_string()))?;
    bar.finish_and_clear();
    if args.json {
        println!("{}", serde_json::to_value(&r)?);
        return Ok(());
    }
    let f = &r.first_frame;
    println!(
        "lazy first frame of {}² (n = {}, {} of {} levels drawn, budget {}): {:.0} ms (target < 1000), {} tris, {} of {} pyramid samples built, peak RSS {} MB",
        f.size,
        f.n,
        f.levels_drawn,
        f.levels,
        f.budget,
        f.first_frame_ms,
        f.triangles,
        f.samples_built,
        f.eager_samples,
        f.peak_rss_bytes.map_or("?".into(), |b| (b >> 20).to_string()),
    );
    match (f.frames_to_all_levels, f.all_levels_ms) {
        (Some(n), Some(ms)) => println!("  every level drawn after {n} more frames ({ms:.0} ms)"),
        _ => println!("  not every level drawn within the frame limit"),
    }
    println!("size     terrain    pyramid   clipmap frame   brute-force frame");
    for row in &r.sizes {
        let brute = match (row.brute_frame_ms, row.brute_triangles) {
            (Some(ms), Some(t)) => format!("{ms:9.1} ms ({t} tris)"),
            _ => "-".into(),
        };
        println!(
            "{:>6}²  {:7.0} ms {:7.0} ms {:8.2} ms ({} tris)   {brute}",
            row.size, row.terrain_ms, row.pyramid_ms, row.clipmap_frame_ms, row.clipmap_triangles
        );
    }
    println!(
        "clipmap frame, largest / smallest: {:.3} (target <= 1.05)",
        r.clipmap_ratio
    );
    if let Some(b) = r.brute_ratio {
        println!("brute force frame, largest / smallest it ran on: {b:.2}");
    }
    let u = &r.update;
    println!(
        "full update n={} L={} on a {}-wide map ({} repeats): {:.3} ms after a jump ({:.3} ms on one thread), {:.3} ms for the same window again ({} texels)",
        u.n, u.levels, u.size, u.repeats, u.full_ms, u.full_one_core_ms, u.full_same_window_ms, u.full_texels
    );
    println!(
        "  its map: {} MB, {} MB of them on huge pages",
        u.map_bytes >> 20,
        u.map_huge_page_bytes
            .map_or("?".into(), |b| (b >> 20).to_string())
    );
    for w in &u.walks {
        let each: Vec<String> = w.overheads.iter().map(|o| format!("{o:.2}")).collect();
        println!(
            "  walk {:<10} {:.3} us/frame ({:.0} texels, {:.1} column rows): time ratio {:.5}, texel ratio {:.5}, overhead {:.2} (target <= 1.2; repeats {}), against one thread {:.2}",
            w.direction, w.incremental_ms * 1e3, w.incremental_texels, w.column_rows, w.time_ratio, w.texel_ratio, w.overhead, each.join(" "), w.overhead_one_core
        );
    }
    let m = &r.memory;
    println!(
        "peak RSS {} MB; heightmaps {} MB + pyramids {} MB; ratio {} (target < 2)",
        m.peak_rss_bytes
            .map_or("?".into(), |b| (b >> 20).to_string()),
        m.heightmap_bytes >> 20,
        m.pyramid_bytes >> 20,
        m.ratio.map_or("?".into(), |r| format!("{r:.2}"))
    );
    Ok(())
}
