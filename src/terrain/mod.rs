//! The terrain stage: heightmaps (an f32 grid with a cell size and a
//! no-data mask), the readers that produce one from files or from a seeded
//! generator, their placement in the world (`world`), and the large-array
//! allocation the terrain and its pyramid share (`huge`).
//!
//! Grid convention: `(col, row)`, row 0 is north, col 0 is west. Heights are
//! metres. No-data texels (declared no-data, NaN or ±inf) are counted, kept in
//! a mask, and filled with the lowest valid height so every later stage can
//! assume finite values.

mod asc;
pub mod crs;
pub(crate) mod huge;
mod image_file;
#[cfg(feature = "lerc")]
mod lerc_tiff;
pub mod netcdf;
pub mod place;
pub mod procedural;
mod raw;
pub mod rows;
mod sidecar;
mod spec;
mod tiff_file;
pub mod world;
pub mod write;

use crate::error::{Error, Result};
pub use spec::{CellSize, Spec, SynthesisSpec};
use std::path::Path;

/// The largest heightmap accepted, in texels (2^28 ≈ 268 M, about 1.3 GiB with
/// its mask). Larger inputs are refused before any allocation.
pub const MAX_TEXELS: u64 = 1 << 28;
/// The largest accepted side length, in texels.
pub const MAX_SIDE: u64 = 1 << 20;

/// A rectangular f32 height grid.
#[derive(Clone, Debug)]
pub struct Heightmap {
    width: usize,
    height: usize,
    data: Vec<f32>,
    nodata: Vec<bool>,
    nodata_count: usize,
    /// Cell size in metres along x (columns) and y (rows).
    pub cell_size: [f64; 2],
    /// Short name of the source format (`png8`, `png16`, `tiff-f32`, `asc`, …).
    pub format: String,
    /// The coordinate reference system a GeoTIFF declares (`EPSG:4326`,
    /// `geographic`, `EPSG:32633`, `projected`), or `None` where the file
    /// names none. A geographic grid's cell size is converted from degrees
    /// to metres at the map's centre latitude.
    pub crs: Option<String>,
    /// Where a GeoTIFF names no CRS, its pixel scale and tie point, which
    /// a declared CRS converts from ([`crs`]).
    pub undeclared: Option<crs::Undeclared>,
    /// Where the map lies (CRS, position, no-data value), where its file
    /// says: a pack keeps it, and `unpack` writes it back.
    pub place: Option<place::Place>,
    /// The lattice the reader decoded every sample from, where it knows
    /// one (a 16-bit PNG and its sidecar, an 8- or 16-bit integer image):
    /// a lossless pack codes the integer codes instead of the f32 bits.
    pub lattice: Option<Lattice>,
}

/// Whether a lower-case file extension is netCDF's.
pub(crate) fn is_netcdf(ext: &str) -> bool {
    matches!(ext, "nc" | "cdf")
}

/// Checks a width × height against [`MAX_SIDE`] and [`MAX_TEXELS`].
pub fn check_dimensions(width: u64, height: u64) -> std::result::Result<(), String> {
    check_side(width, height)?;
    if width * height > MAX_TEXELS {
        return Err(format!(
            "dimensions {width}×{height} exceed the limit of {MAX_TEXELS} texels held in memory"
        ));
    }
    Ok(())
}

/// The `[x, y, w, h]` window of a row-major grid `stride` wide.
pub fn window_of<T: Copy>(v: &[T], stride: usize, [x, y, w, h]: [usize; 4]) -> Vec<T> {
    (y..y + h)
        .flat_map(|r| v[r * stride + x..r * stride + x + w].iter().copied())
        .collect()
}

/// Checks a width × height against [`MAX_SIDE`] alone: the limit of maps
/// read by rows ([`rows`]), which are never held whole.
pub fn check_side(width: u64, height: u64) -> std::result::Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("zero-sized image ({width}×{height})"));
    }
    if width < 2 || height < 2 {
        return Err(format!(
            "a heightmap needs at least 2×2 texels, got {width}×{height}"
        ));
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(format!(
            "dimensions {width}×{height} exceed the limit of {MAX_SIDE} per side"
        ));
    }
    Ok(())
}

