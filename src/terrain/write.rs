//! Heightmaps written back out, in forms this crate's readers (and GIS
//! tools) read: raw f32 with its JSON sidecar, a single-band f32 GeoTIFF,
//! or a 16-bit PNG with its sidecar. A grid with a [`Place`] is written
//! where it lies: the GeoTIFF gets the input's GeoKeys, tie point, pixel
//! scale in the CRS's units and GDAL_NODATA, the f32 sidecar the same
//! facts. No-data samples are written as the input's no-data value, else
//! NaN (f32 forms), or transparent (PNG). Every file goes through a
//! temporary file and a rename.

use super::place::Place;
use super::Lattice;
use crate::error::{write_atomic, Error, Result};
use serde_json::json;
use std::path::{Path, PathBuf};

/// A grid of heights to write.
pub struct Grid<'a> {
    /// Samples across.
    pub width: usize,
    /// Samples down.
    pub height: usize,
    /// Heights, row-major, metres.
    pub data: &'a [f32],
    /// No-data flags, row-major.
    pub nodata: &'a [bool],
    /// Metres per cell, x and y.
    pub cell_size: [f64; 2],
    /// Where this grid (not level 0 of its pack) lies, if known.
    pub place: Option<Place>,
}

impl Grid<'_> {
    /// The value written for no-data: the input's, else NaN.
    fn nodata_value(&self) -> f32 {
        self.place
            .as_ref()
            .and_then(|p| p.nodata)
            .map_or(f32::NAN, |v| v as f32)
    }

    fn values(&self) -> impl Iterator<Item = f32> + '_ {
        let fill = self.nodata_value();
        self.data
            .iter()
            .zip(self.nodata)
            .map(move |(&v, &nd)| if nd { fill } else { v })
    }
}

/// What was written: the files, and for a PNG the quantisation step it
/// used and the largest error that cost (0 on the grid's own lattice).
#[derive(Clone, Debug, Default)]
pub struct Written {
    /// The sidecar written beside the file, if any.
    pub sidecar: Option<PathBuf>,
    /// Metres per PNG code.
    pub step_m: Option<f64>,
    /// The largest |written − height| over valid samples, metres.
    pub max_error_m: f64,
}

/// Writes `g` in the form `path`'s extension names: `.f32`, `.tif`/`.tiff`
/// or `.png`. `lattice` is the grid's own, where known: a PNG then holds
/// its codes exactly.
pub fn write(path: &Path, g: &Grid, lattice: Option<Lattice>) -> Result<Written> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "f32" => write_f32(path, g),
        "tif" | "tiff" => write_tiff(path, g),
        "png" => write_png16(path, g, lattice),
        _ => Err(Error::file(
            path,
            "write .f32 (with a JSON sidecar), .tif or .png (16-bit, with a sidecar)",
        )),
    }
}

fn sidecar(path: &Path, g: &Grid, extra: serde_json::Value) -> Result<PathBuf> {
    let side = path.with_extension("json");
    let mut v = json!({
        "width": g.width, "height": g.height,
        "cell_size_m": {"x": g.cell_size[0], "y": g.cell_size[1]},
    });
    if let (Some(o), Some(e)) = (v.as_object_mut(), extra.as_object()) {
        o.extend(e.clone());
    }
    let text =
        serde_json::to_string_pretty(&v).map_err(|e| Error::value("sidecar", e.to_string()))?;
    write_atomic(&side, text.as_bytes())?;
    Ok(side)
}

fn write_f32(path: &Path, g: &Grid) -> Result<Written> {
    let bytes: Vec<u8> = g.values().flat_map(f32::to_le_bytes).collect();
    write_atomic(path, &bytes)?;
    let extra = match &g.place {
        Some(p) => json!({
            "nodata": p.nodata,
            "crs": p.epsg().map(|c| format!("EPSG:{c}")),
            "geotransform": p.geotransform(),
            "place": p,
        }),
        None => json!({}),
    };
    let side = sidecar(path, g, extra)?;
    Ok(Written {
        sidecar: Some(side),
        ..Written::default()
    })
}

