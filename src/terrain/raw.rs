//! Raw little-endian f32 heightmaps with a JSON sidecar (`<stem>.json`) that
//! gives `width`, `height`, `cell_size_m`, `nodata` and an optional decode.

use super::{named, sidecar::Sidecar, Heightmap};
use crate::error::{Error, Result};
use std::path::Path;

/// What a raw file's sidecar says: enough to read it whole or by rows.
pub(super) struct Raw {
    pub width: usize,
    pub height: usize,
    pub cell_size: [f64; 2],
    offset: f64,
    scale: f64,
    nodata: Option<f32>,
    /// Where the map lies, as the sidecar's `place` says (what `unpack`
    /// writes beside a `.f32`).
    pub place: Option<super::place::Place>,
}

impl Raw {
    /// Reads the sidecar of `path` and checks the file's length against
    /// it; `check` is the size limit (the whole-map one, or the per-side
    /// one of a reader by rows).
    pub fn open(
        path: &Path,
        check: fn(u64, u64) -> std::result::Result<(), String>,
    ) -> Result<Self> {
        let side_path = path.with_extension("json");
        if !side_path.is_file() {
            return Err(Error::file(
                path,
                format!(
                    "raw f32 heightmap needs a JSON sidecar at {}",
                    side_path.display()
                ),
            ));
        }
        let side = Sidecar::read(&side_path)?;
        let (w, h) = match (side.width, side.height) {
            (Some(w), Some(h)) => (w, h),
            _ => return Err(Error::file(&side_path, "sidecar lacks width or height")),
        };
        named(&side_path, check(w, h))?;
        let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
        let want = w * h * 4;
        if meta.len() != want {
            return Err(Error::file(
                path,
                format!(
                    "{} bytes, but {w}×{h} f32 values need {want}{}",
                    meta.len(),
                    if meta.len() < want {
                        " (truncated)"
                    } else {
                        ""
                    }
                ),
            ));
        }
        Ok(Raw {
            width: w as usize,
            height: h as usize,
            cell_size: side.cell_size(),
            offset: side.raw_offset_m.unwrap_or(0.0),
            scale: side.raw_scale_m_per_unit.unwrap_or(1.0),
            nodata: side.nodata.map(|v| v as f32),
            place: side.place,
        })
    }

    /// Heights of stored little-endian f32 `bytes`, NaN where no data.
    pub fn decode<'a>(&'a self, bytes: &'a [u8]) -> impl Iterator<Item = f32> + 'a {
        bytes.chunks_exact(4).map(|b| {
            let v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            // Declared no-data is matched before decoding, on the stored value.
            if Some(v) == self.nodata || !v.is_finite() {
                f32::NAN
            } else {
                (self.offset + v as f64 * self.scale) as f32
            }
        })
    }
}

pub(super) fn read(path: &Path) -> Result<Heightmap> {
    let raw = Raw::open(path, super::check_dimensions)?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let values = raw.decode(&bytes).collect();
    let mut map = named(
        path,
        Heightmap::from_values(
            raw.width,
            raw.height,
            values,
            None,
            raw.cell_size,
            "raw-f32",
        ),
    )?;
    map.place = raw.place;
    Ok(map)
}
