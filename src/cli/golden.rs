//! `terraclip golden`: the golden scenes against their references.

use serde_json::json;
use std::path::PathBuf;
use terraclip::studies::shard::{self, Shard};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder of <name>.toml scenes and <name>.png references.
    #[arg(default_value = "golden")]
    pub dir: PathBuf,
    #[arg(long)]
    pub bless: bool,
    /// Where to write -actual and -diff images of failing scenes.
    #[arg(long, default_value = "target/golden-diff")]
    pub diff_dir: PathBuf,
    /// Also write a conformance pack here: every scene exported (as
    /// `export` writes a frame), a README for its users, a manifest.
    #[arg(long)]
    pub export: Option<PathBuf>,
    /// Check part i of N of the scenes (`merge` joins the parts' JSON).
    #[arg(long, value_parser = Shard::parse, default_value = "0/1", allow_hyphen_values = true)]
    pub shard: Shard,
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    if a.export.is_some() && !a.shard.is_whole() {
        anyhow::bail!("--export writes one pack of every scene: it does not take --shard");
    }
    let results = terraclip::check::golden::check(&a.dir, a.bless, Some(&a.diff_dir), a.shard)?;
    let failed = results.iter().filter(|r| !r.pass).count();
    // A pack is made only from goldens that hold.
    let pack = match &a.export {
        Some(out) if failed == 0 => Some(terraclip::export::conformance_pack(&a.dir, out)?),
        _ => None,
    };
    if a.json {
        let v = json!({ "scenes": results, "export": pack });
        let of = a.dir.display().to_string();
        println!("{}", shard::tag(v, "golden", a.shard, &of));
    } else {
        for r in &results {
            let state = match (r.pass, r.blessed) {
                (_, true) => "blessed",
                (true, _) => "ok",
                _ => "FAIL",
            };
            let depth = if r.depth_pass { "same" } else { "DIFFERS" };
            println!(
                "{:<8} {:<22} {} px differ, depth {depth}",
                state, r.scene, r.px_differ
            );
        }
    }
    if let (Some(p), false) = (&pack, a.json) {
        println!(
            "wrote the conformance pack {} ({} scenes, {} files, {} bytes)",
            p.dir.display(),
            p.scenes.len(),
            p.files,
            p.bytes
        );
    }
    if failed > 0 {
        anyhow::bail!(
            "{failed} golden scene(s) differ; images in {}",
            a.diff_dir.display()
        );
    }
    Ok(())
}
