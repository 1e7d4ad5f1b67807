//! The residual pyramid codec: the error bound on every sample of every
//! level, lossless packs bit for bit, tiles decoded alone equal to whole
//! levels, the no-data mask, and damaged tiles as errors.

mod common;

use std::path::Path;
use terraclip::pack::{Lattice, Packed, Predictor, Quant};
use terraclip::pyramid::{Filter, Pyramid, PyramidLevel};
use terraclip::terrain::Heightmap;

fn levels_of(map: &Heightmap) -> Vec<PyramidLevel> {
    Pyramid::build(map, Filter::default(), 64).levels
}

fn jacksboro() -> (Heightmap, Lattice) {
    // The repository's own copy: a clone has nothing beside it.
    let dem = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let map = Heightmap::load(&dem.join("jacksboro_16.png")).unwrap();
    // The reader reports the sidecar's decode: elev = 236 + code × 0.0128….
    let lattice = map.lattice.unwrap();
    assert_eq!(
        lattice,
        Lattice {
            offset: 236.0,
            scale: 0.012817578393224994,
        }
    );
    (map, lattice)
}

/// Whether every sample of every level has the same f32 bits.
fn same_bits(a: &[PyramidLevel], b: &[PyramidLevel]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(a, b)| {
            a.data.len() == b.data.len()
                && a.data
                    .iter()
                    .zip(&b.data)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
        })
}

/// The largest |decoded − source| over every sample of every level.
fn worst(source: &[PyramidLevel], decoded: &[PyramidLevel]) -> f64 {
    assert_eq!(source.len(), decoded.len());
    source
        .iter()
        .zip(decoded)
        .flat_map(|(s, d)| {
            assert_eq!((s.width, s.height), (d.width, d.height));
            assert_eq!(s.nodata, d.nodata);
            s.data
                .iter()
                .zip(&d.data)
                .map(|(&a, &b)| (a as f64 - b as f64).abs())
        })
        .fold(0.0, f64::max)
}

#[test]
fn every_sample_of_every_level_is_within_the_bound() {
    let map = common::terrain(3, 301, 157);
    let src = levels_of(&map);
    let mut sizes = vec![];
    for (e, predictor) in [0.5, 1.0, 4.0]
        .into_iter()
        .flat_map(|e| [(e, Predictor::Lifting), (e, Predictor::Fitted)])
    {
        let (packed, recon) = Packed::encode_with(&src, e, 64, None, predictor);
        let decoded = packed.decode().unwrap();
        // The decoder gives exactly what the encoder predicted from.
        assert!(same_bits(&recon, &decoded));
        let w = worst(&src, &decoded);
        assert!(w <= e, "E = {e}: worst {w}");
        // The bound is used, not beaten by storing everything raw.
        assert!(w > e / 4.0, "E = {e}: worst {w}");
        sizes.push(packed.coded_bytes());
    }
    // The coder is deterministic, so its sizes are exact figures: a change
    // to the predictor, the quantiser or the models moves them (a wrong
    // four-point weight, or a fitted feature that the encoder and decoder
    // both compute wrong, still decodes within the bound, and only this
    // sees it). Lifting then fitted, at each E: the fitted weights code
    // smaller.
    assert_eq!(sizes, [31711, 29210, 24189, 21981, 11673, 9932]);
    for pair in sizes.chunks(2) {
        assert!(pair[1] < pair[0], "{pair:?}");
    }
}

#[test]
fn a_lossless_pack_gives_the_same_bits() {
    let (map, lattice) = jacksboro();
    let src = levels_of(&map);
    let (packed, _) = Packed::encode(&src, 0.0, 64, Some(lattice));
    assert_eq!(
        packed.levels[0].quant,
        Quant::Lattice {
            offset: lattice.offset,
            scale: lattice.scale
        }
    );
    assert!(packed.levels[1..].iter().all(|l| l.quant == Quant::Bits));
    let decoded = packed.decode().unwrap();
    assert!(same_bits(&src, &decoded));
    // Fitted weights predict lossless levels too, in fewer bytes.
    let (fitted, _) = Packed::encode_with(&src, 0.0, 64, Some(lattice), Predictor::Fitted);
    assert!(same_bits(&src, &fitted.decode().unwrap()));
    assert!(
        fitted.coded_bytes() < packed.coded_bytes(),
        "{} fitted against {} lifting",
        fitted.coded_bytes(),
        packed.coded_bytes()
    );
    // Without the lattice, level 0 is coded as bit patterns: still exact.
    for predictor in [Predictor::Lifting, Predictor::Fitted] {
        let (packed, _) = Packed::encode_with(&src[..2], 0.0, 64, None, predictor);
        let decoded = packed.decode().unwrap();
        assert!(same_bits(&src[..1], &decoded[..1]), "{predictor:?}");
    }
}

/// Both predictors: the lifting one's stencils stay inside the tile, the
/// upsampling one reads only the coarser level.
#[test]
fn a_tile_decoded_alone_equals_its_part_of_the_level() {
    let map = common::terrain(8, 203, 130);
    let src = levels_of(&map);
    for predictor in [Predictor::Lifting, Predictor::Fitted, Predictor::Upsampled] {
        let (packed, recon) = Packed::encode_with(&src, 1.0, 16, None, predictor);
        tiles_alone_equal_levels(&packed, &recon);
    }
}

fn tiles_alone_equal_levels(packed: &Packed, recon: &[PyramidLevel]) {
    for l in 0..recon.len() {
        let coarse = recon.get(l + 1).unwrap_or(&recon[l]);
        let [nx, ny] = packed.tiles_of(l);
        for ty in 0..ny {
            for tx in 0..nx {
                let t = packed.decode_tile(l, [tx, ty], coarse).unwrap();
                let [x0, y0, w, h] = t.rect;
                for row in 0..h {
                    let at = (y0 + row) * recon[l].width + x0;
                    assert_eq!(
                        &t.data[row * w..][..w],
                        &recon[l].data[at..at + w],
                        "level {l} tile ({tx}, {ty}) row {row}"
                    );
                }
            }
        }
    }
}

