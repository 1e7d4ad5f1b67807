//! Readers and the CLI on good and bad input: every bad input is a clean
//! error naming the file and the reason, with a non-zero exit and no panic.

mod common;

use common::cli;
use std::path::{Path, PathBuf};
use std::process::Command;
use terraclip::terrain::Heightmap;

const JACKSBORO: &str = "tests/data/jacksboro_16.png";

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-inputs-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// Asserts a clean failure whose message names `needle` and says
/// `reason`, once: an error's chain that repeats its cause reads as two.
fn fails_cleanly(args: &[&str], needle: &str, reason: &str) {
    let (code, out, err) = cli(args);
    assert_ne!(code, 0, "{args:?} should fail");
    assert!(out.is_empty(), "nothing on stdout: {out}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(needle), "message names {needle}: {err}");
    assert_eq!(
        err.matches(reason).count(),
        1,
        "message says {reason} once: {err}"
    );
}

#[test]
fn info_reports_jacksboro() {
    if !Path::new(JACKSBORO).exists() {
        panic!("{JACKSBORO} missing from the checkout");
    }
    let (code, out, _) = cli(&["info", JACKSBORO, "--json"]);
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["width"], 403);
    assert_eq!(v["height"], 344);
    assert_eq!(v["min"], 236.0);
    assert_eq!(v["max"], 1076.0);
    assert_eq!(v["nodata_count"], 0);
    assert_eq!(v["format"], "png16+sidecar");
}

#[test]
fn diagram_writes_a_png() {
    let out = tmp("diagram.png");
    let (code, stdout, err) = cli(&["diagram", "-o", out.to_str().unwrap(), "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!(v["levels"].as_u64().unwrap() >= 3);
    let img = image::open(&out).unwrap().to_rgba8();
    // The map's 800 px square and the key's panel beside it (its width
    // follows the labels: 308 px for the default scene).
    assert_eq!(img.height(), 800);
    assert!((1000..1200).contains(&img.width()), "{}", img.width());
    let distinct: std::collections::HashSet<_> = img.pixels().map(|p| p.0).collect();
    assert!(
        distinct.len() > 8,
        "diagram has content: {} colours",
        distinct.len()
    );
}

/// CRC-32 (ISO-HDLC, PNG's), bit by bit: enough for one chunk header.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn bad_images_are_clean_errors() {
    let good = std::fs::read(JACKSBORO).unwrap();
    let trunc = tmp("truncated.png");
    std::fs::write(&trunc, &good[..good.len() / 3]).unwrap();
    fails_cleanly(
        &["info", trunc.to_str().unwrap()],
        "truncated.png",
        "cannot decode",
    );
    let corrupt = tmp("corrupt.png");
    let mut bytes = good.clone();
    for b in bytes.iter_mut().skip(100).take(400) {
        *b ^= 0x5a;
    }
    std::fs::write(&corrupt, &bytes).unwrap();
    fails_cleanly(
        &["info", corrupt.to_str().unwrap()],
        "corrupt.png",
        "cannot decode",
    );
    let empty = tmp("empty.png");
    std::fs::write(&empty, b"").unwrap();
    fails_cleanly(
        &["info", empty.to_str().unwrap()],
        "empty.png",
        "cannot decode image: unexpected end of file",
    );
    // A PNG header claiming 2^30 × 2^30 pixels, with its chunk's CRC made
    // right, so that the size is what the reader refuses (with the old CRC
    // the decoder stops at a CRC error before reading the size).
    let resized = |bytes: &[u8], name: &str, w: u32, h: u32| {
        let mut b = bytes.to_vec();
        b[16..20].copy_from_slice(&w.to_be_bytes());
        b[20..24].copy_from_slice(&h.to_be_bytes());
        let crc = crc32(&b[12..29]);
        b[29..33].copy_from_slice(&crc.to_be_bytes());
        let p = tmp(name);
        std::fs::write(&p, &b).unwrap();
        p
    };
    let huge = resized(&good[..33], "huge.png", 1 << 30, 1 << 30);
    fails_cleanly(
        &["info", huge.to_str().unwrap()],
        "huge.png",
        "Image size exceeds limit",
    );
    // Within the decoder's limits but over the heightmap's (2^28 texels):
    // refused from the header, before the 272 M pixels are decoded.
    let big = resized(&good, "big.png", 17_000, 16_000);
    fails_cleanly(
        &["info", big.to_str().unwrap()],
        "big.png",
        "dimensions 17000×16000 exceed the limit",
    );
    fails_cleanly(
        &["info", "/nonexistent/x.png"],
        "/nonexistent/x.png",
        "No such file",
    );
    fails_cleanly(
        &["info", tmp("x.xyz").to_str().unwrap()],
        "x.xyz",
        "unknown heightmap extension",
    );
}

#[test]
fn ascii_grid_nodata_and_nan() {
    let p = tmp("grid.asc");
    std::fs::write(&p, "ncols 4\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 25\nNODATA_value -9999\n1 2 3 4\n5 -9999 nan 8\n9 10 inf 12\n").unwrap();
    let h = Heightmap::load(&p).unwrap();
    assert_eq!((h.width(), h.height(), h.nodata_count()), (4, 3, 3));
    assert_eq!(h.cell_size, [25.0, 25.0]);
    assert_eq!(h.min_max(), (1.0, 12.0));
    // Each malformed grid is rejected with the file name and the reason.
    for (name, text, reason) in [
        (
            "bad.asc",
            "ncols 4\nnrows 3\ncellsize 1\n1 2 3\n",
            "truncated",
        ),
        ("zero.asc", "ncols 0\nnrows 3\ncellsize 1\n", "zero-sized"),
        (
            "big.asc",
            "ncols 100000\nnrows 100000\ncellsize 1\n1\n",
            "exceed the limit",
        ),
        (
            "allnan.asc",
            "ncols 2\nnrows 2\ncellsize 1\nnan nan nan nan\n",
            "no valid height",
        ),
    ] {
        let p = tmp(name);
        std::fs::write(&p, text).unwrap();
        fails_cleanly(&["info", p.to_str().unwrap()], name, reason);
    }
}

#[test]
fn raw_f32_with_sidecar() {
    let p = tmp("dem.f32");
    let vals: Vec<f32> = vec![1.0, 2.0, f32::NAN, 4.0, -32768.0, 6.0];
    let bytes: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&p, &bytes).unwrap();
    std::fs::write(
        tmp("dem.json"),
        r#"{"width": 3, "height": 2, "cell_size_m": {"x": 10.0, "y": 20.0}, "nodata": -32768.0, "raw_offset_m": 100.0, "raw_scale_m_per_unit": 2.0}"#,
    )
    .unwrap();
    let h = Heightmap::load(&p).unwrap();
    assert_eq!(h.nodata_count(), 2);
    assert_eq!(h.min_max(), (102.0, 112.0));
    assert_eq!(h.cell_size, [10.0, 20.0]);
    // Truncated data.
    std::fs::write(&p, &bytes[..10]).unwrap();
    fails_cleanly(&["info", p.to_str().unwrap()], "dem.f32", "truncated");
    // Missing sidecar.
    let lone = tmp("lone.raw");
    std::fs::write(&lone, &bytes).unwrap();
    fails_cleanly(&["info", lone.to_str().unwrap()], "lone.raw", "sidecar");
}

