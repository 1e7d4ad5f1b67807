//! `terraclip compare`: an outside renderer's image of an exported frame
//! against terraclip's reference; exits non-zero when it fails.

use std::path::PathBuf;
use terraclip::check::outside::{self, Mode, Only, Options};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// An export folder (`terraclip export`), one frame.
    pub reference: PathBuf,
    /// The outside renderer's colour image (PNG, or any format the image
    /// crate reads), the reference's size; not needed with --only depth.
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// Its depth buffer: .exr (float) or .f32 (raw little-endian rows).
    #[arg(long)]
    pub depth: Option<PathBuf>,
    /// exact, tiered (check-gpu's tolerance mode) or flip.
    #[arg(long, value_enum, default_value_t = Mode::Exact, hide_possible_values = true)]
    pub mode: Mode,
    /// both, depth or colour: what is compared.
    #[arg(long, value_enum, default_value_t = Only::Both, hide_possible_values = true)]
    pub only: Only,
    /// The renderer's sub-pixel precision in bits, 4 (Vulkan's least, the
    /// default) to 8 (D3D's and most desktop GPUs'): the tie band's width.
    #[arg(long, default_value_t = outside::Options::new(Mode::Exact).subpixel_bits)]
    pub subpixel_bits: u32,
    /// The EXR channel that holds the depth (`Z`, or `layer.Z`), when the
    /// file has several.
    #[arg(long)]
    pub depth_channel: Option<String>,
    /// Where diff.png (reference | error mask | theirs [| depth]) and
    /// flip.png go.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let opts = Options {
        mode: a.mode,
        only: a.only,
        subpixel_bits: a.subpixel_bits,
        depth_channel: a.depth_channel.clone(),
    };
    let o = outside::run(
        &a.reference,
        a.image.as_deref(),
        a.depth.as_deref(),
        &opts,
        a.out.as_deref(),
    )?;
    let what = a
        .image
        .as_ref()
        .or(a.depth.as_ref())
        .map_or(String::new(), |p| p.display().to_string());
    super::report(a.json, serde_json::to_value(&o)?, || {
        let t = &o.tiers;
        format!(
            "{what}: {} in {} mode, {} ({} colour px and {} depth px differ; tiers: {} same, {} \
             shifted, {} unmatched, {} holes, {} outside the tie band; FLIP outside the band: \
             mean {:.4}, 99.99th percentile {:.4})",
            if o.pass { "pass" } else { "FAIL" },
            o.mode,
            o.only,
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
    if let Some(why) = &o.reason {
        let first = o.failing.first().map_or(String::new(), |p| {
            format!(
                "; first failing pixel ({}, {}): {}{}",
                p.x,
                p.y,
                p.tier,
                p.nearest_edge_px
                    .map_or(String::new(), |d| format!(", {d:.3} px from an edge"))
            )
        });
        anyhow::bail!(
            "{what} does not match {} in {} mode: {why}{first}",
            a.reference.display(),
            o.mode
        );
    }
    Ok(())
}