#[test]
fn the_no_data_mask_is_coded() {
    let base = common::terrain(4, 70, 50);
    let mut mask = vec![false; 70 * 50];
    for (i, m) in mask.iter_mut().enumerate() {
        // A hole and a border strip: tiles with none, some and all.
        let (x, y) = (i % 70, i / 70);
        *m = (x as i64 - 30).pow(2) + (y as i64 - 20).pow(2) < 60 || x >= 64;
    }
    let values = base
        .data()
        .iter()
        .zip(&mask)
        .map(|(&v, &m)| if m { f32::NAN } else { v })
        .collect();
    let map = Heightmap::from_values(70, 50, values, None, [1.0; 2], "test").unwrap();
    let src = levels_of(&map);
    for predictor in [Predictor::Lifting, Predictor::Fitted, Predictor::Upsampled] {
        let (packed, _) = Packed::encode_with(&src, 1.0, 8, None, predictor);
        let decoded = packed.decode().unwrap();
        assert_eq!(decoded[0].nodata, mask);
        // `worst` checks every level's mask too.
        assert!(worst(&src, &decoded) <= 1.0);
    }
}

#[test]
fn a_damaged_tile_is_an_error_that_names_it() {
    let map = common::terrain(5, 65, 65);
    let src = levels_of(&map);
    let (packed, recon) = Packed::encode(&src, 1.0, 16, None);
    let at = packed.tiles_of(0)[0] + 1;
    let good = &packed.levels[0].tiles[at];
    let mut seen_errors = 0;
    let mut cases = 0;
    // Every truncation, and a flipped bit in every byte.
    let mut damaged: Vec<Vec<u8>> = (0..good.len()).map(|n| good[..n].to_vec()).collect();
    for i in 0..good.len() {
        let mut b = good.clone();
        b[i] ^= 1 << (i % 8);
        damaged.push(b);
    }
    for bytes in damaged {
        let mut p = packed.clone();
        p.levels[0].tiles[at] = bytes;
        cases += 1;
        match p.decode_tile(0, [1, 1], &recon[1]) {
            Err(e) => {
                assert_eq!((e.level, e.tile), (0, [1, 1]));
                assert!(e.to_string().starts_with("level 0 tile (1, 1): "), "{e}");
                seen_errors += 1;
            }
            // A flipped bit may still decode (to other heights): that is
            // what a format-level checksum is for, not the tile coder.
            Ok(t) => assert_eq!(t.data.len(), 16 * 16),
        }
    }
    // Every truncation is caught.
    assert!(seen_errors >= good.len(), "{seen_errors} of {cases}");
    // The length of the first of the tile's two ANS streams (bytes 9..13)
    // lying: longer than the tile's words, or moving the split by a word.
    let first = u32::from_le_bytes(good[9..13].try_into().unwrap());
    for (lie, why) in [
        (u32::MAX, "first stream of 4294967295 words does not fit"),
        (first + 1, "coded"),
        (first - 1, "coded"),
    ] {
        let mut p = packed.clone();
        p.levels[0].tiles[at][9..13].copy_from_slice(&lie.to_le_bytes());
        let e = p.decode_tile(0, [1, 1], &recon[1]).unwrap_err().to_string();
        assert!(e.contains(why), "{lie}: {e}");
    }
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-pack-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

#[test]
fn a_pack_file_reads_back_what_was_written() {
    use terraclip::pack::file;
    let (map, lattice) = jacksboro();
    let src = levels_of(&map);
    let (packed, recon) = Packed::encode(&src, 1.0, 64, Some(lattice));
    let path = tmp("j.tcz");
    let bytes = file::write(
        &path,
        &packed,
        map.cell_size,
        "sinc-blackman:11",
        "jacksboro",
    )
    .unwrap();
    assert_eq!(bytes, std::fs::metadata(&path).unwrap().len());
    let (header, back) = file::read(&path).unwrap();
    assert_eq!(header.size(), [403, 344]);
    assert_eq!(header.levels(), src.len());
    assert_eq!((header.max_error, header.tile), (1.0, 64));
    assert!(same_bits(&recon, &back.decode().unwrap()));
    // The header alone gives the same header, and level 0's relief as
    // decoded.
    assert_eq!(file::read_header(&path).unwrap(), header);
    assert_eq!(header.range(), [recon[0].min, recon[0].max]);
}

#[test]
fn a_damaged_pack_file_is_an_error_that_names_it_and_the_tile() {
    use terraclip::pack::file;
    let map = common::terrain(6, 90, 70);
    // Every cut of a pack of each predictor is an error.
    for predictor in [Predictor::Lifting, Predictor::Fitted, Predictor::Upsampled] {
        let (packed, _) = Packed::encode_with(&levels_of(&map), 1.0, 32, None, predictor);
        let path = tmp(&format!("cut-{}.tcz", predictor.name()));
        file::write(&path, &packed, [1.0; 2], "box", "test").unwrap();
        let good = std::fs::read(&path).unwrap();
        let cut = tmp(&format!("cut-{}-case.tcz", predictor.name()));
        for n in 0..good.len() {
            std::fs::write(&cut, &good[..n]).unwrap();
            let e = file::read(&cut).map(|_| ()).unwrap_err().to_string();
            assert!(e.starts_with(cut.to_str().unwrap()), "cut at {n}: {e}");
            let mapped = terraclip::pack::reader::PackReader::open(&cut)
                .map(|_| ())
                .unwrap_err()
                .to_string();
            assert!(
                mapped.starts_with(cut.to_str().unwrap()),
                "cut at {n}: {mapped}"
            );
        }
    }
    let (packed, _) = Packed::encode(&levels_of(&map), 1.0, 32, None);
    let path = tmp("good.tcz");
    file::write(&path, &packed, [1.0; 2], "box", "test").unwrap();
    let good = std::fs::read(&path).unwrap();
    let header_len = u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let index = 20 + header_len;
    let bad = tmp("bad.tcz");
    let fails = |bytes: &[u8], expect: &str| {
        std::fs::write(&bad, bytes).unwrap();
        let e = file::read(&bad).unwrap_err().to_string();
        assert!(e.starts_with(bad.to_str().unwrap()), "{e}");
        assert!(e.contains(expect), "{expect:?} not in {e}");
    };
    let mut b = good.clone();
    b[0] = b'X';
    fails(&b, "not a terraclip pack");
    let mut b = good.clone();
    b[8] = 1;
    fails(
        &b,
        "pack version 1; this build reads versions 3 to 5 (pack the map again",
    );
    b[8] = 6;
    fails(&b, "pack version 6; this build reads versions 3 to 5");
    // The first tile's length lies: past the end of the file, or short.
    let mut b = good.clone();
    b[index + 8..index + 12].copy_from_slice(&u32::MAX.to_le_bytes());
    fails(&b, "level 0 tile (0, 0): 4294967295 bytes at offset");
    let mut b = good.clone();
    b[index + 8] -= 1;
    fails(&b, "level 0 tile (0, 0): checksum mismatch");
    // A flipped bit in a tile.
    let mut b = good.clone();
    let last = b.len() - 3;
    b[last] ^= 0x10;
    fails(&b, "checksum mismatch");
    // A header edited: caught by its checksum; with the checksum redone,
    // levels that do not halve.
    let text = String::from_utf8(good[20..index].to_vec()).unwrap();
    let wrong = text.replacen("\"width\":45", "\"width\":44", 1);
    assert_ne!(wrong, text);
    let mut b = good.clone();
    b[20..index].copy_from_slice(wrong.as_bytes());
    fails(&b, "header checksum mismatch");
    b[16..20].copy_from_slice(&crc32fast::hash(wrong.as_bytes()).to_le_bytes());
    fails(&b, "the half of level 0");
    // A level's quantisation that cannot decode (the same length, so the
    // index still fits), its checksum redone.
    let step = "\"kind\":\"step\",\"max_error\":1.0";
    assert!(text.contains(step), "{text}");
    let wrong = text.replacen(step, "\"kind\":\"step\",\"max_error\":0.0", 1);
    let mut b = good.clone();
    b[20..index].copy_from_slice(wrong.as_bytes());
    b[16..20].copy_from_slice(&crc32fast::hash(wrong.as_bytes()).to_le_bytes());
    fails(&b, "quantisation Step { max_error: 0.0 } is not usable");
}

/// The jacksboro golden scene with its terrain replaced by a pack of the
/// same map at bound `e`.
fn jacksboro_scene_from_pack(e: f64, name: &str) -> terraclip::scene::Scene {
    jacksboro_scene_from_pack_tiled(e, 128, name)
}

/// [`jacksboro_scene_from_pack`] in `tile`² tiles.
fn jacksboro_scene_from_pack_tiled(e: f64, tile: usize, name: &str) -> terraclip::scene::Scene {
    use terraclip::pack::file;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let golden = root.join("golden/jacksboro-oblique.toml");
    let mut scene = terraclip::scene::Scene::load(&golden).unwrap();
    let map = Heightmap::load(&root.join("tests/data/jacksboro_16.png")).unwrap();
    let (packed, _) = Packed::encode(&levels_of(&map), e, tile, map.lattice);
    let path = tmp(name);
    file::write(
        &path,
        &packed,
        map.cell_size,
        &Filter::default().name(),
        "jacksboro",
    )
    .unwrap();
    scene.terrain.file = Some(path);
    scene
}

#[test]
fn a_lossless_pack_renders_bit_for_bit_as_the_map_itself() {
    use terraclip::render::{render, RenderOptions};
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let direct =
        terraclip::scene::Scene::load(&root.join("golden/jacksboro-oblique.toml")).unwrap();
    let opts = RenderOptions::default();
    let (want, direct_stats) = render(&direct, &opts).unwrap();
    let (got, stats) = render(&jacksboro_scene_from_pack(0.0, "j0.tcz"), &opts).unwrap();
    // One "terrain" pass each: the pack's decode, or the map's load; a
    // pack builds no pyramid.
    let names = |s: &terraclip::RenderStats| -> Vec<String> {
        s.passes.iter().map(|p| p.name.clone()).take(2).collect()
    };
    assert_eq!(names(&direct_stats), ["terrain", "pyramid"]);
    assert_eq!(names(&stats), ["terrain", "lod"]);
    assert!(stats.triangles > 1000);
    assert_eq!(got.rgba, want.rgba);
    assert!(got
        .depth
        .iter()
        .zip(&want.depth)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    // At E = 1 m the same view renders from the lossy levels: other bits
    // (heights move by up to 1 m × the scene's vertical scale of 2), the
    // same mesh.
    let (lossy, lossy_stats) = render(&jacksboro_scene_from_pack(1.0, "j1.tcz"), &opts).unwrap();
    assert_ne!(lossy.rgba, want.rgba);
    assert_eq!(lossy_stats.levels_drawn, stats.levels_drawn);
}

#[test]
fn a_lossless_level_written_back_reads_as_the_map() {
    use terraclip::terrain::write::{write, Grid};
    let (map, lattice) = jacksboro();
    let grid = Grid {
        width: map.width(),
        height: map.height(),
        data: map.data(),
        nodata: map.nodata_mask(),
        cell_size: map.cell_size,
        place: None,
    };
    for ext in ["f32", "tif", "png"] {
        let path = tmp(&format!("back-{ext}.{ext}"));
        let w = write(&path, &grid, Some(lattice)).unwrap();
        // The PNG holds the map's own 16-bit codes.
        assert_eq!(w.max_error_m, 0.0, "{ext}");
        let back = Heightmap::load(&path).unwrap();
        assert_eq!(back.cell_size, map.cell_size, "{ext}");
        assert!(
            back.data()
                .iter()
                .zip(map.data())
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{ext}"
        );
    }
    // Without a lattice a PNG spreads 65,535 steps over the range and says
    // what that cost. (jacksboro's own PNG was made
    // that way, so a procedural map shows it.)
    let map = common::terrain(2, 50, 40);
    let (lo, hi) = map.min_max();
    let grid = Grid {
        width: 50,
        height: 40,
        data: map.data(),
        nodata: map.nodata_mask(),
        cell_size: [1.0; 2],
        place: None,
    };
    let w = write(&tmp("back-range.png"), &grid, None).unwrap();
    let step = w.step_m.unwrap();
    assert!((step - (hi - lo) as f64 / 65535.0).abs() < 1e-9);
    // Half a step, plus half an f32 ulp of the largest height for the
    // decoded value's rounding.
    let bound = step / 2.0 + lo.abs().max(hi.abs()) as f64 * f64::powi(2.0, -24);
    assert!(
        w.max_error_m > 0.0 && w.max_error_m <= bound,
        "{w:?} vs {bound}"
    );
}

/// The file the in-memory path writes for `map`: its whole pyramid,
/// [`Packed::encode_with`] `predictor`, [`file::write`].
fn in_memory_pack(
    map: &Heightmap,
    e: f64,
    tile: usize,
    source: &str,
    predictor: Predictor,
) -> Vec<u8> {
    use terraclip::pack::file;
    let levels = Pyramid::build(map, Filter::default(), usize::MAX).levels;
    let (packed, _) = Packed::encode_with(&levels, e, tile, map.lattice, predictor);
    let path = tmp(&format!("mem-{source}-{e}-{tile}-{}.tcz", predictor.name()));
    file::write(
        &path,
        &packed,
        map.cell_size,
        &Filter::default().name(),
        source,
    )
    .unwrap();
    std::fs::read(&path).unwrap()
}

/// The file the streaming path writes for `src`, in bands of about
/// `band_bytes`.
fn streamed_pack(
    src: &dyn terraclip::terrain::rows::RowSource,
    (e, tile, predictor): (f64, usize, Predictor),
    source: &str,
    band_bytes: usize,
) -> Vec<u8> {
    use terraclip::pack::stream;
    let path = tmp(&format!(
        "stream-{source}-{e}-{tile}-{band_bytes}-{}.tcz",
        predictor.name()
    ));
    let mut o = stream::Options::new(e, tile, Filter::default(), source);
    o.band_bytes = band_bytes;
    o.predictor = predictor;
    let mut last = (0, 1);
    let s = stream::pack(src, &path, &o, &mut |d, t| last = (d, t)).unwrap();
    assert_eq!(last.0, last.1, "progress reaches its total");
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(s.bytes, bytes.len() as u64);
    // Nothing of this output's is left beside it but the output (other
    // tests pack into the same folder at the same time).
    let dir = path.parent().unwrap();
    let own = format!(".{}.tmp-", path.file_name().unwrap().to_string_lossy());
    let stray: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&own))
        .collect();
    assert!(stray.is_empty(), "temporary files left: {stray:?}");
    bytes
}

