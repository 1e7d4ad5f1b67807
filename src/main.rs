//! The `terraclip` command line: argument handling and printing only.

use clap::{Parser, Subcommand};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;
use terraclip::heightmap::Heightmap;
use terraclip::render::{self, RenderOptions};
use terraclip::scene::{Overrides, Scene};

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

/// Scene values the command line can replace.
#[derive(clap::Args, Debug, Default)]
struct SceneArgs {
    /// Heightmap file instead of the scene's terrain.
    #[arg(long)]
    heightmap: Option<PathBuf>,
    /// Camera position X,Y,Z (metres).
    #[arg(long, value_parser = Overrides::parse_xyz, allow_hyphen_values = true)]
    camera: Option<[f64; 3]>,
    /// Point to look at X,Y,Z (metres).
    #[arg(long, value_parser = Overrides::parse_xyz, allow_hyphen_values = true)]
    look_at: Option<[f64; 3]>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    fov: Option<f64>,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, value_parser = Overrides::parse_size)]
    size: Option<[u32; 2]>,
    /// LOD scheme (clipmap, brute-force).
    #[arg(long)]
    lod: Option<String>,
    /// Comma-separated effects (empty for none).
    #[arg(long)]
    effects: Option<String>,
}

impl SceneArgs {
    fn overrides(&self) -> Overrides {
        Overrides {
            heightmap: self.heightmap.clone(),
            camera: self.camera,
            look_at: self.look_at,
            fov: self.fov,
            size: self.size,
            lod: self.lod.clone(),
            effects: self.effects.as_ref().map(|e| {
                e.split(',')
                    .map(|s| s.trim().to_string())
                    .filter(|s| !s.is_empty())
                    .collect()
            }),
        }
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Check the golden images (0 pixels may differ); --bless rewrites them.
    Golden {
        /// Folder of <name>.toml scenes and <name>.png references.
        #[arg(default_value = "golden")]
        dir: PathBuf,
        #[arg(long)]
        bless: bool,
        /// Where to write -actual and -diff images of failing scenes.
        #[arg(long, default_value = "target/golden-diff")]
        diff_dir: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// Render a scene (the embedded default scene if none is given).
    Render {
        scene: Option<PathBuf>,
        #[arg(short, long, default_value = "terraclip.png")]
        out: PathBuf,
        /// Back end: cpu (the reference) or gpu.
        #[arg(long, default_value = "cpu")]
        backend: String,
        #[command(flatten)]
        args: SceneArgs,
        #[arg(long)]
        json: bool,
    },
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

/// Renders `scene` to `out` and prints its statistics.
fn render_cmd(
    scene: &Option<PathBuf>,
    out: &std::path::Path,
    backend: &str,
    args: &SceneArgs,
    json: bool,
) -> anyhow::Result<()> {
    let mut s = load_scene(scene)?;
    s.apply(&args.overrides())?;
    match backend {
        "cpu" => {}
        "gpu" => anyhow::bail!("--backend gpu: the wgpu back end is not built yet; use cpu"),
        other => anyhow::bail!("--backend must be cpu or gpu, got '{other}'"),
    }
    let (image, stats) = render::render(&s, &RenderOptions::default())?;
    terraclip::error::write_atomic(out, &image.png()?)?;
    let mut v = serde_json::to_value(&stats)?;
    v["output"] = json!(out);
    if json {
        println!("{v}");
    } else {
        println!(
            "wrote {} ({}×{}, {} {} triangles, {:.1} ms)",
            out.display(),
            stats.width,
            stats.height,
            stats.triangles,
            stats.lod,
            stats.ms_total
        );
        for p in &stats.passes {
            println!("  {:<11} {:>9.2} ms", p.name, p.ms);
        }
        if stats.non_finite_vertices > 0 {
            println!(
                "  {} non-finite vertices dropped",
                stats.non_finite_vertices
            );
        }
    }
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.cmd {
        Some(Cmd::Golden {
            dir,
            bless,
            diff_dir,
            json,
        }) => {
            let results = terraclip::golden::check(&dir, bless, Some(&diff_dir))?;
            if json {
                println!("{}", json!({ "scenes": results }));
            } else {
                for r in &results {
                    let state = match (r.pass, r.blessed) {
                        (_, true) => "blessed",
                        (true, _) => "ok",
                        _ => "FAIL",
                    };
                    println!("{:<8} {:<22} {} px differ", state, r.scene, r.px_differ);
                }
            }
            let failed = results.iter().filter(|r| !r.pass).count();
            if failed > 0 {
                anyhow::bail!(
                    "{failed} golden scene(s) differ; images in {}",
                    diff_dir.display()
                );
            }
        }
        Some(Cmd::Render {
            scene,
            out,
            backend,
            args,
            json,
        }) => render_cmd(&scene, &out, &backend, &args, json)?,
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
            // The main job: render the embedded default scene.
            render_cmd(
                &None,
                std::path::Path::new("terraclip.png"),
                "cpu",
                &SceneArgs::default(),
                false,
            )?;
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