/// A lattice samples lie on: `value = (offset + code × scale) as f32` for an
/// integer code, computed in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// The value of code 0.
    pub offset: f64,
    /// The value of one code step.
    pub scale: f64,
}

impl Heightmap {
    /// Builds a heightmap from raw values. Non-finite values and values equal
    /// to `nodata_value` become no-data. Fails if the dimensions are out of
    /// range, the buffer length is wrong, or no texel is valid.
    pub fn from_values(
        width: usize,
        height: usize,
        values: Vec<f32>,
        nodata_value: Option<f32>,
        cell_size: [f64; 2],
        format: &str,
    ) -> std::result::Result<Self, String> {
        check_dimensions(width as u64, height as u64)?;
        if values.len() != width * height {
            return Err(format!(
                "expected {} values for {width}×{height}, found {}",
                width * height,
                values.len()
            ));
        }
        if !(cell_size[0].is_finite()
            && cell_size[1].is_finite()
            && cell_size[0] > 0.0
            && cell_size[1] > 0.0)
        {
            return Err(format!(
                "cell size must be finite and positive, got {:?}",
                cell_size
            ));
        }
        let is_nodata = |v: f32| !v.is_finite() || nodata_value == Some(v);
        let nodata = crate::terrain::huge::collect(values.iter().map(|&v| is_nodata(v)));
        let nodata_count = nodata.iter().filter(|&&b| b).count();
        let fill = values
            .iter()
            .zip(&nodata)
            .filter(|(_, &nd)| !nd)
            .map(|(&v, _)| v)
            .fold(f32::INFINITY, f32::min);
        if !fill.is_finite() {
            return Err("no valid height: every texel is no-data".into());
        }
        let data = values
            .into_iter()
            .zip(&nodata)
            .map(|(v, &nd)| if nd { fill } else { v })
            .collect();
        Ok(Heightmap {
            width,
            height,
            data,
            nodata,
            nodata_count,
            cell_size,
            format: format.into(),
            crs: None,
            undeclared: None,
            place: None,
            lattice: None,
        })
    }

