//! The `terraclip` command line: argument handling and printing only.

use clap::{Parser, Subcommand};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;
use terraclip::render::{self, RenderOptions};
use terraclip::scene::{Overrides, Scene};
use terraclip::terrain::Heightmap;

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

/// `terraclip scaling`'s settings.
#[derive(clap::Args, Debug)]
struct ScalingArgs {
    /// Scene whose camera, shading and seed are used; the embedded default
    /// scene if omitted.
    scene: Option<PathBuf>,
    /// Square terrain sizes in texels per side, comma-separated, smallest
    /// first.
    #[arg(long, default_value = "1024,2048,4096,16384", value_delimiter = ',')]
    sizes: Vec<usize>,
    /// Clipmap n and levels of the size test.
    #[arg(long, default_value_t = 127)]
    n: i64,
    #[arg(long, default_value_t = 3)]
    levels: usize,
    /// Frames per size (median reported).
    #[arg(long, default_value_t = 40)]
    frames: usize,
    /// Largest size brute force renders.
    #[arg(long, default_value_t = 2048)]
    brute_max: usize,
    /// n and levels of the incremental-update test (on its own map, wide
    /// enough for that many levels).
    #[arg(long, default_value_t = 255)]
    update_n: i64,
    #[arg(long, default_value_t = 10)]
    update_levels: usize,
    /// Repeats of the update test (medians reported).
    #[arg(long, default_value_t = 5)]
    update_repeats: usize,
    /// n of the lazy first-frame test (largest size, every level).
    #[arg(long, default_value_t = 255)]
    first_n: i64,
    /// Lazy pyramid samples per frame in the first-frame test.
    #[arg(long, default_value_t = terraclip::scene::DEFAULT_LAZY_BUDGET)]
    first_budget: u64,
    #[arg(long)]
    json: bool,
}

