//! Level 0 read a band of rows at a time, for work that never holds a map
//! whole (`terraclip pack` of maps larger than memory):
//!
//! - raw f32 through a memory mapping, each band's pages dropped once read,
//!   so resident memory follows the band, not the file;
//! - TIFF by its own chunks (strips or tiles), one row of chunks decoded at
//!   a time;
//! - procedural terrain generated band by band;
//! - any other format loaded whole first (those are bounded by
//!   [`super::MAX_TEXELS`] anyway).
//!
//! A source gives heights with NaN where there is no data; the consumer
//! fills no-data as [`Heightmap::from_values`] does (with the lowest valid
//! height), so a map read by rows has the bits of the same map loaded.

use super::procedural::Procedural;
use super::raw::Raw;
use super::tiff_file::Tiff;
use super::{check_side, Heightmap, Lattice};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// A map readable a band of rows at a time.
pub trait RowSource: Sync {
    /// Samples across and down.
    fn size(&self) -> [usize; 2];
    /// Heights of rows `[y0, y1)`, row-major, NaN where there is no data
    /// (declared no-data already matched).
    fn read_rows(&self, y0: usize, y1: usize) -> Result<Vec<f32>>;
    /// Whether a sample may be no-data: if so, a reader must scan the map
    /// for its fill value (the lowest valid height) before using any band.
    fn may_have_nodata(&self) -> bool {
        true
    }
    /// Metres per cell, x and y.
    fn cell_size(&self) -> [f64; 2];
    /// The lattice every sample lies on, where the reader knows one.
    fn lattice(&self) -> Option<Lattice> {
        None
    }
    /// The CRS the file names, and where it names none, its placement in
    /// its own units (a GeoTIFF's pixel scale and tie point).
    fn georef(&self) -> (Option<String>, Option<super::crs::Undeclared>) {
        (None, None)
    }
    /// Where the map lies, as its file says ([`super::place`]).
    fn place(&self) -> Option<super::place::Place> {
        None
    }
}

/// `src` with the CRS `declared` for the file at `path` applied to its
/// cell size ([`super::crs::declare`]).
pub fn with_crs(
    src: Box<dyn RowSource>,
    path: &Path,
    declared: &str,
) -> Result<Box<dyn RowSource>> {
    let (file_crs, undeclared) = src.georef();
    let place = src
        .place()
        .or_else(|| super::crs::declared_place(declared, undeclared.as_ref()));
    let (cell, _) = crate::terrain::named(
        path,
        super::crs::declare(
            declared,
            file_crs.as_deref(),
            undeclared.as_ref(),
            src.cell_size(),
        ),
    )?;
    Ok(Box::new(WithCell(src, cell, place)))
}

/// The warning for a file at `path` read as `src` that names no CRS and
/// whose numbers look like degrees.
pub fn crs_warning(src: &dyn RowSource, path: &Path) -> Option<String> {
    match src.georef() {
        (None, Some(u)) if u.looks_like_degrees() => Some(u.warning(path)),
        _ => None,
    }
}

/// The source a scene's `[terrain]` table names (its cell size applied).
pub fn for_terrain(spec: &crate::terrain::Spec, base_dir: &Path) -> Result<Box<dyn RowSource>> {
    let cell = spec.cell_size.as_ref().map(|c| c.pair());
    let src: Box<dyn RowSource> = match (&spec.file, &spec.procedural) {
        (Some(f), _) => {
            let path = base_dir.join(f);
            match &spec.crs {
                Some(c) => with_crs(open_var(&path, spec.variable.as_deref())?, &path, c)?,
                None => open_var(&path, spec.variable.as_deref())?,
            }
        }
        (_, Some(p)) => Box::new(ProceduralRows::new(p.clone())?),
        (None, None) => {
            return Err(Error::value(
                "terrain",
                "give exactly one of 'file' or 'procedural'",
            ))
        }
    };
    Ok(match cell {
        Some(c) => {
            let place = src.place();
            Box::new(WithCell(src, c, place))
        }
        None => src,
    })
}

/// The source for a heightmap file: read by rows where its format allows
/// (raw f32, TIFF, netCDF), else loaded whole.
pub fn open(path: &Path) -> Result<Box<dyn RowSource>> {
    open_var(path, None)
}

/// [`open`], with the variable of a netCDF file named.
pub fn open_var(path: &Path, variable: Option<&str>) -> Result<Box<dyn RowSource>> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if super::is_netcdf(&ext) {
        return super::netcdf::rows(path, variable);
    }
    if variable.is_some() {
        return Ok(Box::new(MapRows(Heightmap::load_var(path, variable)?)));
    }
    Ok(match ext.as_str() {
        "f32" | "raw" | "bin" => Box::new(RawRows::open(path)?),
        "tif" | "tiff" => Box::new(TiffRows::open(path)?),
        _ => Box::new(MapRows(Heightmap::load(path)?)),
    })
}

