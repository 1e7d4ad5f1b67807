//! Packing a map larger than memory: level 0 is read a band of rows at a
//! time ([`RowSource`]), the coarser levels are built band by band into
//! files beside the output, and the levels are coded coarse to fine a row
//! of tiles at a time, so what is resident is a few bands, whatever the
//! map's size.
//!
//! 1. Scan (only where the source may hold no-data, or a lossless pack may
//!    use a lattice): the lowest valid height, which fills no-data as a
//!    loaded map's is filled, and whether every sample is on the lattice.
//! 2. The pyramid: each coarser level from bands of the one below, with the
//!    whole-level build's own block code (`downsample::block`), so every
//!    sample has the bits `Pyramid::build` gives; written to its spill file.
//! 3. The code: from the coarsest level down, each row of tiles coded from
//!    its band and the band of the coarser level's reconstruction it is
//!    predicted from; the reconstruction then overwrites the level's
//!    filtered rows in its spill file (no later step reads them), for the
//!    next finer level to predict from. Tiles go to one body file per level.
//! 4. The file: header and index, then the bodies finest first, through a
//!    temporary file and a rename. The bytes equal [`super::file::write`]'s
//!    of [`super::Packed::encode`] on the same map (`tests/pack.rs`).

use super::codec::{self, coarse_rows, encode_tile, tile_rect, CodeAs, Coder, Predictor, Quant};
use super::file::{self, Header};
use crate::error::{temp_path, write_atomic_with, Error, Result};
use crate::pyramid::downsample::{self, Block, Scratch};
use crate::pyramid::{Filter, Rows};
use crate::terrain::rows::RowSource;
use rayon::prelude::*;
use std::fs::File;
use std::ops::Range;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// Bytes of level samples a band holds (heights and flags) by default:
/// bands are cut to about this, so resident memory is a few of them.
pub const BAND_BYTES: usize = 48 << 20;
/// Output block of the pyramid step, rows × columns: one worker's scratch
/// then stays near (32·2 + taps) × 2048 × 16 bytes, about 2.5 MB.
const BLOCK: [usize; 2] = [32, 2048];

/// What to pack, and how.
#[derive(Clone, Debug)]
pub struct Options {
    /// Bound on every sample's error, metres; 0 is lossless.
    pub max_error: f64,
    /// Tile side in samples (made even).
    pub tile: usize,
    /// The filter of the coarser levels.
    pub filter: Filter,
    /// What the finer levels are predicted from.
    pub predictor: Predictor,
    /// The tiles' entropy stage.
    pub coder: Coder,
    /// What the header names as the source.
    pub source: String,
    /// About the bytes of samples one band holds ([`BAND_BYTES`]; tests
    /// make it small, so that a small map is cut into many bands).
    pub band_bytes: usize,
}

impl Options {
    /// Options with bands of [`BAND_BYTES`].
    pub fn new(max_error: f64, tile: usize, filter: Filter, source: &str) -> Self {
        Options {
            max_error,
            tile,
            filter,
            predictor: Predictor::Lifting,
            coder: Coder::Ratio,
            source: source.to_string(),
            band_bytes: BAND_BYTES,
        }
    }
}

/// What a pack run did.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Level 0's size.
    pub size: [usize; 2],
    /// Levels coded.
    pub levels: usize,
    /// Tiles coded, every level counted.
    pub tiles: usize,
    /// The file's bytes.
    pub bytes: u64,
    /// The largest error over every sample of every level, metres.
    pub max_error_seen: f64,
}

/// A file beside the output, removed when dropped (on success and on
/// failure alike).
struct Temp {
    path: PathBuf,
    file: File,
}

