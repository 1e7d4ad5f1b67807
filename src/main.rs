//! The `terraclip` command line: argument handling and printing only.

use clap::{Parser, Subcommand};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;
use terraclip::heightmap::Heightmap;
use terraclip::scene::Scene;

#[derive(Parser)]
#[command(
    name = "terraclip",
    version,
    about = "CPU reference geometry-clipmap terrain renderer"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Option<Cmd>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Print a heightmap's size, height range, no-data count and format.
    Info {
        heightmap: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Draw a top-down map of the clipmap levels and regions.
    Diagram {
        /// Scene file; the embedded default scene if omitted.
        scene: Option<PathBuf>,
        #[arg(short, long, default_value = "diagram.png")]
        out: PathBuf,
        /// Image side in pixels.
        #[arg(long, default_value_t = 800)]
        size: u32,
        #[arg(long)]
        json: bool,
    },
}

fn load_scene(path: &Option<PathBuf>) -> terraclip::Result<Scene> {
    match path {
        Some(p) => Scene::load(p),
        None => Ok(Scene::default_scene()),
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.cmd {
        Some(Cmd::Info { heightmap, json }) => {
            let h = Heightmap::load(&heightmap)?;
            let (min, max) = h.min_max();
            let v = json!({
                "width": h.width(), "height": h.height(), "min": min, "max": max,
                "nodata_count": h.nodata_count(), "format": h.format,
                "cell_size": h.cell_size,
            });
            if json {
                println!("{v}");
            } else {
                println!(
                    "{}: {}×{} {}, heights {min}..{max} m, {} no-data, cell {:?} m",
                    heightmap.display(),
                    h.width(),
                    h.height(),
                    h.format,
                    h.nodata_count(),
                    h.cell_size
                );
            }
        }
        Some(Cmd::Diagram {
            scene,
            out,
            size,
            json,
        }) => {
            if size == 0 || size > 16384 {
                anyhow::bail!("--size must be within 1..=16384, got {size}");
            }
            let s = load_scene(&scene)?;
            let (_, cm, world) = s.build_clipmap()?;
            let cam = s.camera();
            let png = terraclip::diagram::draw(&cm, Some((&cam, &world)), size)?;
            terraclip::error::write_atomic(&out, &png)?;
            let active = cm.levels().iter().filter(|l| l.is_active()).count();
            if json {
                println!(
                    "{}",
                    json!({"output": out, "levels": cm.levels().len(), "active_levels": active, "n": cm.n()})
                );
            } else {
                println!(
                    "wrote {} ({} levels, {active} active, n = {})",
                    out.display(),
                    cm.levels().len(),
                    cm.n()
                );
            }
        }
        None => {
            // The main job until rendering lands: the default scene's clipmap.
            let s = Scene::default_scene();
            let (h, cm, _) = s.build_clipmap()?;
            let out = PathBuf::from("terraclip-diagram.png");
            let png = terraclip::diagram::draw(&cm, None, 800)?;
            terraclip::error::write_atomic(&out, &png)?;
            println!(
                "default scene: {}×{} procedural terrain, {} levels of n = {}; wrote {}",
                h.width(),
                h.height(),
                cm.levels().len(),
                cm.n(),
                out.display()
            );
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("terraclip: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
