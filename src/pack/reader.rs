//! A pack opened to be decoded a tile at a time, as a clipmap's windows
//! reach its tiles ([`crate::pyramid::TileSource`]): its header and index
//! are read and checked when it is opened, and each tile is read (one
//! positioned read) and its CRC checked when it is decoded, so opening a
//! pack of any size reads only its header and index.
//!
//! Tiles are read, not memory-mapped: a mapping's pages count in the
//! process's resident set, and the kernel maps whole page-cache folios
//! around a tile (a 128² lossless tile is ~50 KB, a folio up to 2 MB), so
//! a flight's resident file pages grew with the tiles it passed, however
//! each tile's range was dropped after its decode (to 20 MB of a 70 MB
//! pack in 1,200 steps). Read pages stay in the page cache, outside it.

use super::codec::{self, coarse_rows, tile_rect, Quant};
use super::file::{
    check_end, checked_tile, index_end, parse_header, parse_index, tile_name, Entry, Header,
};
use crate::error::{Error, Result};
use crate::pyramid::{PyramidLevel, TileSource};
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// A pack ready to decode tiles from.
#[derive(Debug)]
pub struct PackReader {
    path: PathBuf,
    file: File,
    header: Header,
    index: Vec<Vec<Entry>>,
    quant: Vec<Quant>,
}

/// `len` bytes of `file` at `at`, or why not.
fn read_at(file: &File, at: u64, len: usize) -> std::io::Result<Vec<u8>> {
    let mut buf = vec![0u8; len];
    file.read_exact_at(&mut buf, at)?;
    Ok(buf)
}

impl PackReader {
    /// Reads `path`'s header and index. Errors name the file, and the tile
    /// whose index entry is at fault.
    pub fn open(path: &Path) -> Result<Self> {
        let io = |e| Error::io(path, e);
        let file = File::open(path).map_err(io)?;
        let file_len = file.metadata().map_err(io)?.len();
        let bad = |r: String| Error::file(path, r);
        // The fixed prefix, then the header it says follows (bounded by the
        // file), then the index the header sizes (checked against the
        // bytes after the header before a byte of it is allocated).
        let fixed = read_at(&file, 0, file_len.min(20) as usize).map_err(io)?;
        let json_len = match fixed.get(12..16) {
            Some(b) => u32::from_le_bytes(b.try_into().expect("4 bytes")) as u64,
            None => 0,
        };
        let head = read_at(&file, 0, (20 + json_len).min(file_len) as usize).map_err(io)?;
        let (header, at) = parse_header(&head).map_err(bad)?;
        let index_end = index_end(&header, at, file_len).map_err(bad)?;
        let prefix = read_at(&file, 0, index_end as usize).map_err(io)?;
        let (index, end) = parse_index(&prefix, &header, at, file_len).map_err(bad)?;
        let reader = PackReader {
            path: path.to_path_buf(),
            file,
            quant: (0..header.levels())
                .map(|l| header.level_quant(l).expect("a level of the header"))
                .collect(),
            header,
            index,
        };
        if let Err(r) = check_end(end, file_len) {
            // A length that lies shows as a tile whose bytes do not match
            // its checksum: name it if so (reading every tile, but only on
            // this error path).
            for (l, entries) in reader.index.iter().enumerate() {
                let nx = reader.header.tiles_of(l)[0];
                for (t, &e) in entries.iter().enumerate() {
                    reader.tile(e, || tile_name(l, t, nx)).map_err(bad)?;
                }
            }
            return Err(bad(r));
        }
        Ok(reader)
    }

    /// The pack's header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The bytes of `e`, checked against its CRC (its range lies in the
    /// file: the index was checked against the file's length).
    fn tile(&self, e: Entry, name: impl Fn() -> String) -> std::result::Result<Vec<u8>, String> {
        let bytes = read_at(&self.file, e.offset, e.len as usize)
            .map_err(|err| format!("{}: cannot be read ({err})", name()))?;
        checked_tile(&bytes, e, name)?;
        Ok(bytes)
    }
}

impl TileSource for PackReader {
    fn path(&self) -> &Path {
        &self.path
    }
    fn sizes(&self) -> Vec<[usize; 2]> {
        (0..self.header.levels())
            .map(|l| self.header.level_size(l))
            .collect()
    }
    fn ranges(&self) -> Vec<[f32; 2]> {
        (0..self.header.levels())
            .map(|l| self.header.level_range(l))
            .collect()
    }
    fn tile(&self) -> usize {
        self.header.tile
    }
    fn residual_step(&self, l: usize) -> Option<f32> {
        match self.quant[l] {
            // The coarsest level is predicted from its own samples.
            Quant::Upsampled { max_error } if l + 1 < self.quant.len() => {
                Some((2.0 * max_error) as f32)
            }
            _ => None,
        }
    }
    fn reads(&self, l: usize, [tx, ty]: [usize; 2]) -> Option<[i64; 4]> {
        if l + 1 >= self.header.levels() {
            return None;
        }
        let [w, h] = self.header.level_size(l);
        let [cw, ch] = self.header.level_size(l + 1);
        let (x0, y0, tw, th) = tile_rect(w, h, self.header.tile, tx, ty);
        let q = self.quant[l];
        let fitted = self.header.predictor() == codec::Predictor::Fitted;
        let cols = coarse_rows(cw, x0, x0 + tw, q, fitted);
        let rows = coarse_rows(ch, y0, y0 + th, q, fitted);
        Some([
            cols.start as i64,
            rows.start as i64,
            cols.end as i64 - 1,
            rows.end as i64 - 1,
        ])
    }
    fn decode(
        &self,
        l: usize,
        [tx, ty]: [usize; 2],
        coarse: &PyramidLevel,
    ) -> std::result::Result<(Vec<f32>, Vec<bool>), String> {
        let [nx, ny] = self.header.tiles_of(l);
        let name = || tile_name(l, ty * nx + tx, nx);
        if tx >= nx || ty >= ny {
            return Err(format!("{}: outside the level's {nx} × {ny} tiles", name()));
        }
        let bytes = self.tile(self.index[l][ty * nx + tx], name)?;
        let [w, h] = self.header.level_size(l);
        let rect = tile_rect(w, h, self.header.tile, tx, ty);
        let c = (l + 1 < self.header.levels()).then_some(coarse);
        let q = self.quant[l];
        let code_as = codec::CodeAs {
            coder: self.header.coder,
            fitted: self.header.predictor() == codec::Predictor::Fitted,
        };
        codec::decode_tile(&bytes, c, q, code_as, self.header.level_range(l), rect)
            .map_err(|r| format!("{}: {r}", name()))
    }
}