impl Temp {
    fn create(out: &Path, part: &str) -> Result<Self> {
        let path = temp_path(out, part)?;
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        Ok(Temp { path, file })
    }
    fn read(&self, at: u64, buf: &mut [u8]) -> Result<()> {
        self.file
            .read_exact_at(buf, at)
            .map_err(|e| Error::io(&self.path, e))
    }
    fn write(&self, at: u64, buf: &[u8]) -> Result<()> {
        self.file
            .write_all_at(buf, at)
            .map_err(|e| Error::io(&self.path, e))
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// A band of a level: heights and no-data flags of rows `rows`.
struct Band {
    rows: Range<usize>,
    data: Vec<f32>,
    nodata: Vec<bool>,
}

impl Band {
    fn view(&self, width: usize, height: usize) -> Rows<'_> {
        Rows {
            width,
            height,
            y0: self.rows.start,
            data: &self.data,
            nodata: &self.nodata,
        }
    }
}

/// A coarser level on disk: f32 heights (LE), then one byte of no-data
/// flag per sample.
struct Spill {
    temp: Temp,
    width: usize,
    height: usize,
}

impl Spill {
    fn create(out: &Path, l: usize, [width, height]: [usize; 2]) -> Result<Self> {
        let temp = Temp::create(out, &format!("-level{l}"))?;
        temp.file
            .set_len((width * height * 5) as u64)
            .map_err(|e| Error::io(&temp.path, e))?;
        Ok(Spill {
            temp,
            width,
            height,
        })
    }
    fn read(&self, rows: Range<usize>) -> Result<Band> {
        let (a, b) = (rows.start * self.width, rows.end * self.width);
        let mut bytes = vec![0u8; (b - a) * 4];
        self.temp.read(a as u64 * 4, &mut bytes)?;
        let data = bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let mut flags = vec![0u8; b - a];
        let plane = (self.width * self.height * 4) as u64;
        self.temp.read(plane + a as u64, &mut flags)?;
        Ok(Band {
            rows,
            data,
            nodata: flags.into_iter().map(|f| f != 0).collect(),
        })
    }
    fn write(&self, y0: usize, data: &[f32], nodata: Option<&[bool]>) -> Result<()> {
        let a = y0 * self.width;
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.temp.write(a as u64 * 4, &bytes)?;
        if let Some(nd) = nodata {
            let plane = (self.width * self.height * 4) as u64;
            let flags: Vec<u8> = nd.iter().map(|&b| u8::from(b)).collect();
            self.temp.write(plane + a as u64, &flags)?;
        }
        Ok(())
    }
}

/// Level 0: the source's rows, no-data filled with `fill`.
struct Base<'a> {
    src: &'a dyn RowSource,
    fill: f32,
}

impl Base<'_> {
    fn read(&self, rows: Range<usize>) -> Result<Band> {
        let v = self.src.read_rows(rows.start, rows.end)?;
        let nodata: Vec<bool> = v.iter().map(|x| !x.is_finite()).collect();
        let data = v
            .into_iter()
            .zip(&nodata)
            .map(|(x, &nd)| if nd { self.fill } else { x })
            .collect();
        Ok(Band { rows, data, nodata })
    }
}

/// Rows per band of a level `width` wide: `bytes` of samples.
fn band_rows(bytes: usize, width: usize) -> usize {
    (bytes / (width * 5)).max(1)
}

/// The sizes of every level a map of `size` has, finest first (halved
/// while both sides have 3 samples or more, as `Pyramid::build` does).
fn level_sizes(size: [usize; 2]) -> Vec<[usize; 2]> {
    let mut out = vec![size];
    while let Some(&[w, h]) = out.last().filter(|s| s[0] >= 3 && s[1] >= 3) {
        let (w2, h2) = downsample::halved(w, h);
        out.push([w2, h2]);
    }
    out
}

