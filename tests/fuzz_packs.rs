//! Packs fuzzed past their checksums. Each case damages one seed pack,
//! then makes the header CRC, every index offset and every tile CRC right
//! again ([`common::packs::Parts`]), so the damage reaches the header's
//! parser, the index checks, the tile parser and the reconstruction
//! behind them. The damage: the header JSON edited as a tree (numbers,
//! strings, keys, nesting) or as text; one tile's bytes cut, flipped or
//! overwritten; tiles swapped, dropped or repeated; index fields
//! overwritten (the index has no checksum of its own).
//!
//! Seeds: lossy packs with each predictor, lossless packs on a lattice and
//! as bit patterns, and a pack with mixed and all-no-data tiles, with the
//! ratio coder; the lossy and no-data ones again with the fast coder.
//!
//! Every case must load (finite, equal whole and tile by tile) or be an
//! error naming the file, never a panic; one case in 25 also goes through
//! the CLI binary (`info`, `unpack`), which must exit with a code, never
//! a signal. The run counts how many cases reach each stage and asserts
//! the counts exactly (the run is seeded): a check that starts refusing
//! what it passed, or the reverse, changes them. Each stage must be
//! reached by at least 10 % of the cases.

mod common;

use common::fuzz::{cli_exits, edit_json, mutate, mutate_text, Rng};
use common::packs::{pack_once, Parts};

use std::panic::catch_unwind;
use std::path::{Path, PathBuf};
use std::time::Instant;
use terraclip::pack::Coder::{Fast, Ratio};
use terraclip::pack::Predictor::{Fitted, Lifting, Upsampled};
use terraclip::pack::{file, Coder, Lattice, Packed, Predictor};
use terraclip::pyramid::{Pyramid, PyramidLevel};
use terraclip::terrain::Heightmap;

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-fuzz-packs-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The pack of `map` at `e` in 16² tiles.
fn pack(d: &Path, map: &Heightmap, e: f64, predictor: Predictor, coder: Coder) -> Parts {
    let levels = Pyramid::build(map, Default::default(), 64).levels;
    let (packed, _) = Packed::encode_coded(&levels, e, 16, map.lattice, predictor, coder);
    let p = d.join("seed.tcz");
    file::write(&p, &packed, map.cell_size, "sinc-blackman:11", "seed").unwrap();
    Parts::of(&std::fs::read(&p).unwrap())
}

/// The seeds: (name, parts).
fn seeds(d: &Path) -> Vec<(&'static str, Parts)> {
    let map = common::terrain(9, 40, 30);
    // On a lattice of half-metre codes, as a 16-bit PNG with a sidecar is.
    let codes: Vec<f32> = map
        .data()
        .iter()
        .map(|v| 100.0 + (v * 20.0).round() * 0.5)
        .collect();
    let mut lattice = Heightmap::from_values(40, 30, codes, None, [10.0; 2], "test").unwrap();
    lattice.lattice = Some(Lattice {
        offset: 100.0,
        scale: 0.5,
    });
    let holes = common::packs::holes();
    vec![
        ("lifting", pack(d, &map, 1.0, Lifting, Ratio)),
        ("upsampled", pack(d, &map, 1.0, Upsampled, Ratio)),
        ("lattice", pack(d, &lattice, 0.0, Lifting, Ratio)),
        ("bits", pack(d, &map, 0.0, Lifting, Ratio)),
        ("no-data", pack(d, &holes, 0.5, Lifting, Ratio)),
        ("fast lifting", pack(d, &map, 1.0, Lifting, Fast)),
        ("fast upsampled", pack(d, &map, 1.0, Upsampled, Fast)),
        ("fast no-data", pack(d, &holes, 0.5, Lifting, Fast)),
        ("fitted", pack(d, &map, 1.0, Fitted, Ratio)),
        ("fast fitted no-data", pack(d, &holes, 0.5, Fitted, Fast)),
    ]
}

/// One damaged case of `seed`.
fn damage(rng: &mut Rng, seed: &Parts) -> Vec<u8> {
    let mut p = seed.clone();
    match rng.below(20) {
        // The header as a tree (7 in 20).
        0..=6 => {
            let mut h = p.header();
            for _ in 0..1 + rng.below(2) {
                edit_json(rng, &mut h);
            }
            p = p.with_header(&h);
        }
        // The header as text (1 in 20).
        7 => p.json = mutate_text(rng, &String::from_utf8_lossy(&p.json)).into_bytes(),
        // One tile's bytes (8 in 20), the coarse levels' tiles (the last,
        // few) as often as level 0's.
        8..=15 => {
            let n = p.tiles.len();
            let t = if rng.below(2) == 0 {
                n - 1 - rng.below(n.min(3))
            } else {
                rng.below(n)
            };
            p.tiles[t] = mutate(rng, &p.tiles[t]);
        }
        // Tiles swapped, dropped or repeated (2 in 20).
        16 | 17 => {
            let n = p.tiles.len();
            let (i, j) = (rng.below(n), rng.below(n));
            match rng.below(3) {
                0 => p.tiles.swap(i, j),
                1 => {
                    p.tiles.remove(i);
                }
                _ => p.tiles[i] = p.tiles[j].clone(),
            }
        }
        // An index field overwritten, offsets left to lie (2 in 20).
        _ => {
            let mut bytes = p.assemble();
            let k = rng.below(p.tiles.len());
            let at = p.entry_at(k) + [0, 8, 12][rng.below(3)];
            let v: u32 = [0, 1, u32::MAX, 0x7FFF_FFFF, 16][rng.below(5)];
            bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
            return bytes;
        }
    }
    p.assemble()
}

