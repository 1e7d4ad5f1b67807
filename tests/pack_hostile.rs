//! Hostile pack files: each one built with a valid magic, version and
//! header checksum (and, where the damage is past the index, every tile
//! checksum made right), so that it reaches the check it is aimed at.
//! Each must be an error that names the file and what is wrong, from the
//! library and from the CLI, whose `info` and `unpack` must exit with an
//! error code, never be killed by a signal (an allocation sized by a
//! forged header aborts the process: SIGABRT, exit 134).

mod common;

use common::packs::{mapped_levels, Parts};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;
use terraclip::pack::{file, Coder, Packed, Predictor};

fn dir() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("pack-hostile");
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A lossy pack of a 40 × 30 procedural map in 16² tiles: level 0 has
/// 3 × 2 tiles, the last column 8 samples wide.
fn seed() -> Parts {
    seed_coded(Coder::Ratio)
}

/// [`seed`] with the tiles coded by `coder`.
fn seed_coded(coder: Coder) -> Parts {
    seed_predicted(coder, Predictor::Lifting)
}

/// [`seed`] with the tiles coded by `coder` and predicted by `predictor`.
fn seed_predicted(coder: Coder, predictor: Predictor) -> Parts {
    let map = common::terrain(9, 40, 30);
    let levels = terraclip::pyramid::Pyramid::build(&map, Default::default(), 64).levels;
    let (packed, _) = Packed::encode_coded(&levels, 1.0, 16, None, predictor, coder);
    // A name of its own: the tests run at once, in one folder.
    static SEEDS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = SEEDS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let p = dir().join(format!("seed{k}.tcz"));
    file::write(&p, &packed, [10.0; 2], "sinc-blackman:11", "seed").unwrap();
    Parts::of(&std::fs::read(&p).unwrap())
}

/// The error `terraclip ARGS` prints, checked to be an exit with a code
/// (not a signal) other than 0, naming `name`, without a panic.
fn cli_error(args: &[&std::ffi::OsStr], name: &str) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_terraclip"))
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.code().is_some_and(|c| c != 0),
        "{args:?}: {:?}, {err}",
        out.status
    );
    assert!(err.contains(name) && !err.contains("panicked"), "{err}");
    err
}

/// Writes `bytes` as `name`.tcz and checks that the whole read, the
/// mapped open (with every tile decoded, as a render meets them) and the
/// CLI's `unpack` all refuse it, naming the file and saying `why`; and
/// `info`, which reads the header, index and tiles' checksums but decodes
/// nothing, where `info_sees` it.
fn refused(name: &str, bytes: &[u8], why: &str, info_sees: bool) {
    let p = dir().join(format!("{name}.tcz"));
    std::fs::write(&p, bytes).unwrap();
    let file_name = format!("{name}.tcz");
    // Read and decoded whole, without the size check `read_levels` makes
    // first (which refuses a forged size before the index is read).
    let whole = file::read(&p)
        .and_then(|(_, packed)| {
            packed.decode().map_err(|e| terraclip::Error::BadFile {
                path: p.clone(),
                reason: e.to_string(),
            })
        })
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        whole.contains(&file_name) && whole.contains(why),
        "{name}: {whole}"
    );
    let levels = file::read_levels(&p).map(|_| ()).unwrap_err().to_string();
    assert!(levels.contains(&file_name), "{name}: {levels}");
    let mapped = mapped_levels(&p).map(|_| ()).unwrap_err().to_string();
    assert!(
        mapped.contains(&file_name) && mapped.contains(why),
        "{name}: {mapped}"
    );
    if info_sees {
        let info = cli_error(&["info".as_ref(), p.as_os_str()], &file_name);
        assert!(info.contains(why), "{name}: info: {info}");
    }
    let out = dir().join(format!("{name}.f32"));
    let unpack = cli_error(
        &[
            "unpack".as_ref(),
            p.as_os_str(),
            "-o".as_ref(),
            out.as_os_str(),
        ],
        &file_name,
    );
    assert!(unpack.contains(why), "{name}: unpack: {unpack}");
    assert!(!out.exists(), "{name}: unpack wrote {}", out.display());
}

/// The header's levels as (width, height) of a chain halving from
/// `side`² down to 1 × 1, each quantised and ranged as `like`.
fn chain(side: usize, like: &Value) -> Vec<Value> {
    let mut out = vec![];
    let (mut w, mut h) = (side, side);
    loop {
        let mut l = like.clone();
        l["width"] = json!(w);
        l["height"] = json!(h);
        out.push(l);
        if (w, h) == (1, 1) {
            return out;
        }
        (w, h) = ((w - 1) / 2 + 1, (h - 1) / 2 + 1);
    }
}

#[test]
fn the_seed_is_sound() {
    let bytes = seed().assemble();
    let p = dir().join("sound.tcz");
    std::fs::write(&p, &bytes).unwrap();
    file::read_levels(&p).unwrap();
    mapped_levels(&p).unwrap();
}

