//! Where a map lies on the Earth, kept so that a pack unpacks to a file GIS
//! tools place where the input was. Heights alone are not enough for
//! anyone checking a pack against the source map: without the CRS, the
//! origin and the no-data value, GDAL shows the unpacked grid in pixel
//! coordinates and no-data as NaN.
//!
//! A GeoTIFF's GeoKey directory (GeoTIFF 1.1, section 7) is kept verbatim,
//! with the double and ASCII parameters it points into: any CRS GDAL can
//! write then survives, including user-defined ones no EPSG code names.
//! Where a map's CRS is known only by its EPSG code (a netCDF grid mapping,
//! a declared `--crs`), the directory is written from the code.
//!
//! The position kept is the north-west corner of level 0's first sample in
//! the CRS's units: GDAL's geotransform origin, which unlike a tie point
//! does not depend on whether the file treats pixels as areas or points,
//! and which an area-pixel file (nearly all DEMs) gives back bit for bit.
//! A coarser level or a window is placed from it: level `l`'s sample
//! `(i, j)` is centred on level 0's sample `(i·2^l, j·2^l)` in the
//! vertex-centred pyramid.

use serde::{Deserialize, Serialize};

/// GTModelTypeGeoKey, GTRasterTypeGeoKey, GeographicTypeGeoKey,
/// ProjectedCSTypeGeoKey.
const MODEL_TYPE: u16 = 1024;
const RASTER_TYPE: u16 = 1025;
const GEOGRAPHIC_TYPE: u16 = 2048;
const PROJECTED_TYPE: u16 = 3072;
/// GTRasterTypeGeoKey's value for pixels that are points, not areas.
const PIXEL_IS_POINT: u16 = 2;
/// The tags a GeoKey's location may name: the directory itself (0),
/// GeoDoubleParams and GeoAsciiParams.
const IN_DIRECTORY: u16 = 0;
const DOUBLES: u16 = 34736;
const ASCII: u16 = 34737;

/// A map's CRS, position and no-data value, as its file gave them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Place {
    /// The GeoKey directory (tag 34735): a 4-number header, then a
    /// 4-number entry per key.
    pub geokeys: Vec<u16>,
    /// GeoDoubleParams (tag 34736), which keys may point into.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub geo_doubles: Vec<f64>,
    /// GeoAsciiParams (tag 34737), which keys may point into.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub geo_ascii: String,
    /// Level 0's cell size in the CRS's units, across and down (both
    /// positive; rows run south).
    pub pixel_scale: [f64; 2],
    /// The north-west corner of level 0's first sample, x and y in the
    /// CRS's units.
    pub origin: [f64; 2],
    /// The value the file marked no-data with, written back in its place.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nodata: Option<f64>,
}

impl Place {
    /// The place a GeoTIFF's tags give: its key directory and parameters,
    /// ModelPixelScale and a ModelTiepoint (raster I, J, K, model X, Y, Z).
    /// `None` for a file without all three (a ModelTransformation file,
    /// rotated or sheared, is not kept: its grid is not north-up).
    pub fn from_geotiff(
        geokeys: Option<Vec<u16>>,
        geo_doubles: Vec<f64>,
        geo_ascii: String,
        scale: Option<[f64; 2]>,
        tiepoint: Option<&[f64]>,
        nodata: Option<f64>,
    ) -> Result<Option<Place>, String> {
        let (Some(geokeys), Some(scale), Some(t)) = (geokeys, scale, tiepoint) else {
            return Ok(None);
        };
        let &[i, j, _, x, y, ..] = t else {
            return Err(format!(
                "ModelTiepoint has {} numbers, not 6 or more",
                t.len()
            ));
        };
        let mut p = Place {
            geokeys,
            geo_doubles,
            geo_ascii,
            pixel_scale: scale,
            origin: [0.0; 2],
            nodata,
        };
        // A point tie point is a sample's centre; an area one its corner.
        let half = if p.pixel_is_point() { 0.5 } else { 0.0 };
        p.origin = [x - (i + half) * scale[0], y + (j + half) * scale[1]];
        p.check()?;
        Ok(Some(p))
    }

    /// The place of a grid in the CRS `EPSG:code` (geographic or
    /// projected), its first sample's north-west corner at `origin`, its
    /// cells of `scale` in the CRS's units.
    pub fn from_epsg(
        code: u16,
        geographic: bool,
        scale: [f64; 2],
        origin: [f64; 2],
        nodata: Option<f64>,
    ) -> Place {
        let (model, key) = if geographic {
            (2, GEOGRAPHIC_TYPE)
        } else {
            (1, PROJECTED_TYPE)
        };
        Place {
            geokeys: vec![
                1,
                1,
                0,
                3, //
                MODEL_TYPE,
                0,
                1,
                model, //
                RASTER_TYPE,
                0,
                1,
                1, //
                key,
                0,
                1,
                code,
            ],
            geo_doubles: Vec::new(),
            geo_ascii: String::new(),
            pixel_scale: scale,
            origin,
            nodata,
        }
    }