/// A tiled f32 TIFF written by hand (the `tiff` crate writes strips only):
/// `tile`² tiles, little-endian, uncompressed.
fn tiled_tiff(path: &Path, w: u32, h: u32, tile: u32, v: &[f32]) {
    let (across, down) = (w.div_ceil(tile), h.div_ceil(tile));
    let tiles = across * down;
    let tile_bytes = tile * tile * 4;
    let entries: u16 = 11;
    let ifd = 8u32;
    let ifd_len = 2 + 12 * entries as u32 + 4;
    let offsets_at = ifd + ifd_len;
    let counts_at = offsets_at + 4 * tiles;
    let data_at = counts_at + 4 * tiles;
    let mut b = Vec::new();
    b.extend_from_slice(b"II*\0");
    b.extend_from_slice(&ifd.to_le_bytes());
    b.extend_from_slice(&entries.to_le_bytes());
    let mut entry = |tag: u16, ty: u16, count: u32, value: u32| {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&value.to_le_bytes());
    };
    entry(256, 4, 1, w); // ImageWidth
    entry(257, 4, 1, h); // ImageLength
    entry(258, 3, 1, 32); // BitsPerSample
    entry(259, 3, 1, 1); // Compression: none
    entry(262, 3, 1, 1); // Photometric: black is zero
    entry(277, 3, 1, 1); // SamplesPerPixel
    entry(322, 4, 1, tile); // TileWidth
    entry(323, 4, 1, tile); // TileLength
    entry(324, 4, tiles, offsets_at); // TileOffsets
    entry(325, 4, tiles, counts_at); // TileByteCounts
    entry(339, 3, 1, 3); // SampleFormat: float
    b.extend_from_slice(&0u32.to_le_bytes());
    for t in 0..tiles {
        b.extend_from_slice(&(data_at + t * tile_bytes).to_le_bytes());
    }
    for _ in 0..tiles {
        b.extend_from_slice(&tile_bytes.to_le_bytes());
    }
    for t in 0..tiles {
        let (tx, ty) = (t % across, t / across);
        for y in 0..tile {
            for x in 0..tile {
                let (gx, gy) = (tx * tile + x, ty * tile + y);
                let s = if gx < w && gy < h {
                    v[(gy * w + gx) as usize]
                } else {
                    0.0
                };
                b.extend_from_slice(&s.to_le_bytes());
            }
        }
    }
    std::fs::write(path, b).unwrap();
}

