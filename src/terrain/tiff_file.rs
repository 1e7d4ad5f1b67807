//! TIFF heightmaps, including GeoTIFF single-band files: 8/16/32-bit integer,
//! 16/32/64-bit float. GeoTIFF's ModelPixelScale gives the cell size and
//! GDAL_NODATA the no-data value. The GeoKey directory says whether the
//! grid is projected (cells in its linear unit, converted to metres) or
//! geographic (cells in degrees, as SRTM, Copernicus DEM and GLOBE tiles
//! are), which is converted to metres at the map's centre latitude on the
//! WGS 84 ellipsoid.

use super::{check_dimensions, named, Heightmap, MAX_TEXELS};
use crate::error::{Error, Result};
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::ColorType;

/// An opened TIFF and what its tags say: enough to read it whole or by
/// chunks (strips or tiles).
pub(super) struct Tiff {
    pub dec: Decoder<std::io::BufReader<std::fs::File>>,
    pub width: usize,
    pub height: usize,
    pub cell_size: [f64; 2],
    pub crs: Option<String>,
    pub nodata: Option<f32>,
    /// The pixel scale and tie point of a file that names no CRS.
    pub undeclared: Option<super::crs::Undeclared>,
    /// The CRS, position and no-data value, kept for a GeoTIFF written
    /// back out.
    pub place: Option<super::place::Place>,
    /// A LERC file's chunk table (feature `lerc`).
    #[cfg(feature = "lerc")]
    lerc: Option<super::lerc_tiff::LercChunks>,
}

/// An error of the TIFF decoder, naming the file. A compression the
/// decoder does not read (LERC, which Esri and many elevation COGs use,
/// is TIFF code 34887, read only with the feature `lerc`) is named, with
/// the GDAL command that rewrites the file in one it reads.
pub(super) fn bad(path: &Path) -> impl Fn(tiff::TiffError) -> Error + '_ {
    use tiff::tags::CompressionMethod;
    use tiff::{TiffError, TiffUnsupportedError};
    move |e| match e {
        TiffError::UnsupportedError(TiffUnsupportedError::UnsupportedCompressionMethod(m)) => {
            let (name, build) = match m {
                CompressionMethod::Unknown(34887) => (
                    "LERC (34887)".to_string(),
                    " by this build (one with `--features lerc` reads it, given \
                     libclang-dev to build)",
                ),
                other => (format!("{other:?}"), ""),
            };
            Error::file(
                path,
                format!(
                    "compression {name} is not read{build}; rewrite the file with \
                     `gdal_translate -co COMPRESS=DEFLATE -co PREDICTOR=3 {} out.tif` \
                     (PREDICTOR=2 for integer samples)",
                    path.display()
                ),
            )
        }
        e => Error::file(path, format!("cannot decode TIFF: {e}")),
    }
}