#[test]
fn tiff_and_tga_round_trip() {
    use tiff::encoder::{colortype, TiffEncoder};
    let (w, h) = (5u32, 4u32);
    let f: Vec<f32> = (0..w * h).map(|i| i as f32 * 1.5 - 3.0).collect();
    let p = tmp("f.tif");
    let mut enc = TiffEncoder::new(std::fs::File::create(&p).unwrap()).unwrap();
    enc.write_image::<colortype::Gray32Float>(w, h, &f).unwrap();
    let m = Heightmap::load(&p).unwrap();
    assert_eq!(
        (m.width(), m.height(), m.format.as_str()),
        (5, 4, "tiff-f32")
    );
    assert_eq!(m.data(), &f[..]);
    let u: Vec<u16> = (0..w * h).map(|i| (i * 1000) as u16).collect();
    let p16 = tmp("u.tiff");
    let mut enc = TiffEncoder::new(std::fs::File::create(&p16).unwrap()).unwrap();
    enc.write_image::<colortype::Gray16>(w, h, &u).unwrap();
    let m = Heightmap::load(&p16).unwrap();
    assert_eq!(m.format, "tiff-u16");
    assert_eq!(m.min_max(), (0.0, 19000.0));
    // GeoTIFF: pixel scale gives the cell size, GDAL_NODATA the no-data value.
    let geo = tmp("geo.tif");
    let mut enc = TiffEncoder::new(std::fs::File::create(&geo).unwrap()).unwrap();
    let mut img = enc.new_image::<colortype::Gray32Float>(w, h).unwrap();
    img.encoder()
        .write_tag(
            tiff::tags::Tag::ModelPixelScaleTag,
            &[30.0f64, 25.0, 0.0][..],
        )
        .unwrap();
    img.encoder()
        .write_tag(tiff::tags::Tag::GdalNodata, "1.5")
        .unwrap();
    img.write_data(&f).unwrap();
    let m = Heightmap::load(&geo).unwrap();
    assert_eq!(m.cell_size, [30.0, 25.0]);
    assert_eq!(m.nodata_count(), 1, "the texel equal to GDAL_NODATA");
    let rgb = tmp("rgb.tif");
    let mut enc = TiffEncoder::new(std::fs::File::create(&rgb).unwrap()).unwrap();
    enc.write_image::<colortype::RGB8>(2, 2, &[1, 2, 3].repeat(4))
        .unwrap();
    fails_cleanly(&["info", rgb.to_str().unwrap()], "rgb.tif", "single-band");
    let tga = tmp("g.tga");
    image::GrayImage::from_fn(6, 3, |x, y| image::Luma([(x * 10 + y) as u8]))
        .save(&tga)
        .unwrap();
    let m = Heightmap::load(&tga).unwrap();
    assert_eq!((m.width(), m.height(), m.format.as_str()), (6, 3, "tga8"));
    assert_eq!(m.get(5, 2), 52.0);
}

