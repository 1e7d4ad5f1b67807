//! `terraclip info`: what a heightmap file holds.

use serde_json::json;
use std::path::PathBuf;
use terraclip::terrain::Heightmap;

#[derive(clap::Args, Debug)]
pub struct Args {
    pub heightmap: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let h = Heightmap::load(&a.heightmap)?;
    let (min, max) = h.min_max();
    if a.json {
        let v = json!({
            "width": h.width(), "height": h.height(), "min": min, "max": max,
            "nodata_count": h.nodata_count(), "format": h.format,
            "cell_size": h.cell_size, "cell_size_m": h.cell_size, "crs": h.crs,
        });
        println!("{v}");
    } else {
        println!(
            "{}: {}×{} {}, heights {min}..{max} m, {} no-data, cell {:?} m, CRS {}",
            a.heightmap.display(),
            h.width(),
            h.height(),
            h.format,
            h.nodata_count(),
            h.cell_size,
            h.crs.as_deref().unwrap_or("not given")
        );
    }
    Ok(())
}