impl ScalingArgs {
    fn options(&self) -> terraclip::studies::scaling::Options {
        terraclip::studies::scaling::Options {
            sizes: self.sizes.clone(),
            n: self.n,
            levels: self.levels,
            frames: self.frames,
            brute_max: self.brute_max,
            update_n: self.update_n,
            update_levels: self.update_levels,
            update_repeats: self.update_repeats,
            first_n: self.first_n,
            first_budget: self.first_budget,
            ..Default::default()
        }
    }
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
    /// LOD scheme (clipmap, brute-force, geomipmap, roam, annulus, cdlod).
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
    /// Height of the rendered surface at points and the first hits of rays,
    /// from the very triangles a render of the scene's view draws (LOD,
    /// morph and cell diagonals included). JSON: `points` [{x, y, height}],
    /// `rays` [{origin, dir, t, point}]; null where nothing was drawn.
    Height {
        scene: Option<PathBuf>,
        /// A world point X,Y (repeatable).
        #[arg(long = "at", value_parser = parse_xy, allow_hyphen_values = true)]
        at: Vec<[f64; 2]>,
        /// A ray OX,OY,OZ,DX,DY,DZ (repeatable).
        #[arg(long, value_parser = parse_ray, allow_hyphen_values = true)]
        ray: Vec<[f64; 6]>,
        #[command(flatten)]
        args: SceneArgs,
        #[arg(long)]
        json: bool,
    },
    /// Render scenes on both back ends and compare them pixel for pixel
    /// (exact on the pinned lavapipe, a stated tolerance elsewhere).
    #[cfg(feature = "gpu")]
    CheckGpu {
        /// Scene files; the golden scenes if none.
        scenes: Vec<PathBuf>,
        /// wgpu backend: vulkan or gl.
        #[arg(long, default_value = "vulkan")]
        api: String,
        /// Where the -cpu, -gpu and -diff PNGs go.
        #[arg(long, default_value = "target/check-gpu")]
        out: PathBuf,
        /// Frames along a camera path (1 = the scene's view only).
        #[arg(long, default_value_t = 1)]
        frames: usize,
        /// Camera step per frame along the path, metres.
        #[arg(long, default_value_t = 37.0)]
        step: f64,
        #[arg(long)]
        json: bool,
    },
    /// Frames per second of the CPU rasteriser and the GPU on one scene.
    #[cfg(feature = "gpu")]
    Bench {
        /// Scene file; the embedded default scene if omitted.
        scene: Option<PathBuf>,
        /// Frames per timed repeat.
        #[arg(long, default_value_t = 10)]
        frames: usize,
        /// Repeats; the median is reported.
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Image size WIDTHxHEIGHT.
        #[arg(long, default_value = "1920x1080", value_parser = Overrides::parse_size)]
        size: [u32; 2],
        #[arg(long)]
        json: bool,
    },
    /// Frame time against terrain size (clipmap and brute force), pyramid
    /// build time, incremental update against full rebuild, and peak memory,
    /// on procedural terrains.
    Scaling(ScalingArgs),
    /// Print a heightmap's size, height range, no-data count and format.
    Info {
        heightmap: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Count crack pixels (background enclosed by terrain that brute force
    /// covers) from random views, for one or more LOD schemes.
    Cracks {
        /// Scene file; the embedded default scene if omitted.
        scene: Option<PathBuf>,
        /// Random views above the terrain.
        #[arg(long, default_value_t = 100)]
        views: usize,
        /// Scheme(s): NAME, clipmap/LAYOUT, a comma-separated list, or
        /// "all"; the scene's own scheme if omitted.
        #[arg(long)]
        lod: Option<String>,
        /// Image size WIDTHxHEIGHT.
        #[arg(long, default_value = "160x100", value_parser = Overrides::parse_size)]
        size: [u32; 2],
        /// Exit non-zero if any crack pixel is found.
        #[arg(long)]
        strict: bool,
        /// Write each scheme's worst view (and its brute-force reference)
        /// as PNGs here.
        #[arg(long)]
        out: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// Error against brute force and time for every LOD scheme and
    /// setting, on ATLOD's wide and low-FOV views: CSV, SVG and PNG chart.
    Tradeoff {
        /// Scene file; the embedded default scene if omitted.
        scene: Option<PathBuf>,
        #[arg(long, default_value = "target/tradeoff")]
        out: PathBuf,
        /// Scene overrides (--size defaults to 320x180 here).
        #[command(flatten)]
        args: SceneArgs,
        /// Frames along the popping path.
        #[arg(long, default_value_t = 8)]
        path_frames: usize,
        /// Fewer settings per scheme.
        #[arg(long)]
        quick: bool,
        #[arg(long)]
        json: bool,
    },
    /// Fly a straight camera path: frames as PNGs (and a GIF), per-frame
    /// update statistics and popping against brute force.
    Fly {
        /// Scene file; the embedded default scene if omitted.
        scene: Option<PathBuf>,
        #[arg(long, default_value_t = 60)]
        frames: usize,
        /// Metres per frame (forward, plus 0.37× sideways).
        #[arg(long, default_value_t = 5.0)]
        step: f64,
        /// Where frame_NNNN.png go; no images if omitted.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also write OUT/fly.gif.
        #[arg(long)]
        gif: bool,
        /// Skip the brute-force renders popping needs.
        #[arg(long)]
        no_popping: bool,
        #[command(flatten)]
        args: SceneArgs,
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

/// `n` comma-separated finite numbers.
fn parse_numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    let a: [f64; N] = v
        .try_into()
        .map_err(|v: Vec<f64>| format!("need {N} comma-separated numbers, got {}", v.len()))?;
    if a.iter().all(|x| x.is_finite()) {
        Ok(a)
    } else {
        Err("values must be finite".into())
    }
}

fn parse_xy(s: &str) -> Result<[f64; 2], String> {
    parse_numbers::<2>(s)
}

fn parse_ray(s: &str) -> Result<[f64; 6], String> {
    let r = parse_numbers::<6>(s)?;
    if r[3..] == [0.0; 3] {
        return Err("the ray direction must not be zero".into());
    }
    Ok(r)
}

/// The `height` command.
fn height_cmd(
    scene: &Option<PathBuf>,
    at: &[[f64; 2]],
    rays: &[[f64; 6]],
    args: &SceneArgs,
    json: bool,
) -> anyhow::Result<()> {
    use glam::DVec3;
    let mut s = load_scene(scene)?;
    s.apply(&args.overrides())?;
    let mut session = render::Session::new(&s, &mut Default::default())?;
    let surface = session.surface(&s.camera())?;
    let points: Vec<_> = at
        .iter()
        .map(|&[x, y]| json!({"x": x, "y": y, "height": surface.height_at(x, y)}))
        .collect();
    let hits: Vec<_> = rays
        .iter()
        .map(|r| {
            let (o, d) = (DVec3::new(r[0], r[1], r[2]), DVec3::new(r[3], r[4], r[5]));
            let h = surface.ray_hit(o, d);
            json!({"origin": [r[0], r[1], r[2]], "dir": [r[3], r[4], r[5]],
                   "t": h.map(|h| h.t), "point": h.map(|h| h.point.to_array())})
        })
        .collect();
    if json {
        println!("{}", json!({"points": points, "rays": hits}));
    } else {
        for p in &points {
            println!("height at ({}, {}): {}", p["x"], p["y"], p["height"]);
        }
        for h in &hits {
            println!(
                "ray from {} along {}: t = {}, hit {}",
                h["origin"], h["dir"], h["t"], h["point"]
            );
        }
    }
    Ok(())
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
    let (image, stats) = match backend {
        "cpu" => render::render(&s, &RenderOptions::default())?,
        "gpu" => gpu_render(&s)?,
        other => anyhow::bail!("--backend must be cpu or gpu, got '{other}'"),
    };
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

#[cfg(feature = "gpu")]
fn gpu_render(s: &Scene) -> anyhow::Result<(render::Image, render::RenderStats)> {
    use terraclip::check::parity;
    use terraclip::gpu::{Api, Gpu, GpuRenderer};
    let mut r = GpuRenderer::new(Gpu::new(Api::Vulkan)?);
    Ok(parity::render(&mut r, s)?)
}

#[cfg(not(feature = "gpu"))]
fn gpu_render(_: &Scene) -> anyhow::Result<(render::Image, render::RenderStats)> {
    anyhow::bail!("--backend gpu: this build has no wgpu back end (cargo feature 'gpu')")
}

/// Scene paths given on the command line, or the goldens' scenes.
#[cfg(feature = "gpu")]
fn scene_list(scenes: &[PathBuf]) -> anyhow::Result<Vec<(String, Scene)>> {
    let paths = if scenes.is_empty() {
        terraclip::check::golden::scenes(std::path::Path::new("golden"))?
    } else {
        scenes.to_vec()
    };
    paths
        .iter()
        .map(|p| {
            let name = p
                .file_stem()
                .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
            Ok((name, Scene::load(p)?))
        })
        .collect()
}

#[cfg(feature = "gpu")]
fn check_gpu_cmd(
    scenes: &[PathBuf],
    api: &str,
    out: &std::path::Path,
    frames: usize,
    step: f64,
    json: bool,
) -> anyhow::Result<()> {
    use terraclip::check::parity;
    use terraclip::gpu::{Api, Gpu, GpuRenderer};
    let api = Api::parse(api)
        .ok_or_else(|| anyhow::anyhow!("--api must be vulkan or gl, got '{api}'"))?;
    let list = scene_list(scenes)?;
    let gpu = Gpu::new(api)?;
    let exact = gpu.exact_expected();
    let (adapter, driver) = (gpu.adapter(), gpu.info.driver_info.clone());
    let mut r = GpuRenderer::new(gpu);
    let mut results = vec![];
    for (name, scene) in &list {
        let res = parity::check(&mut r, scene, name, frames, step, out, exact)?;
        if !json {
            println!(
                "{:<6} {:<22} {:>3} frame(s)  colour {} px  depth {} px  max channel {}  max depth {} ulp  shifted {} px  unmatched {} px",
                if res.pass { "ok" } else { "FAIL" },
                res.scene,
                res.frames,
                res.colour_px_differ,
                res.depth_px_differ,
                res.max_channel_diff,
                res.max_depth_ulp,
                res.shifted_px,
                res.unmatched_px
            );
        }
        results.push(res);
    }
    let mode = if exact { "exact" } else { "tolerance" };
    if json {
        println!(
            "{}",
            json!({"adapter": adapter, "driver_info": driver, "exact_expected": exact,
                   "mode": mode, "scenes": results})
        );
    } else {
        println!(
            "adapter {adapter}, driver {driver}: {mode} mode; images in {}",
            out.display()
        );
    }
    let failed = results.iter().filter(|r| !r.pass).count();
    if failed > 0 {
        anyhow::bail!("{failed} scene(s) differ between the CPU and GPU back ends ({mode} mode)");
    }
    Ok(())
}

#[cfg(feature = "gpu")]
fn bench_cmd(
    scene: &Option<PathBuf>,
    frames: usize,
    repeats: usize,
    size: [u32; 2],
    json: bool,
) -> anyhow::Result<()> {
    use terraclip::check::parity;
    use terraclip::gpu::{Api, Gpu, GpuRenderer};
    if frames == 0 || repeats == 0 {
        anyhow::bail!("--frames and --repeats must be at least 1");
    }
    let mut s = load_scene(scene)?;
    s.apply(&terraclip::scene::Overrides {
        size: Some(size),
        ..Default::default()
    })?;
    let mut r = GpuRenderer::new(Gpu::new(Api::Vulkan)?);
    let b = parity::bench(&mut r, &s, frames, repeats)?;
    if json {
        println!("{}", serde_json::to_value(&b)?);
    } else {
        println!(
            "{}×{}, {} triangles, median of {} × {} frames: CPU {:.2} fps, GPU ({}) {:.2} fps, ratio {:.2}",
            b.size[0], b.size[1], b.triangles, b.repeats, b.frames, b.cpu_fps, b.adapter, b.gpu_fps, b.ratio
        );
    }
    Ok(())
}

/// A progress bar on stderr (drawn only when stderr is a terminal).
fn progress(len: usize, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len as u64);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta} left)")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_string());
    bar
}

/// "all", a list, or the scene's own scheme.
fn scheme_list(lod: &Option<String>, s: &Scene) -> Vec<String> {
    match lod.as_deref() {
        Some("all") => terraclip::studies::cracks::ALL
            .iter()
            .map(|s| s.to_string())
            .collect(),
        Some(list) => list.split(',').map(|p| p.trim().to_string()).collect(),
        None => vec![s.lod.scheme.clone()],
    }
}

fn cracks_cmd(
    scene: &Option<PathBuf>,
    views: usize,
    lod: &Option<String>,
    size: [u32; 2],
    strict: bool,
    out: Option<&std::path::Path>,
    json: bool,
) -> anyhow::Result<()> {
    if views == 0 {
        anyhow::bail!("--views must be at least 1");
    }
    let s = load_scene(scene)?;
    let schemes = scheme_list(lod, &s);
    let bar = progress(views, "cracks");
    let r = terraclip::studies::cracks::survey(&s, &schemes, views, size, || bar.inc(1))?;
    bar.finish_and_clear();
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).map_err(|e| terraclip::Error::io(dir, e))?;
        for c in &r.schemes {
            if let Some((img, reference)) = &c.worst_images {
                let name = c.lod.replace('/', "-");
                let write = |suffix: &str, i: &render::Image| -> anyhow::Result<()> {
                    let p = dir.join(format!("{name}-{suffix}.png"));
                    Ok(terraclip::error::write_atomic(&p, &i.png()?)?)
                };
                write("worst", img)?;
                write("brute-force", reference)?;
            }
        }
    }
    if json {
        println!("{}", serde_json::to_value(&r)?);
    } else {
        for c in &r.schemes {
            println!(
                "{:<20} {:>7} crack px in {:>4} of {} views (worst view {}: {} px)",
                c.lod, c.crack_pixels, c.views_with_cracks, r.views, c.worst_view, c.worst_pixels
            );
        }
    }
    if strict && r.crack_pixels > 0 {
        anyhow::bail!("{} crack pixels found", r.crack_pixels);
    }
    Ok(())
}