/// Packs `src` to `out`. `progress(done, total)` is called as work (in
/// samples) is done.
pub fn pack(
    src: &dyn RowSource,
    out: &Path,
    o: &Options,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Summary> {
    let tile = o.tile.max(2).next_multiple_of(2);
    let size = src.size();
    let sizes = level_sizes(size);
    let lattice = codec::usable(src.lattice()).filter(|_| o.max_error == 0.0);
    let scan = src.may_have_nodata() || lattice.is_some();
    let n0 = (size[0] * size[1]) as u64;
    let coarser: u64 = sizes[1..].iter().map(|s| (s[0] * s[1]) as u64).sum();
    let total = if scan { n0 } else { 0 } + coarser + n0 + coarser;
    let mut done = 0u64;
    let mut tick = |n: usize| {
        done += n as u64;
        progress(done, total);
    };

    // 1. Scan.
    let (mut fill, mut on_lattice) = (0f32, lattice.is_some());
    if scan {
        let (mut lo, mut valid) = (f32::INFINITY, false);
        let step = band_rows(o.band_bytes, size[0]);
        for y0 in (0..size[1]).step_by(step) {
            let y1 = (y0 + step).min(size[1]);
            let v = src.read_rows(y0, y1)?;
            let finite = v.iter().filter(|x| x.is_finite());
            lo = finite.clone().fold(lo, |a, &b| a.min(b));
            valid |= finite.clone().next().is_some();
            if let Some(l) = lattice {
                on_lattice &= finite.clone().all(|&x| codec::on_lattice(x, l));
            }
            tick(v.len());
        }
        if !valid {
            return Err(Error::file(
                Path::new(&o.source),
                "no valid height: every texel is no-data",
            ));
        }
        fill = lo;
    }
    let base = Base { src, fill };
    let spills: Vec<Spill> = sizes[1..]
        .iter()
        .enumerate()
        .map(|(i, &s)| Spill::create(out, i + 1, s))
        .collect::<Result<_>>()?;
    let read = |l: usize, rows: Range<usize>| -> Result<Band> {
        if l == 0 {
            base.read(rows)
        } else {
            spills[l - 1].read(rows)
        }
    };

    // 2. The pyramid.
    let kernel = o.filter.kernel();
    let r = kernel.len() / 2;
    for l in 0..sizes.len() - 1 {
        let ([w, h], [w2, h2]) = (sizes[l], sizes[l + 1]);
        let step = (band_rows(o.band_bytes, w) / 2).max(1);
        for j0 in (0..h2).step_by(step) {
            let j1 = (j0 + step).min(h2);
            let band = read(l, downsample::input_rows(h, r, j0, j1))?;
            let view = band.view(w, h);
            let blocks: Vec<Block> = (j0..j1)
                .step_by(BLOCK[0])
                .flat_map(|y0| {
                    (0..w2).step_by(BLOCK[1]).map(move |x0| Block {
                        x0,
                        y0,
                        x1: (x0 + BLOCK[1]).min(w2),
                        y1: (y0 + BLOCK[0]).min(j1),
                    })
                })
                .collect();
            let outs: Vec<(Vec<f32>, Vec<bool>)> = blocks
                .par_iter()
                .map_init(Scratch::default, |s, &b| {
                    let (mut v, mut nd) = (vec![0f32; b.len()], vec![false; b.len()]);
                    downsample::block(view, &kernel, b, s, &mut v, &mut nd);
                    (v, nd)
                })
                .collect();
            let n = (j1 - j0) * w2;
            let (mut data, mut nodata) = (vec![0f32; n], vec![false; n]);
            for (b, (v, nd)) in blocks.iter().zip(&outs) {
                for y in b.y0..b.y1 {
                    let at = (y - j0) * w2 + b.x0;
                    let from = (y - b.y0) * b.width();
                    data[at..at + b.width()].copy_from_slice(&v[from..from + b.width()]);
                    nodata[at..at + b.width()].copy_from_slice(&nd[from..from + b.width()]);
                }
            }
            spills[l].write(j0, &data, Some(&nodata))?;
            tick(n);
        }
    }

    // 3. The code, coarse to fine.
    let levels = sizes.len();
    let mut index: Vec<Vec<(u32, u32)>> = vec![Vec::new(); levels];
    let mut ranges = vec![[0f32; 2]; levels];
    let mut quants = vec![Quant::Bits; levels];
    let mut bodies = Vec::with_capacity(levels);
    let mut worst = 0f64;
    for l in (0..levels).rev() {
        let [w, h] = sizes[l];
        let quant = codec::quant(
            o.max_error,
            if l == 0 && on_lattice { lattice } else { None },
            o.predictor,
        );
        quants[l] = quant;
        let body = Temp::create(out, &format!("-body{l}"))?;
        let mut at = 0u64;
        let (nx, ny) = (w.div_ceil(tile), h.div_ceil(tile));
        let group = (64usize.div_ceil(nx))
            .min(band_rows(o.band_bytes, w) / tile)
            .max(1);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut first = None;
        for ty0 in (0..ny).step_by(group) {
            let ty1 = (ty0 + group).min(ny);
            let rows = ty0 * tile..(ty1 * tile).min(h);
            let band = read(l, rows.clone())?;
            let coarse = match spills.get(l) {
                Some(c) => {
                    let fitted = o.predictor == Predictor::Fitted;
                    Some(c.read(coarse_rows(c.height, rows.start, rows.end, quant, fitted))?)
                }
                None => None,
            };
            let view = band.view(w, h);
            let cview = coarse
                .as_ref()
                .zip(sizes.get(l + 1))
                .map(|(b, s)| b.view(s[0], s[1]));
            let coded: Vec<(Vec<u8>, Vec<f32>, f64)> = (0..(ty1 - ty0) * nx)
                .into_par_iter()
                .map(|t| {
                    let rect = tile_rect(w, h, tile, t % nx, ty0 + t / nx);
                    let c = cview.as_ref();
                    let code_as = CodeAs {
                        coder: o.coder,
                        fitted: o.predictor == Predictor::Fitted,
                    };
                    let (bytes, rec) = encode_tile(view, c, quant, code_as, rect);
                    let (x0, y0, tw, _) = rect;
                    let err = rec
                        .iter()
                        .enumerate()
                        .map(|(i, &v)| {
                            let s = view.data[view.index(x0 + i % tw, y0 + i / tw)];
                            (s as f64 - v as f64).abs()
                        })
                        .fold(0.0, f64::max);
                    (bytes, rec, err)
                })
                .collect();
            let mut recon = vec![0f32; band.data.len()];
            for (t, (bytes, rec, err)) in coded.iter().enumerate() {
                body.write(at, bytes)?;
                at += bytes.len() as u64;
                index[l].push((bytes.len() as u32, crc32fast::hash(bytes)));
                worst = worst.max(*err);
                let (x0, y0, tw, th) = tile_rect(w, h, tile, t % nx, ty0 + t / nx);
                for row in 0..th {
                    let dst = (y0 - rows.start + row) * w + x0;
                    recon[dst..dst + tw].copy_from_slice(&rec[row * tw..][..tw]);
                }
            }
            first.get_or_insert(recon[0]);
            for (&v, &nd) in recon.iter().zip(&band.nodata) {
                if !nd {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            if l > 0 {
                spills[l - 1].write(rows.start, &recon, None)?;
            }
            tick(recon.len());
        }
        // A level of only no-data still has the fill value everywhere.
        let f = first.unwrap_or(0.0);
        ranges[l] = if lo <= hi { [lo, hi] } else { [f, f] };
        bodies.push(body);
    }
    bodies.reverse();

    // 4. The file.
    let mut header = Header::new(
        src.cell_size(),
        &o.filter.name(),
        o.max_error,
        tile,
        &o.source,
        (0..levels).map(|l| (sizes[l][0], sizes[l][1], quants[l], ranges[l])),
    );
    header.place = src.place();
    header.coder = o.coder;
    header.set_predictor(o.predictor);
    let all: Vec<(u32, u32)> = index.iter().flatten().copied().collect();
    let prefix = file::prefix(&header, &all)?;
    let bytes = prefix.len() as u64 + all.iter().map(|t| t.0 as u64).sum::<u64>();
    write_atomic_with(out, |f| {
        use std::io::{Seek, Write};
        f.write_all(&prefix)?;
        for b in &bodies {
            let mut r = &b.file;
            r.seek(std::io::SeekFrom::Start(0))?;
            std::io::copy(&mut r, f)?;
        }
        Ok(())
    })?;
    Ok(Summary {
        size,
        levels,
        tiles: all.len(),
        bytes,
        max_error_seen: worst,
    })
}
