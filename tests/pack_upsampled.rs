//! Packs whose finer levels are predicted by the four-point upsampling of
//! the coarser level alone (`pack --predictor upsampled`): the error bound
//! on every sample, the residual grid a GPU pass rebuilds from (every
//! sample is the subdivision plus a whole number of f32 steps), streaming,
//! and the errors. Tiles decoded alone and the no-data mask are tested
//! for both predictors in `tests/pack.rs`.

mod common;

use std::path::Path;
use std::process::Command;
use terraclip::pack::{stream, Packed, Predictor, Quant};
use terraclip::pyramid::subdivide::subdivide_window;
use terraclip::pyramid::{Filter, Pyramid, PyramidLevel};
use terraclip::terrain::Heightmap;

fn levels_of(map: &Heightmap) -> Vec<PyramidLevel> {
    Pyramid::build(map, Filter::default(), 64).levels
}

fn encode(src: &[PyramidLevel], e: f64, tile: usize) -> (Packed, Vec<PyramidLevel>) {
    Packed::encode_with(src, e, tile, None, Predictor::Upsampled)
}

/// The subdivision of `coarse` at the size of a level `w` × `h` (a
/// pyramid's finer level may be one sample narrower than 2w − 1, or
/// wider: the stencils clamp either way).
fn upsample(coarse: &PyramidLevel, w: usize, h: usize) -> Vec<f32> {
    subdivide_window(coarse, [0, 0, w, h]).0
}

#[test]
fn every_sample_is_within_the_bound_and_on_the_upsampled_grid() {
    let map = common::terrain(3, 301, 157);
    let src = levels_of(&map);
    let mut sizes = vec![];
    for e in [0.3, 0.5, 1.0, 4.0] {
        let (packed, recon) = encode(&src, e, 64);
        assert!(packed
            .levels
            .iter()
            .all(|l| l.quant == Quant::Upsampled { max_error: e }));
        let decoded = packed.decode().unwrap();
        for (l, (s, d)) in src.iter().zip(&decoded).enumerate() {
            assert_eq!(
                d.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                recon[l]
                    .data
                    .iter()
                    .map(|v| v.to_bits())
                    .collect::<Vec<_>>(),
                "E = {e}: level {l} decodes to the encoder's reconstruction"
            );
            let w = s
                .data
                .iter()
                .zip(&d.data)
                .map(|(&a, &b)| (a as f64 - b as f64).abs())
                .fold(0.0, f64::max);
            assert!(w <= e && w > e / 4.0, "E = {e}: level {l} worst {w}");
        }
        // What the GPU pass computes: p + f32(q) · s from the coarser
        // level's subdivision p and a whole residual q, bit for bit.
        let s = (2.0 * e) as f32;
        let mut residuals = 0u64;
        for l in 0..decoded.len() - 1 {
            let d = &decoded[l];
            let p = upsample(&decoded[l + 1], d.width, d.height);
            for (i, (&h, &p)) in d.data.iter().zip(&p).enumerate() {
                let q = ((h as f64 - p as f64) / s as f64).round() as f32;
                assert_eq!(
                    (p + q * s).to_bits(),
                    h.to_bits(),
                    "E = {e}: level {l} sample {i}: {h} is not {p} + {q}·{s}"
                );
                residuals += u64::from(q != 0.0);
            }
        }
        assert!(residuals > 0);
        sizes.push(packed.coded_bytes());
    }
    // Exact figures: the coder is deterministic (a change to the stencil,
    // the contexts or the quantiser moves them).
    assert_eq!(sizes, [36278, 30615, 23124, 10351]);
}

#[test]
fn lossless_levels_are_lifted() {
    let src = levels_of(&common::terrain(5, 65, 65));
    let (packed, _) = encode(&src, 0.0, 32);
    assert!(packed.levels.iter().all(|l| l.quant == Quant::Bits));
}

/// A path of this test target's, with no file left there by an earlier run.
fn tmp(name: &str) -> std::path::PathBuf {
    let p = common::fresh_tmp("pack_upsampled", name);
    let _ = std::fs::remove_file(&p);
    p
}