/// A source with its cell size overridden (a scene's `cell_size`, or a
/// declared CRS's conversion) and its place (kept, or the declared CRS's).
struct WithCell(Box<dyn RowSource>, [f64; 2], Option<super::place::Place>);

impl RowSource for WithCell {
    fn size(&self) -> [usize; 2] {
        self.0.size()
    }
    fn read_rows(&self, y0: usize, y1: usize) -> Result<Vec<f32>> {
        self.0.read_rows(y0, y1)
    }
    fn may_have_nodata(&self) -> bool {
        self.0.may_have_nodata()
    }
    fn cell_size(&self) -> [f64; 2] {
        self.1
    }
    fn lattice(&self) -> Option<Lattice> {
        self.0.lattice()
    }
    fn place(&self) -> Option<super::place::Place> {
        self.2.clone()
    }
}

/// A heightmap already in memory, given back by rows.
pub struct MapRows(pub Heightmap);

impl RowSource for MapRows {
    fn size(&self) -> [usize; 2] {
        [self.0.width(), self.0.height()]
    }
    fn read_rows(&self, y0: usize, y1: usize) -> Result<Vec<f32>> {
        let w = self.0.width();
        let (data, nodata) = (self.0.data(), self.0.nodata_mask());
        Ok((y0 * w..y1 * w)
            .map(|i| if nodata[i] { f32::NAN } else { data[i] })
            .collect())
    }
    fn may_have_nodata(&self) -> bool {
        self.0.nodata_count() > 0
    }
    fn cell_size(&self) -> [f64; 2] {
        self.0.cell_size
    }
    fn georef(&self) -> (Option<String>, Option<super::crs::Undeclared>) {
        (self.0.crs.clone(), self.0.undeclared)
    }
    fn place(&self) -> Option<super::place::Place> {
        self.0.place.clone()
    }
    fn lattice(&self) -> Option<Lattice> {
        self.0.lattice
    }
}

/// Procedural terrain generated band by band; any size up to
/// [`super::MAX_SIDE`] a side.
pub struct ProceduralRows(Procedural);

impl ProceduralRows {
    /// Checks the generator's parameters, with the per-side size limit only.
    pub fn new(p: Procedural) -> Result<Self> {
        p.validate_shape()
            .and_then(|_| check_side(p.width as u64, p.height as u64))
            .map_err(|r| Error::value("terrain.procedural", r))?;
        Ok(ProceduralRows(p))
    }
}

impl RowSource for ProceduralRows {
    fn size(&self) -> [usize; 2] {
        [self.0.width, self.0.height]
    }
    fn read_rows(&self, y0: usize, y1: usize) -> Result<Vec<f32>> {
        let w = self.0.width;
        // Each texel is a function of (seed, x, y) alone: bands in parallel.
        use rayon::prelude::*;
        let mut out = vec![0f32; (y1 - y0) * w];
        out.par_chunks_mut(w * 16)
            .enumerate()
            .for_each(|(b, band)| {
                let r0 = y0 + b * 16;
                band.copy_from_slice(&self.0.generate_rect([0, r0, w, r0 + band.len() / w]));
            });
        Ok(out)
    }
    fn may_have_nodata(&self) -> bool {
        false
    }
    fn cell_size(&self) -> [f64; 2] {
        [1.0, 1.0]
    }
}

/// A raw f32 file with its sidecar, mapped.
pub struct RawRows {
    path: PathBuf,
    raw: Raw,
    map: memmap2::Mmap,
}

impl RawRows {
    /// Maps `path` after checking its sidecar and length.
    pub fn open(path: &Path) -> Result<Self> {
        let raw = Raw::open(path, check_side)?;
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        // SAFETY: the mapping is read-only and private; a file truncated
        // under it by another process could fault, which no reader of a
        // shared file can rule out, but nothing here writes through it.
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
        let _ = map.advise(memmap2::Advice::Sequential);
        Ok(RawRows {
            path: path.to_path_buf(),
            raw,
            map,
        })
    }
}