impl Tiff {
    /// Opens `path` and reads its tags; `check` is the size limit (the
    /// whole-map one, or the per-side one of a reader by rows).
    pub fn open(
        path: &Path,
        check: fn(u64, u64) -> std::result::Result<(), String>,
    ) -> Result<Self> {
        let bad = bad(path);
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut limits = Limits::default();
        limits.decoding_buffer_size = (MAX_TEXELS * 8) as usize;
        limits.intermediate_buffer_size = (MAX_TEXELS * 8) as usize;
        let mut dec = Decoder::new(std::io::BufReader::new(file))
            .map_err(&bad)?
            .with_limits(limits);
        let (w, h) = dec.dimensions().map_err(&bad)?;
        named(path, check(w as u64, h as u64))?;
        match dec.colortype().map_err(&bad)? {
            ColorType::Gray(_) => {}
            ColorType::Multiband { num_samples: 1, .. } => {}
            other => {
                return Err(Error::file(
                    path,
                    format!("expected a single-band grayscale TIFF, found {other:?}"),
                ))
            }
        }
        let scale = match dec.find_tag(Tag::ModelPixelScaleTag) {
            Ok(Some(v)) => {
                let s = v.into_f64_vec().map_err(&bad)?;
                if s.len() < 2
                    || !(s[0] > 0.0 && s[1] > 0.0 && s[0].is_finite() && s[1].is_finite())
                {
                    return Err(Error::file(path, "GeoTIFF ModelPixelScale is not positive"));
                }
                Some([s[0], s[1]])
            }
            _ => None,
        };
        let directory = match dec.find_tag(Tag::GeoKeyDirectoryTag) {
            Ok(Some(v)) => Some(v.into_u16_vec().map_err(&bad)?),
            _ => None,
        };
        let keys = match &directory {
            Some(d) => {
                geo_keys(d).map_err(|r| Error::file(path, format!("GeoTIFF key directory: {r}")))?
            }
            None => GeoKeys::default(),
        };
        let tiepoint = match dec.find_tag(Tag::ModelTiepointTag) {
            Ok(Some(v)) => Some(v.into_f64_vec().map_err(&bad)?),
            _ => None,
        };
        let (cell, crs) = cell_in_metres(scale, &keys, tiepoint.as_deref(), h)
            .map_err(|r| Error::file(path, r))?;
        // No CRS named: what a CRS declared later converts from.
        let undeclared = match (keys.model, scale, tiepoint.as_deref()) {
            (None, Some(scale), Some(t)) if t.len() >= 6 => Some(super::crs::Undeclared {
                scale,
                corner: [t[3] - t[0] * scale[0], t[4] + t[1] * scale[1]],
                rows: h as usize,
            }),
            _ => None,
        };
        let nodata =
            match dec.find_tag(Tag::GdalNodata) {
                Ok(Some(v)) => {
                    let s = v.into_string().map_err(&bad)?;
                    let t = s.trim_matches(|c: char| c == '\0' || c.is_whitespace());
                    Some(t.parse::<f64>().map_err(|_| {
                        Error::file(path, format!("GDAL_NODATA '{t}' is not a number"))
                    })?)
                }
                _ => None,
            };
        let doubles = match dec.find_tag(Tag::GeoDoubleParamsTag) {
            Ok(Some(v)) => v.into_f64_vec().map_err(&bad)?,
            _ => Vec::new(),
        };
        let ascii = match dec.find_tag(Tag::GeoAsciiParamsTag) {
            Ok(Some(v)) => v.into_string().map_err(&bad)?,
            _ => String::new(),
        };
        // Kept only to be written back: a placement that does not add up
        // (a key pointing past its parameters, a short tie point) costs
        // the unpacked file its place, not the map its heights, as GDAL
        // too reads such files with a warning.
        let place = super::place::Place::from_geotiff(
            directory,
            doubles,
            ascii,
            scale,
            tiepoint.as_deref(),
            nodata.filter(|v| v.is_finite()),
        )
        .ok()
        .flatten();
        let nodata = nodata.map(|v| v as f32);
        #[cfg(feature = "lerc")]
        let lerc = super::lerc_tiff::LercChunks::open(&mut dec, path)?;
        Ok(Tiff {
            dec,
            width: w as usize,
            height: h as usize,
            cell_size: cell,
            crs,
            nodata,
            undeclared,
            place,
            #[cfg(feature = "lerc")]
            lerc,
        })
    }

    /// Chunk `index` (a strip or tile, its data width × height) as f32,
    /// with the format's short name.
    pub fn chunk(&mut self, index: u32, path: &Path) -> Result<(Vec<f32>, &'static str)> {
        #[cfg(feature = "lerc")]
        if let Some(l) = &self.lerc {
            let size = [self.width, self.height];
            return Ok((l.read(&mut self.dec, size, index, path)?, "tiff-lerc"));
        }
        let img = self.dec.read_chunk(index).map_err(bad(path))?;
        named(path, to_f32(img))
    }