#[test]
fn bad_scenes_are_clean_errors() {
    let base = terraclip::scene::BENCH_SCENE;
    let out = tmp("o.png");
    // Writes a scene variant and checks `diagram` rejects it cleanly.
    let rejects = |name: &str, text: &str, reason: &str| {
        let p = tmp(name);
        std::fs::write(&p, text).unwrap();
        fails_cleanly(
            &["diagram", p.to_str().unwrap(), "-o", out.to_str().unwrap()],
            name,
            reason,
        );
    };
    rejects("n.toml", &base.replace("n = 63", "n = 100"), "2^k − 1");
    rejects(
        "levels.toml",
        &base.replace("n = 63", "n = 63\nlevels = 40"),
        "lod.levels",
    );
    rejects(
        "effect.toml",
        &base.replace("\"fog\"", "\"bloom\""),
        "unknown effect 'bloom'",
    );
    let text = base.replace("fov = 60.0", "fov = 60.0\nzoom = 3");
    let line = text.lines().position(|l| l.starts_with("zoom")).unwrap() + 1;
    rejects("key.toml", &text, &format!("line {line}, column 1"));
    rejects("key.toml", &text, "unknown field `zoom`");
    let missing = tmp("missing.toml");
    fails_cleanly(
        &[
            "diagram",
            missing.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "missing.toml",
        "No such file or directory",
    );
    assert!(!out.exists(), "no output is written on error");
}

/// Outputs are written to a temporary file and renamed: a render killed at
/// any moment, or one whose write fails, leaves the previous file intact.
/// Three renders are asserted: one killed before its write, one killed in
/// the middle of its write (held there by `TERRACLIP_TEST_STALL_WRITE_MS`,
/// its temporary file half-written), and one left to finish, which replaces
/// the file with the whole new image.
#[test]
fn killed_or_failed_renders_leave_the_previous_output_intact() {
    use std::time::{Duration, Instant};
    let out = tmp("kept.png");
    let old = image::GrayImage::from_fn(3, 2, |x, _| image::Luma([x as u8]));
    old.save(&out).unwrap();
    let before = std::fs::read(&out).unwrap();
    let render = |stall_ms: Option<u64>| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_terraclip"));
        cmd.args([
            "render",
            "--size",
            "800x600",
            "--out",
            out.to_str().unwrap(),
        ])
        .env_remove("TERRACLIP_TEST_STALL_WRITE_MS")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null());
        if let Some(ms) = stall_ms {
            cmd.env("TERRACLIP_TEST_STALL_WRITE_MS", ms.to_string());
        }
        cmd.spawn().unwrap()
    };
    #[cfg(unix)]
    let killed = |s: std::process::ExitStatus| {
        use std::os::unix::process::ExitStatusExt;
        s.signal() == Some(libc::SIGKILL)
    };
    #[cfg(not(unix))]
    let killed = |s: std::process::ExitStatus| !s.success();
    // Kills a running render and asserts it died of the kill, with the old
    // output still in place.
    let kill = |mut child: std::process::Child, when: &str| {
        child.kill().unwrap_or_else(|e| panic!("{when}: {e}"));
        let status = child.wait().unwrap();
        assert!(killed(status), "{when}: killed, not finished: {status:?}");
        assert_eq!(std::fs::read(&out).unwrap(), before, "{when}");
    };

    // Killed long before its write: the render of an 800×600 frame of the
    // default scene takes far more than 20 ms.
    let child = render(None);
    std::thread::sleep(Duration::from_millis(20));
    kill(child, "killed before its write");

    // Killed in the middle of its write.
    let mut child = render(Some(120_000));
    let part = out.with_file_name(format!(".kept.png.tmp-{}", child.id()));
    let t = Instant::now();
    while std::fs::metadata(&part).map_or(true, |m| m.len() == 0) {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the render ended early"
        );
        assert!(t.elapsed() < Duration::from_secs(120), "no write began");
        std::thread::sleep(Duration::from_millis(5));
    }
    kill(child, "killed mid-write");
    let partial = std::fs::read(&part).unwrap();
    assert!(
        image::load_from_memory(&partial).is_err(),
        "the temporary file holds half a PNG ({} bytes)",
        partial.len()
    );
    std::fs::remove_file(&part).unwrap();

    // Left to finish: the whole new image replaces the old one.
    let status = render(None).wait().unwrap();
    assert!(status.success(), "{status:?}");
    let img = image::load_from_memory(&std::fs::read(&out).unwrap()).expect("complete PNG");
    assert_eq!((img.width(), img.height()), (800, 600));

    // A write that fails (the target is a directory): error, nothing lost,
    // no temporary file left beside it.
    let target = tmp("a-directory.png");
    std::fs::create_dir_all(&target).unwrap();
    std::fs::write(target.join("inside"), b"keep").unwrap();
    let (code, _, err) = cli(&[
        "render",
        "--size",
        "64x48",
        "--out",
        target.to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    assert!(
        err.contains("a-directory.png") && !err.contains("panicked"),
        "{err}"
    );
    assert_eq!(std::fs::read(target.join("inside")).unwrap(), b"keep");
    let parent = target.parent().unwrap();
    let leftovers: Vec<_> = std::fs::read_dir(parent)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .map(|e| e.file_name())
        .collect();
    // Killed renders may leave their own temporary file; a failed write
    // must remove its one.
    assert!(
        !leftovers
            .iter()
            .any(|n| n.to_string_lossy().starts_with(".a-directory.png")),
        "{leftovers:?}"
    );
}

/// Printing into a closed pipe (`terraclip … | head`) ends the process
/// quietly instead of panicking.
#[test]
fn a_closed_stdout_pipe_is_not_a_panic() {
    let mut args = vec!["height".to_string()];
    for i in 0..3000 {
        args.push("--at".into());
        args.push(format!("{},{}", 5000 + i, -5000 - i));
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_terraclip"))
        .args(&args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.is_empty(), "quietly: {err}");
    // Killed by SIGPIPE, as Unix tools are, not an error exit.
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(out.status.signal(), Some(libc::SIGPIPE), "{:?}", out.status);
    }
    #[cfg(not(unix))]
    assert!(
        !out.status.success(),
        "the write into the closed pipe must end it"
    );
}

/// `render --heightmap` with no camera frames the map: the embedded scene's
/// camera, far plane and fog were placed for a 10 km procedural map, and on
/// any other map they showed a fog plane, or a view from inside the map.
/// Framed, the whole map is in view: sky along the top and bottom rows
/// (the map's far and near edges are inside the frame), terrain over much
/// of the rest, with real contrast. With `--camera` the scene's own camera
/// is kept, and its view runs off the bottom of the frame.
#[test]
fn a_heightmap_without_a_camera_is_framed() {
    let view = |extra: &[&str]| {
        let out = tmp(&format!("framed-{}.png", extra.len()));
        let mut args = vec![
            "render",
            "--heightmap",
            "tests/data/jacksboro_16.png",
            "--size",
            "160x90",
        ];
        args.extend_from_slice(extra);
        args.extend(["-o", out.to_str().unwrap()]);
        let (code, _, err) = cli(&args);
        assert_eq!(code, 0, "{err}");
        image::open(&out).unwrap().to_rgb8()
    };
    // The default scene's background, [0.55, 0.70, 0.90].
    let sky = |p: &image::Rgb<u8>| {
        p.0.iter()
            .zip([140u8, 179, 230])
            .all(|(&a, b)| a.abs_diff(b) <= 2)
    };
    let row_sky =
        |img: &image::RgbImage, y: u32| (0..160).filter(|&x| sky(img.get_pixel(x, y))).count();
    let framed = view(&[]);
    let ground: Vec<u8> = framed
        .pixels()
        .filter(|p| !sky(p))
        .map(|p| p.0[1])
        .collect();
    let share = ground.len() as f64 / (160.0 * 90.0);
    let spread = ground.iter().max().unwrap() - ground.iter().min().unwrap();
    assert!(
        share > 0.25,
        "terrain covers {:.0} % of the frame",
        100.0 * share
    );
    assert!(
        spread > 60,
        "the green channel spans only {spread} levels: a fog plane"
    );
    assert_eq!(row_sky(&framed, 0), 160, "the map's far edge is in view");
    assert_eq!(row_sky(&framed, 89), 160, "the map's near edge is in view");
    let kept = view(&["--camera", "5120,-5120,900"]);
    assert!(
        row_sky(&kept, 89) < 160,
        "--camera keeps the scene's own view"
    );
}

/// A scene without a camera whose map `--heightmap` replaces is not
/// framed on its own map first: framing reads the whole map, so a scene
/// naming a large raw file paid for reading it once more. Here the
/// scene's own map does not exist, so reading it would be an error.
#[test]
fn a_replaced_map_is_not_read() {
    let dir = tmp("replaced-map");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("terrain-only.toml");
    std::fs::write(&scene, "[terrain]\nfile = \"missing.png\"\n").unwrap();
    let out = dir.join("out.png");
    let (code, _, err) = cli(&[
        "render",
        scene.to_str().unwrap(),
        "--heightmap",
        "tests/data/jacksboro_16.png",
        "--size",
        "160x90",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    // Without --heightmap the scene's own map is read, and named.
    let (code, _, err) = cli(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(code != 0 && err.contains("missing.png"), "{err}");
}

/// A GeoTIFF in geographic coordinates (SRTM, Copernicus DEM and GLOBE
/// tiles are in degrees): its 30″ cells become metres at the map's centre
/// latitude, and `info` names the CRS. Before, the cell size came out as
/// 0.0083 "metres", and the map less than a metre wide. A projected one
/// keeps its metres (or converts its feet).
/// A 12 × 8 f32 GeoTIFF `name` with a pixel scale, a tie point and, when
/// given, a GeoKey directory.
fn geotiff(name: &str, keys: Option<&[u16]>, scale: [f64; 3], tie: [f64; 6]) -> PathBuf {
    use tiff::encoder::{colortype, TiffEncoder};
    use tiff::tags::Tag;
    let (w, h) = (12u32, 8u32);
    let z: Vec<f32> = (0..w * h).map(|i| i as f32).collect();
    let p = tmp(name);
    let mut enc = TiffEncoder::new(std::fs::File::create(&p).unwrap()).unwrap();
    let mut img = enc.new_image::<colortype::Gray32Float>(w, h).unwrap();
    let e = img.encoder();
    e.write_tag(Tag::ModelPixelScaleTag, &scale[..]).unwrap();
    e.write_tag(Tag::ModelTiepointTag, &tie[..]).unwrap();
    if let Some(keys) = keys {
        e.write_tag(Tag::GeoKeyDirectoryTag, keys).unwrap();
    }
    img.write_data(&z).unwrap();
    p
}

#[test]
fn geographic_geotiffs_get_metres() {
    let write = |name: &str, keys: &[u16], scale: [f64; 3], tie: [f64; 6]| {
        geotiff(name, Some(keys), scale, tie)
    };
    let info = |p: &Path| -> serde_json::Value {
        let (code, out, err) = cli(&["info", p.to_str().unwrap(), "--json"]);
        assert_eq!(code, 0, "{err}");
        serde_json::from_str(&out).unwrap()
    };
    // 30″ cells, the top row at 46.1° N: the middle row at 46.1 − 4/120.
    let arc = 1.0 / 120.0;
    let geo = write(
        "geographic.tif",
        &[1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326],
        [arc, arc, 0.0],
        [0.0, 0.0, 0.0, 10.0, 46.1, 0.0],
    );
    let v = info(&geo);
    assert_eq!(v["crs"], "EPSG:4326");
    let lat = (46.1f64 - 4.0 * arc).to_radians();
    // The usual WGS 84 series for a degree of longitude and of latitude.
    let lon_m = 111_412.84 * lat.cos() - 93.5 * (3.0 * lat).cos() + 0.118 * (5.0 * lat).cos();
    let lat_m = 111_132.954 - 559.822 * (2.0 * lat).cos() + 1.175 * (4.0 * lat).cos();
    let got = [
        v["cell_size_m"][0].as_f64().unwrap(),
        v["cell_size_m"][1].as_f64().unwrap(),
    ];
    assert!(
        (got[0] - arc * lon_m).abs() < 1e-3,
        "x: {} m against {} m",
        got[0],
        arc * lon_m
    );
    assert!(
        (got[1] - arc * lat_m).abs() < 1e-3,
        "y: {} m against {} m",
        got[1],
        arc * lat_m
    );
    assert_eq!(v["cell_size"], v["cell_size_m"]);
    // Projected, in US survey feet, then in metres by default.
    let feet = write(
        "utm-feet.tif",
        &[
            1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32633, 3076, 0, 1, 9003,
        ],
        [100.0, 100.0, 0.0],
        [0.0, 0.0, 0.0, 500_000.0, 5_000_000.0, 0.0],
    );
    let v = info(&feet);
    assert_eq!(v["crs"], "EPSG:32633");
    assert!((v["cell_size_m"][0].as_f64().unwrap() - 100.0 * 1200.0 / 3937.0).abs() < 1e-9);
    let utm = write(
        "utm.tif",
        &[1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32633],
        [30.0, 30.0, 0.0],
        [0.0, 0.0, 0.0, 500_000.0, 5_000_000.0, 0.0],
    );
    assert_eq!(info(&utm)["cell_size_m"], serde_json::json!([30.0, 30.0]));
    // A geographic grid must say where it is.
    let lost = write(
        "nowhere.tif",
        &[1, 1, 0, 1, 1024, 0, 1, 2],
        [arc, arc, 0.0],
        [0.0, 0.0, 0.0, 10.0, 146.0, 0.0],
    );
    fails_cleanly(
        &["info", lost.to_str().unwrap()],
        "nowhere.tif",
        "not on the globe",
    );
}

/// A GeoTIFF in degrees that names no CRS (what `gdal_translate` writes
/// from a netCDF grid) reads as 0.004 "m" cells: `info`, `render` and
/// `pack` warn, naming the file and how to declare the CRS. `--crs
/// EPSG:4326` (or `terrain.crs` in a scene) converts it as a geographic
/// GeoTIFF's keys would, and silences the warning. Cells of 30 do not look
/// like degrees; a file's own CRS is not overruled; a declaration that is
/// not EPSG:<code> is refused, naming the field.
#[test]
fn degrees_without_a_crs_warn_and_a_declared_crs_converts_them() {
    let arc = 1.0 / 240.0;
    let tie = [0.0, 0.0, 0.0, 86.5, 28.1, 0.0];
    let bare = geotiff("bare-degrees.tif", None, [arc, arc, 0.0], tie);
    let keyed = geotiff(
        "keyed-degrees.tif",
        Some(&[1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326]),
        [arc, arc, 0.0],
        tie,
    );
    let b = bare.to_str().unwrap();
    let info = |args: &[&str]| -> (serde_json::Value, String) {
        let (code, out, err) = cli(&[&["info", "--json"], args].concat());
        assert_eq!(code, 0, "{err}");
        (serde_json::from_str(&out).unwrap(), err)
    };
    let warned = |err: &str| {
        err.contains("warning: ")
            && err.contains("bare-degrees.tif")
            && err.contains("names no CRS")
            && err.contains("--crs EPSG:4326")
    };
    let (v, err) = info(&[b]);
    assert!(warned(&err), "{err}");
    assert_eq!(v["cell_size_m"], serde_json::json!([arc, arc]));
    assert_eq!(v["crs"], serde_json::Value::Null);
    let (declared, err) = info(&[b, "--crs", "EPSG:4326"]);
    assert!(err.is_empty(), "{err}");
    let (truth, _) = info(&[keyed.to_str().unwrap()]);
    assert_eq!(declared["cell_size_m"], truth["cell_size_m"]);
    assert_eq!(declared["crs"], "EPSG:4326");
    let x = truth["cell_size_m"][0].as_f64().unwrap();
    assert!((x - 409.5).abs() < 0.1, "{x} m across at 28.08° N");
    // Metres-like cells with no CRS: no warning.
    let metres = geotiff("bare-metres.tif", None, [30.0, 30.0, 0.0], tie);
    let (_, err) = info(&[metres.to_str().unwrap()]);
    assert!(err.is_empty(), "{err}");
    // The file's own CRS stands.
    fails_cleanly(
        &["info", keyed.to_str().unwrap(), "--crs", "EPSG:32633"],
        "keyed-degrees.tif",
        "differs",
    );
    // render and pack warn the same way, and --crs silences them.
    let png = tmp("bare-degrees.png");
    let p = png.to_str().unwrap();
    let (code, _, err) = cli(&["render", "--heightmap", b, "-o", p, "--size", "64x48"]);
    assert!(code == 0 && warned(&err), "{err}");
    let (code, _, err) = cli(&[
        "render",
        "--heightmap",
        b,
        "--crs",
        "EPSG:4326",
        "-o",
        p,
        "--size",
        "64x48",
    ]);
    assert!(code == 0 && !err.contains("warning"), "{err}");
    let tcz = tmp("bare-degrees.tcz");
    let t = tcz.to_str().unwrap();
    let (code, _, err) = cli(&["pack", b, "-o", t]);
    assert!(code == 0 && warned(&err), "{err}");
    let (code, _, err) = cli(&["pack", b, "--crs", "EPSG:4326", "-o", t]);
    assert!(code == 0 && !err.contains("warning"), "{err}");
    let (packed, _) = info(&[t]);
    assert_eq!(packed["cell_size_m"], truth["cell_size_m"]);
    // A scene declares it as terrain.crs.
    let scene = tmp("bare-degrees.toml");
    let write_scene = |crs: &str| {
        std::fs::write(
            &scene,
            format!("[terrain]\nfile = \"bare-degrees.tif\"\n{crs}\n"),
        )
        .unwrap()
    };
    write_scene("crs = \"EPSG:4326\"");
    let s = scene.to_str().unwrap();
    let (code, _, err) = cli(&["render", s, "-o", p, "--size", "64x48"]);
    assert!(code == 0 && !err.contains("warning"), "{err}");
    let (code, _, err) = cli(&["pack", s, "-o", t]);
    assert!(code == 0 && !err.contains("warning"), "{err}");
    let (packed, _) = info(&[t]);
    assert_eq!(packed["cell_size_m"], truth["cell_size_m"]);
    write_scene("");
    let (code, _, err) = cli(&["render", s, "-o", p, "--size", "64x48"]);
    assert!(code == 0 && warned(&err), "{err}");
    write_scene("crs = \"4326\"");
    fails_cleanly(&["render", s, "-o", p], "terrain.crs", "EPSG:<code>");
}

/// Every GeoTIFF compression GDAL writes for DEMs that the `tiff` crate
/// decodes (DEFLATE, LZW and PackBits by default, ZSTD by its feature),
/// with predictors 1, 2 and 3, striped and tiled, and BigTIFF, reads to
/// the samples of the uncompressed fixture, whole and by rows (what
/// `pack` streams). LERC, plain and with DEFLATE or ZSTD, is refused with
/// its name and the `gdal_translate` line that rewrites the file.
#[test]
fn every_geotiff_compression_reads_the_same_samples_or_names_itself() {
    use terraclip::terrain::rows;
    use terraclip::terrain::Heightmap;
    let dir = Path::new("tests/data/tiff");
    let truth = Heightmap::load(&dir.join("none.tif")).unwrap();
    assert_eq!((truth.width(), truth.height()), (64, 48));
    let (lo, hi) = truth.min_max();
    assert!(lo > 260.0 && hi < 773.0 && hi - lo > 500.0, "{lo}..{hi}");
    let read = [
        "deflate-p1",
        "deflate-p2",
        "deflate-p3",
        "lzw-p2",
        "lzw-p3-tiled",
        "packbits",
        "zstd-p1",
        "zstd-p2",
        "zstd-p3-tiled",
        "bigtiff-deflate",
    ];
    for name in read {
        let path = dir.join(format!("{name}.tif"));
        let h = Heightmap::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(h.data(), truth.data(), "{name}");
        assert_eq!(h.cell_size, [30.0, 30.0], "{name}");
        assert_eq!(h.crs.as_deref(), Some("EPSG:32614"), "{name}");
        let src = rows::open(&path).unwrap();
        assert_eq!(
            src.read_rows(0, 48).unwrap(),
            truth.data(),
            "{name} by rows"
        );
        assert_eq!(
            src.read_rows(17, 33).unwrap(),
            truth.data()[17 * 64..33 * 64],
            "{name}"
        );
    }
    // LERC with the feature `lerc` (Esri's library); without it, refused
    // with the line that rewrites the file.
    let v0 = truth.get(5, 5);
    for name in [
        "lerc",
        "lerc-deflate",
        "lerc-zstd",
        "lerc-zstd-tiled-nodata",
    ] {
        let path = dir.join(format!("{name}.tif"));
        if !cfg!(feature = "lerc") {
            fails_cleanly(
                &["info", path.to_str().unwrap()],
                &format!("{name}.tif"),
                "compression LERC (34887) is not read by this build (one with `--features lerc` \
                 reads it, given libclang-dev to build); rewrite the file with `gdal_translate -co \
                 COMPRESS=DEFLATE",
            );
            continue;
        }
        let h = Heightmap::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(h.format, "tiff-lerc");
        // The tiled one (48 × 32 tiles, so its edge tiles are padded)
        // declares one height as no-data: the LERC mask GDAL wrote.
        let masked = name.ends_with("nodata");
        let want: Vec<f32> = truth
            .data()
            .iter()
            .map(|&v| if masked && v == v0 { f32::NAN } else { v })
            .collect();
        let nodata = want.iter().filter(|v| v.is_nan()).count();
        assert_eq!(h.nodata_count(), nodata, "{name}");
        assert_eq!(nodata > 0, masked, "{name}");
        let by_rows = rows::open(&path).unwrap().read_rows(0, 48).unwrap();
        for (i, (a, b)) in by_rows.iter().zip(&want).enumerate() {
            assert!(
                a == b || (a.is_nan() && b.is_nan()),
                "{name} sample {i}: {a} against {b}"
            );
            assert_eq!(h.nodata_mask()[i], b.is_nan(), "{name} sample {i}");
            if !b.is_nan() {
                assert_eq!(h.data()[i], *b, "{name} sample {i}");
            }
        }
    }
}

#[test]
fn pack_writes_a_pack_info_reads_and_bad_ones_are_clean_errors() {
    let out = tmp("j.tcz");
    let o = out.to_str().unwrap();
    let jacksboro = "tests/data/jacksboro_16.png";
    let (code, stdout, err) = cli(&["pack", jacksboro, "-o", o, "--max-error", "1", "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        (v["width"].as_u64(), v["levels"].as_u64()),
        (Some(403), Some(9))
    );
    assert!(v["max_error_seen"].as_f64().unwrap() <= 1.0);
    assert!(v["ratio"].as_f64().unwrap() > 6.0, "{v}");
    // The ratio coder's default predictor is the fitted one.
    assert_eq!(
        (&v["coder"], &v["predictor"]),
        (&"ratio".into(), &"fitted".into())
    );
    let (code, stdout, err) = cli(&["info", o, "--json"]);
    assert_eq!(code, 0, "{err}");
    let i: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(i["bytes"], v["bytes"]);
    assert_eq!(i["format"], "tcz");
    assert_eq!(i["predictor"], "fitted");
    // It is smaller than lifting's pack of the same map.
    let lifting = tmp("j-lifting.tcz");
    let args = [
        "pack",
        jacksboro,
        "-o",
        lifting.to_str().unwrap(),
        "--max-error",
        "1",
    ];
    let (code, stdout, err) = cli(&[&args[..], &["--predictor", "lifting", "--json"]].concat());
    assert_eq!(code, 0, "{err}");
    let l: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(l["predictor"], "lifting");
    assert!(
        v["bytes"].as_u64() < l["bytes"].as_u64(),
        "fitted {} against lifting {}",
        v["bytes"],
        l["bytes"]
    );
    let (code, _, err) = cli(&[&args[..], &["--predictor", "guessed"]].concat());
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("(fitted, lifting or upsampled)"), "{err}");
    // A cut pack: exit 1, the file named, no panic; the good one is kept
    // when a second pack fails before writing.
    let bytes = std::fs::read(&out).unwrap();
    let cut = tmp("cut.tcz");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let (code, _, err) = cli(&["info", cut.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("cut.tcz") && err.contains("past the end"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    for bad in [["--tile", "7"], ["--max-error", "inf"]] {
        let (code, _, err) = cli(&["pack", jacksboro, "-o", o, bad[0], bad[1]]);
        assert_eq!(code, 1, "{bad:?}: {err}");
        assert!(err.contains(bad[0]), "{err}");
    }
    assert_eq!(std::fs::read(&out).unwrap(), bytes);
    // unpack: level 0 back to raw f32, within the bound of the source; bad
    // levels, windows and formats are clean errors.
    let raw = tmp("u.f32");
    let (code, _, err) = cli(&["unpack", o, "-o", raw.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let (a, b) = (
        terraclip::terrain::Heightmap::load(&raw).unwrap(),
        terraclip::terrain::Heightmap::load(std::path::Path::new(jacksboro)).unwrap(),
    );
    let worst = a
        .data()
        .iter()
        .zip(b.data())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    assert!(worst <= 1.0 && worst > 0.5, "{worst}");
    for (bad, says) in [
        (vec!["--level", "9"], "does not exist"),
        (vec!["--window", "400,0,10,10"], "leaves level 0"),
        (vec!["-o", "x.bmp"], "write .f32"),
    ] {
        let mut args = vec!["unpack", o];
        if bad[0] != "-o" {
            args.extend(["-o", raw.to_str().unwrap()]);
        }
        args.extend(bad);
        let (code, _, err) = cli(&args);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains(says) && !err.contains("panicked"), "{err}");
    }
}

/// `synthesis` runs on jacksboro and writes its picture; a factor other
/// than 2 or 4, a negative roughness, a window off the map and a map too
/// small to decimate are clean errors that say why.
#[test]
fn synthesis_measures_and_bad_options_are_clean_errors() {
    let out = tmp("synthesis.png");
    let o = out.to_str().unwrap();
    let (code, json, err) = cli(&["synthesis", JACKSBORO, "--factor", "2", "-o", o, "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["factor"], 2);
    assert_eq!(v["amplitudes"].as_array().unwrap().len(), 1);
    let png = image::open(&out).unwrap();
    // Three panels of the compared region, 4 pixels apart.
    assert_eq!(png.width() as u64, 3 * v["width"].as_u64().unwrap() + 8);
    let (code, json, err) = cli(&["synthesis", JACKSBORO, "--local", "--json"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        serde_json::from_str::<serde_json::Value>(&json).unwrap()["local"],
        true
    );
    fails_cleanly(
        &["synthesis", JACKSBORO, "--factor", "3"],
        "factor",
        "must be 2 or 4",
    );
    fails_cleanly(
        &["synthesis", JACKSBORO, "--roughness", "-0.5"],
        "roughness",
        "within 0..=2",
    );
    fails_cleanly(
        &["synthesis", JACKSBORO, "--window", "400,0,10,10"],
        "jacksboro",
        "does not fit",
    );
    fails_cleanly(
        &[
            "synthesis",
            JACKSBORO,
            "--window",
            "0,0,6,6",
            "--factor",
            "4",
        ],
        "jacksboro",
        "too small",
    );
    // A flat map has no detail to continue.
    let flat = tmp("flat.asc");
    let mut asc = String::from("ncols 16\nnrows 16\nxllcorner 0\nyllcorner 0\ncellsize 10\n");
    for _ in 0..16 {
        asc.push_str(&"5 ".repeat(16));
        asc.push('\n');
    }
    std::fs::write(&flat, asc).unwrap();
    fails_cleanly(
        &["synthesis", flat.to_str().unwrap()],
        "flat.asc",
        "no detail",
    );
}

/// LERC files damaged byte by byte (truncated, bits flipped, sizes made
/// extreme): each loads or fails naming the file, and no damage reaches
/// Esri's decoder as a crash. The split is asserted exactly.
#[cfg(feature = "lerc")]
#[test]
fn damaged_lerc_files_load_or_name_the_file() {
    use common::fuzz::{mutate, Rng};
    let mut rng = Rng(0x4C45_5243_2026_1205);
    let path = tmp("case-lerc.tif");
    // Loaded, refused by the LERC chunk reader, refused before it.
    let (mut loaded, mut chunk, mut refused) = (0, 0, 0);
    for (k, seed) in ["lerc", "lerc-deflate", "lerc-zstd-tiled-nodata"]
        .iter()
        .map(|n| std::fs::read(format!("tests/data/tiff/{n}.tif")).unwrap())
        .enumerate()
    {
        for case in 0..300 {
            std::fs::write(&path, mutate(&mut rng, &seed)).unwrap();
            match Heightmap::load(&path) {
                Ok(h) => {
                    assert!(h.data().iter().all(|v| v.is_finite()));
                    loaded += 1;
                }
                Err(e) => {
                    let msg = e.to_string();
                    assert!(msg.contains("case-lerc.tif"), "seed {k} case {case}: {msg}");
                    if msg.contains("LERC chunk") {
                        chunk += 1;
                    } else {
                        refused += 1;
                    }
                }
            }
        }
    }
    // A strip whose byte count claims 4 GiB: refused before a byte is
    // allocated for it. (Little-endian TIFF: the first IFD's entries are
    // 12 bytes each; StripByteCounts, tag 279, holds 2 LONGs at an offset.)
    let mut forged = std::fs::read("tests/data/tiff/lerc.tif").unwrap();
    let u16_at = |b: &[u8], i: usize| u16::from_le_bytes([b[i], b[i + 1]]) as usize;
    let u32_at = |b: &[u8], i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap()) as usize;
    let ifd = u32_at(&forged, 4);
    let entry = (0..u16_at(&forged, ifd))
        .map(|e| ifd + 2 + 12 * e)
        .find(|&e| u16_at(&forged, e) == 279)
        .expect("StripByteCounts");
    assert_eq!(u32_at(&forged, entry + 4), 2, "two strips");
    let counts = u32_at(&forged, entry + 8);
    forged[counts..counts + 4].copy_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
    std::fs::write(&path, &forged).unwrap();
    let e = Heightmap::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("case-lerc.tif") && e.contains("LERC chunk 0: 4294967280 bytes at offset"),
        "{e}"
    );
    eprintln!("LERC fuzz: {loaded} loaded, {chunk} refused by a chunk, {refused} before");
    assert_eq!((loaded, chunk, refused), (73, 614, 213));
}