/// A pack streamed in bands (level 0 read by rows, the coarser levels built
/// and coded band by band through files) is byte for byte the in-memory
/// pack of the same map: a PNG on its lattice, raw f32 and TIFF (strips and
/// tiles) with no-data, and procedural terrain; in one band and in many.
#[test]
fn a_streamed_pack_equals_the_in_memory_pack() {
    use terraclip::terrain::procedural::Procedural;
    use terraclip::terrain::rows::{self, MapRows, ProceduralRows};
    let (map, _) = jacksboro();
    // Fitted weights read two coarse rows each way, lifting one.
    for (e, tile, p) in [
        (0.0, 64, Predictor::Lifting),
        (1.0, 128, Predictor::Lifting),
        (0.0, 64, Predictor::Fitted),
        (1.0, 32, Predictor::Fitted),
    ] {
        let want = in_memory_pack(&map, e, tile, "jacksboro", p);
        for band in [usize::MAX / 8, 20_000] {
            let got = streamed_pack(&MapRows(map.clone()), (e, tile, p), "jacksboro", band);
            assert!(
                got == want,
                "jacksboro E = {e}, tile {tile}, {p:?}, bands of {band} bytes"
            );
        }
    }
    // Heights with holes: raw f32 (-9999 declared), TIFF strips of 3 rows
    // (NaN), and a TIFF of 16² tiles.
    let (w, h) = (157usize, 133usize);
    let v: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            if (x - 60.0).powi(2) + (y - 40.0).powi(2) < 150.0 {
                f32::NAN
            } else {
                (x * 0.07).sin() * 80.0 + (y * 0.05).cos() * 50.0 + x * 0.3
            }
        })
        .collect();
    let raw = tmp("holes.f32");
    let stored: Vec<u8> = v
        .iter()
        .flat_map(|&x| if x.is_nan() { -9999f32 } else { x }.to_le_bytes())
        .collect();
    std::fs::write(&raw, stored).unwrap();
    std::fs::write(
        raw.with_extension("json"),
        format!(r#"{{"width": {w}, "height": {h}, "nodata": -9999, "cell_size_m": {{"x": 10, "y": 10}}}}"#),
    )
    .unwrap();
    let strips = tmp("holes.tif");
    {
        use tiff::encoder::{colortype, TiffEncoder};
        let mut enc = TiffEncoder::new(std::fs::File::create(&strips).unwrap()).unwrap();
        let mut img = enc
            .new_image::<colortype::Gray32Float>(w as u32, h as u32)
            .unwrap();
        img.rows_per_strip(3).unwrap();
        img.write_data(&v).unwrap();
    }
    let tiled = tmp("holes-tiled.tif");
    tiled_tiff(&tiled, w as u32, h as u32, 16, &v);
    for path in [&raw, &strips, &tiled] {
        let map = Heightmap::load(path).unwrap();
        assert!(map.nodata_count() > 0);
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        for (e, p) in [
            (0.0, Predictor::Lifting),
            (0.5, Predictor::Lifting),
            (0.5, Predictor::Fitted),
        ] {
            let want = in_memory_pack(&map, e, 32, &name, p);
            let src = rows::open(path).unwrap();
            for band in [usize::MAX / 8, 3_000] {
                let got = streamed_pack(src.as_ref(), (e, 32, p), &name, band);
                assert!(got == want, "{name} E = {e}, {p:?}, bands of {band} bytes");
            }
        }
    }
    let p = Procedural::new(7, 190, 77);
    let map = p.generate().unwrap();
    let want = in_memory_pack(&map, 1.0, 32, "procedural", Predictor::Lifting);
    let got = streamed_pack(
        &ProceduralRows::new(p).unwrap(),
        (1.0, 32, Predictor::Lifting),
        "procedural",
        5_000,
    );
    assert!(got == want, "procedural");
}