fn scaling_cmd(args: &ScalingArgs) -> anyhow::Result<()> {
    use terraclip::studies::scaling;
    let s = load_scene(&args.scene)?;
    let opts = args.options();
    let bar = progress(0, "scaling");
    let r = scaling::run(&s, &opts, |label| bar.set_message(label.to_string()))?;
    bar.finish_and_clear();
    if args.json {
        println!("{}", serde_json::to_value(&r)?);
        return Ok(());
    }
    let f = &r.first_frame;
    println!(
        "lazy first frame of {}² (n = {}, {} of {} levels drawn, budget {}): {:.0} ms (target < 1000), {} tris, {} of {} pyramid samples built, peak RSS {} MB",
        f.size,
        f.n,
        f.levels_drawn,
        f.levels,
        f.budget,
        f.first_frame_ms,
        f.triangles,
        f.samples_built,
        f.eager_samples,
        f.peak_rss_bytes.map_or("?".into(), |b| (b >> 20).to_string()),
    );
    match (f.frames_to_all_levels, f.all_levels_ms) {
        (Some(n), Some(ms)) => println!("  every level drawn after {n} more frames ({ms:.0} ms)"),
        _ => println!("  not every level drawn within the frame limit"),
    }
    println!("size     terrain    pyramid   clipmap frame   brute-force frame");
    for row in &r.sizes {
        let brute = match (row.brute_frame_ms, row.brute_triangles) {
            (Some(ms), Some(t)) => format!("{ms:9.1} ms ({t} tris)"),
            _ => "-".into(),
        };
        println!(
            "{:>6}²  {:7.0} ms {:7.0} ms {:8.2} ms ({} tris)   {brute}",
            row.size, row.terrain_ms, row.pyramid_ms, row.clipmap_frame_ms, row.clipmap_triangles
        );
    }
    println!(
        "clipmap frame, largest / smallest: {:.3} (target <= 1.05)",
        r.clipmap_ratio
    );
    if let Some(b) = r.brute_ratio {
        println!("brute force frame, largest / smallest it ran on: {b:.2}");
    }
    let u = &r.update;
    println!(
        "full update n={} L={} on a {}-wide map ({} repeats): {:.3} ms after a jump ({:.3} ms on one thread), {:.3} ms for the same window again ({} texels)",
        u.n, u.levels, u.size, u.repeats, u.full_ms, u.full_one_core_ms, u.full_same_window_ms, u.full_texels
    );
    println!(
        "  its map: {} MB, {} MB of them on huge pages",
        u.map_bytes >> 20,
        u.map_huge_page_bytes
            .map_or("?".into(), |b| (b >> 20).to_string())
    );
    for w in &u.walks {
        let each: Vec<String> = w.overheads.iter().map(|o| format!("{o:.2}")).collect();
        println!(
            "  walk {:<10} {:.3} us/frame ({:.0} texels, {:.1} column rows): time ratio {:.5}, texel ratio {:.5}, overhead {:.2} (target <= 1.2; repeats {}), against one thread {:.2}",
            w.direction, w.incremental_ms * 1e3, w.incremental_texels, w.column_rows, w.time_ratio, w.texel_ratio, w.overhead, each.join(" "), w.overhead_one_core
        );
    }
    let m = &r.memory;
    println!(
        "peak RSS {} MB; heightmaps {} MB + pyramids {} MB; ratio {} (target < 2)",
        m.peak_rss_bytes
            .map_or("?".into(), |b| (b >> 20).to_string()),
        m.heightmap_bytes >> 20,
        m.pyramid_bytes >> 20,
        m.ratio.map_or("?".into(), |r| format!("{r:.2}"))
    );
    Ok(())
}

