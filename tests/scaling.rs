//! Frame work does not depend on terrain size for clipmaps, and does for
//! brute force; the scaling report's exact figures.

use terraclip::frame::stats::Passes;
use terraclip::render::{RenderOptions, Session};
use terraclip::scene::Scene;
use terraclip::studies::scaling::{self, Options};
use terraclip::terrain::procedural::Procedural;

/// The JSON a `terraclip … --json` run printed, which must have succeeded.
fn ok_json(out: std::process::Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The default scene over a procedural `size`² map, eye over its centre.
fn scene(size: usize, lod: &str) -> Scene {
    let mut s = Scene::bench_scene();
    s.terrain.procedural = Some(Procedural::new(20041, size, size));
    s.lod.scheme = lod.parse().unwrap();
    s.lod.n = 63;
    s.lod.levels = Some(3);
    s.image.width = 160;
    s.image.height = 90;
    // 256 texels of 10 m: the centre of the smallest map below.
    s.camera.position = [2560.0, -2560.0, 600.0];
    s.camera.look_at = Some([3300.0, -3400.0, 100.0]);
    s
}

fn render(s: &Scene) -> (terraclip::render::Image, usize) {
    let mut session = Session::new(s, &mut Passes::default()).unwrap();
    let (img, stats) = session
        .render(&s.camera(), &RenderOptions::default(), Passes::default())
        .unwrap();
    (img, stats.triangles)
}

/// The same view of 512² and 2048² maps: a clipmap draws the very same
/// triangles and depths (its levels cover the same ground, and the pyramid
/// there does not depend on what lies beyond), while brute force draws
/// every cell of the bigger map.
#[test]
fn clipmap_frames_are_identical_across_terrain_sizes() {
    let (small, t_small) = render(&scene(512, "clipmap"));
    let (large, t_large) = render(&scene(2048, "clipmap"));
    assert!(t_small > 1000, "the view sees terrain: {t_small} triangles");
    assert_eq!(t_small, t_large, "triangles");
    // Colour is not compared: the height-ramp albedo is normalised by the
    // whole map's height range, a property of the scene, not of the frame.
    let bits = |d: &[f32]| d.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&small.depth), bits(&large.depth), "depth differs");

    let (_, b_small) = render(&scene(256, "brute-force"));
    let (_, b_large) = render(&scene(512, "brute-force"));
    assert!(
        b_large > 3 * b_small,
        "brute force grows with the map: {b_small} -> {b_large}"
    );
}

