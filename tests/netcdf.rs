//! netCDF grids with CF conventions as input: read as GDAL's GeoTIFF
//! conversion of the same grid reads, sample for sample; CF's variable
//! choice, axes, packing and no-data; bad files named; and every command
//! that takes a map takes one. Fixtures: tests/data/netcdf (README.md gives
//! the command that made each).

mod common;

use common::cli;
use common::fuzz::{cli_exits, Rng};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use terraclip::terrain::{rows, Heightmap};

const DIR: &str = "tests/data/netcdf";

fn fixture(name: &str) -> PathBuf {
    Path::new(DIR).join(name)
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-netcdf-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// Metres per degree on WGS 84 by the usual series (the "length of a
/// degree" tables), independent of the reader's closed form.
fn series(lat: f64) -> [f64; 2] {
    let p = lat.to_radians();
    [
        111_412.84 * p.cos() - 93.5 * (3.0 * p).cos() + 0.118 * (5.0 * p).cos(),
        111_132.954 - 559.822 * (2.0 * p).cos() + 1.175 * (4.0 * p).cos()
            - 0.0023 * (6.0 * p).cos(),
    ]
}

fn nodata(h: &Heightmap) -> Vec<bool> {
    h.nodata_mask().to_vec()
}

/// Heights with no-data as None, row-major.
fn heights(h: &Heightmap) -> Vec<Option<f32>> {
    h.data()
        .iter()
        .zip(h.nodata_mask())
        .map(|(&v, &n)| (!n).then_some(v))
        .collect()
}

#[test]
fn a_netcdf_grid_reads_as_its_geotiff_conversion_sample_for_sample() {
    // GDAL writes the grid south to north (lat ascending); the GeoTIFF it
    // converts the same file to is north first.
    let nc = Heightmap::load(&fixture("gdal-int16.nc")).unwrap();
    let tif = Heightmap::load(&fixture("gdal-int16.tif")).unwrap();
    assert_eq!((nc.width(), nc.height()), (64, 48));
    assert_eq!((tif.width(), tif.height()), (64, 48));
    assert_eq!(nc.data(), tif.data(), "heights");
    assert_eq!(nodata(&nc), nodata(&tif));
    let (lo, hi) = nc.min_max();
    assert!(lo > 236.0 && hi < 1076.0 && hi - lo > 400.0, "{lo}..{hi}");
    assert_eq!(nc.format, "netcdf1-i16");
    assert_eq!(nc.crs.as_deref(), Some("EPSG:4326"));
    assert_eq!(tif.crs.as_deref(), Some("EPSG:4326"));
    // 3" cells at the centre latitude, 36.62958 N: within 0.1 % of WGS 84's
    // metres per degree there (the series is good to 0.05 m).
    let lat = 36.649_583_333_333_33 - 24.0 / 1200.0;
    let [mx, my] = series(lat);
    for (got, want) in nc.cell_size.iter().zip([mx / 1200.0, my / 1200.0]) {
        assert!(
            (got / want - 1.0).abs() < 1e-3,
            "cell {got} m against {want} m"
        );
    }
    for (a, b) in nc.cell_size.iter().zip(tif.cell_size) {
        assert!((a / b - 1.0).abs() < 1e-9, "{a} against the GeoTIFF's {b}");
    }
    // By rows: the bands of a pack read the same samples.
    let src = rows::open(&fixture("gdal-int16.nc")).unwrap();
    assert_eq!(src.size(), [64, 48]);
    assert_eq!(src.read_rows(0, 48).unwrap(), tif.data());
    assert_eq!(src.read_rows(17, 33).unwrap(), tif.data()[17 * 64..33 * 64]);
    assert_eq!(src.read_rows(47, 48).unwrap(), tif.data()[47 * 64..]);
}

#[test]
fn cf_conventions_choose_the_variable_and_orient_scale_and_mask_it() {
    // CDF-2. `elevation` is named by its standard_name over the other grid
    // (`tid`); latitude ascends, so the last file row is the first map row;
    // -32767 is a short's default fill.
    let g = Heightmap::load(&fixture("gebco-like.nc")).unwrap();
    assert_eq!(
        (g.width(), g.height(), g.format.as_str()),
        (4, 3, "netcdf2-i16")
    );
    assert_eq!(
        heights(&g),
        [
            Some(9.0),
            Some(10.0),
            None,
            Some(12.0),
            Some(5.0),
            Some(6.0),
            Some(7.0),
            Some(8.0),
            Some(1.0),
            Some(2.0),
            Some(3.0),
            Some(4.0)
        ]
    );
    let [mx, my] = series(45.25);
    assert!((g.cell_size[0] / (0.25 * mx) - 1.0).abs() < 1e-3);
    assert!((g.cell_size[1] / (0.25 * my) - 1.0).abs() < 1e-3);
    assert_eq!(g.crs.as_deref(), Some("geographic"));
    // The other grid, by name.
    let t = Heightmap::load_var(&fixture("gebco-like.nc"), Some("tid")).unwrap();
    assert_eq!(t.format, "netcdf2-i8");

    // CDF-1. A depth below the geoid is negated after scale_factor 0.5 and
    // add_offset 10; _FillValue -1, missing_value -2 and 1001 (over
    // valid_max 1000) are no-data. Latitude descends: no flip.
    let d = Heightmap::load(&fixture("depth-scaled.nc")).unwrap();
    assert_eq!(
        heights(&d),
        [Some(-10.0), Some(-60.0), None, None, None, Some(-510.0)]
    );

    // CDF-5, (time, lon, lat): a record variable with one record, the
    // grid transposed (longitude first) and latitude ascending. No
    // _FillValue: a float's default fill, 9.96921e36, is no-data.
    let l = Heightmap::load(&fixture("lonlat.nc")).unwrap();
    assert_eq!(
        (l.width(), l.height(), l.format.as_str()),
        (3, 2, "netcdf5-f32")
    );
    assert_eq!(
        heights(&l),
        [Some(2.5), Some(4.5), Some(6.5), Some(1.5), Some(3.5), None]
    );
    // A transposed grid by rows reads the same.
    let src = rows::open(&fixture("lonlat.nc")).unwrap();
    let by_rows = src.read_rows(0, 2).unwrap();
    assert_eq!(by_rows[..5], [2.5, 4.5, 6.5, 1.5, 3.5]);
    assert!(by_rows[5].is_nan());

    // Two grids and no standard_name: the variable must be named.
    let b = Heightmap::load_var(&fixture("two-grids.nc"), Some("b")).unwrap();
    assert_eq!(b.data(), [10.0, 20.0, 30.0, 40.0, 50.0, 60.0]);
    assert_eq!((b.cell_size, b.crs.as_deref()), ([1.0, 1.0], None));
}

/// netCDF-4 (HDF5, here DEFLATE-compressed by `nccopy -k nc4 -d 5`) reads
/// through libnetcdf to the classic file's samples, whole and by rows.
#[cfg(feature = "netcdf4")]
#[test]
fn netcdf4_files_read_as_their_classic_originals() {
    for (nc4, classic) in [
        ("gdal-int16-nc4.nc", "gdal-int16.nc"),
        ("lonlat-nc4.nc", "lonlat.nc"),
    ] {
        let a = Heightmap::load(&fixture(nc4)).unwrap();
        let b = Heightmap::load(&fixture(classic)).unwrap();
        assert_eq!(heights(&a), heights(&b), "{nc4}");
        assert_eq!((a.cell_size, &a.crs), (b.cell_size, &b.crs), "{nc4}");
        assert!(a.format.starts_with("netcdf4-"), "{}", a.format);
        let (ra, rb) = (
            rows::open(&fixture(nc4)).unwrap(),
            rows::open(&fixture(classic)).unwrap(),
        );
        let h = b.height();
        for (y0, y1) in [(0, h), (1, h), (0, 1)] {
            let (va, vb) = (ra.read_rows(y0, y1).unwrap(), rb.read_rows(y0, y1).unwrap());
            assert_eq!(va.len(), vb.len());
            for (x, y) in va.iter().zip(&vb) {
                assert!(
                    x == y || (x.is_nan() && y.is_nan()),
                    "{nc4} rows {y0}..{y1}"
                );
            }
        }
    }
    let b = Heightmap::load_var(&fixture("netcdf4.nc"), Some("b")).unwrap();
    assert_eq!(b.data(), [10.0, 20.0, 30.0, 40.0, 50.0, 60.0]);
}

/// `args` fails with exit code 1, no signal, and stderr naming `file` and
/// saying `reason`.
fn fails_cleanly(args: &[&str], file: &str, reason: &str) {
    let (code, _, err) = cli(args);
    assert_eq!(code, 1, "{args:?}: {err}");
    assert!(err.contains(file), "{args:?} does not name {file}: {err}");
    assert!(
        err.contains(reason),
        "{args:?} does not say '{reason}': {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn files_the_reader_cannot_take_say_why_and_how_to_convert_them() {
    let p = |n: &str| fixture(n).to_str().unwrap().to_string();
    fails_cleanly(
        &["info", &p("two-grids.nc")],
        "two-grids.nc",
        "several variables could be the map ('a', 'b')",
    );
    fails_cleanly(
        &["info", &p("two-grids.nc"), "--variable", "c"],
        "two-grids.nc",
        "variable 'c' is not in the file; its grids are 'a', 'b'",
    );
    fails_cleanly(
        &["info", &p("gebco-like.nc"), "--variable", "lat"],
        "gebco-like.nc",
        "variable 'lat': a 1-dimensional Double variable is not a map",
    );
    if !cfg!(feature = "netcdf4") {
        fails_cleanly(
            &["info", &p("netcdf4.nc")],
            "netcdf4.nc",
            "a netCDF-4 (HDF5) file, which this build does not read (one with `--features \
             netcdf4` does, given libnetcdf-dev); rewrite it in the classic format with `nccopy \
             -k classic",
        );
    }
    fails_cleanly(
        &["info", &p("rec-axis.nc")],
        "rec-axis.nc",
        "the record (unlimited) dimension is one of the map's axes",
    );
    fails_cleanly(
        &["info", "tests/data/jacksboro_16.png", "--variable", "z"],
        "jacksboro_16.png",
        "only netCDF files (.nc) hold several",
    );
}

#[test]
fn degrees_on_unnamed_axes_warn_and_a_declared_crs_converts_them() {
    let p = fixture("xy-degrees.nc");
    let path = p.to_str().unwrap();
    let (code, out, err) = cli(&["info", path, "--json"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("warning: tests/data/netcdf/xy-degrees.nc: the file names no CRS"),
        "{err}"
    );
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(v["cell_size"][0].as_f64().unwrap() < 0.01);
    let (code, out, err) = cli(&["info", path, "--json", "--crs", "EPSG:4326"]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("warning"), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    // 15" of longitude at the grid's centre, 28.08125 N.
    let want = series(28.081_25)[0] / 240.0;
    let got = v["cell_size"][0].as_f64().unwrap();
    assert!((got / want - 1.0).abs() < 1e-3, "{got} against {want}");
}

#[test]
fn every_command_that_takes_a_map_takes_a_netcdf_grid() {
    let nc = fixture("gdal-int16.nc");
    let nc = nc.to_str().unwrap();
    let tif = fixture("gdal-int16.tif");
    let tif = tif.to_str().unwrap();

    let (code, out, err) = cli(&["info", nc, "--json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(64), Some(48))
    );
    assert_eq!(v["format"], "netcdf1-i16");

    // render: the same picture as the GeoTIFF conversion's.
    let (a, b) = (tmp("nc.png"), tmp("tif.png"));
    for (map, out) in [(nc, &a), (tif, &b)] {
        let (code, _, err) = cli(&[
            "render",
            "--heightmap",
            map,
            "--size",
            "96x64",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
    }
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());

    // pack (by rows) and unpack: level 0 comes back within the bound, and
    // the packs of the two files hold the same samples.
    let (pa, pb) = (tmp("nc.tcz"), tmp("tif.tcz"));
    for (map, out) in [(nc, &pa), (tif, &pb)] {
        let (code, out, err) = cli(&[
            "pack",
            map,
            "-o",
            out.to_str().unwrap(),
            "--max-error",
            "0",
            "--json",
            "--tile",
            "16",
        ]);
        assert_eq!(code, 0, "{err}");
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(v["max_error_seen"].as_f64(), Some(0.0));
    }
    let (ua, ub) = (tmp("nc.f32"), tmp("tif.f32"));
    for (p, u) in [(&pa, &ua), (&pb, &ub)] {
        let (code, _, err) = cli(&["unpack", p.to_str().unwrap(), "-o", u.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
    }
    let unpacked = std::fs::read(&ua).unwrap();
    assert_eq!(unpacked, std::fs::read(&ub).unwrap());
    let truth = Heightmap::load(&fixture("gdal-int16.tif")).unwrap();
    let back: Vec<f32> = unpacked
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(back, truth.data());

    // synthesis reads it.
    let (code, out, err) = cli(&["synthesis", nc, "--json"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("rmse"), "{out}");

    // A scene whose terrain is the netCDF grid exports.
    let scene = tmp("nc.toml");
    std::fs::write(
        &scene,
        format!(
            "[terrain]\nfile = {:?}\n[camera]\nposition = [2400.0, -1500.0, 1500.0]\n\
             look_at = [2400.0, 2200.0, 500.0]\n[image]\nwidth = 64\nheight = 48\n",
            std::fs::canonicalize(nc).unwrap()
        ),
    )
    .unwrap();
    let dir = tmp("nc-export");
    let (code, _, err) = cli(&[
        "export",
        scene.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(dir.join("frame.glb").is_file());
}

// ---- Structured fuzz: files written from a model, one field made wrong.

/// An attribute: name, type code, element count and big-endian values.
#[derive(Clone)]
struct Att(String, u32, u64, Vec<u8>);

/// A variable: name, dimension ids, attributes, type code, data (padded
/// to 4 on writing) and a `begin` that replaces the true one.
#[derive(Clone)]
struct V {
    name: String,
    dims: Vec<u64>,
    attrs: Vec<Att>,
    ty: u32,
    data: Vec<u8>,
    begin: Option<u64>,
}

/// A classic-format file as fields, written with every offset right
/// unless a mutation set one.
#[derive(Clone)]
struct Cdf {
    version: u8,
    dims: Vec<(String, u64)>,
    vars: Vec<V>,
}

fn text(name: &str, v: &str) -> Att {
    Att(name.into(), 2, v.len() as u64, v.as_bytes().to_vec())
}
fn f64s(name: &str, v: &[f64]) -> Att {
    Att(
        name.into(),
        6,
        v.len() as u64,
        v.iter().flat_map(|x| x.to_be_bytes()).collect(),
    )
}
fn i16s(name: &str, v: &[i16]) -> Att {
    Att(
        name.into(),
        3,
        v.len() as u64,
        v.iter().flat_map(|x| x.to_be_bytes()).collect(),
    )
}

impl Cdf {
    /// The bytes, and the offsets of every count the header holds (where
    /// a mutation may write a lie).
    fn write(&self) -> (Vec<u8>, Vec<usize>) {
        let big = self.version == 5;
        let mut counts = vec![];
        let mut b: Vec<u8> = b"CDF".to_vec();
        b.push(self.version);
        let count = |b: &mut Vec<u8>, counts: &mut Vec<usize>, n: u64| {
            counts.push(b.len());
            if big {
                b.extend(n.to_be_bytes())
            } else {
                b.extend((n as u32).to_be_bytes())
            }
        };
        let pad = |b: &mut Vec<u8>| b.resize(b.len().next_multiple_of(4), 0);
        let name = |b: &mut Vec<u8>, counts: &mut Vec<usize>, s: &str| {
            count(b, counts, s.len() as u64);
            b.extend(s.as_bytes());
            pad(b);
        };
        let attrs = |b: &mut Vec<u8>, counts: &mut Vec<usize>, a: &[Att]| {
            if a.is_empty() {
                b.extend([0u8; 4]);
                count(b, counts, 0);
                return;
            }
            b.extend(12u32.to_be_bytes());
            count(b, counts, a.len() as u64);
            for Att(n, ty, k, v) in a {
                name(b, counts, n);
                b.extend(ty.to_be_bytes());
                count(b, counts, *k);
                b.extend(v);
                pad(b);
            }
        };
        count(&mut b, &mut counts, 0); // numrecs
        b.extend(10u32.to_be_bytes());
        count(&mut b, &mut counts, self.dims.len() as u64);
        for (n, len) in &self.dims {
            name(&mut b, &mut counts, n);
            count(&mut b, &mut counts, *len);
        }
        attrs(&mut b, &mut counts, &[text("Conventions", "CF-1.10")]);
        b.extend(11u32.to_be_bytes());
        count(&mut b, &mut counts, self.vars.len() as u64);
        let mut begins = vec![];
        for v in &self.vars {
            name(&mut b, &mut counts, &v.name);
            count(&mut b, &mut counts, v.dims.len() as u64);
            for &d in &v.dims {
                count(&mut b, &mut counts, d);
            }
            attrs(&mut b, &mut counts, &v.attrs);
            b.extend(v.ty.to_be_bytes());
            count(&mut b, &mut counts, v.data.len().next_multiple_of(4) as u64);
            begins.push(b.len());
            b.extend(if self.version == 1 {
                vec![0u8; 4]
            } else {
                vec![0u8; 8]
            });
        }
        for (v, at) in self.vars.iter().zip(begins) {
            let begin = v.begin.unwrap_or(b.len() as u64);
            if self.version == 1 {
                b[at..at + 4].copy_from_slice(&(begin as u32).to_be_bytes());
            } else {
                b[at..at + 8].copy_from_slice(&begin.to_be_bytes());
            }
            b.extend(&v.data);
            pad(&mut b);
        }
        (b, counts)
    }
}

/// A GEBCO-like grid: 6 × 5 shorts, latitude ascending, scaled, with a
/// fill value; and a transposed f32 grid with its depth named.
fn models() -> Vec<Cdf> {
    let lat = |n: usize, first: f64, step: f64| -> Vec<f64> {
        (0..n).map(|i| first + step * i as f64).collect()
    };
    let coord = |name: &str, dim: u64, units: &str, v: &[f64]| V {
        name: name.into(),
        dims: vec![dim],
        attrs: vec![text("units", units)],
        ty: 6,
        data: v.iter().flat_map(|x| x.to_be_bytes()).collect(),
        begin: None,
    };
    let shorts: Vec<u8> = (0..30i16)
        .map(|i| if i == 7 { -999 } else { i * 37 - 200 })
        .flat_map(|x| x.to_be_bytes())
        .collect();
    let gebco = Cdf {
        version: 1,
        dims: vec![("lat".into(), 5), ("lon".into(), 6)],
        vars: vec![
            coord("lat", 0, "degrees_north", &lat(5, 45.0, 0.25)),
            coord("lon", 1, "degrees_east", &lat(6, 6.0, 0.25)),
            V {
                name: "elevation".into(),
                dims: vec![0, 1],
                attrs: vec![
                    text("standard_name", "height_above_mean_sea_level"),
                    f64s("scale_factor", &[0.5]),
                    f64s("add_offset", &[100.0]),
                    i16s("_FillValue", &[-999]),
                ],
                ty: 3,
                data: shorts,
                begin: None,
            },
        ],
    };
    let floats: Vec<u8> = (0..20)
        .map(|i| i as f32 * 1.5 - 3.0)
        .flat_map(|x| x.to_be_bytes())
        .collect();
    let transposed = Cdf {
        version: 5,
        dims: vec![("lon".into(), 4), ("lat".into(), 5)],
        vars: vec![
            coord("lon", 0, "degrees_east", &lat(4, 10.0, -0.1)),
            coord("lat", 1, "degrees_north", &lat(5, -60.0, 0.1)),
            V {
                name: "depth".into(),
                dims: vec![0, 1],
                attrs: vec![text("standard_name", "sea_floor_depth_below_geoid")],
                ty: 5,
                data: floats,
                begin: None,
            },
        ],
    };
    let mut cdf2 = gebco.clone();
    cdf2.version = 2;
    vec![gebco, transposed, cdf2]
}

/// One field of `m` made wrong, or its written bytes damaged.
/// Damage done to a model's written bytes, given the offsets of its counts.
type Damage = Box<dyn Fn(&mut Vec<u8>, &[usize])>;

fn mutate_model(rng: &mut Rng, m: &mut Cdf) -> Option<Damage> {
    let extreme = |rng: &mut Rng| -> u64 {
        [
            0,
            1,
            2,
            3,
            7,
            1 << 20,
            1 << 31,
            u32::MAX as u64,
            u64::MAX,
            rng.next(),
        ][rng.below(10)]
    };
    let nv = m.vars.len();
    match rng.below(12) {
        0 => {
            let d = rng.below(m.dims.len());
            m.dims[d].1 = extreme(rng);
        }
        1 => {
            let v = rng.below(nv);
            m.vars[v].ty = rng.below(13) as u32;
        }
        2 => {
            let v = rng.below(nv);
            let e = extreme(rng);
            m.vars[v].begin = Some(
                e.min(u32::MAX as u64 * u64::from(rng.below(2) == 0))
                    .max(e * u64::from(rng.below(4) == 0)),
            );
        }
        3 => {
            // An attribute's value made absurd.
            let v = m.vars.last_mut().unwrap();
            let val = [0.0, f64::NAN, f64::INFINITY, -1.0, 1e300, -999.0][rng.below(6)];
            let name = [
                "scale_factor",
                "add_offset",
                "_FillValue",
                "missing_value",
                "valid_min",
                "valid_max",
            ][rng.below(6)];
            v.attrs.retain(|a| a.0 != name);
            v.attrs.push(f64s(name, &[val]));
            if rng.below(3) == 0 {
                v.attrs.push(f64s("valid_range", &[val, -val]));
            }
        }
        4 => {
            // A coordinate value made wrong.
            let c = &mut m.vars[rng.below(2)];
            let n = c.data.len() / 8;
            let i = rng.below(n.max(1));
            let bad = [f64::NAN, 0.0, 1e9, -91.0, 45.0][rng.below(5)];
            c.data[i * 8..i * 8 + 8].copy_from_slice(&bad.to_be_bytes());
        }
        5 => {
            let v = rng.below(nv);
            m.vars.remove(v);
        }
        6 => m.vars.last_mut().unwrap().dims.reverse(),
        7 => {
            let d = rng.below(m.dims.len());
            m.dims[d].0 = ["lat", "lon", "x", "y", "latitude", "q"][rng.below(6)].into();
        }
        8 => {
            let mut twin = m.vars.last().unwrap().clone();
            twin.name = "twin".into();
            if rng.below(2) == 0 {
                twin.attrs.retain(|a| a.0 != "standard_name");
            }
            m.vars.push(twin);
        }
        9 => m.version = [1, 2, 3, 5, 0][rng.below(5)],
        10 => {
            // A count in the header made a lie.
            let e = extreme(rng);
            let pick = rng.next();
            let big = m.version == 5;
            return Some(Box::new(move |b: &mut Vec<u8>, counts: &[usize]| {
                let at = counts[pick as usize % counts.len()];
                if at + 8 > b.len() {
                    return; // cut off by an earlier truncation
                }
                if big {
                    b[at..at + 8].copy_from_slice(&e.to_be_bytes());
                } else {
                    b[at..at + 4].copy_from_slice(&(e as u32).to_be_bytes());
                }
            }));
        }
        _ => {
            let cut = rng.next();
            return Some(Box::new(move |b: &mut Vec<u8>, _: &[usize]| {
                b.truncate(cut as usize % b.len());
            }));
        }
    }
    None
}

/// Where a case stopped: the header refused, the grid refused (variable,
/// axes, extent, packing) or the map loaded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    Header,
    Grid,
    Loaded,
}

/// The stage an error message names: the header's fields, or else the
/// grid's.
fn stage_of(msg: &str) -> Stage {
    const HEADER: [&str; 10] = [
        "magic",
        "numrecs",
        "dimension list",
        "dimension '",
        "'s name",
        "global attribute",
        "variable list",
        "'s attribute",
        "dimension id",
        "type",
    ];
    if HEADER.iter().any(|h| msg.contains(h)) && !msg.contains("is not a map") {
        Stage::Header
    } else {
        Stage::Grid
    }
}

/// Cases per stage in the seeded run, measured once and checked exactly:
/// a reader that starts accepting what it refused (or the reverse) fails.
const EXPECTED_STAGES: [(Stage, usize); 3] = [
    (Stage::Header, 365),
    (Stage::Grid, 583),
    (Stage::Loaded, 552),
];

#[test]
fn structured_netcdf_mutations_load_or_name_the_file_and_reach_every_stage() {
    let path = tmp("case.nc");
    let mut rng = Rng(0x6E65_7443_4446_2026);
    let mut stages = [0usize; 3];
    let mut failures = vec![];
    let models = models();
    // Each seed loads untouched.
    for m in &models {
        std::fs::write(&path, m.write().0).unwrap();
        Heightmap::load(&path).unwrap_or_else(|e| panic!("seed: {e}"));
    }
    const CASES: usize = 1500;
    for case in 0..CASES {
        let mut m = models[case % models.len()].clone();
        let mut damage = vec![];
        for _ in 0..1 + rng.below(2) {
            damage.extend(mutate_model(&mut rng, &mut m));
        }
        let (mut bytes, counts) = m.write();
        for d in &damage {
            d(&mut bytes, &counts);
        }
        std::fs::write(&path, &bytes).unwrap();
        let stage = match catch_unwind(AssertUnwindSafe(|| Heightmap::load(&path))) {
            Err(_) => {
                failures.push(format!("case {case}: panic"));
                continue;
            }
            Ok(Ok(h)) => {
                // The same samples by rows, and a sound mask.
                let src = rows::open(&path).unwrap();
                let by_rows = src.read_rows(0, h.height()).unwrap();
                for (i, (&v, &nd)) in by_rows.iter().zip(h.nodata_mask()).enumerate() {
                    if nd != v.is_nan() || (!nd && v != h.data()[i]) {
                        failures.push(format!("case {case}: sample {i} by rows {v}"));
                        break;
                    }
                }
                if h.data().iter().any(|v| !v.is_finite()) {
                    failures.push(format!("case {case}: a non-finite height"));
                }
                Stage::Loaded
            }
            Ok(Err(e)) => {
                let msg = e.to_string();
                if !msg.contains("case.nc") {
                    failures.push(format!("case {case}: error names no file: {msg}"));
                }
                stage_of(&msg)
            }
        };
        stages[stage as usize] += 1;
        // Every 50th case through the binary: an exit code, no signal.
        if case % 50 == 0 {
            if let Err(e) = cli_exits(&["info".as_ref(), path.as_os_str()], "case.nc") {
                failures.push(format!("case {case} through the CLI: {e}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    let got: Vec<(Stage, usize)> = [Stage::Header, Stage::Grid, Stage::Loaded]
        .into_iter()
        .map(|s| (s, stages[s as usize]))
        .collect();
    eprintln!("netCDF fuzz: {CASES} cases, stopped at {got:?}");
    for (s, n) in &got {
        assert!(
            *n * 10 >= CASES,
            "{s:?} reached by {n} of {CASES} cases, under 10 %"
        );
    }
    assert_eq!(got, EXPECTED_STAGES, "cases per stage");
}
