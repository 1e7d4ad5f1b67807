//! A pack keeps where its map lies, and `unpack` writes it back: the
//! unpacked GeoTIFF has the input's CRS (its GeoKey directory), origin,
//! pixel size and no-data value, and the `.f32` sidecar says the same.
//!
//! The in-process tests read the output with terraclip's own reader; the
//! GDAL test asks `gdalinfo -json` (Debian's `gdal-bin`), which `.ci/run`
//! installs and requires with `TERRACLIP_REQUIRE_GDAL=1`; elsewhere a
//! machine without it skips that test, saying so.

mod common;

use common::cli;
use std::path::{Path, PathBuf};
use terraclip::terrain::Heightmap;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-georef-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// A geographic Int16 GeoTIFF in 30″ cells with −32768 marking 120
/// samples no-data, and a projected (UTM 14N) f32 one with none.
const GEOGRAPHIC: &str = "tests/data/tiff/geo-30s-nodata.tif";
const PROJECTED: &str = "tests/data/tiff/none.tif";

fn run(args: &[&str]) -> String {
    let (code, out, err) = cli(args);
    assert_eq!(code, 0, "{args:?}: {err}");
    out
}

/// Packs `input` at bound `e` and unpacks `--level l --window w` to `out`.
fn round_trip(input: &str, e: &str, name: &str, extra: &[&str], out: &Path) {
    let pack = tmp(&format!("{name}.tcz"));
    let p = pack.to_str().unwrap();
    run(&["pack", input, "-o", p, "--max-error", e, "--tile", "16"]);
    let mut args = vec!["unpack", p, "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    run(&args);
}

/// Level 0 unpacked to a GeoTIFF reads with the input's place, exactly,
/// lossless and at a 1 m bound; the no-data samples come back as no-data.
#[test]
fn an_unpacked_geotiff_is_placed_where_the_input_was() {
    for input in [GEOGRAPHIC, PROJECTED] {
        let src = Heightmap::load(Path::new(input)).unwrap();
        let want = src.place.clone().expect("the fixture is georeferenced");
        for e in ["0", "1"] {
            let out = tmp(&format!(
                "l0-{e}-{}",
                Path::new(input).file_name().unwrap().to_string_lossy()
            ));
            round_trip(input, e, &format!("l0-{e}"), &[], &out);
            let back = Heightmap::load(&out).unwrap();
            assert_eq!(back.place.as_ref(), Some(&want), "{input} at E = {e}");
            assert_eq!(back.crs, src.crs, "{input}");
            assert_eq!(back.cell_size, src.cell_size, "{input}");
            assert_eq!(back.nodata_mask(), src.nodata_mask(), "{input}");
            // No-data is written as the input's value, which GDAL_NODATA names.
            let mut dec = tiff::decoder::Decoder::new(std::fs::File::open(&out).unwrap()).unwrap();
            let tiff::decoder::DecodingResult::F32(v) = dec.read_image().unwrap() else {
                panic!("{input}: not f32")
            };
            let marked = v.iter().filter(|&&x| Some(x as f64) == want.nodata).count();
            assert_eq!(marked, src.nodata_count(), "{input}");
            assert!(v.iter().all(|x| x.is_finite()), "{input}");
        }
    }
    assert_eq!(
        Heightmap::load(Path::new(GEOGRAPHIC))
            .unwrap()
            .nodata_count(),
        120
    );
}

/// A window of level 2 is placed from level 0: its first sample is
/// centred on level 0's sample (4·3, 4·2), in cells 4 times as large.
#[test]
fn a_window_of_a_coarser_level_is_placed_on_level_0() {
    let src = Heightmap::load(Path::new(PROJECTED)).unwrap();
    let out = tmp("window.tif");
    round_trip(
        PROJECTED,
        "1",
        "window",
        &["--level", "2", "--window", "3,2,8,6"],
        &out,
    );
    let back = Heightmap::load(&out).unwrap();
    let p = back.place.clone().unwrap();
    // none.tif: origin (500000, 4000000), 30 m cells.
    assert_eq!(
        src.place.unwrap().geotransform()[..4],
        [500_000.0, 30.0, 0.0, 4_000_000.0]
    );
    let centre = [500_000.0 + 12.5 * 30.0, 4_000_000.0 - 8.5 * 30.0];
    assert_eq!(
        p.geotransform(),
        [centre[0] - 60.0, 120.0, 0.0, centre[1] + 60.0, 0.0, -120.0]
    );
    assert_eq!((back.width(), back.height()), (8, 6));
}

/// `unpack -o x.f32` writes the place in the sidecar (with the CRS, the
/// geotransform and the no-data value for other tools), the raw file holds
/// −32768 where there was no data, and packing the `.f32` again gives a
/// GeoTIFF placed as the original.
#[test]
fn the_f32_sidecar_carries_the_place_through_another_pack() {
    let src = Heightmap::load(Path::new(GEOGRAPHIC)).unwrap();
    let raw = tmp("geo.f32");
    round_trip(GEOGRAPHIC, "0", "raw", &[], &raw);
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(raw.with_extension("json")).unwrap()).unwrap();
    assert_eq!(side["crs"], "EPSG:4326");
    assert_eq!(side["nodata"], -32768.0);
    let gt: Vec<f64> = serde_json::from_value(side["geotransform"].clone()).unwrap();
    assert_eq!(gt, src.place.as_ref().unwrap().geotransform());
    let bytes = std::fs::read(&raw).unwrap();
    let holes = bytes
        .chunks_exact(4)
        .filter(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) == -32768.0)
        .count();
    assert_eq!(holes, 120);
    let again = tmp("geo-again.tif");
    round_trip(raw.to_str().unwrap(), "0", "again", &[], &again);
    let back = Heightmap::load(&again).unwrap();
    assert_eq!(back.place, src.place);
    assert_eq!(back.nodata_mask(), src.nodata_mask());
    assert_eq!(back.data(), src.data());
}

