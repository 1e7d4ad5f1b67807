//! `terraclip pack`: a heightmap or a scene's terrain as a compressed
//! residual pyramid (`.tcz`).

use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;
use terraclip::pack::{file, Packed};
use terraclip::pyramid::{Filter, Pyramid};
use terraclip::scene::Scene;
use terraclip::terrain::{self, Heightmap};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A heightmap file `info` reads, or a scene (`.toml`) whose terrain
    /// (a file or procedural) is packed.
    pub input: PathBuf,
    #[arg(short, long)]
    pub out: PathBuf,
    /// Every sample of every level is within this many metres of the
    /// pyramid the filter builds; 0 is lossless, bit for bit.
    #[arg(long, default_value_t = 0.0)]
    pub max_error: f64,
    /// The filter the coarser levels are made with.
    #[arg(long, default_value = "sinc-blackman", value_parser = Filter::parse)]
    pub filter: Filter,
    /// Tile side in samples (even, 2..=4096).
    #[arg(long, default_value_t = 128)]
    pub tile: usize,
    #[arg(long)]
    pub json: bool,
}

fn load(input: &std::path::Path) -> anyhow::Result<Heightmap> {
    if input.extension().is_some_and(|e| e == "toml") {
        let s = Scene::load(input)?;
        Ok(terrain::load(&s.terrain, &s.base_dir).map_err(|e| s.named(e))?)
    } else {
        Ok(Heightmap::load(input)?)
    }
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    if !(a.max_error.is_finite() && (0.0..=1e6).contains(&a.max_error)) {
        anyhow::bail!(
            "--max-error must be within 0..=1e6 metres, got {}",
            a.max_error
        );
    }
    if !(2..=4096).contains(&a.tile) || a.tile % 2 != 0 {
        anyhow::bail!("--tile must be even and within 2..=4096, got {}", a.tile);
    }
    let t = Instant::now();
    let map = load(&a.input)?;
    let (w, h, cell_size, lattice) = (map.width(), map.height(), map.cell_size, map.lattice);
    // The map becomes level 0 rather than being copied into it.
    let pyramid = Pyramid::from_heightmap(map, a.filter, usize::MAX);
    let (packed, recon) = Packed::encode(&pyramid.levels, a.max_error, a.tile, lattice);
    // The bound as achieved, over every sample of every level.
    let worst = pyramid
        .levels
        .iter()
        .zip(&recon)
        .flat_map(|(s, r)| s.data.iter().zip(&r.data))
        .map(|(&x, &y)| (x as f64 - y as f64).abs())
        .fold(0.0, f64::max);
    let source = a.input.display().to_string();
    let bytes = file::write(&a.out, &packed, cell_size, &a.filter.name(), &source)?;
    let ratio = (w * h * 4) as f64 / bytes as f64;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let v = json!({
        "output": a.out, "width": w, "height": h,
        "levels": packed.levels.len(), "max_error": a.max_error,
        "max_error_seen": worst, "tile": packed.tile, "bytes": bytes,
        "ratio": ratio, "ms": ms,
        "peak_rss_bytes": terraclip::studies::scaling::peak_rss(),
    });
    let (levels, out) = (packed.levels.len(), a.out.display());
    super::report(a.json, v, || {
        format!(
            "wrote {out}: {w}×{h}, {levels} levels, {bytes} bytes ({ratio:.2}× of f32), largest error {worst} m (bound {}), {ms:.0} ms",
            a.max_error
        )
    });
    Ok(())
}
