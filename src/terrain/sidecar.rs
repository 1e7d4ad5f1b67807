//! JSON sidecars in the shape of `shared/data/dem/*.json`: dimensions, cell
//! size, no-data value, and the offset/scale that turns stored values into
//! metres.

use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize, Default, Clone)]
pub(crate) struct CellSize {
    pub x: f64,
    pub y: f64,
}

#[derive(Debug, Deserialize, Clone)]
pub(crate) struct Png16 {
    pub file: String,
    pub png16_offset_m: f64,
    pub png16_scale_m_per_unit: f64,
}

#[derive(Debug, Deserialize, Clone, Default)]
pub(crate) struct Sidecar {
    pub width: Option<u64>,
    pub height: Option<u64>,
    pub cell_size_m: Option<CellSize>,
    pub nodata: Option<f64>,
    pub png16: Option<Png16>,
    /// Decode for raw f32 files: `elev = raw_offset_m + value × raw_scale_m_per_unit`.
    pub raw_offset_m: Option<f64>,
    pub raw_scale_m_per_unit: Option<f64>,
    /// Where the map lies (CRS, position, no-data), as `unpack` writes it.
    pub place: Option<super::place::Place>,
}

impl Sidecar {
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let s: Sidecar = serde_json::from_str(&text)
            .map_err(|e| Error::file(path, format!("invalid JSON sidecar: {e}")))?;
        if let Some(c) = &s.cell_size_m {
            if !(c.x.is_finite() && c.y.is_finite() && c.x > 0.0 && c.y > 0.0) {
                return Err(Error::file(path, "cell_size_m must be finite and positive"));
            }
        }
        if let Some(p) = &s.place {
            p.check()
                .map_err(|r| Error::file(path, format!("place: {r}")))?;
        }
        if let Some(p) = &s.png16 {
            if !(p.png16_offset_m.is_finite() && p.png16_scale_m_per_unit.is_finite()) {
                return Err(Error::file(path, "png16 offset and scale must be finite"));
            }
        }
        Ok(s)
    }

    pub fn cell_size(&self) -> [f64; 2] {
        self.cell_size_m
            .as_ref()
            .map(|c| [c.x, c.y])
            .unwrap_or([1.0, 1.0])
    }

    /// Checks the sidecar's declared dimensions, if any, against the data's.
    pub fn check_dims(&self, path: &Path, width: usize, height: usize) -> Result<()> {
        let bad = |what: &str, want: u64, got: usize| {
            Error::file(
                path,
                format!("sidecar says {what} {want} but the data has {got}"),
            )
        };
        match (self.width, self.height) {
            (Some(w), _) if w != width as u64 => Err(bad("width", w, width)),
            (_, Some(h)) if h != height as u64 => Err(bad("height", h, height)),
            _ => Ok(()),
        }
    }
}

/// Finds the sidecar for a data file: `<stem>.json` beside it, else any JSON in
/// the same folder whose `png16.file` names it (e.g. `jacksboro.json` for
/// `jacksboro_16.png`).
pub(crate) fn find(data: &Path) -> Option<(PathBuf, Sidecar)> {
    let direct = data.with_extension("json");
    if direct.is_file() {
        return Sidecar::read(&direct).ok().map(|s| (direct, s));
    }
    let name = data.file_name()?.to_string_lossy().into_owned();
    let dir = match data.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut entries: Vec<PathBuf> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    entries.sort();
    entries.into_iter().find_map(|p| {
        let s = Sidecar::read(&p).ok()?;
        (s.png16.as_ref()?.file == name).then_some((p, s))
    })
}