/// A streamed pack (in bands) is byte for byte the in-memory pack, and its
/// header says how it was predicted.
#[test]
fn a_streamed_pack_equals_the_in_memory_pack() {
    use terraclip::pack::file;
    use terraclip::terrain::procedural::Procedural;
    use terraclip::terrain::rows::ProceduralRows;
    let p = Procedural::new(7, 190, 77);
    let map = p.generate().unwrap();
    let levels = Pyramid::build(&map, Filter::default(), usize::MAX).levels;
    let (packed, _) = encode(&levels, 1.0, 32);
    let mem = tmp("mem.tcz");
    file::write(&mem, &packed, map.cell_size, &Filter::default().name(), "p").unwrap();
    let want = std::fs::read(&mem).unwrap();
    for band in [usize::MAX / 8, 5_000] {
        let out = tmp(&format!("stream-{band}.tcz"));
        let mut o = stream::Options::new(1.0, 32, Filter::default(), "p");
        o.predictor = Predictor::Upsampled;
        o.band_bytes = band;
        stream::pack(
            &ProceduralRows::new(p.clone()).unwrap(),
            &out,
            &o,
            &mut |_, _| {},
        )
        .unwrap();
        assert!(
            std::fs::read(&out).unwrap() == want,
            "bands of {band} bytes"
        );
    }
    let (header, _) = file::read(&mem).unwrap();
    assert_eq!(header.predictor(), Predictor::Upsampled);
}

