//! TIFF heightmaps, including GeoTIFF single-band files: 8/16/32-bit integer,
//! 16/32/64-bit float. GeoTIFF's ModelPixelScale gives the cell size and
//! GDAL_NODATA the no-data value.

use super::{check_dimensions, named, Heightmap, MAX_TEXELS};
use crate::error::{Error, Result};
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::ColorType;

pub(super) fn read(path: &Path) -> Result<Heightmap> {
    let bad = |e: tiff::TiffError| Error::file(path, format!("cannot decode TIFF: {e}"));
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut limits = Limits::default();
    limits.decoding_buffer_size = (MAX_TEXELS * 8) as usize;
    limits.intermediate_buffer_size = (MAX_TEXELS * 8) as usize;
    let mut dec = Decoder::new(std::io::BufReader::new(file))
        .map_err(bad)?
        .with_limits(limits);
    let (w, h) = dec.dimensions().map_err(bad)?;
    named(path, check_dimensions(w as u64, h as u64))?;
    match dec.colortype().map_err(bad)? {
        ColorType::Gray(_) => {}
        ColorType::Multiband { num_samples: 1, .. } => {}
        other => {
            return Err(Error::file(
                path,
                format!("expected a single-band grayscale TIFF, found {other:?}"),
            ))
        }
    }
    let cell = match dec.find_tag(Tag::ModelPixelScaleTag) {
        Ok(Some(v)) => {
            let s = v.into_f64_vec().map_err(bad)?;
            if s.len() < 2 || !(s[0] > 0.0 && s[1] > 0.0 && s[0].is_finite() && s[1].is_finite()) {
                return Err(Error::file(path, "GeoTIFF ModelPixelScale is not positive"));
            }
            [s[0], s[1]]
        }
        _ => [1.0, 1.0],
    };
    let nodata = match dec.find_tag(Tag::GdalNodata) {
        Ok(Some(v)) => {
            let s = v.into_string().map_err(bad)?;
            let t = s.trim_matches(|c: char| c == '\0' || c.is_whitespace());
            Some(
                t.parse::<f64>()
                    .map_err(|_| Error::file(path, format!("GDAL_NODATA '{t}' is not a number")))?
                    as f32,
            )
        }
        _ => None,
    };
    let img = dec.read_image().map_err(bad)?;
    let (values, format): (Vec<f32>, &str) = match img {
        DecodingResult::U8(v) => (v.into_iter().map(f32::from).collect(), "tiff-u8"),
        DecodingResult::U16(v) => (v.into_iter().map(f32::from).collect(), "tiff-u16"),
        DecodingResult::I8(v) => (v.into_iter().map(f32::from).collect(), "tiff-i8"),
        DecodingResult::I16(v) => (v.into_iter().map(f32::from).collect(), "tiff-i16"),
        DecodingResult::U32(v) => (v.into_iter().map(|x| x as f32).collect(), "tiff-u32"),
        DecodingResult::I32(v) => (v.into_iter().map(|x| x as f32).collect(), "tiff-i32"),
        DecodingResult::F16(v) => (v.into_iter().map(f32::from).collect(), "tiff-f16"),
        DecodingResult::F32(v) => (v, "tiff-f32"),
        DecodingResult::F64(v) => (v.into_iter().map(|x| x as f32).collect(), "tiff-f64"),
        DecodingResult::U64(_) | DecodingResult::I64(_) => {
            return Err(Error::file(
                path,
                "64-bit integer TIFF samples are not supported",
            ))
        }
    };
    named(
        path,
        Heightmap::from_values(w as usize, h as usize, values, nodata, cell, format),
    )
}
