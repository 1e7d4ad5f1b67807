//! `terraclip compare`: an outside renderer's image of an exported frame
//! against terraclip's reference; exits non-zero when it fails.

use std::path::PathBuf;
use terraclip::check::outside::{self, Mode};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// An export folder (`terraclip export`), one frame.
    pub reference: PathBuf,
    /// The outside renderer's colour image (PNG, or any format the image
    /// crate reads), the reference's size.
    #[arg(long)]
    pub image: PathBuf,
    /// Its depth buffer: .exr (float) or .f32 (raw little-endian rows).
    #[arg(long)]
    pub depth: Option<PathBuf>,
    /// exact, tiered (check-gpu's tolerance mode) or flip.
    #[arg(long, value_enum, default_value_t = Mode::Exact, hide_possible_values = true)]
    pub mode: Mode,
    /// Where diff.png (reference | error mask | theirs) and flip.png go.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = outside::run(
        &a.reference,
        &a.image,
        a.depth.as_deref(),
        a.mode,
        a.out.as_deref(),
    )?;
    super::report(a.json, serde_json::to_value(&o)?, || {
        let t = &o.tiers;
        format!(
            "{}: {} in {} mode ({} colour px and {} depth px differ; tiers: {} same, {} shifted, \
             {} unmatched, {} holes, {} outside the tie band; FLIP mean {:.4}, 99.99th percentile {:.4})",
            a.image.display(),
            if o.pass { "pass" } else { "FAIL" },
            o.mode,
            o.colour_px_differ,
            o.depth_px_differ,
            t.same,
            t.shifted,
            t.unmatched,
            t.holes,
            t.outside_band,
            o.flip.mean,
            o.flip.p9999
        )
    });
    if !o.pass {
        anyhow::bail!(
            "{} does not match {} in {} mode",
            a.image.display(),
            a.reference.display(),
            o.mode
        );
    }
    Ok(())
}
