//! `terraclip info`: what a heightmap file holds.

use serde_json::json;
use std::path::PathBuf;
use terraclip::pack::file;
use terraclip::terrain::Heightmap;

#[derive(clap::Args, Debug)]
pub struct Args {
    pub heightmap: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// The CRS of a map whose file names none, as EPSG:<code> (a
    /// geographic one converts its degrees to metres).
    #[arg(long)]
    pub crs: Option<String>,
    /// The variable of a netCDF file that holds the map, where its CF
    /// standard_names do not single one out.
    #[arg(long)]
    pub variable: Option<String>,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    if file::is_pack_file(&a.heightmap) {
        return pack_info(a);
    }
    let mut h = Heightmap::load_var(&a.heightmap, a.variable.as_deref())?;
    match &a.crs {
        Some(c) => h.declare_crs(&a.heightmap, c)?,
        None => {
            if let Some(w) = h.crs_warning(&a.heightmap) {
                eprintln!("warning: {w}");
            }
        }
    }
    let (min, max) = h.min_max();
    let v = json!({
        "width": h.width(), "height": h.height(), "min": min, "max": max,
        "nodata_count": h.nodata_count(), "format": h.format,
        "cell_size": h.cell_size, "cell_size_m": h.cell_size, "crs": h.crs,
    });
    super::report(a.json, v, || {
        format!(
            "{}: {}×{} {}, heights {min}..{max} m, {} no-data, cell {:?} m, CRS {}",
            a.heightmap.display(),
            h.width(),
            h.height(),
            h.format,
            h.nodata_count(),
            h.cell_size,
            h.crs.as_deref().unwrap_or("not given")
        )
    });
    Ok(())
}

/// What a pack holds: its header, checked with every tile.
fn pack_info(a: &Args) -> anyhow::Result<()> {
    let (h, packed) = file::read(&a.heightmap)?;
    let bytes = std::fs::metadata(&a.heightmap)?.len();
    let [w, hh] = h.size();
    let tiles: usize = packed.levels.iter().map(|l| l.tiles.len()).sum();
    let v = json!({
        "width": w, "height": hh, "format": "tcz", "levels": h.levels(),
        "max_error": h.max_error, "tile": h.tile, "bytes": bytes, "tiles": tiles,
        "cell_size": h.cell_size, "cell_size_m": h.cell_size, "filter": h.filter,
        "source": h.source, "predictor": h.predictor().name(), "coder": h.coder.name(),
        "crs": h.place.as_ref().and_then(|p| p.epsg()).map(|c| format!("EPSG:{c}")),
        "geotransform": h.place.as_ref().map(|p| p.geotransform()),
        "nodata": h.place.as_ref().and_then(|p| p.nodata),
    });
    super::report(a.json, v, || {
        format!(
            "{}: pack of {w}×{hh}, {} levels, max error {} m ({} prediction, {} coder), {tiles} tiles of {}², {bytes} bytes, from {}{}",
            a.heightmap.display(),
            h.levels(),
            h.max_error,
            h.predictor().name(),
            h.coder.name(),
            h.tile,
            h.source,
            match &h.place {
                Some(p) => format!(
                    ", placed ({}, origin {:?}, cells {:?})",
                    p.epsg().map_or("CRS by its GeoKeys".into(), |c| format!("EPSG:{c}")),
                    p.origin,
                    p.pixel_scale
                ),
                None => String::new(),
            }
        )
    });
    Ok(())
}
