//! Raw little-endian f32 heightmaps with a JSON sidecar (`<stem>.json`) that
//! gives `width`, `height`, `cell_size_m`, `nodata` and an optional decode.

use super::{named, sidecar::Sidecar, Heightmap};
use crate::error::{Error, Result};
use std::path::Path;

pub(super) fn read(path: &Path) -> Result<Heightmap> {
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
    named(&side_path, super::check_dimensions(w, h))?;
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
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let offset = side.raw_offset_m.unwrap_or(0.0);
    let scale = side.raw_scale_m_per_unit.unwrap_or(1.0);
    let nodata = side.nodata.map(|v| v as f32);
    let values = bytes
        .chunks_exact(4)
        .map(|b| {
            let v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            // Declared no-data is matched before decoding, on the stored value.
            if Some(v) == nodata || !v.is_finite() {
                f32::NAN
            } else {
                (offset + v as f64 * scale) as f32
            }
        })
        .collect();
    named(
        path,
        Heightmap::from_values(
            w as usize,
            h as usize,
            values,
            None,
            side.cell_size(),
            "raw-f32",
        ),
    )
}