/// Frames of `scene` along a path of `frames` frames, `step` metres each,
/// rendered in one session: images and stats.
fn flight(
    scene: &terraclip::scene::Scene,
    frames: usize,
    step: f64,
) -> Vec<(terraclip::render::Image, terraclip::RenderStats)> {
    use terraclip::frame::stats::Passes;
    use terraclip::render::{RenderOptions, Session};
    let mut session = Session::new(scene, &mut Passes::default()).unwrap();
    terraclip::camera::path(&scene.camera(), frames, step)
        .iter()
        .map(|cam| {
            session
                .render(cam, &RenderOptions::default(), Passes::default())
                .unwrap()
        })
        .collect()
}

/// A lossless pack decoded tile by tile as a flight's windows reach its
/// tiles (and evicting those they leave) renders every frame bit for bit
/// as the map loaded whole; each frame decodes only what its windows
/// newly reach, and what stays decoded is bounded by the windows. The map
/// is 4097 wide, so the runs of evicted tiles along a row span whole pages
/// that are given back (and read as zeros until decoded again).
#[test]
fn a_flight_over_a_pack_decoded_as_it_goes_renders_the_map_itself() {
    use terraclip::pack::stream;
    use terraclip::terrain::procedural::Procedural;
    use terraclip::terrain::rows::ProceduralRows;
    let mut direct = terraclip::scene::Scene::bench_scene();
    let p = Procedural::new(20041, 4097, 513);
    direct.terrain.procedural = Some(p.clone());
    direct.camera.position = [2000.0, -2500.0, 900.0];
    direct.camera.look_at = Some([4000.0, -2500.0, 150.0]);
    (direct.image.width, direct.image.height) = (320, 180);
    let path = tmp("flight.tcz");
    let o = stream::Options::new(0.0, 32, Filter::default(), "flight");
    stream::pack(&ProceduralRows::new(p).unwrap(), &path, &o, &mut |_, _| {}).unwrap();
    let mut packed = direct.clone();
    (packed.terrain.procedural, packed.terrain.file) = (None, Some(path));
    let (frames, step) = (48, 400.0);
    let want = flight(&direct, frames, step);
    let got = flight(&packed, frames, step);
    let mut evicted = 0;
    for (i, ((a, _), (b, s))) in want.iter().zip(&got).enumerate() {
        assert!(a.rgba == b.rgba, "frame {i}: colour differs");
        assert!(
            a.depth
                .iter()
                .zip(&b.depth)
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "frame {i}: depth differs"
        );
        let z = s.lazy.as_ref().expect("a pack decoded tile by tile");
        assert_eq!((z.levels_unbuilt, z.levels_waiting), (0, 0), "frame {i}");
        if i == 0 {
            assert!(z.tiles_this_frame > 0);
        }
        // A window of n = 63 (65 texels with its ring) spans at most 4 × 4
        // tiles of 32², and one tile around them is kept: 6 × 6 per drawn
        // level (7 of them), and the 5 coarser levels' 11 tiles.
        assert!(z.tiles_resident.unwrap() <= 36 * 7 + 11, "frame {i}: {z:?}");
        evicted += z.tiles_evicted.unwrap();
    }
    assert!(evicted > 100, "the flight leaves tiles behind: {evicted}");
    // Held still, the windows uncover nothing, so after the first update
    // the ring of tiles around them is decoded ahead a tile an update (the
    // least decoding ahead earns), then nothing more.
    let mut session = terraclip::render::Session::new(&packed, &mut Default::default()).unwrap();
    let cam = packed.camera();
    let opts = terraclip::render::RenderOptions::default();
    let mut ahead = vec![];
    for _ in 0..400 {
        let (img, s) = session.render(&cam, &opts, Default::default()).unwrap();
        assert!(img.rgba == want[0].0.rgba);
        let z = s.lazy.unwrap();
        if !ahead.is_empty() {
            assert!(z.tiles_this_frame <= 1, "{z:?}");
        }
        ahead.push(z.tiles_this_frame);
        if z.tiles_this_frame == 0 {
            break;
        }
    }
    assert_eq!(ahead.last(), Some(&0), "{ahead:?}");
    assert!(
        ahead.len() > 10,
        "the ring is decoded over frames: {ahead:?}"
    );
}

