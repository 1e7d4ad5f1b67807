//! `terraclip cracks`: a crack survey over random views.

use super::{load_scene, progress};
use std::path::PathBuf;
use terraclip::frame::stats::Rusage;
use terraclip::render::Image;
use terraclip::scene::{Overrides, Scene};
use terraclip::studies::cracks;
use terraclip::studies::shard::{self, Shard};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file; the benchmark's scene (benches/scenes/bench.toml) if omitted.
    pub scene: Option<PathBuf>,
    /// Random views above the terrain.
    #[arg(long, default_value_t = 100)]
    pub views: usize,
    /// Scheme(s): NAME, clipmap/LAYOUT, a comma-separated list, or
    /// "all"; the scene's own scheme if omitted.
    #[arg(long)]
    pub lod: Option<String>,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, default_value = "160x100", value_parser = Overrides::parse_size)]
    pub size: [u32; 2],
    /// Survey part i of N of the views (`merge` joins the parts' JSON).
    #[arg(long, value_parser = Shard::parse, default_value = "0/1", allow_hyphen_values = true)]
    pub shard: Shard,
    /// Exit non-zero if any crack pixel is found.
    #[arg(long)]
    pub strict: bool,
    /// Write each scheme's worst view (and its brute-force reference)
    /// as PNGs here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

/// "all", a list, or the scene's own scheme.
fn scheme_list(lod: &Option<String>, s: &Scene) -> Vec<String> {
    match lod.as_deref() {
        Some("all") => cracks::all(),
        Some(list) => list.split(',').map(|p| p.trim().to_string()).collect(),
        None => vec![s.lod.scheme.to_string()],
    }
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let start = Rusage::now();
    if a.views == 0 {
        anyhow::bail!("--views must be at least 1");
    }
    let s = load_scene(&a.scene, Scene::bench_scene)?;
    let schemes = scheme_list(&a.lod, &s);
    let bar = progress(a.views, "cracks");
    let r = cracks::survey(&s, &schemes, a.views, a.size, a.shard, || bar.inc(1))?;
    bar.finish_and_clear();
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).map_err(|e| terraclip::Error::io(dir, e))?;
        for c in &r.schemes {
            if let Some((img, reference)) = &c.worst_images {
                let name = c.lod.replace('/', "-");
                let write = |suffix: &str, i: &Image| -> anyhow::Result<()> {
                    let p = dir.join(format!("{name}-{suffix}.png"));
                    Ok(terraclip::error::write_atomic(&p, &i.png()?)?)
                };
                write("worst", img)?;
                write("brute-force", reference)?;
            }
        }
    }
    if a.json {
        let of = format!(
            "{} --views {} --lod {} --size {}x{}",
            a.scene
                .as_ref()
                .map_or("<default scene>".into(), |p| p.display().to_string()),
            a.views,
            schemes.join(","),
            a.size[0],
            a.size[1]
        );
        let mut v = shard::tag(serde_json::to_value(&r)?, "cracks", a.shard, &of);
        v["rusage"] = serde_json::to_value(Rusage::since(&start))?;
        println!("{v}");
    } else {
        for c in &r.schemes {
            println!(
                "{:<20} {:>7} crack px in {:>4} of {} views (worst view {}: {} px)",
                c.lod, c.crack_pixels, c.views_with_cracks, r.views, c.worst_view, c.worst_pixels
            );
        }
    }
    if a.strict && r.crack_pixels > 0 {
        anyhow::bail!("{} crack pixels found", r.crack_pixels);
    }
    Ok(())
}