fn tradeoff_cmd(
    scene: &Option<PathBuf>,
    out: &std::path::Path,
    args: &SceneArgs,
    path_frames: usize,
    quick: bool,
    json: bool,
) -> anyhow::Result<()> {
    use terraclip::studies::tradeoff;
    if path_frames < 2 {
        anyhow::bail!("--path-frames must be at least 2");
    }
    let size = args.size.unwrap_or([320, 180]);
    if size[0] == 0 || size[1] == 0 || size[0] > 2048 || size[1] > 2048 {
        anyhow::bail!(
            "--size must be within 1..=2048 per side (64× supersampling multiplies it by 8)"
        );
    }
    let mut s = load_scene(scene)?;
    s.apply(&args.overrides())?;
    let opts = tradeoff::Options {
        size,
        path_frames,
        quick,
    };
    let count = tradeoff::settings(&s, quick)?.len();
    let bar = progress(count, "tradeoff");
    let report = tradeoff::run(&s, &opts, |label| {
        bar.set_message(label.to_string());
        bar.inc(1);
    })?;
    bar.finish_and_clear();
    let title = match &args.heightmap {
        Some(h) => format!("{} at {}x{}", h.display(), size[0], size[1]),
        None => format!("{} at {}x{}", s.origin, size[0], size[1]),
    };
    tradeoff::write(&report, out, &title)?;
    if json {
        println!("{}", serde_json::to_value(&report)?);
    } else {
        println!(
            "{:<12} {:<26} {:>9} {:>8} {:>4} {:>9} {:>10} {:>8}",
            "lod", "config", "ms", "rmse", "max", "depth m", "triangles", "popping"
        );
        for r in &report.rows {
            println!(
                "{:<12} {:<26} {:>9.2} {:>8.3} {:>4} {:>9.2} {:>10.0} {:>8.3}{}",
                r.lod,
                r.config,
                r.ms,
                r.rmse,
                r.max_abs,
                r.depth_m,
                r.triangles,
                r.popping,
                if r.pareto { "  *" } else { "" }
            );
        }
        match &report.best_in_budget {
            Some(b) => println!(
                "within 1/10 of brute force ({:.2} ms): {} {} has the lowest RMSE, {:.3}",
                report.budget_ms, b.lod, b.config, b.rmse
            ),
            None => println!(
                "no setting ran within 1/10 of brute force ({:.2} ms)",
                report.budget_ms
            ),
        }
        println!("wrote {}/tradeoff.{{csv,svg,png}}", out.display());
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn fly_cmd(
    scene: &Option<PathBuf>,
    frames: usize,
    step: f64,
    out: Option<&std::path::Path>,
    gif: bool,
    no_popping: bool,
    args: &SceneArgs,
    json: bool,
) -> anyhow::Result<()> {
    if frames == 0 || frames > 100_000 {
        anyhow::bail!("--frames must be within 1..=100000, got {frames}");
    }
    if !step.is_finite() {
        anyhow::bail!("--step must be finite");
    }
    if gif && out.is_none() {
        anyhow::bail!("--gif needs --out DIR");
    }
    let mut s = load_scene(scene)?;
    s.apply(&args.overrides())?;
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).map_err(|e| terraclip::Error::io(dir, e))?;
    }
    let bar = progress(frames, "fly");
    let mut kept = Vec::new();
    let report = terraclip::studies::fly::fly(&s, frames, step, !no_popping, |i, img| {
        bar.inc(1);
        if let Some(dir) = out {
            terraclip::error::write_atomic(&dir.join(format!("frame_{i:04}.png")), &img.png()?)?;
            if gif {
                kept.push(img.clone());
            }
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    if let (Some(dir), true) = (out, gif) {
        terraclip::error::write_atomic(
            &dir.join("fly.gif"),
            &terraclip::studies::fly::gif(&kept)?,
        )?;
    }
    if json {
        println!("{}", serde_json::to_value(&report)?);
    } else {
        println!(
            "{} frames of {}: mean update {:.3} ms, {} texels rewritten, popping max {:.3}",
            report.frames.len(),
            report.lod,
            report.mean_update_ms,
            report.texels_updated,
            report.popping_max
        );
    }
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<()> {
    terraclip::raster::Path::check_env().map_err(anyhow::Error::msg)?;
    match cli.cmd {
        Some(Cmd::Golden {
            dir,
            bless,
            diff_dir,
            json,
        }) => {
            let results = terraclip::check::golden::check(&dir, bless, Some(&diff_dir))?;
            if json {
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
        #[cfg(feature = "gpu")]
        Some(Cmd::CheckGpu {
            scenes,
            api,
            out,
            frames,
            step,
            json,
        }) => check_gpu_cmd(&scenes, &api, &out, frames, step, json)?,
        #[cfg(feature = "gpu")]
        Some(Cmd::Bench {
            scene,
            frames,
            repeats,
            size,
            json,
        }) => bench_cmd(&scene, frames, repeats, size, json)?,
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
        Some(Cmd::Cracks {
            scene,
            views,
            lod,
            size,
            strict,
            out,
            json,
        }) => cracks_cmd(&scene, views, &lod, size, strict, out.as_deref(), json)?,
        Some(Cmd::Scaling(args)) => scaling_cmd(&args)?,
        Some(Cmd::Tradeoff {
            scene,
            out,
            args,
            path_frames,
            quick,
            json,
        }) => tradeoff_cmd(&scene, &out, &args, path_frames, quick, json)?,
        Some(Cmd::Fly {
            scene,
            frames,
            step,
            out,
            gif,
            no_popping,
            args,
            json,
        }) => fly_cmd(
            &scene,
            frames,
            step,
            out.as_deref(),
            gif,
            no_popping,
            &args,
            json,
        )?,
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
            let png = terraclip::studies::diagram::draw(&cm, Some((&cam, &world)), size)?;
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
        Some(Cmd::Height {
            scene,
            at,
            ray,
            args,
            json,
        }) => height_cmd(&scene, &at, &ray, &args, json)?,
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