/// The geographic fixture packed losslessly in 16² tiles to `name`, taken
/// apart to have its header edited.
fn placed_pack(name: &str) -> common::packs::Parts {
    let pack = tmp(name);
    run(&[
        "pack",
        GEOGRAPHIC,
        "-o",
        pack.to_str().unwrap(),
        "--tile",
        "16",
    ]);
    common::packs::Parts::of(&std::fs::read(&pack).unwrap())
}

/// A pack whose header's place does not add up is refused, naming the
/// file and the field, before a sample is written.
#[test]
fn a_pack_with_a_broken_place_is_refused() {
    let parts = placed_pack("broken.tcz");
    let header = parts.header();
    assert_eq!(header["place"]["nodata"], -32768.0, "{header}");
    let cases: [(&str, serde_json::Value, &str); 4] = [
        (
            "geokeys",
            serde_json::json!([1, 1, 0, 9]),
            "announces 9 keys",
        ),
        ("pixel_scale", serde_json::json!([0.0, 1.0]), "pixel scale"),
        (
            "origin",
            serde_json::json!([null, 0.0]),
            "header is not valid",
        ),
        ("nodata", serde_json::json!("x"), "header is not valid"),
    ];
    for (field, value, want) in cases {
        let mut h = header.clone();
        h["place"][field] = value;
        let forged = tmp(&format!("broken-{field}.tcz"));
        std::fs::write(&forged, parts.with_header(&h).assemble()).unwrap();
        let out = tmp(&format!("broken-{field}.tif"));
        let (code, _, err) = cli(&[
            "unpack",
            forged.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{field}: {err}");
        assert!(
            err.contains(&format!("broken-{field}.tcz")) && err.contains(want),
            "{field}: {err}"
        );
        assert!(!out.exists(), "{field}");
    }
}

/// `gdalinfo -json` of a file.
fn gdalinfo(path: &Path) -> Option<serde_json::Value> {
    let out = std::process::Command::new("gdalinfo")
        .arg("-json")
        .arg(path)
        .output();
    match out {
        Ok(o) if o.status.success() => Some(serde_json::from_slice(&o.stdout).unwrap()),
        Ok(o) => panic!(
            "gdalinfo {}: {}",
            path.display(),
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => {
            assert!(
                std::env::var("TERRACLIP_REQUIRE_GDAL").as_deref() != Ok("1"),
                "TERRACLIP_REQUIRE_GDAL=1 but gdalinfo cannot run: {e}"
            );
            None
        }
    }
}

/// What GDAL says of a file's place: the CRS's WKT, the geotransform and
/// band 1's no-data value.
fn gdal_place(v: &serde_json::Value) -> (String, Vec<f64>, Option<f64>) {
    (
        v["coordinateSystem"]["wkt"]
            .as_str()
            .unwrap_or("")
            .to_string(),
        serde_json::from_value(v["geoTransform"].clone()).unwrap(),
        v["bands"][0]["noDataValue"].as_f64(),
    )
}

/// GDAL reads each unpacked map with the input's CRS, geotransform and
/// no-data value: a geographic Int16 GeoTIFF with −32768, a projected
/// f32 one, and GDAL's own netCDF file (against GDAL's GeoTIFF of it, its
/// axes' spacing within 1e-9 of a cell: the netCDF reader takes the step
/// from the first and last coordinates, GDAL from its own fit).
#[test]
fn gdal_places_unpacked_maps_where_the_input_was() {
    let cases = [
        (GEOGRAPHIC, GEOGRAPHIC, 0.0),
        (PROJECTED, PROJECTED, 0.0),
        (
            "tests/data/netcdf/gdal-int16.nc",
            "tests/data/netcdf/gdal-int16.tif",
            1e-9,
        ),
    ];
    for (input, reference, tol) in cases {
        let Some(want) = gdalinfo(Path::new(reference)) else {
            eprintln!("skipped: gdalinfo is not installed (apt install gdal-bin)");
            return;
        };
        let out = tmp(&format!(
            "gdal-{}.tif",
            Path::new(input).file_stem().unwrap().to_string_lossy()
        ));
        round_trip(input, "0.5", "gdal", &[], &out);
        let (wkt, gt, nd) = gdal_place(&gdalinfo(&out).unwrap());
        let (want_wkt, want_gt, want_nd) = gdal_place(&want);
        assert!(!want_wkt.is_empty(), "{reference} has a CRS");
        assert_eq!(wkt, want_wkt, "{input}");
        assert_eq!(nd, want_nd, "{input}");
        let cell = want_gt[1].abs();
        for (a, b) in gt.iter().zip(&want_gt) {
            assert!(
                (a - b).abs() <= tol * cell,
                "{input}: {gt:?} against {want_gt:?}"
            );
        }
    }
}

/// The header's `place` mutated as a JSON tree (numbers, strings, keys,
/// nesting), the checksums made right: every case loads or is refused
/// naming the file, never a panic; every 8th loaded case is unpacked to a
/// GeoTIFF through the CLI, which exits 0 with a file terraclip reads
/// back, or 1.
#[test]
fn mutated_places_load_or_name_the_file() {
    use common::fuzz::{edit_json, Rng};
    let parts = placed_pack("fuzz-seed.tcz");
    let header = parts.header();
    let mut rng = Rng(0x9E0_7EF5_0001);
    let case = tmp("fuzz-case.tcz");
    let (mut loaded, mut refused, mut unpacked, mut failures) = (0, 0, 0, vec![]);
    for i in 0..400 {
        let mut h = header.clone();
        edit_json(&mut rng, &mut h["place"]);
        std::fs::write(&case, parts.with_header(&h).assemble()).unwrap();
        match common::packs::pack_once(&case) {
            Ok(true) => {
                loaded += 1;
                if loaded % 8 == 0 {
                    let out = tmp("fuzz-out.tif");
                    let (code, _, err) = cli(&[
                        "unpack",
                        case.to_str().unwrap(),
                        "-o",
                        out.to_str().unwrap(),
                    ]);
                    match code {
                        0 if Heightmap::load(&out).is_ok() => unpacked += 1,
                        1 if err.contains("fuzz-case.tcz") => {}
                        _ => failures.push(format!("case {i}: unpack exit {code}: {err}")),
                    }
                }
            }
            Ok(false) => refused += 1,
            Err(e) => failures.push(format!("case {i}: {e}")),
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    eprintln!("place fuzz: of 400, {loaded} loaded ({unpacked} unpacked), {refused} refused");
    assert_eq!((loaded, refused, unpacked), (151, 249, 18));
    assert!(loaded >= 40 && refused >= 40);
}