#[test]
fn a_forged_header_of_a_million_squared_map_in_2x2_tiles_is_an_error() {
    // 2^40 index entries claimed by a file of about 2 KB: the index's
    // vector was sized from the header before a byte of it was read.
    let s = seed();
    let mut h = s.header();
    let like = h["levels"][0].clone();
    h["tile"] = json!(2);
    h["levels"] = Value::Array(chain(1 << 20, &like));
    let forged = Parts {
        json: serde_json::to_vec(&h).unwrap(),
        tiles: vec![],
    }
    .assemble();
    assert!(forged.len() < 4096, "{} bytes", forged.len());
    refused(
        "forged",
        &forged,
        "index: the header's 21 levels of 2² tiles need",
        true,
    );
}

#[test]
fn a_header_of_a_thousand_levels_is_an_error() {
    // The seed's levels halved on down to 1 × 1 (each the half of the one
    // before, as the header requires), then 1 × 1 levels to 1,000.
    let s = seed();
    let mut h = s.header();
    let mut levels = h["levels"].as_array().unwrap().clone();
    let last = levels.pop().unwrap();
    let side = |k: &str| last[k].as_u64().unwrap() as usize;
    let mut tail = vec![];
    let (mut w, mut hh) = (side("width"), side("height"));
    loop {
        let mut l = last.clone();
        l["width"] = json!(w);
        l["height"] = json!(hh);
        tail.push(l);
        if (w, hh) == (1, 1) {
            break;
        }
        (w, hh) = ((w - 1) / 2 + 1, (hh - 1) / 2 + 1);
    }
    levels.extend(tail);
    let one = levels.last().unwrap().clone();
    levels.resize(1000, one);
    h["levels"] = Value::Array(levels);
    let forged = s.with_header(&h).assemble();
    refused(
        "levels",
        &forged,
        "a pyramid ends at its first 1×1 level (the header lists 1000 levels)",
        true,
    );
}

#[test]
fn tile_offsets_that_overlap_are_an_error() {
    let s = seed();
    let mut bytes = s.assemble();
    // Tile 1 said to start where tile 0 does.
    let first = bytes[s.entry_at(0)..][..8].to_vec();
    let at = s.entry_at(1);
    bytes[at..at + 8].copy_from_slice(&first);
    refused("overlap", &bytes, "level 0 tile (1, 0): offset", true);
    assert!(std::str::from_utf8(&bytes).is_err());
}

#[test]
fn index_lengths_that_sum_past_the_file_are_an_error() {
    let s = seed();
    let mut bytes = s.assemble();
    // Each tile inside the file, but tile 0 as long as the rest of it,
    // its checksum made to match that span.
    let at = s.entry_at(0);
    let offset = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let len = (bytes.len() - offset) as u32;
    let crc = crc32fast::hash(&bytes[offset..]);
    bytes[at + 8..at + 12].copy_from_slice(&len.to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&crc.to_le_bytes());
    refused("lengths", &bytes, "tiles overlap or leave a gap", true);
}