    /// The whole image as f32, with the format's short name: a LERC file
    /// chunk by chunk, any other by the decoder.
    fn image(&mut self, path: &Path) -> Result<(Vec<f32>, &'static str)> {
        #[cfg(feature = "lerc")]
        if self.lerc.is_some() {
            let (cw, ch) = self.dec.chunk_dimensions();
            let (cw, ch) = (cw as usize, ch as usize);
            let across = self.width.div_ceil(cw);
            let mut out = vec![0f32; self.width * self.height];
            for r in 0..self.height.div_ceil(ch) {
                for c in 0..across {
                    let (v, _) = self.chunk((r * across + c) as u32, path)?;
                    let w = cw.min(self.width - c * cw);
                    for (y, row) in v.chunks_exact(w).enumerate() {
                        out[(r * ch + y) * self.width + c * cw..][..w].copy_from_slice(row);
                    }
                }
            }
            return Ok((out, "tiff-lerc"));
        }
        let img = self.dec.read_image().map_err(bad(path))?;
        named(path, to_f32(img))
    }
}

/// Samples decoded from a TIFF as f32, with the format's short name.
pub(super) fn to_f32(img: DecodingResult) -> std::result::Result<(Vec<f32>, &'static str), String> {
    Ok(match img {
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
            return Err("64-bit integer TIFF samples are not supported".into())
        }
    })
}

pub(super) fn read(path: &Path) -> Result<Heightmap> {
    let mut t = Tiff::open(path, check_dimensions)?;
    let (values, format) = t.image(path)?;
    let mut map = named(
        path,
        Heightmap::from_values(t.width, t.height, values, t.nodata, t.cell_size, format),
    )?;
    map.crs = t.crs;
    map.undeclared = t.undeclared;
    map.place = t.place;
    Ok(map)
}

/// The GeoKeys this reader uses (GeoTIFF 1.1, section 7).
#[derive(Debug, Default, PartialEq)]
struct GeoKeys {
    /// GTModelTypeGeoKey (1024): 1 projected, 2 geographic, 3 geocentric.
    model: Option<u16>,
    /// GeographicTypeGeoKey (2048): an EPSG geographic CRS code.
    geographic: Option<u16>,
    /// ProjectedCSTypeGeoKey (3072): an EPSG projected CRS code.
    projected: Option<u16>,
    /// ProjLinearUnitsGeoKey (3076): an EPSG unit code.
    linear_units: Option<u16>,
}

/// Reads the keys whose values sit in the directory itself (TIFFTagLocation
/// 0), the only kind the keys above have.
fn geo_keys(dir: &[u16]) -> std::result::Result<GeoKeys, String> {
    let [version, _, _, count] = dir
        .get(..4)
        .and_then(|h| h.try_into().ok())
        .ok_or("no header")?;
    if version != 1 {
        return Err(format!("version {version}, expected 1"));
    }
    let entries = dir
        .get(4..4 + 4 * count as usize)
        .ok_or_else(|| format!("{count} keys announced, {} present", (dir.len() - 4) / 4))?;
    let mut keys = GeoKeys::default();
    for e in entries.chunks_exact(4) {
        let (id, location, value) = (e[0], e[1], e[3]);
        let slot = match id {
            1024 => &mut keys.model,
            2048 => &mut keys.geographic,
            3072 => &mut keys.projected,
            3076 => &mut keys.linear_units,
            _ => continue,
        };
        if location == 0 {
            *slot = Some(value);
        }
    }
    Ok(keys)
}