impl RowSource for RawRows {
    fn size(&self) -> [usize; 2] {
        [self.raw.width, self.raw.height]
    }
    fn read_rows(&self, y0: usize, y1: usize) -> Result<Vec<f32>> {
        let row = self.raw.width * 4;
        let (a, b) = (y0 * row, y1 * row);
        let bytes = self
            .map
            .get(a..b)
            .ok_or_else(|| Error::file(&self.path, format!("rows {y0}..{y1} are past the end")))?;
        let out = self.raw.decode(bytes).collect();
        // Resident memory then follows the band, not the file.
        super::huge::drop_mapped(&self.map, a..b);
        Ok(out)
    }
    fn cell_size(&self) -> [f64; 2] {
        self.raw.cell_size
    }
    fn place(&self) -> Option<super::place::Place> {
        self.raw.place.clone()
    }
}

/// A TIFF read by its chunks: each band decodes the rows of chunks it
/// overlaps, and keeps the last row of chunks for the next band.
pub struct TiffRows {
    path: PathBuf,
    width: usize,
    height: usize,
    cell_size: [f64; 2],
    crs: Option<String>,
    undeclared: Option<super::crs::Undeclared>,
    place: Option<super::place::Place>,
    nodata: Option<f32>,
    chunk: [usize; 2],
    inner: Mutex<TiffState>,
}

struct TiffState {
    tiff: Tiff,
    /// The last row of chunks decoded: its index and its rows' heights.
    cached: Option<(usize, Vec<f32>)>,
}

impl TiffRows {
    /// Opens `path` and reads its tags and chunk layout.
    pub fn open(path: &Path) -> Result<Self> {
        let tiff = Tiff::open(path, check_side)?;
        let (cw, ch) = tiff.dec.chunk_dimensions();
        if cw == 0 || ch == 0 {
            return Err(Error::file(path, "TIFF chunks of zero size"));
        }
        let chunk = [
            (cw as usize).min(tiff.width),
            (ch as usize).min(tiff.height),
        ];
        Ok(TiffRows {
            path: path.to_path_buf(),
            width: tiff.width,
            height: tiff.height,
            cell_size: tiff.cell_size,
            crs: tiff.crs.clone(),
            undeclared: tiff.undeclared,
            place: tiff.place.clone(),
            nodata: tiff.nodata,
            chunk,
            inner: Mutex::new(TiffState { tiff, cached: None }),
        })
    }

    /// Heights of row of chunks `r`, NaN where there is no data.
    fn chunk_row(&self, st: &mut TiffState, r: usize) -> Result<Vec<f32>> {
        let [cw, ch] = self.chunk;
        let across = self.width.div_ceil(cw);
        let rows = ch.min(self.height - r * ch);
        let mut out = vec![0f32; rows * self.width];
        for c in 0..across {
            let index = (r * across + c) as u32;
            let (v, _) = st.tiff.chunk(index, &self.path)?;
            let w = cw.min(self.width - c * cw);
            if v.len() < w * rows {
                return Err(Error::file(
                    &self.path,
                    format!("chunk {index} holds {} samples, not {w}×{rows}", v.len()),
                ));
            }
            let stride = v.len() / rows;
            for y in 0..rows {
                let dst = &mut out[y * self.width + c * cw..][..w];
                for (d, &s) in dst.iter_mut().zip(&v[y * stride..][..w]) {
                    *d = if !s.is_finite() || Some(s) == self.nodata {
                        f32::NAN
                    } else {
                        s
                    };
                }
            }
        }
        Ok(out)
    }
}

impl RowSource for TiffRows {
    fn size(&self) -> [usize; 2] {
        [self.width, self.height]
    }
    fn read_rows(&self, y0: usize, y1: usize) -> Result<Vec<f32>> {
        let ch = self.chunk[1];
        let mut st = self
            .inner
            .lock()
            .map_err(|_| Error::file(&self.path, "TIFF reader poisoned by an earlier failure"))?;
        let mut out = Vec::with_capacity((y1 - y0) * self.width);
        for r in y0 / ch..(y1 - 1) / ch + 1 {
            if st.cached.as_ref().map(|c| c.0) != Some(r) {
                let rows = self.chunk_row(&mut st, r)?;
                st.cached = Some((r, rows));
            }
            let (_, rows) = st.cached.as_ref().expect("just cached");
            let (a, b) = (y0.max(r * ch) - r * ch, y1.min((r + 1) * ch) - r * ch);
            out.extend_from_slice(&rows[a * self.width..b * self.width]);
        }
        Ok(out)
    }
    fn cell_size(&self) -> [f64; 2] {
        self.cell_size
    }
    fn georef(&self) -> (Option<String>, Option<super::crs::Undeclared>) {
        (self.crs.clone(), self.undeclared)
    }
    fn place(&self) -> Option<super::place::Place> {
        self.place.clone()
    }
}
