//! LERC-compressed GeoTIFF chunks (TIFF compression 34887, which Esri and
//! many elevation COGs use), with the feature `lerc`. The `tiff` crate
//! does not decode LERC, so each strip or tile is read raw from its offset
//! and byte count, unwrapped from the extra compression GDAL's
//! `LercParameters` tag (50674) names (0 none, 1 DEFLATE as zlib, 2 ZSTD;
//! `LERC`, `LERC_DEFLATE`, `LERC_ZSTD`) with `flate2` or `zstd`, and
//! decoded by Esri's LERC library through the `lerc` crate. A feature, not
//! a default: the crate's bindings are generated with bindgen, which needs
//! libclang (`apt install libclang-dev`) where a fresh clone needs nothing.
//!
//! A blob states its own size; it is decoded only once that size is the
//! chunk's, so no allocation follows a forged header.

use crate::error::{Error, Result};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;
use tiff::decoder::Decoder;
use tiff::tags::Tag;

/// TIFF's compression code for LERC.
pub(super) const LERC: u16 = 34887;

/// Where a LERC TIFF's chunks are, and how they are wrapped.
pub(super) struct LercChunks {
    /// 0 none, 1 DEFLATE, 2 ZSTD.
    extra: u32,
    offsets: Vec<u64>,
    counts: Vec<u64>,
    file_len: u64,
}

type Dec = Decoder<std::io::BufReader<std::fs::File>>;

impl LercChunks {
    /// The chunk table of a LERC TIFF, or `None` for another compression.
    pub fn open(dec: &mut Dec, path: &Path) -> Result<Option<Self>> {
        let bad = super::tiff_file::bad(path);
        if dec
            .find_tag_unsigned::<u16>(Tag::Compression)
            .map_err(&bad)?
            != Some(LERC)
        {
            return Ok(None);
        }
        let extra = match dec.find_tag_unsigned_vec::<u32>(Tag::Unknown(50674)) {
            Ok(Some(p)) => p.get(1).copied().unwrap_or(0),
            _ => 0,
        };
        if extra > 2 {
            return Err(Error::file(
                path,
                format!("LercParameters: extra compression {extra} is not 0, 1 or 2"),
            ));
        }
        let tiled = dec.find_tag(Tag::TileOffsets).map_err(&bad)?.is_some();
        let (o, c) = if tiled {
            (Tag::TileOffsets, Tag::TileByteCounts)
        } else {
            (Tag::StripOffsets, Tag::StripByteCounts)
        };
        let offsets = dec.get_tag_u64_vec(o).map_err(&bad)?;
        let counts = dec.get_tag_u64_vec(c).map_err(&bad)?;
        if offsets.len() != counts.len() {
            return Err(Error::file(
                path,
                format!("{} offsets and {} byte counts", offsets.len(), counts.len()),
            ));
        }
        let file_len = dec
            .inner()
            .get_ref()
            .metadata()
            .map_err(|e| Error::io(path, e))?
            .len();
        Ok(Some(LercChunks {
            extra,
            offsets,
            counts,
            file_len,
        }))
    }

    /// Chunk `index`'s samples as f32, its data width × height (an edge
    /// tile cropped), NaN where the blob's mask says invalid.
    pub fn read(
        &self,
        dec: &mut Dec,
        [width, height]: [usize; 2],
        index: u32,
        path: &Path,
    ) -> Result<Vec<f32>> {
        let err = |r: String| Error::file(path, format!("LERC chunk {index}: {r}"));
        let i = index as usize;
        let (Some(&at), Some(&n)) = (self.offsets.get(i), self.counts.get(i)) else {
            return Err(err("not in the chunk table".into()));
        };
        if at > self.file_len || n > self.file_len - at {
            return Err(err(format!(
                "{n} bytes at offset {at} run past the file's {} bytes",
                self.file_len
            )));
        }
        let (cw, ch) = dec.chunk_dimensions();
        let across = width.div_ceil(cw as usize);
        let (r, c) = (i / across, i % across);
        if r * ch as usize >= height {
            return Err(err("past the image's last row".into()));
        }
        let dw = (cw as usize).min(width - c * cw as usize) as u32;
        let dh = (ch as usize).min(height - r * ch as usize) as u32;
        let mut raw = vec![0u8; n as usize];
        let r = dec.inner();
        r.seek(SeekFrom::Start(at))
            .and_then(|_| r.read_exact(&mut raw))
            .map_err(|e| err(e.to_string()))?;
        // A blob is at most its samples as f64 and a mask, plus headers.
        let limit = cw as u64 * ch as u64 * 9 + (1 << 16);
        let unwrap = |mut rd: Box<dyn Read + '_>| -> Result<Vec<u8>> {
            let mut out = Vec::new();
            rd.by_ref()
                .take(limit + 1)
                .read_to_end(&mut out)
                .map_err(|e| err(format!("unwrapping: {e}")))?;
            if out.len() as u64 > limit {
                return Err(err(format!("unwraps to more than {limit} bytes")));
            }
            Ok(out)
        };
        let blob = match self.extra {
            0 => raw,
            1 => unwrap(Box::new(flate2::read::ZlibDecoder::new(&raw[..])))?,
            _ => unwrap(Box::new(
                zstd::stream::read::Decoder::new(&raw[..]).map_err(|e| err(e.to_string()))?,
            ))?,
        };
        let info = lerc::get_blob_info(&blob).map_err(|e| err(format!("{e:?}")))?;
        let (w, h) = (info.width, info.height);
        if info.depth != 1 || info.bands != 1 || info.masks > 1 || w != cw || !(h == ch || h == dh)
        {
            return Err(err(format!(
                "the blob holds {w}×{h}, depth {}, {} bands, {} masks; the chunk is {cw}×{ch} \
                 ({dw}×{dh} of data), one band",
                info.depth, info.bands, info.masks
            )));
        }
        let (w, h) = (w as usize, h as usize);
        let m = info.masks as usize;
        macro_rules! decode {
            ($t:ty) => {{
                let (v, mask) =
                    lerc::decode::<$t>(&blob, w, h, 1, 1, m).map_err(|e| err(format!("{e:?}")))?;
                (v.into_iter().map(|x| x as f32).collect::<Vec<f32>>(), mask)
            }};
        }
        let (v, mask) = match info.data_type {
            0 => decode!(i8),
            1 => decode!(u8),
            2 => decode!(i16),
            3 => decode!(u16),
            4 => decode!(i32),
            5 => decode!(u32),
            6 => decode!(f32),
            7 => decode!(f64),
            t => return Err(err(format!("data type {t} is not a LERC type"))),
        };
        let mut out = Vec::with_capacity(dw as usize * dh as usize);
        for y in 0..dh as usize {
            for x in 0..dw as usize {
                let k = y * w + x;
                let valid = mask.as_ref().is_none_or(|m| m[k] != 0);
                out.push(if valid { v[k] } else { f32::NAN });
            }
        }
        Ok(out)
    }
}