/// With a budget of one sample an update, the coarsest drawn level comes
/// first and the finer ones wait, then appear frame by frame (LH04's
/// graceful degradation); once all are drawn the frame is the map's own.
#[test]
fn a_pack_over_budget_draws_the_coarse_levels_first() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let direct =
        terraclip::scene::Scene::load(&root.join("golden/jacksboro-oblique.toml")).unwrap();
    let mut packed = jacksboro_scene_from_pack_tiled(0.0, 32, "budget.tcz");
    packed.pyramid.budget = 1;
    let got = flight(&packed, 40, 0.0);
    let waiting: Vec<usize> = got
        .iter()
        .map(|(_, s)| s.lazy.as_ref().unwrap().levels_waiting)
        .collect();
    let drawn: Vec<usize> = got.iter().map(|(_, s)| s.levels_drawn).collect();
    assert!(waiting[0] > 0, "{waiting:?}");
    assert!(waiting.windows(2).all(|w| w[1] <= w[0]), "{waiting:?}");
    assert_eq!(*waiting.last().unwrap(), 0, "{waiting:?}");
    assert!(drawn[0] < *drawn.last().unwrap(), "{drawn:?}");
    let want = flight(&direct, 1, 0.0);
    assert!(got.last().unwrap().0.rgba == want[0].0.rgba);
}

/// A damaged tile met during a render is an error that names the pack,
/// the level and the tile, not a panic or wrong heights.
#[test]
fn a_damaged_tile_met_by_a_render_is_an_error_naming_it() {
    use terraclip::render::{render, RenderOptions};
    let scene = jacksboro_scene_from_pack_tiled(1.0, 64, "damaged-render.tcz");
    let path = scene.terrain.file.clone().unwrap();
    let mut b = std::fs::read(&path).unwrap();
    let last = b.len() - 5;
    b[last] ^= 0x01;
    std::fs::write(&path, &b).unwrap();
    let e = render(&scene, &RenderOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains(path.to_str().unwrap()), "{e}");
    // The file's last bytes are the coarsest level's tile, the first one
    // any frame decodes.
    assert!(e.contains("level 8 tile (0, 0): checksum mismatch"), "{e}");
}

/// Any window of any level decoded from the mapped pack alone has the
/// bits of the whole decode there, for each predictor; and it decodes
/// exactly the tiles it needs: its own tiles on level l, then on each
/// coarser level the tiles that meet what the level's needed tiles are
/// predicted from (the predictors' stencils' reach, worked out here
/// apart from the reader's own), nothing more. `unpack --level L --window X,Y,W,H` writes those samples: a
/// window wider than tall, so a reader that swapped x and y fails.
#[test]
fn a_window_decoded_alone_equals_the_whole_decode() {
    use std::collections::BTreeSet;
    use std::sync::Arc;
    use terraclip::pack::{file, reader::PackReader};
    let (map, lattice) = jacksboro();
    for predictor in [Predictor::Lifting, Predictor::Fitted, Predictor::Upsampled] {
        let (packed, _) = Packed::encode_with(&levels_of(&map), 0.5, 32, Some(lattice), predictor);
        let path = tmp(&format!("window-{}.tcz", predictor.name()));
        file::write(&path, &packed, map.cell_size, "sinc-blackman:11", "j").unwrap();
        let whole = packed.decode().unwrap();
        // Tiles of level `k` meeting `[x0, y0, x1, y1]` (inclusive).
        let meeting = |k: usize, [x0, y0, x1, y1]: [i64; 4]| {
            let (nx, ny) = (
                whole[k].width.div_ceil(32) as i64,
                whole[k].height.div_ceil(32) as i64,
            );
            let mut out = BTreeSet::new();
            for ty in (y0.max(0) / 32)..=(y1 / 32).min(ny - 1) {
                for tx in (x0.max(0) / 32)..=(x1 / 32).min(nx - 1) {
                    out.insert([tx as usize, ty as usize]);
                }
            }
            out
        };
        for (l, rect) in [
            (0, [0i64, 0, 402, 343]),
            (0, [150, 77, 151, 77]),
            (0, [31, 31, 32, 32]),
            (1, [60, 10, 140, 171]),
            (3, [0, 0, 0, 0]),
            (8, [0, 0, 1, 1]),
        ] {
            let mut need = meeting(l, rect);
            let mut want = need.len() as u64;
            for k in l..whole.len() - 1 {
                let mut coarser = BTreeSet::new();
                for &[tx, ty] in &need {
                    // The stencils' reach: fine samples a..=b read coarse
                    // a/2 - 1 ..= b/2 + 1 lifting, ..= b/2 + 2 upsampling
                    // (the four-point stencil), clamped to the level.
                    let after = if predictor == Predictor::Upsampled {
                        2
                    } else {
                        1
                    };
                    let reach = |t: usize, n: usize, cn: usize| {
                        let (a, b) = (t * 32, ((t + 1) * 32).min(n) - 1);
                        (
                            ((a / 2) as i64 - 1).max(0),
                            ((b / 2 + after) as i64).min(cn as i64 - 1),
                        )
                    };
                    let (x0, x1) = reach(tx, whole[k].width, whole[k + 1].width);
                    let (y0, y1) = reach(ty, whole[k].height, whole[k + 1].height);
                    coarser.extend(meeting(k + 1, [x0, y0, x1, y1]));
                }
                want += coarser.len() as u64;
                need = coarser;
            }
            let r = PackReader::open(&path).unwrap();
            let mut p = Pyramid::decoded(Arc::new(r), Filter::default(), 1).unwrap();
            p.decode_window(l, rect).unwrap();
            common::same_window(&p.levels[l], &whole[l], l, rect);
            let tiles = p.lazy_stats().unwrap().tiles_built;
            assert_eq!(
                tiles, want,
                "{predictor:?} level {l} {rect:?}: tiles decoded"
            );
        }
        // unpack: level 1, a 40 × 23 window at (5, 17), against the whole
        // decode sample by sample.
        let out = tmp(&format!("window-{}.f32", predictor.name()));
        let st = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
            .arg("unpack")
            .arg(&path)
            .args(["--level", "1", "--window", "5,17,40,23", "-o"])
            .arg(&out)
            .status()
            .unwrap();
        assert!(st.success());
        let got = Heightmap::load(&out).unwrap();
        assert_eq!((got.width(), got.height()), (40, 23));
        for y in 0..23 {
            for x in 0..40 {
                let w = whole[1].data[(17 + y) * whole[1].width + 5 + x];
                assert_eq!(
                    got.get(x, y).to_bits(),
                    w.to_bits(),
                    "{predictor:?} ({x}, {y})"
                );
            }
        }
    }
}