    /// The key entries, once [`Place::check`] has passed.
    fn entries(&self) -> impl Iterator<Item = [u16; 4]> + '_ {
        let n = self.geokeys.get(3).copied().unwrap_or(0) as usize;
        self.geokeys
            .get(4..4 + 4 * n)
            .unwrap_or(&[])
            .chunks_exact(4)
            .map(|e| [e[0], e[1], e[2], e[3]])
    }

    /// A key whose value sits in the directory.
    fn key(&self, id: u16) -> Option<u16> {
        self.entries()
            .find(|e| e[0] == id && e[1] == IN_DIRECTORY)
            .map(|e| e[3])
    }

    fn pixel_is_point(&self) -> bool {
        self.key(RASTER_TYPE) == Some(PIXEL_IS_POINT)
    }

    /// The CRS's EPSG code, where the keys name one (32767 is
    /// "user-defined").
    pub fn epsg(&self) -> Option<u16> {
        self.key(PROJECTED_TYPE)
            .or_else(|| self.key(GEOGRAPHIC_TYPE))
            .filter(|&c| c != 32767 && c != 0)
    }

    /// Checks what a file or a pack header could get wrong: a directory
    /// whose key count or parameter references do not fit it, scales that
    /// are not finite and positive, a position or no-data value that is
    /// not finite (a NaN no-data is kept as absent: NaN is then no-data).
    pub fn check(&self) -> Result<(), String> {
        let [version, _, _, count] = match self.geokeys.get(..4) {
            Some(&[a, b, c, d]) => [a, b, c, d],
            _ => return Err("GeoKey directory has no 4-number header".into()),
        };
        if version != 1 {
            return Err(format!("GeoKey directory version {version}, expected 1"));
        }
        let want = 4 + 4 * count as usize;
        if self.geokeys.len() != want {
            return Err(format!(
                "GeoKey directory announces {count} keys ({want} numbers) but holds {}",
                self.geokeys.len()
            ));
        }
        for [id, location, n, offset] in self.entries() {
            let (n, offset) = (n as usize, offset as usize);
            let room = match location {
                IN_DIRECTORY => continue,
                DOUBLES => self.geo_doubles.len(),
                // A count may include the NUL that ends the tag's text,
                // which the reader strips.
                ASCII => self.geo_ascii.len() + 1,
                other => return Err(format!("GeoKey {id} points into tag {other}")),
            };
            if offset + n > room {
                return Err(format!(
                    "GeoKey {id} reads {n} values at {offset} of tag {location}, which holds {room}"
                ));
            }
        }
        if !self.pixel_scale.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(format!(
                "pixel scale {:?} is not finite and positive",
                self.pixel_scale
            ));
        }
        if !self.origin.iter().all(|c| c.is_finite()) {
            return Err(format!("origin {:?} is not finite", self.origin));
        }
        if self.geo_doubles.iter().any(|d| !d.is_finite()) {
            return Err("GeoDoubleParams holds a value that is not finite".into());
        }
        if self.nodata.is_some_and(|v| !v.is_finite()) {
            return Err("the no-data value is not finite".into());
        }
        Ok(())
    }

    /// The place of level `level`'s samples from `(x, y)` on: cells 2^level
    /// times level 0's, centred on level 0's samples `(x·2^level,
    /// y·2^level)` and on; the corner is then half a coarse cell up and
    /// left of that centre. Level 0 keeps its origin exactly.
    pub fn of_window(&self, level: usize, x: usize, y: usize) -> Place {
        let k = (1u64 << level.min(62)) as f64;
        let [sx, sy] = self.pixel_scale;
        // In level-0 cells from the origin: centre (x·k + ½), corner k/2 back.
        let cells = |i: usize| i as f64 * k + 0.5 - k / 2.0;
        Place {
            pixel_scale: [sx * k, sy * k],
            origin: [
                self.origin[0] + cells(x) * sx,
                self.origin[1] - cells(y) * sy,
            ],
            ..self.clone()
        }
    }

    /// ModelTiepoint for this place: raster (0, 0) at the first sample's
    /// corner, or its centre where pixels are points.
    pub fn tiepoint(&self) -> [f64; 6] {
        let half = if self.pixel_is_point() { 0.5 } else { 0.0 };
        let [sx, sy] = self.pixel_scale;
        [
            0.0,
            0.0,
            0.0,
            self.origin[0] + half * sx,
            self.origin[1] - half * sy,
            0.0,
        ]
    }

    /// GDAL's geotransform: origin x, pixel width, 0, origin y, 0, −pixel
    /// height.
    pub fn geotransform(&self) -> [f64; 6] {
        let [sx, sy] = self.pixel_scale;
        [self.origin[0], sx, 0.0, self.origin[1], 0.0, -sy]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn utm() -> Place {
        Place::from_epsg(32614, false, [30.0, 30.0], [500_000.0, 4_000_000.0], None)
    }

    /// An area tie point is the first sample's corner, a point tie point
    /// its centre; both give the same geotransform GDAL computes (GDAL
    /// moves a point-raster's origin half a cell up and left).
    #[test]
    fn tie_points_of_areas_and_points_place_the_same_centre() {
        let area = Place::from_geotiff(
            Some(utm().geokeys),
            vec![],
            String::new(),
            Some([30.0, 30.0]),
            Some(&[0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0]),
            None,
        )
        .unwrap()
        .unwrap();
        assert_eq!(area.origin, [500_000.0, 4_000_000.0]);
        assert_eq!(
            area.tiepoint(),
            [0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0]
        );
        let mut keys = utm().geokeys;
        keys[11] = PIXEL_IS_POINT;
        // Tie point at raster (2, 1): the centre of that sample.
        let point = Place::from_geotiff(
            Some(keys),
            vec![],
            String::new(),
            Some([30.0, 30.0]),
            Some(&[2.0, 1.0, 0.0, 500_075.0, 3_999_955.0, 0.0]),
            None,
        )
        .unwrap()
        .unwrap();
        assert_eq!(point.origin, [500_000.0, 4_000_000.0]);
        assert_eq!(
            point.tiepoint(),
            [0.0, 0.0, 0.0, 500_015.0, 3_999_985.0, 0.0]
        );
        assert_eq!(point.geotransform(), area.geotransform());
        assert_eq!(
            area.geotransform(),
            [500_000.0, 30.0, 0.0, 4_000_000.0, 0.0, -30.0]
        );
        assert_eq!(area.epsg(), Some(32614));
    }

    /// Level 2's sample (3, 5) is level 0's (12, 20), in cells 4 times as
    /// large.
    #[test]
    fn a_window_of_a_coarser_level_is_placed_from_level_0() {
        let w = utm().of_window(2, 3, 5);
        assert_eq!(w.pixel_scale, [120.0, 120.0]);
        // Centre of level 0's (12, 20), less half of a 120 m cell.
        let centre = [500_000.0 + 12.5 * 30.0, 4_000_000.0 - 20.5 * 30.0];
        assert_eq!(w.origin, [centre[0] - 60.0, centre[1] + 60.0]);
        assert_eq!(
            w.geotransform(),
            [500_315.0, 120.0, 0.0, 3_999_445.0, 0.0, -120.0]
        );
        assert_eq!(utm().of_window(0, 0, 0), utm());
    }

    #[test]
    fn directories_and_numbers_that_do_not_fit_are_refused() {
        let bad = |f: &dyn Fn(&mut Place), want: &str| {
            let mut p = utm();
            f(&mut p);
            let e = p.check().unwrap_err();
            assert!(e.contains(want), "{e}");
        };
        bad(&|p| p.geokeys.truncate(3), "no 4-number header");
        bad(&|p| p.geokeys[0] = 2, "version 2");
        bad(&|p| p.geokeys[3] = 4, "announces 4 keys");
        bad(
            &|p| p.geokeys[13] = DOUBLES,
            "reads 1 values at 32614 of tag 34736",
        );
        bad(&|p| p.geokeys[13] = 99, "points into tag 99");
        bad(&|p| p.pixel_scale[1] = 0.0, "pixel scale");
        bad(&|p| p.origin[0] = f64::NAN, "origin");
        bad(&|p| p.nodata = Some(f64::INFINITY), "no-data");
        bad(&|p| p.geo_doubles = vec![f64::NAN], "GeoDoubleParams");
        assert!(utm().check().is_ok());
        let mut p = utm();
        p.geokeys[13] = ASCII;
        p.geokeys[15] = 2;
        p.geokeys[14] = 6;
        p.geo_ascii = "WGS 84|".into();
        assert!(p.check().is_ok(), "{:?}", p.check());
        p.geokeys[14] = 7;
        assert!(p
            .check()
            .unwrap_err()
            .contains("reads 7 values at 2 of tag 34737, which holds 8"));
    }
}
