//! `terraclip unpack`: a pack's samples written back out, so users get
//! their data back and anyone can check the bound with their own tools.

use serde_json::json;
use std::path::PathBuf;
use std::sync::Arc;
use terraclip::pack::reader::PackReader;
use terraclip::pack::Quant;
use terraclip::pyramid::{Filter, Pyramid};
use terraclip::terrain::write::{self, Grid};
use terraclip::terrain::Lattice;

#[derive(clap::Args, Debug)]
pub struct Args {
    pub pack: PathBuf,
    /// The level to write (0, the finest, by default).
    #[arg(long, default_value_t = 0)]
    pub level: usize,
    /// A window X,Y,W,H of the level's samples (the whole level if absent).
    #[arg(long, value_parser = parse_window)]
    pub window: Option<[usize; 4]>,
    /// `.f32` (raw, with a JSON sidecar), `.tif` (f32 GeoTIFF) or `.png`
    /// (16-bit, with a sidecar).
    #[arg(short, long)]
    pub out: PathBuf,
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn parse_window(s: &str) -> Result<[usize; 4], String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|p| p.trim().parse::<usize>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    let w: [usize; 4] = v
        .try_into()
        .map_err(|v: Vec<usize>| format!("need X,Y,W,H, got {} numbers", v.len()))?;
    if w[2] == 0 || w[3] == 0 {
        return Err("the window must be at least 1×1".into());
    }
    Ok(w)
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    // Only the tiles under the window are decoded (and the coarser ones
    // they are predicted from), so a window of a pack of any size is cheap.
    let reader = PackReader::open(&a.pack)?;
    let header = reader.header().clone();
    if a.level >= header.levels() {
        anyhow::bail!(
            "{}: --level {} does not exist (the pack has levels 0..={})",
            a.pack.display(),
            a.level,
            header.levels() - 1
        );
    }
    let [lw, lh] = header.level_size(a.level);
    let [x, y, w, h] = a.window.unwrap_or([0, 0, lw, lh]);
    if x + w > lw || y + h > lh {
        anyhow::bail!(
            "--window {x},{y},{w},{h} leaves level {} ({lw}×{lh})",
            a.level
        );
    }
    if (w * h) as u64 > terraclip::terrain::MAX_TEXELS {
        anyhow::bail!(
            "{}: level {} is {w}×{h}, more than the {} samples unpack writes at once; give a --window",
            a.pack.display(),
            a.level,
            terraclip::terrain::MAX_TEXELS
        );
    }
    let filter =
        Filter::parse(&header.filter).map_err(|r| anyhow::anyhow!("{}: {r}", a.pack.display()))?;
    let mut pyramid = Pyramid::decoded(Arc::new(reader), filter, u64::MAX)
        .map_err(|r| anyhow::anyhow!("{}: {r}", a.pack.display()))?;
    let rect = [x as i64, y as i64, (x + w) as i64 - 1, (y + h) as i64 - 1];
    pyramid.decode_window(a.level, rect)?;
    let lv = &pyramid.levels[a.level];
    let data = terraclip::terrain::window_of(&lv.data, lv.width, [x, y, w, h]);
    let nodata = terraclip::terrain::window_of(&lv.nodata, lv.width, [x, y, w, h]);
    let spacing = (1u64 << a.level.min(62)) as f64;
    let grid = Grid {
        width: w,
        height: h,
        data: &data,
        nodata: &nodata,
        cell_size: header.cell_size.map(|c| c * spacing),
        place: header.place.as_ref().map(|p| p.of_window(a.level, x, y)),
    };
    let lattice = match header.level_quant(a.level) {
        Some(Quant::Lattice { offset, scale }) => Some(Lattice { offset, scale }),
        _ => None,
    };
    let written = write::write(&a.out, &grid, lattice)?;
    let v = json!({
        "output": a.out, "level": a.level, "window": [x, y, w, h],
        "width": w, "height": h, "cell_size_m": grid.cell_size,
        "max_error": header.max_error, "sidecar": written.sidecar,
        "png_step_m": written.step_m, "png_error_m": written.max_error_m,
        "crs": grid.place.as_ref().and_then(|p| p.epsg()).map(|c| format!("EPSG:{c}")),
        "geotransform": grid.place.as_ref().map(|p| p.geotransform()),
        "nodata": grid.place.as_ref().and_then(|p| p.nodata),
    });
    let out = a.out.display();
    super::report(a.json, v, || {
        format!(
            "wrote {out}: level {} window {x},{y} {w}×{h} (pack bound {} m)",
            a.level, header.max_error
        )
    });
    Ok(())
}
