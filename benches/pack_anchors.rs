//! The pack, with each of its coders under its default predictor (`ratio`
//! with `fitted`, what `terraclip pack` writes, and `fast` with
//! `lifting`) and the ratio coder under `lifting` too, against the
//! strongest peers, side by side in one process on the same maps and the
//! same pyramid:
//!
//! - SZ3 (error-bounded lossy compression's state of the art, the `sz3`
//!   crate's bindings to its C++ library) in absolute-error mode at E;
//! - pcodec (the `pco` crate, pure Rust) on the grid quantised to 2E steps;
//! - LERC (Esri's bounded-error raster codec, the `lerc` crate) at
//!   `maxZError = E`;
//! - zstd level 19 on the grid quantised to 2E steps (level 0 only).
//!
//! A clipmap needs every level, so each peer codes every level of the
//! pyramid the pack holds (the same `Pyramid::build` levels, each to E) as
//! well as level 0 alone. For each row: the ratio (f32 bytes of level 0 ÷
//! coded bytes, whatever the row holds), the max and RMS error over every
//! sample it holds, and encode and decode M level-0 samples per second on
//! one core (the pack's tile pool pinned to one thread; the fastest of at
//! least 3 runs and half a second of runs).
//!
//! Writes `target/pack-anchors/rows.json` and `rows.csv`, and per map a
//! chart of ratio against decode speed with the Pareto front
//! (`chart-MAP.png` and `.svg`), and prints the table.
//!
//! Run: `cargo bench --features anchors --bench pack_anchors`. The peers'
//! bindings need `apt-get install libclang-dev cmake libzstd-dev
//! pkg-config` (SZ3's build looks for the system's zstd and fetches one
//! from the network otherwise). etopo5 is read where `docs/get-etopo5.sh
//! target` writes it.

use serde::Serialize;
use std::path::Path;
use std::time::Instant;
use terraclip::pack::{
    Coder, Lattice, Packed,
    Predictor::{Fitted, Lifting},
};
use terraclip::pyramid::{Filter, Pyramid, PyramidLevel};
use terraclip::studies::chart::{Chart, Series};
use terraclip::terrain::Heightmap;

#[derive(Serialize)]
struct Row {
    map: String,
    e: f64,
    codec: String,
    /// "pyramid" (every level) or "level 0".
    holds: &'static str,
    bytes: usize,
    ratio: f64,
    max_error: f64,
    rms_error: f64,
    encode_ms_per_s: f64,
    decode_ms_per_s: f64,
}

/// Max and RMS |a − b| over every sample of every level.
fn errors(a: &[&[f32]], b: &[Vec<f32>]) -> (f64, f64) {
    let (mut max, mut sq, mut n) = (0f64, 0f64, 0usize);
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.len(), y.len(), "a level came back at another size");
        for (&p, &q) in x.iter().zip(y) {
            let d = (p as f64 - q as f64).abs();
            max = max.max(d);
            sq += d * d;
        }
        n += x.len();
    }
    (max, (sq / n as f64).sqrt())
}

/// The fastest run of `f`, in seconds, with its last result: at least `n`
/// runs, and more until they have taken half a second, so that a
/// millisecond's decode is the best of hundreds of runs (the best of 3
/// moved jacksboro's LERC decode between 250 and 437 M samples/s from one
/// day to the next).
fn best<T>(n: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut out = None;
    let mut t = f64::INFINITY;
    let start = Instant::now();
    let mut runs = 0;
    while runs < n || start.elapsed().as_secs_f64() < 0.5 {
        let s = Instant::now();
        let v = f();
        t = t.min(s.elapsed().as_secs_f64());
        out = Some(v);
        runs += 1;
    }
    (t, out.expect("n > 0"))
}

/// A peer: code one level (samples, width, height) to E, and decode it.
struct Peer {
    name: &'static str,
    encode: fn(&[f32], usize, usize, f64) -> Vec<u8>,
    decode: fn(&[u8], usize, usize, f64) -> Vec<f32>,
}

fn quantise(v: &[f32], e: f64) -> Vec<i32> {
    v.iter()
        .map(|&x| (x as f64 / (2.0 * e)).round() as i32)
        .collect()
}

