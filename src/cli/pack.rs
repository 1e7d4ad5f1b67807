//! `terraclip pack`: a heightmap or a scene's terrain as a compressed
//! residual pyramid (`.tcz`).

use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;
use terraclip::pack::{stream, Coder, Predictor};
use terraclip::pyramid::Filter;
use terraclip::scene::Scene;
use terraclip::terrain::rows::{self, RowSource};

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
    /// What the finer levels are predicted from: `fitted` (lifting's
    /// phases under weights fitted to each tile, the smallest pack, and
    /// the default with the ratio coder), `lifting` (fixed weights, which
    /// decodes about twice as fast under the fast coder, and its default)
    /// or `upsampled` (LH04's four-point upsampling of the coarser level
    /// alone, which `[gpu] update = "gpu"` rebuilds on the GPU from
    /// uploaded residuals; needs --max-error > 0).
    #[arg(long, value_parser = parse_predictor)]
    pub predictor: Option<Predictor>,
    /// The tiles' entropy stage: `ratio` (ANS under per-context models,
    /// the smaller pack) or `fast` (zstd, which decodes about twice as
    /// fast for a pack of about the same size). Both code the same
    /// residuals to the same bound.
    #[arg(long, default_value = "ratio", value_parser = parse_coder)]
    pub coder: Coder,
    /// Tile side in samples (even, 2..=4096).
    #[arg(long, default_value_t = 128)]
    pub tile: usize,
    /// About the bytes of samples (heights and flags) one band of rows
    /// holds, in MiB: what is resident while packing is a few bands, so
    /// this bounds the memory a pack of any size takes (default 48).
    #[arg(long, default_value_t = 48.0)]
    pub band_mib: f64,
    /// The CRS of a map whose file names none, as EPSG:<code> (a
    /// geographic one converts its degrees to metres).
    #[arg(long)]
    pub crs: Option<String>,
    /// The variable of a netCDF file that holds the map, where its CF
    /// standard_names do not single one out.
    #[arg(long)]
    pub variable: Option<String>,
    #[arg(long)]
    pub json: bool,
}

fn parse_coder(s: &str) -> Result<Coder, String> {
    Coder::parse(s).ok_or_else(|| format!("unknown coder {s:?} (ratio or fast)"))
}

fn parse_predictor(s: &str) -> Result<Predictor, String> {
    Predictor::parse(s)
        .ok_or_else(|| format!("unknown predictor {s:?} (fitted, lifting or upsampled)"))
}

/// The input as rows: a scene's terrain, or a heightmap file.
fn source(
    input: &std::path::Path,
    crs: Option<&str>,
    variable: Option<&str>,
) -> anyhow::Result<Box<dyn RowSource>> {
    if input.extension().is_some_and(|e| e == "toml") {
        let mut s = Scene::load(input)?;
        if let Some(c) = crs {
            s.terrain.crs = Some(c.to_string());
            s.validate()?;
        }
        if let Some(v) = variable {
            s.terrain.variable = Some(v.to_string());
        }
        super::warn_crs(&s.terrain, &s.base_dir);
        Ok(rows::for_terrain(&s.terrain, &s.base_dir).map_err(|e| s.named(e))?)
    } else {
        let src = rows::open_var(input, variable)?;
        match crs {
            Some(c) => Ok(rows::with_crs(src, input, c)?),
            None => {
                if let Some(w) = rows::crs_warning(&*src, input) {
                    eprintln!("warning: {w}");
                }
                Ok(src)
            }
        }
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
    // Each coder's default: the fitted weights cost the fast coder half
    // its decode speed, and the ratio coder a third of its.
    let predictor = a.predictor.unwrap_or(match a.coder {
        Coder::Ratio => Predictor::Fitted,
        Coder::Fast => Predictor::Lifting,
    });
    if predictor == Predictor::Upsampled && a.max_error == 0.0 {
        anyhow::bail!(
            "--predictor upsampled needs --max-error > 0: its f32 sums p + q·s cannot rebuild every map bit for bit (a lossless pack uses lifting)"
        );
    }
    if !(a.band_mib.is_finite() && (0.0625..=65536.0).contains(&a.band_mib)) {
        anyhow::bail!(
            "--band-mib must be within 0.0625..=65536, got {}",
            a.band_mib
        );
    }
    let t = Instant::now();
    let src = source(&a.input, a.crs.as_deref(), a.variable.as_deref())?;
    let [w, h] = src.size();
    let source_name = a.input.display().to_string();
    let mut opts = stream::Options::new(a.max_error, a.tile, a.filter, &source_name);
    opts.predictor = predictor;
    opts.coder = a.coder;
    opts.band_bytes = (a.band_mib * (1 << 20) as f64) as usize;
    let bar = super::progress(0, "pack");
    let summary = stream::pack(src.as_ref(), &a.out, &opts, &mut |done, total| {
        bar.set_length(total);
        bar.set_position(done);
    })?;
    bar.finish_and_clear();
    let stream::Summary {
        levels,
        bytes,
        max_error_seen: worst,
        ..
    } = summary;
    let ratio = (w * h * 4) as f64 / bytes as f64;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let v = json!({
        "output": a.out, "width": w, "height": h,
        "levels": levels, "max_error": a.max_error,
        "max_error_seen": worst, "tile": a.tile, "bytes": bytes,
        "predictor": predictor.name(),
        "coder": a.coder.name(),
        "ratio": ratio, "ms": ms,
        "peak_rss_bytes": terraclip::studies::scaling::peak_rss(),
    });
    let out = a.out.display();
    super::report(a.json, v, || {
        format!(
            "wrote {out}: {w}×{h}, {levels} levels, {bytes} bytes ({ratio:.2}× of f32), largest error {worst} m (bound {}), {ms:.0} ms",
            a.max_error
        )
    });
    Ok(())
}
