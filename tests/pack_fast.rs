//! The fast coder (`pack --coder fast`): it codes the ratio coder's
//! residual symbols with zstd, so a pack's heights must not depend on
//! the coder. Every sample of every level of a fast pack is the ratio
//! pack's, bit for bit, and so within the bound; tiles decode alone; the
//! header names the coder; the CLI and the streaming packer write it.

mod common;

use std::path::{Path, PathBuf};
use terraclip::pack::{file, stream, Coder, Packed, Predictor};
use terraclip::pyramid::{Filter, Pyramid, PyramidLevel};
use terraclip::terrain::Heightmap;

fn jacksboro() -> Heightmap {
    let dem = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    Heightmap::load(&dem.join("jacksboro_16.png")).unwrap()
}

fn bits(levels: &[PyramidLevel]) -> Vec<Vec<u32>> {
    levels
        .iter()
        .map(|l| l.data.iter().map(|v| v.to_bits()).collect())
        .collect()
}

/// The largest |decoded − source| over every valid sample of every level.
fn worst(source: &[PyramidLevel], decoded: &[PyramidLevel]) -> f64 {
    source
        .iter()
        .zip(decoded)
        .flat_map(|(s, d)| {
            assert_eq!(s.nodata, d.nodata);
            s.data
                .iter()
                .zip(&d.data)
                .zip(&s.nodata)
                .filter(|(_, &nd)| !nd)
                .map(|((&a, &b), _)| (a as f64 - b as f64).abs())
        })
        .fold(0.0, f64::max)
}