/// The goldens' packs are what `terraclip pack` writes today (a codec or
/// format change shows here first: re-make them with the commands in
/// their scenes, then bless), and the lossless one renders the map's own
/// frame.
#[test]
fn the_golden_packs_are_todays_and_the_lossless_one_is_the_map() {
    use terraclip::pack::stream;
    use terraclip::terrain::rows;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (input, e, pack) in [
        (
            "tests/data/jacksboro_16.png",
            0.0,
            "golden/jacksboro-e0.tcz",
        ),
        (
            "golden/level-tint.toml",
            1.0,
            "golden/procedural-513-e1.tcz",
        ),
    ] {
        let src = if input.ends_with(".toml") {
            let s = terraclip::scene::Scene::load(Path::new(input)).unwrap();
            rows::for_terrain(&s.terrain, &s.base_dir).unwrap()
        } else {
            rows::open(Path::new(input)).unwrap()
        };
        let out = tmp(&format!("today-{e}.tcz"));
        let o = stream::Options::new(e, 128, Filter::default(), input);
        stream::pack(src.as_ref(), &out, &o, &mut |_, _| {}).unwrap();
        assert!(
            std::fs::read(&out).unwrap() == std::fs::read(pack).unwrap(),
            "{pack} is not what `terraclip pack {input}` writes now"
        );
    }
    use terraclip::render::{render, RenderOptions};
    let packed = terraclip::scene::Scene::load(Path::new("golden/pack-lossless.toml")).unwrap();
    let mut direct = packed.clone();
    direct.terrain.file = Some(root.join("tests/data/jacksboro_16.png"));
    let (a, _) = render(&direct, &RenderOptions::default()).unwrap();
    let (b, s) = render(&packed, &RenderOptions::default()).unwrap();
    assert!(s.lazy.is_some(), "decoded tile by tile");
    assert!(a.rgba == b.rgba);
    assert!(a
        .depth
        .iter()
        .zip(&b.depth)
        .all(|(x, y)| x.to_bits() == y.to_bits()));
}

/// Walking two windows (levels 0 and 1) across a pack of 9 levels, the
/// coarser levels the windows' tiles are predicted from are evicted too,
/// so what is held stops growing however far the walk goes. The bound is
/// derived level by level from the eviction rule: after each update a
/// level holds only tiles that meet its window (the coarsest drawn one
/// halved level by level below the drawn levels) grown by the ring of
/// one tile decoded ahead; and a drawn level holds every tile under its
/// window.
#[test]
fn a_long_walk_holds_a_bounded_set_of_tiles_on_every_level() {
    use std::sync::Arc;
    use terraclip::pack::{reader::PackReader, stream};
    use terraclip::terrain::procedural::Procedural;
    use terraclip::terrain::rows::ProceduralRows;
    let path = tmp("walk.tcz");
    let o = stream::Options::new(1.0, 32, Filter::default(), "walk");
    let p = Procedural::new(3, 4097, 257);
    stream::pack(&ProceduralRows::new(p).unwrap(), &path, &o, &mut |_, _| {}).unwrap();
    let reader = PackReader::open(&path).unwrap();
    let mut pyr = Pyramid::decoded(Arc::new(reader), Filter::default(), u64::MAX).unwrap();
    assert_eq!(pyr.levels.len(), 9);
    let sizes: Vec<[i64; 2]> = pyr
        .levels
        .iter()
        .map(|l| [l.width as i64, l.height as i64])
        .collect();
    // Tiles of a level of `size` meeting `[x0, y0, x1, y1]` grown by
    // `ring` tiles (32-sample tiles).
    let meeting = |[w, h]: [i64; 2], [x0, y0, x1, y1]: [i64; 4], ring: i64| -> u64 {
        let span = |a: i64, b: i64, n: i64| {
            let last = (n - 1).div_euclid(32);
            let (lo, hi) = (
                (a.div_euclid(32) - ring).max(0),
                (b.div_euclid(32) + ring).min(last),
            );
            (hi - lo + 1).max(0) as u64
        };
        span(x0, x1, w) * span(y0, y1, h)
    };
    let mut most = vec![0u64; 9];
    for step in 0..64i64 {
        let x = 40 * step;
        let windows = [[x, 64, x + 64, 128], [x / 2 - 2, 30, x / 2 + 64, 96]];
        let b = pyr.build_around(&windows);
        assert_eq!(b.ready, 0..2);
        let held = pyr.tiles_resident_per_level().unwrap();
        let mut keep = windows.to_vec();
        while keep.len() < 9 {
            let [x0, y0, x1, y1] = *keep.last().unwrap();
            keep.push([
                x0.div_euclid(2),
                y0.div_euclid(2),
                x1.div_euclid(2) + 1,
                y1.div_euclid(2) + 1,
            ]);
        }
        for l in 0..9 {
            let bound = meeting(sizes[l], keep[l], 1);
            assert!(
                held[l] <= bound,
                "step {step}, level {l}: {} held, bound {bound}",
                held[l]
            );
            if l < 2 {
                let under = meeting(sizes[l], keep[l], 0);
                assert!(
                    held[l] >= under,
                    "step {step}, level {l}: {} held, {under} under the window",
                    held[l]
                );
            }
            most[l] = most[l].max(held[l]);
        }
    }
    assert!(most.iter().all(|&m| m > 0), "{most:?}");
}