#[test]
fn a_level_range_that_is_not_two_finite_heights_is_an_error() {
    let s = seed();
    let last = s.header()["levels"].as_array().unwrap().len() - 1;
    // JSON has no NaN (serde writes it as null) and no infinity (1e39,
    // past f32, is refused as out of range); a range least last is as
    // wrong.
    for (k, (l, range, why)) in [
        (
            0,
            json!([null, 1.0]),
            "header is not valid: invalid type: null, expected f32",
        ),
        (
            last,
            json!([1e39, 1e39]),
            "header is not valid: number out of range",
        ),
        (
            0,
            json!([5.0, 1.0]),
            "level 0's range [5, 1] is not two finite heights, least first",
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let mut h = s.header();
        h["levels"][l]["range"] = range;
        refused(
            &format!("range{k}"),
            &s.with_header(&h).assemble(),
            why,
            true,
        );
    }
}

#[test]
fn a_tile_that_decodes_to_more_samples_than_it_holds_is_an_error() {
    // Tile (2, 0) of level 0 is 8 × 16; tile (0, 0)'s stream codes 16 × 16.
    let mut s = seed();
    s.tiles[2] = s.tiles[0].clone();
    refused(
        "more",
        &s.assemble(),
        "level 0 tile (2, 0): coded words left over",
        false,
    );
}

#[test]
fn a_tile_that_decodes_outside_its_level_range_is_an_error() {
    // The header's range of level 0 narrowed by a metre at the top: the
    // tile holding the highest sample decodes above it.
    let s = seed();
    let mut h = s.header();
    let hi = h["levels"][0]["range"][1].as_f64().unwrap();
    h["levels"][0]["range"][1] = json!(hi - 1.0);
    refused(
        "above",
        &s.with_header(&h).assemble(),
        "outside the level's range",
        false,
    );
}

#[test]
fn a_fast_tile_whose_zstd_frame_claims_terabytes_is_an_error() {
    // Tile (0, 0) of level 0 is 16 × 16 with no no-data: its symbols'
    // frame starts after the 9-byte header, the side stream and the
    // codes' width. Two forged
    // frames take its place, each with one raw block of a byte: one that
    // says it holds 2^40 bytes (single segment, so its window is that size
    // too), which zstd calls corrupt; and one that asks for zstd's largest
    // window, 2^31 bytes, which one-shot decoding never allocates (it
    // decodes into the tile's buffer), so its one byte decodes and the
    // tile's length refuses it. Both are errors naming the tile.
    let s = seed_coded(Coder::Fast);
    let tile = &s.tiles[0];
    assert_eq!(tile[0], 0, "no no-data in the seed's first tile");
    let side = u32::from_le_bytes(tile[1..5].try_into().unwrap()) as usize;
    // The header, the side stream and the codes' width.
    let keep = tile[..9 + side + 1].to_vec();
    let magic = 0xFD2F_B528u32.to_le_bytes();
    // A raw block, the last: header 3 bytes LE (last = 1, type 0, size 1),
    // then its byte.
    let block = [0b1_001, 0, 0, 7];
    let mut terabytes = magic.to_vec();
    terabytes.push(0b1110_0000); // 8-byte content size, single segment
    terabytes.extend_from_slice(&(1u64 << 40).to_le_bytes());
    terabytes.extend_from_slice(&block);
    let mut window = magic.to_vec();
    window.push(0); // no content size, a window descriptor
    window.push((31 - 10) << 3); // window log 31, no mantissa
    window.extend_from_slice(&block);
    for (name, frame, why) in [
        ("terabytes", terabytes, "coded symbols broken"),
        ("window", window, "coded symbols hold 1 bytes, not the"),
    ] {
        let mut forged = seed_coded(Coder::Fast);
        forged.tiles[0] = [&keep[..], &frame[..]].concat();
        refused(
            name,
            &forged.assemble(),
            &format!("level 0 tile (0, 0): {why}"),
            false,
        );
    }
}

#[test]
fn a_fitted_tile_whose_weights_are_out_of_range_or_cut_is_an_error() {
    // A fast tile: the 9-byte header (flags, the side stream's length, the
    // no-data count), then the side stream, which in a fitted tile of a
    // level below the coarsest starts with its 16 weights as zigzag
    // varints. Tile (0, 0) of level 0 has no no-data.
    let s = seed_predicted(Coder::Fast, Predictor::Fitted);
    let tile = &s.tiles[0];
    assert_eq!(tile[0], 0, "no no-data in the seed's first tile");
    let side = u32::from_le_bytes(tile[1..5].try_into().unwrap()) as usize;
    // The first weight's varint.
    let first = tile[9..].iter().position(|b| b & 0x80 == 0).unwrap() + 1;
    let with_side = |new_side: &[u8]| {
        let mut t = tile[..1].to_vec();
        t.extend_from_slice(&(new_side.len() as u32).to_le_bytes());
        t.extend_from_slice(&tile[5..9]);
        t.extend_from_slice(new_side);
        t.extend_from_slice(&tile[9 + side..]);
        let mut forged = s.clone();
        forged.tiles[0] = t;
        forged.assemble()
    };
    // 32768/1024: one past the largest weight (zigzag 65536, three bytes).
    let mut big = vec![0x80, 0x80, 0x04];
    big.extend_from_slice(&tile[9 + first..9 + side]);
    refused(
        "weight",
        &with_side(&big),
        "level 0 tile (0, 0): a prediction weight of 32768/1024, past the largest, 32767/1024",
        false,
    );
    // The side stream cut inside the weights.
    refused(
        "weights-cut",
        &with_side(&tile[9..9 + first]),
        "level 0 tile (0, 0): coded stream broken in the prediction weights",
        false,
    );
    // The same bytes sound: the seed decodes.
    let p = dir().join("fitted-sound.tcz");
    std::fs::write(&p, s.assemble()).unwrap();
    file::read_levels(&p).unwrap();
    mapped_levels(&p).unwrap();
}

#[test]
fn a_header_that_names_a_predictor_it_cannot_hold_is_an_error() {
    // Version 4 had no fitted predictor.
    let mut b = seed_predicted(Coder::Ratio, Predictor::Fitted).assemble();
    b[8] = 4;
    refused(
        "fitted-v4",
        &b,
        "pack version 4 names the fitted predictor, which version 5 brought",
        true,
    );
    // Upsampling is said by the levels' quantisation, never by name.
    let s = seed();
    let mut h = s.header();
    h["predictor"] = json!("upsampled");
    refused(
        "named-upsampled",
        &s.with_header(&h).assemble(),
        "predictor \"upsampled\": the levels' quantisation says so",
        true,
    );
    let up = {
        let map = common::terrain(9, 40, 30);
        let levels = terraclip::pyramid::Pyramid::build(&map, Default::default(), 64).levels;
        let (packed, _) =
            Packed::encode_coded(&levels, 1.0, 16, None, Predictor::Upsampled, Coder::Ratio);
        let p = dir().join("up-seed.tcz");
        file::write(&p, &packed, [10.0; 2], "sinc-blackman:11", "seed").unwrap();
        Parts::of(&std::fs::read(&p).unwrap())
    };
    let mut h = up.header();
    h["predictor"] = json!("fitted");
    refused(
        "fitted-upsampled",
        &up.with_header(&h).assemble(),
        "predictor \"fitted\" with upsampled levels",
        true,
    );
}