#[test]
fn a_fast_pack_decodes_to_the_ratio_packs_heights_within_the_bound() {
    let j = jacksboro();
    let procedural = common::terrain(5, 150, 110);
    let holes = common::packs::holes();
    let cases: [(&str, &Heightmap, f64, Predictor, usize); 8] = [
        ("jacksboro lifting E=1", &j, 1.0, Predictor::Lifting, 64),
        ("jacksboro fitted E=1", &j, 1.0, Predictor::Fitted, 64),
        ("holes fitted E=0.5", &holes, 0.5, Predictor::Fitted, 16),
        ("jacksboro upsampled E=1", &j, 1.0, Predictor::Upsampled, 64),
        (
            "jacksboro lossless lattice",
            &j,
            0.0,
            Predictor::Lifting,
            64,
        ),
        (
            "procedural lossless bits",
            &procedural,
            0.0,
            Predictor::Lifting,
            32,
        ),
        ("procedural E=4", &procedural, 4.0, Predictor::Lifting, 32),
        ("holes E=0.5", &holes, 0.5, Predictor::Lifting, 16),
    ];
    for (name, map, e, predictor, tile) in cases {
        let src = Pyramid::build(map, Filter::default(), 64).levels;
        let (ratio, recon) =
            Packed::encode_coded(&src, e, tile, map.lattice, predictor, Coder::Ratio);
        let (fast, fast_recon) =
            Packed::encode_coded(&src, e, tile, map.lattice, predictor, Coder::Fast);
        assert_eq!(fast.coder, Coder::Fast);
        assert_ne!(
            ratio.levels[0].tiles, fast.levels[0].tiles,
            "{name}: the coders write different bytes"
        );
        assert_eq!(bits(&fast_recon), bits(&recon), "{name}: reconstruction");
        let decoded = fast.decode().unwrap();
        assert_eq!(bits(&decoded), bits(&recon), "{name}: decode");
        let err = worst(&src, &decoded);
        // Lossless is exact; lossy holds the bound on every valid sample.
        assert!(err <= e, "{name}: error {err} over the bound {e}");
        // Every tile of level 0 and of the level above it alone equals its
        // part of the whole decode.
        for l in [0, 1] {
            let [nx, ny] = fast.tiles_of(l);
            for t in 0..nx * ny {
                let tile = fast
                    .decode_tile(l, [t % nx, t / nx], &decoded[l + 1])
                    .unwrap();
                let [x0, y0, w, h] = tile.rect;
                for r in 0..h {
                    let at = (y0 + r) * decoded[l].width + x0;
                    let want: Vec<u32> = decoded[l].data[at..at + w]
                        .iter()
                        .map(|v| v.to_bits())
                        .collect();
                    let got: Vec<u32> = tile.data[r * w..][..w]
                        .iter()
                        .map(|v| v.to_bits())
                        .collect();
                    assert_eq!(got, want, "{name}: level {l} tile {t} row {r}");
                    assert_eq!(tile.nodata[r * w..][..w], decoded[l].nodata[at..at + w]);
                }
            }
        }
    }
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-pack-fast-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

#[test]
fn a_fast_pack_file_names_its_coder_and_reads_back() {
    let map = common::terrain(3, 70, 50);
    let src = Pyramid::build(&map, Filter::default(), 64).levels;
    for coder in [Coder::Ratio, Coder::Fast] {
        let (packed, recon) = Packed::encode_coded(&src, 1.0, 16, None, Predictor::Lifting, coder);
        let path = tmp(&format!("{}.tcz", coder.name()));
        file::write(&path, &packed, map.cell_size, "sinc-blackman:11", "test").unwrap();
        let parts = common::packs::Parts::of(&std::fs::read(&path).unwrap());
        let json = String::from_utf8(parts.json.clone()).unwrap();
        // A ratio pack's header is as before there was a choice.
        assert_eq!(
            json.contains(r#""coder":"fast""#),
            coder == Coder::Fast,
            "{json}"
        );
        assert!(!json.contains(r#""coder":"ratio""#));
        let (header, read) = file::read(&path).unwrap();
        assert_eq!(header.coder, coder);
        assert_eq!(read.coder, coder);
        assert_eq!(bits(&read.decode().unwrap()), bits(&recon));
        let (code, out, _) = common::cli(&["info", path.to_str().unwrap(), "--json"]);
        assert_eq!(code, 0);
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(v["coder"], coder.name());
        // Version 3 is version 4 but for the fast coder's tiles (pcodec
        // then): a version-3 ratio pack reads the same heights, a fast one
        // is refused, naming the file, the version and what to do.
        let mut old = std::fs::read(&path).unwrap();
        assert_eq!(old[8..12], file::VERSION.to_le_bytes());
        old[8..12].copy_from_slice(&3u32.to_le_bytes());
        let v3 = tmp(&format!("{}-v3.tcz", coder.name()));
        std::fs::write(&v3, &old).unwrap();
        match (coder, file::read(&v3)) {
            (Coder::Ratio, Ok((_, read))) => {
                assert_eq!(bits(&read.decode().unwrap()), bits(&recon))
            }
            (Coder::Fast, Err(e)) => {
                let e = e.to_string();
                assert!(e.starts_with(v3.to_str().unwrap()), "{e}");
                assert!(
                    e.contains("pack version 3 with the fast coder")
                        && e.contains("pack the map again"),
                    "{e}"
                );
            }
            (_, r) => panic!("{}: {:?}", coder.name(), r.map(|_| ())),
        }
    }
    // A coder the reader does not know is an error naming the file and
    // the field, not a guess.
    let path = tmp("fast.tcz");
    let mut parts = common::packs::Parts::of(&std::fs::read(&path).unwrap());
    let mut h = parts.header();
    h["coder"] = "zippy".into();
    parts = parts.with_header(&h);
    let bad = tmp("zippy.tcz");
    std::fs::write(&bad, parts.assemble()).unwrap();
    let e = file::read(&bad).unwrap_err().to_string();
    assert!(e.contains("zippy.tcz") && e.contains("zippy`"), "{e}");
    // A fast tile read as a ratio tile (its header's coder removed) is an
    // error naming the tile, not heights.
    h.as_object_mut().unwrap().remove("coder");
    let parts = parts.with_header(&h);
    std::fs::write(&bad, parts.assemble()).unwrap();
    let e = file::read_levels(&bad).unwrap_err().to_string();
    assert!(e.contains("zippy.tcz") && e.contains("tile"), "{e}");
}

#[test]
fn the_cli_and_the_streaming_packer_write_the_in_memory_fast_pack() {
    let map = jacksboro();
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/jacksboro_16.png");
    let source = input.display().to_string();
    let src = Pyramid::build(&map, Filter::default(), usize::MAX).levels;
    let (packed, _) =
        Packed::encode_coded(&src, 1.0, 128, map.lattice, Predictor::Lifting, Coder::Fast);
    let mem = tmp("mem.tcz");
    file::write(
        &mem,
        &packed,
        map.cell_size,
        &Filter::default().name(),
        &source,
    )
    .unwrap();
    let want = std::fs::read(&mem).unwrap();
    // The tiles' bytes, pinned: zstd's level (15) sets how small the
    // frames are and how fast they decode, and another level writes other
    // bytes that decode to the same heights.
    assert_eq!(packed.coded_bytes(), 83_838);
    // Streamed in bands much smaller than the map.
    let streamed = tmp("streamed.tcz");
    let mut o = stream::Options::new(1.0, 128, Filter::default(), &source);
    o.coder = Coder::Fast;
    o.band_bytes = 20_000;
    let rows = terraclip::terrain::rows::open(&input).unwrap();
    stream::pack(rows.as_ref(), &streamed, &o, &mut |_, _| {}).unwrap();
    assert!(std::fs::read(&streamed).unwrap() == want, "streamed");
    let cli = tmp("cli.tcz");
    let (code, out, err) = common::cli(&[
        "pack",
        input.to_str().unwrap(),
        "-o",
        cli.to_str().unwrap(),
        "--max-error",
        "1",
        "--coder",
        "fast",
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["coder"], "fast");
    assert!(std::fs::read(&cli).unwrap() == want, "the CLI's pack");
    let (code, _, err) = common::cli(&[
        "pack",
        input.to_str().unwrap(),
        "-o",
        cli.to_str().unwrap(),
        "--coder",
        "zippy",
    ]);
    assert_ne!(code, 0);
    assert!(
        err.contains("unknown coder \"zippy\" (ratio or fast)"),
        "{err}"
    );
}
