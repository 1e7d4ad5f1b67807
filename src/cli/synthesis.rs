//! `terraclip synthesis`: how plausible synthesised detail is, on a real
//! map decimated by its own pyramid and synthesised back down.

use std::path::PathBuf;
use terraclip::error::write_atomic;
use terraclip::pyramid::Filter;
use terraclip::studies::synthesis::{self, Options};
use terraclip::terrain::{window_of, Heightmap};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A heightmap `info` reads.
    pub map: PathBuf,
    /// Decimate 2× or 4× before synthesising back down.
    #[arg(long, default_value_t = 2)]
    pub factor: usize,
    /// A window X,Y,W,H of the map's samples (the whole map if absent).
    #[arg(long, value_parser = super::unpack::parse_window)]
    pub window: Option<[usize; 4]>,
    /// Roughness H: each synthesised level's noise 2^−H of the one above
    /// (measured from the decimated map if absent).
    #[arg(long, allow_hyphen_values = true)]
    pub roughness: Option<f64>,
    /// The noise table's seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The pyramid's filter (the decimation).
    #[arg(long, default_value = "sinc-blackman", value_parser = Filter::parse)]
    pub filter: Filter,
    /// Scale the noise by the map's local detail instead of one amplitude
    /// everywhere (LH04's).
    #[arg(long)]
    pub local: bool,
    /// A PNG of hillshades side by side: the real map, the decimated map
    /// and the synthesised one.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

/// `map`'s window `[x, y, w, h]`, no-data kept.
fn window(
    map: &Heightmap,
    [x, y, w, h]: [usize; 4],
    path: &std::path::Path,
) -> anyhow::Result<Heightmap> {
    if x + w > map.width() || y + h > map.height() {
        anyhow::bail!(
            "{}: window {x},{y},{w},{h} does not fit the {}×{} map",
            path.display(),
            map.width(),
            map.height()
        );
    }
    let rect = [x, y, w, h];
    let nd = window_of(map.nodata_mask(), map.width(), rect);
    let values = window_of(map.data(), map.width(), rect)
        .into_iter()
        .zip(nd)
        .map(|(v, nd)| if nd { f32::NAN } else { v })
        .collect();
    Heightmap::from_values(w, h, values, None, map.cell_size, &map.format)
        .map_err(|e| anyhow::anyhow!("{}: the window: {e}", path.display()))
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let mut map = Heightmap::load(&a.map)?;
    if let Some(w) = a.window {
        map = window(&map, w, &a.map)?;
    }
    let opts = Options {
        factor: a.factor,
        roughness: a.roughness,
        seed: a.seed,
        filter: a.filter,
        local: a.local,
    };
    let (r, s) =
        synthesis::run(&map, &opts).map_err(|e| anyhow::anyhow!("{}: {e}", a.map.display()))?;
    if let Some(out) = &a.out {
        let name = a
            .map
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into());
        let mut title = match a.window {
            Some([x, y, w, h]) => format!("{name}, window {w} × {h} at ({x}, {y})"),
            None => name,
        };
        if a.local {
            title += ", local noise";
        }
        let png = synthesis::comparison_png(&s, a.factor, &title)?;
        write_atomic(out, &png)?;
    }
    if a.json {
        println!("{}", serde_json::to_string(&r)?);
        return Ok(());
    }
    println!(
        "{} × {} samples, decimated {}×, roughness {:.3}{}, noise amplitudes {:?}",
        r.width,
        r.height,
        r.factor,
        r.roughness,
        if r.roughness_measured {
            " (measured)"
        } else {
            ""
        },
        r.amplitudes
    );
    println!("real variogram slope {:.3}", r.real_variogram_slope);
    for (name, s) in [
        ("synthesised", &r.synthesised),
        ("subdivided", &r.subdivided),
    ] {
        println!(
            "{name:<12} variogram slope {:.3} ({:+.1} %), slope KS {:.3}, RMSE {:.3}",
            s.variogram_slope,
            s.variogram_slope_error * 100.0,
            s.slope_ks,
            s.rmse
        );
    }
    Ok(())
}