fn write_tiff(path: &Path, g: &Grid) -> Result<Written> {
    use tiff::encoder::{colortype, TiffEncoder};
    use tiff::tags::Tag;
    let bad = |e: tiff::TiffError| Error::file(path, format!("TIFF encoding failed: {e}"));
    let mut out = std::io::Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut out).map_err(bad)?;
    let (w, h) = (g.width as u32, g.height as u32);
    let mut img = enc.new_image::<colortype::Gray32Float>(w, h).map_err(bad)?;
    let e = img.encoder();
    match &g.place {
        Some(p) => {
            let [sx, sy] = p.pixel_scale;
            e.write_tag(Tag::ModelPixelScaleTag, &[sx, sy, 0.0][..])
                .map_err(bad)?;
            e.write_tag(Tag::ModelTiepointTag, &p.tiepoint()[..])
                .map_err(bad)?;
            e.write_tag(Tag::GeoKeyDirectoryTag, &p.geokeys[..])
                .map_err(bad)?;
            if !p.geo_doubles.is_empty() {
                e.write_tag(Tag::GeoDoubleParamsTag, &p.geo_doubles[..])
                    .map_err(bad)?;
            }
            if !p.geo_ascii.is_empty() {
                e.write_tag(Tag::GeoAsciiParamsTag, p.geo_ascii.as_str())
                    .map_err(bad)?;
            }
        }
        None => e
            .write_tag(
                Tag::ModelPixelScaleTag,
                &[g.cell_size[0], g.cell_size[1], 0.0][..],
            )
            .map_err(bad)?,
    }
    // GDAL's no-data tag: the input's value, or NaN where the grid has
    // no-data and no value was given.
    let nodata = match g.place.as_ref().and_then(|p| p.nodata) {
        Some(v) => Some(format!("{v}")),
        None => g.nodata.contains(&true).then(|| "nan".to_string()),
    };
    if let Some(text) = nodata {
        e.write_tag(Tag::GdalNodata, text.as_str()).map_err(bad)?;
    }
    let values: Vec<f32> = g.values().collect();
    img.write_data(&values).map_err(bad)?;
    write_atomic(path, out.get_ref())?;
    Ok(Written::default())
}

fn write_png16(path: &Path, g: &Grid, lattice: Option<Lattice>) -> Result<Written> {
    let valid = || {
        g.data
            .iter()
            .zip(g.nodata)
            .filter(|(_, &nd)| !nd)
            .map(|(&v, _)| v)
    };
    let (lo, hi) = valid().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if lo > hi {
        return Err(Error::file(path, "every sample is no-data"));
    }
    // The grid's own lattice when every code fits 16 bits; else 65,535
    // steps over the range.
    let own = lattice.and_then(|l| {
        let code = |v: f32| ((v as f64 - l.offset) / l.scale).round();
        let base = code(lo);
        let fits = valid().all(|v| {
            let k = code(v) - base;
            (0.0..=65535.0).contains(&k) && (l.offset + (base + k) * l.scale) as f32 == v
        });
        fits.then_some((l.offset + base * l.scale, l.scale))
    });
    let (offset, step) = own.unwrap_or_else(|| {
        let span = (hi - lo) as f64;
        (lo as f64, if span > 0.0 { span / 65535.0 } else { 1.0 })
    });
    let alpha = g.nodata.iter().any(|&b| b);
    let mut max_error = 0f64;
    let mut px: Vec<u16> = Vec::with_capacity(g.data.len() * if alpha { 2 } else { 1 });
    for (&v, &nd) in g.data.iter().zip(g.nodata) {
        let k = if nd {
            0
        } else {
            let k = ((v as f64 - offset) / step).round().clamp(0.0, 65535.0);
            let back = (offset + k * step) as f32;
            max_error = max_error.max((back as f64 - v as f64).abs());
            k as u16
        };
        px.push(k);
        if alpha {
            px.push(if nd { 0 } else { u16::MAX });
        }
    }
    // The encoder takes native-endian samples and writes them big-endian.
    let bytes: Vec<u8> = px.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let mut out = Vec::new();
    {
        use image::ImageEncoder;
        let colour = if alpha {
            image::ExtendedColorType::La16
        } else {
            image::ExtendedColorType::L16
        };
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&bytes, g.width as u32, g.height as u32, colour)
            .map_err(|e| Error::file(path, format!("PNG encoding failed: {e}")))?;
    }
    write_atomic(path, &out)?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let side = sidecar(
        path,
        g,
        json!({"png16": {"file": name, "png16_offset_m": offset, "png16_scale_m_per_unit": step}}),
    )?;
    Ok(Written {
        sidecar: Some(side),
        step_m: Some(step),
        max_error_m: max_error,
    })
}
