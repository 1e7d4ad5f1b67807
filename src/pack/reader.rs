//! A pack opened to be decoded a tile at a time, as a clipmap's windows
//! reach its tiles ([`crate::pyramid::TileSource`]): the file is
//! memory-mapped, its header and index are read and checked when it is
//! opened, and each tile's CRC when it is decoded, so opening a pack of
//! any size reads only its header and index.

use super::codec::{self, coarse_rows, tile_rect, Quant};
use super::file::{check_end, parse_header, parse_index, tile_bytes, tile_name, Entry, Header};
use crate::error::{Error, Result};
use crate::pyramid::{PyramidLevel, TileSource};
use crate::terrain::huge;
use std::path::{Path, PathBuf};

/// A pack ready to decode tiles from.
#[derive(Debug)]
pub struct PackReader {
    path: PathBuf,
    map: memmap2::Mmap,
    header: Header,
    index: Vec<Vec<Entry>>,
    quant: Vec<Quant>,
}

impl PackReader {
    /// Maps `path` and reads its header and index. Errors name the file,
    /// and the tile whose index entry is at fault.
    pub fn open(path: &Path) -> Result<Self> {
        let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        // SAFETY: read-only and private; a pack truncated under a running
        // session by another process could fault, as with any reader of a
        // shared file; nothing writes through the mapping.
        let map = unsafe { memmap2::Mmap::map(&f) }.map_err(|e| Error::io(path, e))?;
        let bad = |r: String| Error::file(path, r);
        let (header, at) = parse_header(&map).map_err(bad)?;
        let (index, end) = parse_index(&map, &header, at, map.len() as u64).map_err(bad)?;
        if let Err(r) = check_end(end, map.len() as u64) {
            // A length that lies shows as a tile whose bytes do not match
            // its checksum: name it if so (reading every tile, but only on
            // this error path).
            for (l, entries) in index.iter().enumerate() {
                let nx = header.tiles_of(l)[0];
                for (t, &e) in entries.iter().enumerate() {
                    tile_bytes(&map, e, || tile_name(l, t, nx)).map_err(bad)?;
                }
            }
            return Err(bad(r));
        }
        huge::drop_mapped(&map, 0..end as usize);
        let quant = (0..header.levels())
            .map(|l| header.level_quant(l).expect("a level of the header"))
            .collect();
        Ok(PackReader {
            path: path.to_path_buf(),
            map,
            header,
            index,
            quant,
        })
    }

    /// The pack's header.
    pub fn header(&self) -> &Header {
        &self.header
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
        let cols = coarse_rows(cw, x0, x0 + tw, q);
        let rows = coarse_rows(ch, y0, y0 + th, q);
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
        let e = self.index[l][ty * nx + tx];
        let bytes = tile_bytes(&self.map, e, name)?;
        let [w, h] = self.header.level_size(l);
        let rect = tile_rect(w, h, self.header.tile, tx, ty);
        let c = (l + 1 < self.header.levels()).then_some(coarse);
        let out = codec::decode_tile(bytes, c, self.quant[l], self.header.level_range(l), rect)
            .map_err(|r| format!("{}: {r}", name()));
        huge::drop_mapped(
            &self.map,
            e.offset as usize..(e.offset + e.len as u64) as usize,
        );
        out
    }
}