    /// Reads a heightmap, choosing the reader by file extension: `.png`,
    /// `.tga`, `.tif`/`.tiff`, `.asc`, `.f32`/`.raw`/`.bin` (with a JSON sidecar).
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_var(path, None)
    }

    /// [`Heightmap::load`], with the variable of a netCDF file named
    /// (`terrain.variable`, `--variable`); other formats hold one map and
    /// refuse a name.
    pub fn load_var(path: &Path, variable: Option<&str>) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if let (Some(v), false) = (variable, is_netcdf(&ext)) {
            return Err(Error::file(
                path,
                format!("variable '{v}' is given, but only netCDF files (.nc) hold several"),
            ));
        }
        match ext.as_str() {
            "nc" | "cdf" => netcdf::read(path, variable),
            "png" | "tga" => image_file::read(path),
            "tif" | "tiff" => tiff_file::read(path),
            "asc" => asc::read(path),
            "f32" | "raw" | "bin" => raw::read(path),
            _ => Err(Error::file(
                path,
                format!(
                    "unknown heightmap extension '{ext}' (expected png, tga, tif, tiff, asc, nc, f32, raw or bin)"
                ),
            )),
        }
    }

    /// Applies a CRS declared for the map read from `path` (see
    /// [`crs::declare`]); errors name the file.
    pub fn declare_crs(&mut self, path: &Path, declared: &str) -> Result<()> {
        let (cell, name) = named(
            path,
            crs::declare(
                declared,
                self.crs.as_deref(),
                self.undeclared.as_ref(),
                self.cell_size,
            ),
        )?;
        self.cell_size = cell;
        self.crs = Some(name);
        if self.place.is_none() {
            self.place = crs::declared_place(declared, self.undeclared.as_ref());
        }
        Ok(())
    }

    /// The warning for a map read from `path` whose file names no CRS and
    /// whose numbers look like degrees; none once a CRS is declared.
    pub fn crs_warning(&self, path: &Path) -> Option<String> {
        self.undeclared
            .filter(|u| self.crs.is_none() && u.looks_like_degrees())
            .map(|u| u.warning(path))
    }

    /// Samples across.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Samples down.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Heights in row-major order (no-data texels hold the fill value).
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    /// Number of no-data texels (declared no-data, NaN or inf).
    pub fn nodata_count(&self) -> usize {
        self.nodata_count
    }
    /// Whether texel (x, y) is no-data.
    pub fn is_nodata(&self, x: usize, y: usize) -> bool {
        self.nodata[y * self.width + x]
    }
    /// Height at (x, y); the caller keeps x, y in range.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }
    /// Height at (x, y) with coordinates clamped to the map.
    #[inline]
    pub fn get_clamped(&self, x: i64, y: i64) -> f32 {
        let xc = x.clamp(0, self.width as i64 - 1) as usize;
        let yc = y.clamp(0, self.height as i64 - 1) as usize;
        self.data[yc * self.width + xc]
    }
    /// (min, max) over valid texels.
    pub fn min_max(&self) -> (f32, f32) {
        self.data
            .iter()
            .zip(&self.nodata)
            .filter(|(_, &nd)| !nd)
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (&v, _)| {
                (lo.min(v), hi.max(v))
            })
    }
    /// Heights and no-data mask, row-major, without copying them (the
    /// pyramid takes them as its level 0).
    pub fn into_parts(self) -> (Vec<f32>, Vec<bool>) {
        (self.data, self.nodata)
    }
    /// The no-data mask in row-major order.
    pub fn nodata_mask(&self) -> &[bool] {
        &self.nodata
    }
}

/// Converts a reader's plain-string failure into an error naming the file.
pub(crate) fn named<T>(path: &Path, r: std::result::Result<T, String>) -> Result<T> {
    r.map_err(|reason| Error::file(path, reason))
}

/// The terrain a scene's `[terrain]` table names, loaded from its file
/// (relative to `base_dir`) or generated, with the table's cell size
/// applied. Errors name the file, or the field (`terrain.procedural`).
pub fn load(spec: &crate::terrain::Spec, base_dir: &Path) -> Result<Heightmap> {
    let mut h = match (&spec.file, &spec.procedural) {
        (Some(f), _) => {
            let path = base_dir.join(f);
            let mut h = Heightmap::load_var(&path, spec.variable.as_deref())?;
            if let Some(c) = &spec.crs {
                h.declare_crs(&path, c)?;
            }
            h
        }
        (_, Some(p)) => p
            .generate()
            .map_err(|r| Error::value("terrain.procedural", r))?,
        (None, None) => {
            return Err(Error::value(
                "terrain",
                "give exactly one of 'file' or 'procedural'",
            ))
        }
    };
    if let Some(c) = &spec.cell_size {
        h.cell_size = c.pair();
    }
    Ok(h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_and_inf_become_counted_nodata() {
        let v = vec![1.0, f32::NAN, f32::INFINITY, 4.0, -9999.0, 2.0];
        let h = Heightmap::from_values(3, 2, v, Some(-9999.0), [1.0, 1.0], "t").unwrap();
        assert_eq!(h.nodata_count(), 3);
        assert_eq!(h.min_max(), (1.0, 4.0));
        assert!(h.data().iter().all(|v| v.is_finite()));
        assert_eq!(
            h.get(1, 0),
            1.0,
            "no-data filled with the lowest valid height"
        );
    }

    #[test]
    fn dimension_limits() {
        assert!(check_dimensions(0, 5).is_err());
        assert!(check_dimensions(1, 5).is_err());
        assert!(check_dimensions(MAX_SIDE + 1, 2).is_err());
        assert!(check_dimensions(1 << 15, 1 << 14).is_err());
        assert!(check_dimensions(403, 344).is_ok());
    }
}