/// How far a case gets: header parsed, index parsed, the coarsest
/// level's first tile decoded, and the next level reconstructed whole
/// from the coarsest (the first level a predictor, lifting or upsampled,
/// reconstructs). Each stage through the public API a reader would use;
/// a panic in any is a failure.
fn stages(p: &Path) -> Result<[bool; 4], String> {
    catch_unwind(|| {
        let header = file::read_header(p).is_ok();
        let index = terraclip::pack::reader::PackReader::open(p).is_ok();
        let (tile, level) = match file::read(p) {
            Ok((_, packed)) => {
                let top = packed.levels.len() - 1;
                let tile = packed
                    .decode_tile(top, [0, 0], &PyramidLevel::single())
                    .is_ok();
                let level = packed
                    .decode_level(top, None)
                    .and_then(|c| packed.decode_level(top - 1, Some(&c)))
                    .is_ok();
                (tile, level)
            }
            Err(_) => (false, false),
        };
        [header, index, tile, level]
    })
    .map_err(|_| format!("panic on {}", p.display()))
}

/// Cases per seed.
const CASES: usize = 1000;

/// Per seed: cases reaching the header, the index, the first tile, the
/// first predicted level, and loading whole.
const EXPECTED: [(&str, [usize; 5]); 10] = [
    ("lifting", [663, 566, 429, 321, 33]),
    ("upsampled", [691, 565, 430, 334, 36]),
    ("lattice", [663, 565, 454, 348, 64]),
    ("bits", [683, 579, 446, 350, 62]),
    ("no-data", [665, 567, 450, 361, 31]),
    ("fast lifting", [659, 562, 435, 335, 50]),
    ("fast upsampled", [691, 595, 448, 351, 58]),
    ("fast no-data", [650, 551, 431, 351, 35]),
    ("fitted", [651, 549, 422, 321, 30]),
    ("fast fitted no-data", [694, 611, 487, 392, 44]),
];

#[test]
fn packs_with_their_checksums_made_right_reach_every_stage() {
    let d = dir();
    let start = Instant::now();
    let mut rng = Rng(0x7C2_C8C5_F1ED_0001);
    let mut failures = vec![];
    let mut got = vec![];
    let case = d.join("case.tcz");
    let out = d.join("case-out.f32");
    let mut through_cli = 0;
    for (name, seed) in seeds(&d) {
        // The seed itself reaches every stage.
        std::fs::write(&case, seed.assemble()).unwrap();
        assert_eq!(stages(&case), Ok([true; 4]), "{name}");
        assert_eq!(pack_once(&case), Ok(true), "{name}");
        let mut reached = [0usize; 5];
        for i in 0..CASES {
            std::fs::write(&case, damage(&mut rng, &seed)).unwrap();
            match stages(&case) {
                Ok(s) => {
                    for (r, &ok) in reached.iter_mut().zip(&s) {
                        *r += usize::from(ok);
                    }
                }
                Err(e) => failures.push(e),
            }
            match pack_once(&case) {
                Ok(loaded) => reached[4] += usize::from(loaded),
                Err(e) => failures.push(format!("{name} case {i}: {e}")),
            }
            if i % 25 == 0 {
                through_cli += 1;
                let _ = std::fs::remove_file(&out);
                for args in [
                    vec!["info".as_ref(), case.as_os_str()],
                    vec![
                        "unpack".as_ref(),
                        case.as_os_str(),
                        "-o".as_ref(),
                        out.as_os_str(),
                    ],
                ] {
                    if let Err(e) = cli_exits(&args, "case.tcz") {
                        failures.push(format!("{name} case {i}: {e}"));
                    }
                }
            }
        }
        println!(
            "{name}: of {CASES}, header {}, index {}, first tile {}, first predicted level {}, loaded {}",
            reached[0], reached[1], reached[2], reached[3], reached[4]
        );
        for (stage, &n) in ["header", "index", "first tile", "first predicted level"]
            .iter()
            .zip(&reached)
        {
            assert!(n * 10 >= CASES, "{name}: {stage} reached by {n} of {CASES}");
        }
        got.push((name, reached));
    }
    println!(
        "fuzz packs: {} cases ({through_cli} through the CLI twice) in {:.1} s",
        CASES * got.len(),
        start.elapsed().as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&d);
    assert!(
        failures.is_empty(),
        "{} failures, first: {}",
        failures.len(),
        failures[0]
    );
    assert_eq!(through_cli, 10 * CASES.div_ceil(25));
    assert_eq!(got, EXPECTED, "cases reaching each stage, per seed");
}