/// Heights near ±1e7 with 1e9 spikes at E = 0.01, each predictor: the
/// spikes are past the upsampled predictor's 2^24 residual steps, so its
/// finer levels send them raw (the raw path itself is unit-tested in
/// `codec`). The bound holds on every sample of every level, exactly,
/// and each spike comes back with its own bits.
#[test]
fn extreme_heights_and_spikes_keep_the_bound_and_come_back_exact() {
    let (w, h) = (70usize, 50usize);
    let spikes = [(5usize, 7usize), (33, 20), (64, 44), (12, 40)];
    let values: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if spikes.contains(&(x, y)) {
                1e9
            } else {
                (if x < w / 2 { 1e7 } else { -1e7 }) + (x * 13 + y * 7) as f32 * 0.37
            }
        })
        .collect();
    let map = Heightmap::from_values(w, h, values, None, [10.0; 2], "test").unwrap();
    let src = levels_of(&map);
    for predictor in [Predictor::Lifting, Predictor::Fitted, Predictor::Upsampled] {
        let (packed, recon) = Packed::encode_with(&src, 0.01, 16, None, predictor);
        let decoded = packed.decode().unwrap();
        assert!(
            same_bits(&decoded, &recon),
            "{predictor:?}: decode differs from the encoder's"
        );
        for (l, (s, d)) in src.iter().zip(&decoded).enumerate() {
            for (i, (a, b)) in s.data.iter().zip(&d.data).enumerate() {
                if !s.nodata[i] {
                    assert!(
                        (*a as f64 - *b as f64).abs() <= 0.01,
                        "{predictor:?} level {l} sample {i}: {a} decoded as {b}"
                    );
                }
            }
        }
        for &(x, y) in &spikes {
            assert_eq!(
                decoded[0].data[y * w + x].to_bits(),
                1e9f32.to_bits(),
                "{predictor:?}"
            );
        }
    }
}

/// Eviction gives pages back: a window decoded at the west end of a
/// 4097-wide level, then moved 3,000 samples east, leaves the tiles it
/// left behind evicted, and the whole pages of their rows are no longer
/// resident (`mincore`) and read as zeros, the documented stand-in until
/// they are decoded again; decoded again, they are the whole decode's
/// bits. A row is 16 KiB, so each of the 64 rows under the window holds
/// whole 4 KiB pages inside the evicted run of tiles.
#[cfg(target_os = "linux")]
#[test]
fn evicted_tiles_give_their_pages_back() {
    use std::sync::Arc;
    use terraclip::pack::{reader::PackReader, stream};
    use terraclip::terrain::procedural::Procedural;
    let path = tmp("evict.tcz");
    let o = stream::Options::new(0.0, 32, Filter::default(), "evict");
    let p = Procedural::new(11, 4097, 257);
    common::pack_procedural(&p, &path, &o);
    let whole = p.generate().unwrap();
    let reader = PackReader::open(&path).unwrap();
    let mut pyr = Pyramid::decoded(Arc::new(reader), Filter::default(), u64::MAX).unwrap();
    let page = 4096usize;
    // Resident pages and the samples of level 0 over columns 0..2048 of
    // rows 64..128, counting only pages wholly inside that span.
    let survey = |pyr: &Pyramid| -> (usize, usize, bool) {
        let lv = &pyr.levels[0];
        let (mut pages, mut resident) = (0, 0);
        let mut zeros = true;
        for y in 64..128 {
            let row = &lv.data[y * lv.width..y * lv.width + 2048];
            let (a, b) = (row.as_ptr() as usize, row.as_ptr() as usize + 2048 * 4);
            let (first, last) = (a.div_ceil(page) * page, b / page * page);
            let mut vec = vec![0u8; (last - first) / page];
            // SAFETY: the range is whole pages inside a live allocation;
            // mincore only reports residency.
            let r = unsafe {
                libc::mincore(first as *mut libc::c_void, last - first, vec.as_mut_ptr())
            };
            assert_eq!(r, 0);
            pages += vec.len();
            resident += vec.iter().filter(|&&v| v & 1 == 1).count();
            let inner = (first - a) / 4..(last - a) / 4;
            zeros &= row[inner].iter().all(|&v| v == 0.0);
        }
        (pages, resident, zeros)
    };
    // A window over columns 0..2047 of rows 64..127.
    pyr.build_around(&[[0, 64, 2047, 127]]);
    let (pages, resident, zeros) = survey(&pyr);
    assert!(pages >= 64, "{pages}");
    assert_eq!(resident, pages, "decoded, every page is resident");
    assert!(!zeros);
    // Moved east: columns 0..2047 are more than a ring of tiles away.
    let b = pyr.build_around(&[[3000, 64, 4000, 127]]);
    // The 64 × 2 tiles of 32² under the old window at least.
    assert!(b.evicted >= 128, "{b:?}");
    let (_, resident, _) = survey(&pyr);
    assert_eq!(resident, 0, "evicted, no page of the span is resident");
    let (_, _, zeros) = survey(&pyr);
    assert!(zeros, "evicted samples read as zeros");
    // And back: the whole decode's bits again.
    pyr.build_around(&[[0, 64, 2047, 127]]);
    let lv = &pyr.levels[0];
    for y in 64..128 {
        for x in 0..2048 {
            assert_eq!(
                lv.data[y * lv.width + x].to_bits(),
                whole.get(x, y).to_bits(),
                "({x}, {y})"
            );
        }
    }
}