/// `packs` times packs in place of the procedural sizes (which it then
/// ignores), with frames interleaved the same way: lossless packs of the
/// 256² and 512² maps draw what those maps draw, and brute force does not
/// run on them.
#[test]
fn scaling_times_packs_in_place_of_sizes() {
    use terraclip::pack::stream;
    use terraclip::pyramid::Filter;
    use terraclip::terrain::rows::ProceduralRows;
    let dir = std::env::temp_dir().join(format!("terraclip-scaling-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut packs = vec![];
    for size in [256, 512] {
        let path = dir.join(format!("p{size}.tcz"));
        let o = stream::Options::new(0.0, 64, Filter::default(), "scaling");
        let src = ProceduralRows::new(Procedural::new(20041, size, size)).unwrap();
        stream::pack(&src, &path, &o, &mut |_, _| {}).unwrap();
        packs.push(path);
    }
    let mut opts = figures_options();
    let mut base = Scene::bench_scene();
    base.camera.position = [1280.0, -1280.0, 500.0];
    base.camera.look_at = Some([1800.0, -1900.0, 100.0]);
    let maps = scaling::run(&base, &opts, |_| {}).unwrap();
    (opts.sizes, opts.packs) = (vec![1024, 2048], packs);
    let r = scaling::run(&base, &opts, |_| {}).unwrap();
    let sizes: Vec<usize> = r.sizes.iter().map(|s| s.size).collect();
    assert_eq!(sizes, [256, 512]);
    for (p, m) in r.sizes.iter().zip(&maps.sizes) {
        assert_eq!(p.clipmap_triangles, m.clipmap_triangles);
        assert_eq!((p.brute_frame_ms, p.brute_triangles), (None, None));
    }
    opts.packs = vec![dir.join("missing.tcz")];
    let e = scaling::run(&base, &opts, |_| {}).unwrap_err().to_string();
    assert!(e.contains("missing.tcz"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

fn figures_options() -> Options {
    Options {
        sizes: vec![256, 512],
        packs: vec![],
        n: 31,
        levels: 3,
        frames: 2,
        brute_max: 512,
        update_n: 31,
        update_levels: 4,
        update_repeats: 3,
        image: [96, 54],
        first_n: 31,
        first_budget: 20_000,
        first_max_frames: 200,
    }
}

/// The report's exact figures: a full rebuild writes L·n² texels, a walk of
/// one texel per frame far fewer; clipmap triangles equal across sizes.
#[test]
fn scaling_report_figures() {
    let opts = figures_options();
    let mut base = Scene::bench_scene();
    base.camera.position = [1280.0, -1280.0, 500.0];
    base.camera.look_at = Some([1800.0, -1900.0, 100.0]);
    let r = scaling::run(&base, &opts, |_| {}).unwrap();
    assert_eq!(r.sizes.len(), 2);
    assert_eq!(r.sizes[0].clipmap_triangles, r.sizes[1].clipmap_triangles);
    assert!(r.sizes[0].clipmap_triangles > 0);
    let (b0, b1) = (
        r.sizes[0].brute_triangles.unwrap(),
        r.sizes[1].brute_triangles.unwrap(),
    );
    assert!(b1 > 3 * b0, "brute force: {b0} -> {b1}");
    assert_eq!(r.update.full_texels, 4 * 31 * 31);
    // Heights (4 bytes) and no-data (1 byte) of every level of the map.
    let map = scaling::update_map(31, 4).unwrap();
    let bytes: u64 = map
        .levels
        .iter()
        .map(|l| (l.width * l.height * 5) as u64)
        .sum();
    assert_eq!(r.update.map_bytes, bytes);
    assert!(r.update.full_ms > 0.0 && r.update.full_same_window_ms > 0.0);
    assert!(r.update.full_one_core_ms > 0.0);
    assert_eq!((r.update.repeats, r.update.walks.len()), (3, 3));
    let dirs: Vec<_> = r.update.walks.iter().map(|w| w.direction).collect();
    assert_eq!(dirs, ["east", "south", "south-east"]);
    // Rows write no columns, so copy no column blocks; the other walks do.
    let rows: Vec<_> = r.update.walks.iter().map(|w| w.column_rows).collect();
    assert!(rows[0] > 0.0 && rows[1] == 0.0 && rows[2] > 0.0, "{rows:?}");
    for w in &r.update.walks {
        assert_eq!(w.frames, 32);
        assert_eq!(w.overheads.len(), 3);
        assert!(
            w.overheads.contains(&w.overhead),
            "the median is one of them"
        );
        assert!(w.overhead_one_core > 0.0);
        assert!(w.incremental_texels > 0.0);
        assert!(w.texel_ratio < 0.2, "{}", w.texel_ratio);
    }
    assert!(r.memory.heightmap_bytes == (256 * 256 + 512 * 512) * 5);
    if cfg!(target_os = "linux") {
        assert!(r.memory.peak_rss_bytes.unwrap() > 0);
    }
    // The memory ratio itself is checked in its own process below: this
    // one's peak includes the other tests' running beside it.
    // The lazy first frame of the 512² map: every level n = 31 allows
    // (`region::max_levels`: 7), the coarser ones deferred by the small
    // budget and drawn within the frame limit; part of the pyramid built
    // at first.
    let f = &r.first_frame;
    assert_eq!((f.size, f.n, f.levels), (512, 31, 7));
    assert!(f.levels_drawn >= 1 && f.levels_drawn < f.levels, "{f:?}");
    assert!(f.samples_built < f.eager_samples, "{f:?}");
    let all: u64 = [512u64, 256, 128, 64, 32, 16, 8]
        .iter()
        .map(|s| s * s)
        .sum();
    assert_eq!(f.eager_samples, all);
    assert!(f.frames_to_all_levels.is_some_and(|n| n >= 1), "{f:?}");
}

/// Bad settings are errors that name the setting, found before any map is
/// built.
#[test]
fn bad_scaling_options_are_errors() {
    let ok = Options {
        sizes: vec![256],
        packs: vec![],
        n: 31,
        levels: 3,
        frames: 1,
        brute_max: 0,
        update_n: 31,
        update_levels: 4,
        update_repeats: 1,
        image: [32, 18],
        first_n: 31,
        first_budget: 1000,
        first_max_frames: 5,
    };
    let cases = [
        (
            Options {
                frames: 0,
                ..ok.clone()
            },
            "frame",
        ),
        (
            Options {
                sizes: vec![],
                ..ok.clone()
            },
            "size",
        ),
        (
            Options {
                update_n: 100,
                ..ok.clone()
            },
            "update_n",
        ),
        (
            Options {
                update_levels: 0,
                ..ok.clone()
            },
            "update_levels",
        ),
        (
            Options {
                update_repeats: 0,
                ..ok.clone()
            },
            "update_repeats",
        ),
        (
            Options {
                update_levels: 20,
                ..ok.clone()
            },
            "exceed",
        ),
        (
            Options {
                sizes: vec![0],
                ..ok.clone()
            },
            "zero",
        ),
        (
            Options {
                n: 100,
                ..ok.clone()
            },
            "lod.n",
        ),
        (
            Options {
                first_n: 100,
                ..ok.clone()
            },
            "lod.n",
        ),
        (
            Options {
                first_budget: 0,
                ..ok.clone()
            },
            "pyramid.budget",
        ),
    ];
    for (opts, word) in cases {
        let err = scaling::run(&Scene::bench_scene(), &opts, |_| {}).unwrap_err();
        assert!(err.to_string().contains(word), "{err} (wanted '{word}')");
    }
}

/// Peak memory while a 2048² map and its pyramid are built stays under
/// twice what they hold (README's memory target), measured in a process
/// of its own, where nothing else inflates the peak: 0.96 on 2026-12-01
/// (46.7 MB against 21.0 MB of map and 27.5 MB of pyramid). The peak must
/// also cover the pyramid, which is alive at the end, so a reading that
/// broke and gave a small number fails too.
#[cfg(target_os = "linux")]
#[test]
fn peak_memory_is_under_twice_the_map_and_pyramid() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
        .args([
            "scaling",
            "--sizes",
            "2048",
            "--n",
            "31",
            "--levels",
            "3",
            "--frames",
            "2",
            "--brute-max",
            "0",
            "--update-n",
            "31",
            "--update-levels",
            "4",
            "--update-repeats",
            "1",
            "--first-n",
            "31",
            "--first-budget",
            "20000",
            "--json",
        ])
        .output()
        .unwrap();
    let v = ok_json(out);
    let m = &v["memory"];
    let (peak, map, pyramid) = (
        m["peak_rss_bytes"].as_f64().unwrap(),
        m["heightmap_bytes"].as_f64().unwrap(),
        m["pyramid_bytes"].as_f64().unwrap(),
    );
    println!(
        "peak {peak} B, map {map} B, pyramid {pyramid} B, ratio {}",
        m["ratio"]
    );
    assert_eq!(map, 2048.0 * 2048.0 * 5.0);
    assert!(peak >= pyramid, "the pyramid is alive at the peak");
    assert!(m["ratio"].as_f64().unwrap() < 2.0, "{m}");
}

/// Peak resident memory of a streaming pack, in a process of its own:
/// what a band holds times the bands resident at once, over the same
/// command's peak on a 65² map (the program, its threads and buffers that
/// do not grow with the map). The bound: a band of the level being coded,
/// its reconstruction, the band of the coarser level it is predicted from
/// and the band being read (4 bands), and one pyramid block's scratch per
/// worker (about 2.5 MB each, `stream::BLOCK`), on 2 workers. A 2049²
/// map (21 MB of samples) at 1 and 2 MiB bands is cut into 20 and 10
/// bands. Measured 2026-12-04 in a debug build on 2 workers: 10.6 MiB
/// for 65², 16.2 MiB at 1 MiB bands (bound 19.4), 19.8 at 2 (bound 23.4).
#[cfg(target_os = "linux")]
#[test]
fn a_streaming_pack_holds_a_few_bands_whatever_the_map() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("pack-rss");
    std::fs::create_dir_all(&dir).unwrap();
    let default = include_str!("../benches/scenes/bench.toml");
    let peak = |side: usize, band_mib: u32| -> f64 {
        let scene = dir.join(format!("p{side}.toml"));
        let text = default.replace(
            "width = 1025, height = 1025",
            &format!("width = {side}, height = {side}"),
        );
        assert_ne!(text, default);
        std::fs::write(&scene, text).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
            .env("RAYON_NUM_THREADS", "2")
            .arg("pack")
            .arg(&scene)
            .arg("-o")
            .arg(dir.join(format!("p{side}.tcz")))
            .args([
                "--max-error",
                "1",
                "--band-mib",
                &band_mib.to_string(),
                "--json",
            ])
            .output()
            .unwrap();
        ok_json(out)["peak_rss_bytes"].as_f64().unwrap()
    };
    let base = peak(65, 1);
    let mib = (1u64 << 20) as f64;
    for band in [1u32, 2] {
        let p = peak(2049, band);
        let bound = base + 4.0 * band as f64 * mib + 2.0 * 2.5e6;
        println!(
            "band {band} MiB: peak {:.1} MiB, base {:.1}, bound {:.1}",
            p / mib,
            base / mib,
            bound / mib
        );
        assert!(p <= bound, "band {band} MiB: peak {p} B over {bound} B");
        // A reading that broke and gave a small number fails too: a band
        // at least is resident above the small map's peak.
        assert!(p >= base + band as f64 * mib, "band {band} MiB: peak {p} B");
    }
}

/// Peak resident memory of a flight over a pack, in a process of its
/// own: the default scene (n = 63) over a 4097² lossless pack in 128²
/// tiles, flown 160 and 640 frames of 100 m. Tiles are decoded under each
/// level's window and a ring of one tile, and evicted beyond it, so each
/// level holds tiles over at most 4 × 4 tiles of 128² (65 texels and a
/// tile each side): on each of their at most 512 sample rows, at most 5
/// pages (2 KiB of heights over 2 pages and a page they straddle, 512 B
/// of flags over 2). Levels shorter than 512 rows hold their own height
/// in rows. Over the same command's peak over a 513² pack (the program,
/// its buffers and a whole small map), that is the bound.
///
/// And a flight four times longer peaks within 1 MiB of the shorter one's:
/// what the windows hold does not grow with the path. The shorter flight
/// runs 384 frames, to the map's east edge (the path moves 93.4 m east a
/// frame from x = 5,120 m; the map ends at 40,960 m), because the peak
/// depends on where the windows sit against the tile grid: flights of 100
/// and 160 frames peak near 35.1 MiB and every flight from 200 frames on
/// near 36.5, so a shorter flight would compare a position, not a path.
/// The 1 MiB is twice the spread of six runs of one length (384 frames:
/// 36.47 to 36.92 MiB; 1,536: 36.62 to 37.04). A peak is a coarse leak
/// detector: a flight whose every frame kept 16 KiB failed here (40.5 ->
/// 49.6 MiB), one keeping 4 KiB a frame did not, its 4.5 MiB going into
/// heap the peak's transient had already freed. Measured 2026-12-05, debug build,
/// 2 workers: 36.7 and 36.9 MiB against a bound of 63.9 MiB (the 513²
/// flight 14.1); before pack tiles were read rather than mapped and whole
/// rows of evicted tiles released as one span, 45.8 and 76.1 MiB.
#[cfg(target_os = "linux")]
#[test]
fn a_flight_over_a_pack_holds_what_its_windows_need() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("fly-rss");
    std::fs::create_dir_all(&dir).unwrap();
    let default = include_str!("../benches/scenes/bench.toml");
    let run = |args: &[&str]| -> serde_json::Value {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
            .env("RAYON_NUM_THREADS", "2")
            .current_dir(&dir)
            .args(args)
            .output()
            .unwrap();
        ok_json(out)
    };
    let peak = |side: usize, frames: usize| -> f64 {
        let (src, pack, scene) = (
            format!("p{side}.toml"),
            format!("p{side}.tcz"),
            format!("fly{side}.toml"),
        );
        let text = default.replace(
            "width = 1025, height = 1025",
            &format!("width = {side}, height = {side}"),
        );
        std::fs::write(dir.join(&src), &text).unwrap();
        if !dir.join(&pack).exists() {
            run(&["pack", &src, "-o", &pack, "--band-mib", "4", "--json"]);
        }
        let over = text
            .lines()
            .map(|l| {
                if l.starts_with("procedural =") {
                    format!("file = \"{pack}\"")
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        assert!(over.contains(&format!("file = \"{pack}\"")));
        std::fs::write(dir.join(&scene), over).unwrap();
        let f = frames.to_string();
        let v = run(&[
            "fly",
            &scene,
            "--frames",
            &f,
            "--step",
            "100",
            "--no-popping",
            "--size",
            "160x90",
            "--json",
        ]);
        v["peak_rss_bytes"].as_f64().unwrap()
    };
    let mib = (1u64 << 20) as f64;
    let base = peak(513, 80);
    // Rows a level holds at most: 4 tiles of 128, or its own height.
    let rows: f64 = (0..9).map(|l| ((4096usize >> l) + 1).min(512) as f64).sum();
    let bound = base + rows * 5.0 * 4096.0;
    let (short, long) = (peak(4097, 384), peak(4097, 1536));
    println!(
        "base {:.1} MiB, 384 frames {:.1}, 1536 frames {:.1}, bound {:.1}",
        base / mib,
        short / mib,
        long / mib,
        bound / mib
    );
    assert!(long <= bound && short <= bound, "over {bound} B");
    assert!(
        long <= short + mib,
        "the peak grows with the path: {short} -> {long} B"
    );
}
