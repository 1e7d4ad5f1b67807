//! `terraclip merge`: joins the JSON of a sweep's shards (`--shard i/N` of
//! `cracks`, `golden`, `check-gpu`, `tradeoff`, `fly` or `export`) into
//! what one run of the sweep prints, and with `--dir` writes the files
//! only the whole sweep has.

use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Each shard's `--json` output, one file per shard.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// Also write the merged JSON here.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Write the files one run writes into this folder: tradeoff's CSV and
    /// charts, fly's charts, or the joined export folder (which an
    /// export's merge needs).
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// (The merged JSON is printed either way.)
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let mut parts = vec![];
    for p in &a.parts {
        let bytes = std::fs::read(p).map_err(|e| terraclip::Error::io(p, e))?;
        let v: serde_json::Value =
            serde_json::from_slice(&bytes).map_err(|e| terraclip::Error::BadFile {
                path: p.clone(),
                reason: format!("not one JSON object: {e}"),
            })?;
        parts.push((p.display().to_string(), v));
    }
    let merged = terraclip::studies::merge::merge(&parts, a.dir.as_deref())?;
    if let Some(out) = &a.out {
        terraclip::error::write_atomic(out, format!("{merged}\n").as_bytes())?;
    }
    println!("{merged}");
    Ok(())
}
