//! The pack against the anchors the GIS world uses, side by side in one
//! process on the same maps: LERC (Esri's bounded-error raster codec, via
//! the `lerc` crate) at `maxZError = E`, and zstd level 19 over the grid
//! quantised to steps of 2E. For each: ratio (f32 level 0 bytes ÷ coded
//! bytes; the pack holds every pyramid level, the anchors level 0 only),
//! max and RMS error on level 0, and encode and decode M level-0 samples
//! per second on one core (the pack's tile pool pinned to one thread).
//! A second LERC row codes every level of the same pyramid, each to E, as
//! the pack does: the like-for-like size, and the speed per level-0
//! sample of decoding all of them.
//!
//! Run: `cargo bench --features anchors --bench pack_anchors` (LERC's
//! bindings need libclang: `apt-get install libclang-dev`).

use std::path::Path;
use std::time::Instant;
use terraclip::pack::{Lattice, Packed};
use terraclip::pyramid::{Filter, Pyramid};
use terraclip::terrain::Heightmap;

struct Row {
    codec: String,
    bytes: usize,
    max: f64,
    rms: f64,
    enc_s: f64,
    dec_s: f64,
}

fn errors(a: &[f32], b: &[f32]) -> (f64, f64) {
    let (mut max, mut sq) = (0f64, 0f64);
    for (&x, &y) in a.iter().zip(b) {
        let d = (x as f64 - y as f64).abs();
        max = max.max(d);
        sq += d * d;
    }
    (max, (sq / a.len() as f64).sqrt())
}

/// The fastest of `n` runs of `f`, in seconds, with its last result.
fn best<T>(n: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut out = None;
    let mut t = f64::INFINITY;
    for _ in 0..n {
        let s = Instant::now();
        let v = f();
        t = t.min(s.elapsed().as_secs_f64());
        out = Some(v);
    }
    (t, out.expect("n > 0"))
}

fn main() {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    // jacksboro is in the repository; etopo5 is where
    // `docs/get-etopo5.sh target` writes it.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
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
    println!("| map | E (m) | codec | ratio | max error (m) | RMS error (m) | encode Ms/s | decode Ms/s |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for (name, file, offset, scale) in maps {
        let map = Heightmap::load(&file)
            .unwrap_or_else(|e| panic!("{e} (etopo5: run docs/get-etopo5.sh target first)"));
        let (w, h) = (map.width(), map.height());
        let n = (w * h) as f64;
        let src = Pyramid::build(&map, Filter::default(), 64).levels;
        let lattice = Lattice { offset, scale };
        for e in [0.5, 1.0, 4.0] {
            let mut rows = Vec::new();
            let (enc_s, (packed, _)) =
                pool.install(|| best(3, || Packed::encode(&src, e, 128, Some(lattice))));
            let (dec_s, decoded) = pool.install(|| best(3, || packed.decode().unwrap()));
            let (max, rms) = errors(map.data(), &decoded[0].data);
            rows.push(Row {
                codec: format!("terraclip pack ({} levels)", packed.levels.len()),
                bytes: packed.coded_bytes(),
                max,
                rms,
                enc_s,
                dec_s,
            });
            let (enc_s, blob) = best(3, || {
                lerc::encode(map.data(), None, w, h, 1, 1, 0, e).unwrap()
            });
            let (dec_s, (back, _)) = best(3, || lerc::decode::<f32>(&blob, w, h, 1, 1, 0).unwrap());
            let (max, rms) = errors(map.data(), &back);
            rows.push(Row {
                codec: "LERC".into(),
                bytes: blob.len(),
                max,
                rms,
                enc_s,
                dec_s,
            });
            // LERC holding what the pack holds: every level, each to E.
            let (enc_s, blobs) = best(3, || {
                src.iter()
                    .map(|l| lerc::encode(&l.data, None, l.width, l.height, 1, 1, 0, e).unwrap())
                    .collect::<Vec<_>>()
            });
            let (dec_s, back) = best(3, || {
                src.iter()
                    .zip(&blobs)
                    .map(|(l, b)| {
                        lerc::decode::<f32>(b, l.width, l.height, 1, 1, 0)
                            .unwrap()
                            .0
                    })
                    .collect::<Vec<_>>()
            });
            let (max, rms) = errors(map.data(), &back[0]);
            rows.push(Row {
                codec: format!("LERC, every level ({})", src.len()),
                bytes: blobs.iter().map(|b| b.len()).sum(),
                max,
                rms,
                enc_s,
                dec_s,
            });
            let step = 2.0 * e;
            let (enc_s, z) = best(3, || {
                let q: Vec<u8> = map
                    .data()
                    .iter()
                    .flat_map(|&v| ((v as f64 / step).round() as i32).to_le_bytes())
                    .collect();
                zstd::bulk::compress(&q, 19).unwrap()
            });
            let (dec_s, back) = best(3, || {
                let q = zstd::bulk::decompress(&z, w * h * 4).unwrap();
                q.chunks_exact(4)
                    .map(|c| (i32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64 * step) as f32)
                    .collect::<Vec<f32>>()
            });
            let (max, rms) = errors(map.data(), &back);
            rows.push(Row {
                codec: "zstd-19, 2E steps".into(),
                bytes: z.len(),
                max,
                rms,
                enc_s,
                dec_s,
            });
            for r in rows {
                println!(
                    "| {name} | {e} | {} | {:.2} | {:.3} | {:.3} | {:.1} | {:.1} |",
                    r.codec,
                    n * 4.0 / r.bytes as f64,
                    r.max,
                    r.rms,
                    n / r.enc_s / 1e6,
                    n / r.dec_s / 1e6
                );
            }
        }
    }
}