fn terraclip(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_terraclip"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn the_cli_packs_upsampled_and_refuses_it_lossless() {
    let dem = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/jacksboro_16.png");
    let out = tmp("jacksboro.tcz");
    let (d, o) = (dem.to_str().unwrap(), out.to_str().unwrap());
    let r = terraclip(&[
        "pack",
        d,
        "-o",
        o,
        "--max-error",
        "0",
        "--predictor",
        "upsampled",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && err.contains("--max-error > 0"),
        "{err}"
    );
    assert!(!err.contains("panicked"));
    assert!(!out.exists());
    let r = terraclip(&[
        "pack",
        d,
        "-o",
        o,
        "--predictor",
        "tensor",
        "--max-error",
        "1",
    ]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("lifting or upsampled"));
    let r = terraclip(&[
        "pack",
        d,
        "-o",
        o,
        "--max-error",
        "1",
        "--predictor",
        "upsampled",
        "--json",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(v["predictor"], "upsampled");
    assert_eq!(v["max_error_seen"].as_f64(), Some(1.0));
    let r = terraclip(&["info", o, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(v["predictor"], "upsampled");
    // Decoded back out, every sample is within the bound of the map.
    let back = tmp("back.f32");
    let r = terraclip(&["unpack", o, "-o", back.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let map = Heightmap::load(&dem).unwrap();
    let got = Heightmap::load(&back).unwrap();
    let worst = map
        .data()
        .iter()
        .zip(got.data())
        .map(|(&a, &b)| (a as f64 - b as f64).abs())
        .fold(0.0, f64::max);
    assert!(worst <= 1.0 && worst > 0.5, "{worst}");
}

/// A flight over an upsampled pack decoded tile by tile as its windows
/// reach the tiles (and evicting those they leave): on each of 48 frames,
/// every drawn level's window holds the whole decode's bits, so the frame
/// is the one the whole decode draws; each frame's levels are all ready.
/// (The lossless flight in `tests/pack.rs` compares images with the map
/// itself; a lossy pack's reference is its own whole decode.)
#[test]
fn a_flight_over_an_upsampled_pack_decoded_as_it_goes_holds_the_whole_decode() {
    use terraclip::frame::stats::Passes;
    use terraclip::pack::{file, stream, Predictor};
    use terraclip::render::Session;
    use terraclip::terrain::procedural::Procedural;
    use terraclip::terrain::rows::ProceduralRows;
    let p = Procedural::new(20041, 4097, 513);
    let path = tmp("flight-upsampled.tcz");
    let mut o = stream::Options::new(1.0, 32, Filter::default(), "flight");
    o.predictor = Predictor::Upsampled;
    stream::pack(&ProceduralRows::new(p).unwrap(), &path, &o, &mut |_, _| {}).unwrap();
    let (_, whole) = file::read_levels(&path).unwrap();
    let mut scene = terraclip::scene::Scene::bench_scene();
    (scene.terrain.procedural, scene.terrain.file) = (None, Some(path));
    scene.camera.position = [2000.0, -2500.0, 900.0];
    scene.camera.look_at = Some([4000.0, -2500.0, 150.0]);
    (scene.image.width, scene.image.height) = (320, 180);
    let mut session = Session::new(&scene, &mut Passes::default()).unwrap();
    let (mut evicted, mut windows) = (0, 0);
    for (i, cam) in terraclip::camera::path(&scene.camera(), 48, 400.0)
        .iter()
        .enumerate()
    {
        let (frame, clip) = session.frame(cam, &mut Passes::default()).unwrap();
        let lazy = session
            .lazy_frame(clip.as_ref())
            .expect("a pack decoded tile by tile");
        if i == 0 {
            assert!(lazy.tiles_this_frame > 0);
        }
        assert_eq!(
            (lazy.levels_unbuilt, lazy.levels_waiting),
            (0, 0),
            "frame {i}"
        );
        evicted += lazy.tiles_evicted.unwrap_or(0);
        for info in frame.resources.levels.iter().flatten() {
            let [x, y] = info.origin;
            let [w, h] = info.size.map(|v| v as i64);
            common::same_window(
                &session.pyramid().levels[info.level],
                &whole[info.level],
                info.level,
                [x, y, x + w - 1, y + h - 1],
            );
            windows += 1;
        }
    }
    assert!(windows >= 48 * 5, "{windows} windows checked");
    assert!(evicted > 100, "the flight leaves tiles behind: {evicted}");
}

/// What a GPU pass is told to rebuild from residuals: over an upsampled
/// pack, each level but the coarsest has the step 2E as an f32, and the
/// coarsest none; synthesised levels stacked over the pack have none, and
/// the pack's levels beneath them keep theirs at their new indices; a
/// lossless pack has none at all.
#[test]
fn the_residual_steps_are_the_packs_under_synthesis_too() {
    use terraclip::frame::stats::Passes;
    use terraclip::pack::{stream, Predictor};
    use terraclip::render::Session;
    use terraclip::terrain::procedural::Procedural;
    let p = Procedural::new(11, 513, 385);
    let steps = |predictor: Predictor, e: f64, synth: Option<usize>| {
        let path = tmp(&format!("steps-{predictor:?}-{synth:?}.tcz"));
        let mut o = stream::Options::new(e, 32, Filter::default(), "steps");
        o.predictor = predictor;
        common::pack_procedural(&p, &path, &o);
        let mut scene = terraclip::scene::Scene::bench_scene();
        (scene.terrain.procedural, scene.terrain.file) = (None, Some(path));
        scene.terrain.synthesis = synth.map(|levels| terraclip::synthesis::source::Spec {
            levels,
            roughness: None,
            seed: 5,
        });
        let session = Session::new(&scene, &mut Passes::default()).unwrap();
        let pyr = session.pyramid();
        (0..pyr.levels.len())
            .map(|l| pyr.residual_step(l))
            .collect::<Vec<_>>()
    };
    let own = steps(Predictor::Upsampled, 0.5, None);
    let n = own.len();
    assert!(n >= 4, "{own:?}");
    let mut want = vec![Some(1.0f32); n - 1];
    want.push(None);
    assert_eq!(own, want);
    let stacked = steps(Predictor::Upsampled, 0.5, Some(2));
    let mut want = vec![None, None];
    want.extend(own.iter().copied());
    assert_eq!(stacked, want);
    assert!(steps(Predictor::Lifting, 0.5, Some(1))
        .iter()
        .all(Option::is_none));
}