fn dequantise(q: &[i32], e: f64) -> Vec<f32> {
    q.iter().map(|&k| (k as f64 * 2.0 * e) as f32).collect()
}

const PEERS: [Peer; 4] = [
    Peer {
        name: "SZ3",
        encode: |v, w, h, e| {
            let d = sz3::DimensionedData::build(&v)
                .dim(h)
                .unwrap()
                .dim(w)
                .unwrap()
                .finish()
                .unwrap();
            sz3::compress(&d, sz3::ErrorBound::Absolute(e)).unwrap()
        },
        decode: |b, _, _, _| sz3::decompress::<f32, _>(b).unwrap().1.into_data(),
    },
    Peer {
        name: "pcodec",
        encode: |v, _, _, e| {
            pco::standalone::simple_compress(&quantise(v, e), &pco::ChunkConfig::default()).unwrap()
        },
        decode: |b, _, _, e| dequantise(&pco::standalone::simple_decompress::<i32>(b).unwrap(), e),
    },
    Peer {
        name: "LERC",
        encode: |v, w, h, e| lerc::encode(v, None, w, h, 1, 1, 0, e).unwrap(),
        decode: |b, w, h, _| lerc::decode::<f32>(b, w, h, 1, 1, 0).unwrap().0,
    },
    Peer {
        name: "zstd-19, 2E steps",
        encode: |v, _, _, e| {
            let q: Vec<u8> = quantise(v, e)
                .iter()
                .flat_map(|k| k.to_le_bytes())
                .collect();
            zstd::bulk::compress(&q, 19).unwrap()
        },
        decode: |b, w, h, e| {
            let q: Vec<i32> = zstd::bulk::decompress(b, w * h * 4)
                .unwrap()
                .chunks_exact(4)
                .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            dequantise(&q, e)
        },
    },
];

/// Codes `levels` with `peer` to E; the row's bytes, errors and speeds.
fn peer_row(peer: &Peer, levels: &[&PyramidLevel], e: f64, n0: f64) -> (usize, f64, f64, f64, f64) {
    let (enc_s, blobs) = best(3, || {
        levels
            .iter()
            .map(|l| (peer.encode)(&l.data, l.width, l.height, e))
            .collect::<Vec<_>>()
    });
    let (dec_s, back) = best(3, || {
        levels
            .iter()
            .zip(&blobs)
            .map(|(l, b)| (peer.decode)(b, l.width, l.height, e))
            .collect::<Vec<_>>()
    });
    let src: Vec<&[f32]> = levels.iter().map(|l| &l.data[..]).collect();
    let (max, rms) = errors(&src, &back);
    let bytes = blobs.iter().map(|b| b.len()).sum();
    (bytes, max, rms, n0 / enc_s / 1e6, n0 / dec_s / 1e6)
}

/// The points no other point beats on both ratio and decode speed, by speed.
fn pareto(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut front: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|&(s, r)| {
            !points
                .iter()
                .any(|&(s2, r2)| s2 >= s && r2 >= r && (s2, r2) != (s, r))
        })
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    front
}

