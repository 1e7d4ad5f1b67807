//! `terraclip golden`: the golden scenes against their references.

use serde_json::json;
use std::path::PathBuf;

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
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let results = terraclip::check::golden::check(&a.dir, a.bless, Some(&a.diff_dir))?;
    if a.json {
        println!("{}", json!({ "scenes": results }));
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
    let failed = results.iter().filter(|r| !r.pass).count();
    if failed > 0 {
        anyhow::bail!(
            "{failed} golden scene(s) differ; images in {}",
            a.diff_dir.display()
        );
    }
    Ok(())
}
