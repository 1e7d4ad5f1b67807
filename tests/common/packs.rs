//! A pack taken apart and put back together with its header checksum,
//! index offsets and tile checksums made right, so that damage to the
//! header's JSON or to a tile's bytes reaches the parsers and decoders
//! behind those checks instead of stopping at them.

use std::path::Path;
use terraclip::pack::file::{MAGIC, VERSION};

/// Bytes of one index entry: offset u64, length u32, CRC-32 u32.
pub const ENTRY: usize = 16;

/// A pack's header JSON and its tiles in index order.
#[derive(Clone, Debug)]
pub struct Parts {
    pub json: Vec<u8>,
    pub tiles: Vec<Vec<u8>>,
}

impl Parts {
    /// The parts of `bytes`, a pack this build wrote (its first tile's
    /// offset says where the index ends).
    pub fn of(bytes: &[u8]) -> Parts {
        let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        let len = u32_at(12) as usize;
        let json = bytes[20..20 + len].to_vec();
        let index = 20 + len;
        let first = u64::from_le_bytes(bytes[index..index + 8].try_into().unwrap()) as usize;
        let tiles = (index..first)
            .step_by(ENTRY)
            .map(|e| {
                let at = u64::from_le_bytes(bytes[e..e + 8].try_into().unwrap()) as usize;
                bytes[at..at + u32_at(e + 8) as usize].to_vec()
            })
            .collect();
        Parts { json, tiles }
    }

    /// Where index entry `k` starts in [`Parts::assemble`]'s bytes.
    pub fn entry_at(&self, k: usize) -> usize {
        20 + self.json.len() + ENTRY * k
    }

    /// The pack's bytes: every checksum and offset right for these parts.
    pub fn assemble(&self) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(self.json.len() as u32).to_le_bytes());
        out.extend_from_slice(&crc32fast::hash(&self.json).to_le_bytes());
        out.extend_from_slice(&self.json);
        let mut at = self.entry_at(self.tiles.len()) as u64;
        for t in &self.tiles {
            out.extend_from_slice(&at.to_le_bytes());
            out.extend_from_slice(&(t.len() as u32).to_le_bytes());
            out.extend_from_slice(&crc32fast::hash(t).to_le_bytes());
            at += t.len() as u64;
        }
        for t in &self.tiles {
            out.extend_from_slice(t);
        }
        out
    }

    /// The header as JSON, to edit.
    pub fn header(&self) -> serde_json::Value {
        serde_json::from_slice(&self.json).unwrap()
    }

    /// These parts with `header` as the header.
    pub fn with_header(&self, header: &serde_json::Value) -> Parts {
        Parts {
            json: serde_json::to_vec(header).unwrap(),
            tiles: self.tiles.clone(),
        }
    }
}

/// Reads and decodes a pack: Ok(true) decoded (finite, the sizes the header
/// says), Ok(false) a clean error naming the file, Err on a panic or an
/// error that does not name it.
///
/// Each case is also opened as a render opens it (mapped, the index
/// checked, each tile's CRC at decode) and decoded tile by tile through a
/// window over all of level 0, which needs every tile: it must agree, the
/// same bits or an error naming the file.
pub fn pack_once(p: &Path) -> Result<bool, String> {
    let r = std::panic::catch_unwind(|| terraclip::pack::file::read_levels(p));
    let mapped = std::panic::catch_unwind(|| mapped_levels(p));
    let bits = |l: &[terraclip::pyramid::PyramidLevel]| -> Vec<Vec<u32>> {
        l.iter()
            .map(|l| l.data.iter().map(|v| v.to_bits()).collect())
            .collect()
    };
    let file = p.file_name().unwrap().to_string_lossy();
    let names = |e: &terraclip::Error| e.to_string().contains(&*file);
    match (r, mapped) {
        (Err(_), _) | (_, Err(_)) => Err(format!("panic on {}", p.display())),
        (Ok(Ok((h, levels))), Ok(m)) => {
            if levels.len() != h.levels()
                || levels.iter().any(|l| l.data.iter().any(|v| !v.is_finite()))
            {
                return Err(format!("pack decoded badly: {h:?}"));
            }
            match m {
                Ok(m) if bits(&m) == bits(&levels) => Ok(true),
                Ok(_) => Err("the mapped decode differs from the whole one".into()),
                Err(e) => Err(format!(
                    "the mapped decode fails where the whole one does not: {e}"
                )),
            }
        }
        (Ok(Err(e)), Ok(m)) if names(&e) => match m {
            Err(e) if names(&e) => Ok(false),
            Err(e) => Err(format!("mapped pack error does not name the file: {e}")),
            Ok(_) => Err(format!(
                "the mapped decode loads what the whole one refuses: {e}"
            )),
        },
        (Ok(Err(e)), _) => Err(format!("pack error does not name the file: {e}")),
    }
}

/// Every level of the pack at `p` as a render decodes it.
pub fn mapped_levels(p: &Path) -> terraclip::Result<Vec<terraclip::pyramid::PyramidLevel>> {
    use terraclip::pyramid::{Filter, Pyramid};
    let r = terraclip::pack::reader::PackReader::open(p)?;
    let [w, h] = r.header().size();
    let bad = |e: String| terraclip::Error::BadFile {
        path: p.to_path_buf(),
        reason: e,
    };
    let filter = Filter::parse(&r.header().filter).map_err(bad)?;
    let mut py = Pyramid::decoded(std::sync::Arc::new(r), filter, 1).map_err(bad)?;
    py.decode_window(0, [0, 0, w as i64 - 1, h as i64 - 1])?;
    Ok(py.levels)
}

/// A 48 × 40 map with, in 16² tiles, tile (1, 0) all no-data and tile
/// (0, 1) half no-data: packs of it code mixed and all-no-data tiles.
pub fn holes() -> terraclip::terrain::Heightmap {
    let v: Vec<f32> = (0..48 * 40)
        .map(|i| {
            let (x, y) = (i % 48, i / 48);
            let hole =
                (16..32).contains(&x) && y < 16 || (x < 16 && (16..32).contains(&y) && x > y - 16);
            if hole {
                f32::NAN
            } else {
                (x as f32 * 0.7).sin() * 40.0 + y as f32 * 3.0
            }
        })
        .collect();
    terraclip::terrain::Heightmap::from_values(48, 40, v, None, [10.0; 2], "test").unwrap()
}