fn main() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    // jacksboro is in the repository; etopo5 is where
    // `docs/get-etopo5.sh target` writes it.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = root.join("target/pack-anchors");
    std::fs::create_dir_all(&out).unwrap();
    let maps = [
        (
            "jacksboro",
            root.join("tests/data/jacksboro_16.png"),
            236.0,
            0.012817578393224994,
        ),
        (
            "etopo5",
            root.join("target/etopo5_16.png"),
            -10376.0,
            0.27785152971694516,
        ),
    ];
    let mut rows: Vec<Row> = Vec::new();
    println!("| map | E (m) | codec | holds | ratio | max error (m) | RMS error (m) | encode Ms/s | decode Ms/s |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for (name, file, offset, scale) in maps {
        let map = Heightmap::load(&file)
            .unwrap_or_else(|e| panic!("{e} (etopo5: run docs/get-etopo5.sh target first)"));
        let n0 = (map.width() * map.height()) as f64;
        let src = Pyramid::build(&map, Filter::default(), 64).levels;
        let all: Vec<&PyramidLevel> = src.iter().collect();
        let lattice = Lattice { offset, scale };
        let first = rows.len();
        for e in [0.5, 1.0, 4.0] {
            let mut push = |codec: String, holds, (bytes, max, rms, enc, dec)| {
                rows.push(Row {
                    map: name.into(),
                    e,
                    codec,
                    holds,
                    bytes,
                    ratio: n0 * 4.0 / bytes as f64,
                    max_error: max,
                    rms_error: rms,
                    encode_ms_per_s: enc,
                    decode_ms_per_s: dec,
                })
            };
            // Each coder with its default predictor (what `terraclip pack`
            // writes), then the ratio coder with lifting's fixed weights.
            for (coder, predictor, codec) in [
                (Coder::Ratio, Fitted, "terraclip"),
                (Coder::Ratio, Lifting, "terraclip lifting"),
                (Coder::Fast, Lifting, "terraclip fast"),
            ] {
                let (enc_s, (packed, _)) = pool.install(|| {
                    best(3, || {
                        Packed::encode_coded(&src, e, 128, Some(lattice), predictor, coder)
                    })
                });
                let (dec_s, decoded) = pool.install(|| best(3, || packed.decode().unwrap()));
                let levels: Vec<&[f32]> = src.iter().map(|l| &l.data[..]).collect();
                let back: Vec<Vec<f32>> = decoded.into_iter().map(|l| l.data).collect();
                let (max, rms) = errors(&levels, &back);
                push(
                    codec.into(),
                    "pyramid",
                    (
                        packed.coded_bytes(),
                        max,
                        rms,
                        n0 / enc_s / 1e6,
                        n0 / dec_s / 1e6,
                    ),
                );
            }
            for peer in &PEERS {
                if !peer.name.starts_with("zstd") {
                    push(peer.name.into(), "pyramid", peer_row(peer, &all, e, n0));
                }
                push(
                    peer.name.into(),
                    "level 0",
                    peer_row(peer, &all[..1], e, n0),
                );
            }
        }
        for r in &rows[first..] {
            println!(
                "| {} | {} | {} | {} | {:.2} | {:.3} | {:.3} | {:.1} | {:.1} |",
                r.map,
                r.e,
                r.codec,
                r.holds,
                r.ratio,
                r.max_error,
                r.rms_error,
                r.encode_ms_per_s,
                r.decode_ms_per_s
            );
        }
        // Ratio against decode speed, one series per codec and what it
        // holds, a point per E.
        let mut series: Vec<Series> = Vec::new();
        for r in &rows[first..] {
            let label = format!("{} ({})", r.codec, r.holds);
            let point = (r.decode_ms_per_s, r.ratio);
            match series.iter_mut().find(|s| s.name == label) {
                Some(s) => s.points.push(point),
                None => series.push(Series {
                    name: label,
                    points: vec![point],
                }),
            }
        }
        let points: Vec<(f64, f64)> = rows[first..]
            .iter()
            .filter(|r| r.holds == "pyramid")
            .map(|r| (r.decode_ms_per_s, r.ratio))
            .collect();
        let chart = Chart {
            title: format!("{name}: ratio against decode speed, E = 0.5, 1, 4 m, one core"),
            x_label: "decode, M level-0 samples/s".into(),
            y_label: "ratio (f32 level 0 bytes / coded bytes)".into(),
            series,
            front: pareto(&points),
            linear_x: false,
        };
        std::fs::write(out.join(format!("chart-{name}.svg")), chart.svg()).unwrap();
        std::fs::write(out.join(format!("chart-{name}.png")), chart.png().unwrap()).unwrap();
    }
    std::fs::write(
        out.join("rows.json"),
        serde_json::to_string_pretty(&rows).unwrap(),
    )
    .unwrap();
    let mut csv = String::from(
        "map,e,codec,holds,bytes,ratio,max_error,rms_error,encode_ms_per_s,decode_ms_per_s\n",
    );
    for r in &rows {
        csv += &format!(
            "{},{},{},{},{},{},{},{},{},{}\n",
            r.map,
            r.e,
            r.codec.replace(',', ";"),
            r.holds,
            r.bytes,
            r.ratio,
            r.max_error,
            r.rms_error,
            r.encode_ms_per_s,
            r.decode_ms_per_s
        );
    }
    std::fs::write(out.join("rows.csv"), csv).unwrap();
    println!("wrote {}", out.display());
}