/// The cell size in metres and the CRS's name, from the pixel scale (in the
/// CRS's units), the keys and the tie point (which places the top row, so
/// a geographic grid's centre latitude is known). 32767 is GeoTIFF's
/// "user-defined" code, which names no EPSG CRS.
fn cell_in_metres(
    scale: Option<[f64; 2]>,
    keys: &GeoKeys,
    tiepoint: Option<&[f64]>,
    rows: u32,
) -> std::result::Result<([f64; 2], Option<String>), String> {
    let epsg = |code: Option<u16>, kind: &str| match code {
        Some(c) if c != 32767 => format!("EPSG:{c}"),
        _ => kind.to_string(),
    };
    match keys.model {
        Some(2) => {
            let [dx, dy] = scale.ok_or("a geographic GeoTIFF needs ModelPixelScale")?;
            let t = tiepoint
                .filter(|t| t.len() >= 6)
                .ok_or("a geographic GeoTIFF needs ModelTiepoint to place its latitude")?;
            // Latitude of the middle row: the tie point's raster row t[1]
            // sits at latitude t[4], rows run south.
            let lat = t[4] - (rows as f64 / 2.0 - t[1]) * dy;
            if !(lat.is_finite() && lat.abs() <= 90.0) {
                return Err(format!("centre latitude {lat}° is not on the globe"));
            }
            let [mx, my] = metres_per_degree(lat);
            Ok((
                [dx * mx, dy * my],
                Some(epsg(keys.geographic, "geographic")),
            ))
        }
        Some(1) => {
            let [dx, dy] = scale.unwrap_or([1.0, 1.0]);
            let unit = match keys.linear_units {
                None | Some(9001) => 1.0,
                Some(9002) => 0.3048,
                Some(9003) => 1200.0 / 3937.0,
                Some(u) => return Err(format!("linear unit EPSG:{u} is not metres or feet")),
            };
            Ok((
                [dx * unit, dy * unit],
                Some(epsg(keys.projected, "projected")),
            ))
        }
        Some(m) => Err(format!(
            "model type {m} (geocentric or unknown) is not a map"
        )),
        None => Ok((scale.unwrap_or([1.0, 1.0]), None)),
    }
}

/// Metres per degree of longitude and of latitude at latitude `lat`
/// (degrees), on the WGS 84 ellipsoid: the radius of the parallel and the
/// meridian's radius of curvature, times π/180.
pub(super) fn metres_per_degree(lat: f64) -> [f64; 2] {
    const A: f64 = 6_378_137.0;
    const F: f64 = 1.0 / 298.257_223_563;
    let e2 = F * (2.0 - F);
    let phi = lat.to_radians();
    let w = (1.0 - e2 * phi.sin().powi(2)).sqrt();
    let prime_vertical = A / w;
    let meridian = A * (1.0 - e2) / (w * w * w);
    let rad = std::f64::consts::PI / 180.0;
    [prime_vertical * phi.cos() * rad, meridian * rad]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the usual series for WGS 84 (the "length of a degree"
    /// tables): 111,412.84 cos φ − 93.5 cos 3φ + 0.118 cos 5φ along a
    /// parallel, 111,132.954 − 559.822 cos 2φ + 1.175 cos 4φ − 0.0023 cos 6φ
    /// along a meridian. With its coefficients rounded as quoted the series
    /// is off by up to 0.033 m (at the equator), so they must agree within
    /// 0.05 m.
    #[test]
    fn metres_per_degree_matches_the_series() {
        for lat in [0.0f64, 15.0, 30.0, 45.0, 46.5, 60.0, 75.0, 89.0] {
            let p = lat.to_radians();
            let lon = 111_412.84 * p.cos() - 93.5 * (3.0 * p).cos() + 0.118 * (5.0 * p).cos();
            let mer = 111_132.954 - 559.822 * (2.0 * p).cos() + 1.175 * (4.0 * p).cos()
                - 0.0023 * (6.0 * p).cos();
            let [x, y] = metres_per_degree(lat);
            assert!((x - lon).abs() < 0.05, "{lat}°: {x} against {lon}");
            assert!((y - mer).abs() < 0.05, "{lat}°: {y} against {mer}");
        }
    }

    #[test]
    fn key_directories_that_do_not_add_up_are_errors() {
        assert!(geo_keys(&[1, 1, 0, 2, 1024, 0, 1, 2]).is_err());
        assert!(geo_keys(&[2, 1, 0, 0]).is_err());
        assert!(geo_keys(&[1, 1]).is_err());
        let k = geo_keys(&[1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326]).unwrap();
        assert_eq!((k.model, k.geographic), (Some(2), Some(4326)));
    }
}
