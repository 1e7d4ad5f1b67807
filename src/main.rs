//! The `terraclip` command line. Each command's arguments and printing are
//! in `cli/`, one file per command; this file only dispatches.

mod cli;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

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
    /// Check the golden images (0 pixels may differ); --bless rewrites them.
    Golden(cli::golden::Args),
    /// Render a scene (the embedded default scene if none is given).
    Render(cli::render::Args),
    /// Height of the rendered surface at points and the first hits of rays,
    /// from the very triangles a render of the scene's view draws (LOD,
    /// morph and cell diagonals included). JSON: `points` [{x, y, height}],
    /// `rays` [{origin, dir, t, point}]; null where nothing was drawn.
    Height(cli::height::Args),
    /// Render scenes on both back ends and compare them pixel for pixel
    /// (exact on the pinned lavapipe, a stated tolerance elsewhere).
    #[cfg(feature = "gpu")]
    CheckGpu(cli::check_gpu::Args),
    /// Frames per second of the CPU rasteriser and the GPU on one scene.
    #[cfg(feature = "gpu")]
    Bench(cli::bench::Args),
    /// Frame time against terrain size (clipmap and brute force), pyramid
    /// build time, incremental update against full rebuild, and peak memory,
    /// on procedural terrains.
    Scaling(cli::scaling::Args),
    /// Print a heightmap's size, height range, no-data count and format, or
    /// what a pack holds.
    Info(cli::info::Args),
    /// Pack a heightmap (or a scene's terrain) into a compressed residual
    /// pyramid, every sample of every level within --max-error metres.
    Pack(cli::pack::Args),
    /// Write a pack's level (or a window of it) back out as .f32 + sidecar,
    /// .tif or 16-bit .png + sidecar.
    Unpack(cli::unpack::Args),
    /// Count crack pixels (background enclosed by terrain that brute force
    /// covers) from random views, for one or more LOD schemes.
    Cracks(cli::cracks::Args),
    /// Error against brute force and time for every LOD scheme and
    /// setting, on ATLOD's wide and low-FOV views: CSV, SVG and PNG chart.
    Tradeoff(cli::tradeoff::Args),
    /// Fly a straight camera path: frames as PNGs (and a GIF), per-frame
    /// update statistics and popping against brute force.
    Fly(cli::fly::Args),
    /// Draw a top-down map of the clipmap levels and regions.
    Diagram(cli::diagram::Args),
    /// Decimate a map 2× or 4× by its pyramid, synthesise it back down
    /// (subdivision plus noise) and compare its statistics with the real
    /// map's: variogram slope, slope distribution (KS), RMSE.
    Synthesis(cli::synthesis::Args),
    /// Write a frame (or a path of frames) for other renderers: triangles
    /// as glTF binary, camera, reference colour (PNG) and depth (EXR and
    /// raw f32), clipmap toroids, a manifest of hashes.
    Export(cli::export::Args),
    /// Compare another renderer's image (and depth) of an exported frame
    /// with the reference: exact, tiered or FLIP; non-zero exit on failure.
    Compare(cli::compare::Args),
    /// Join the JSON of a sweep's shards (`--shard i/N` of `golden`,
    /// `check-gpu`, `cracks`, `tradeoff`, `fly` or `export`) into what one
    /// run prints.
    Merge(cli::merge::Args),
}

fn run(cli: Cli) -> anyhow::Result<()> {
    terraclip::raster::Path::check_env().map_err(anyhow::Error::msg)?;
    match cli.cmd {
        Some(Cmd::Golden(a)) => cli::golden::run(&a),
        Some(Cmd::Render(a)) => cli::render::run(&a),
        Some(Cmd::Height(a)) => cli::height::run(&a),
        #[cfg(feature = "gpu")]
        Some(Cmd::CheckGpu(a)) => cli::check_gpu::run(&a),
        #[cfg(feature = "gpu")]
        Some(Cmd::Bench(a)) => cli::bench::run(&a),
        Some(Cmd::Scaling(a)) => cli::scaling::run(&a),
        Some(Cmd::Info(a)) => cli::info::run(&a),
        Some(Cmd::Pack(a)) => cli::pack::run(&a),
        Some(Cmd::Unpack(a)) => cli::unpack::run(&a),
        Some(Cmd::Cracks(a)) => cli::cracks::run(&a),
        Some(Cmd::Tradeoff(a)) => cli::tradeoff::run(&a),
        Some(Cmd::Fly(a)) => cli::fly::run(&a),
        Some(Cmd::Synthesis(a)) => cli::synthesis::run(&a),
        Some(Cmd::Diagram(a)) => cli::diagram::run(&a),
        Some(Cmd::Export(a)) => cli::export::run(&a),
        Some(Cmd::Compare(a)) => cli::compare::run(&a),
        Some(Cmd::Merge(a)) => cli::merge::run(&a),
        // The main job: render the embedded default scene.
        None => cli::render::run(&cli::render::Args::main_job()),
    }
}

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing into a closed pipe (`| head`) would
    // panic; restore the default so the process ends quietly, as Unix
    // tools do.
    #[cfg(unix)]
    // SAFETY: resetting one signal's disposition at start-up, before any
    // thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // Frame buffers (depth, triangle ids, colour: 8 MB each at 1080p) are
    // freed and allocated again every frame. By default glibc maps each from
    // the kernel and gives it back, so every frame pays ~6,000 page faults
    // and the zeroing of 24 MB; keeping freed memory in the heap reuses it.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: allocator tuning at start-up, before any thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 512 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("terraclip: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
