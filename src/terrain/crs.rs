//! A CRS declared for a map whose file names none (`terrain.crs`,
//! `--crs`). A GeoTIFF without a GeoKey directory still has its pixel scale
//! and tie point; `gdal_translate` from a netCDF grid writes such files,
//! with cells in degrees that would otherwise read as metres (0.004 "m"
//! cells, and a map a few metres wide). Where the numbers look like
//! degrees, the commands that read the map warn; a declared geographic CRS
//! converts them as a geographic GeoTIFF's are converted.

use super::tiff_file::metres_per_degree;

/// The geographic CRSs (latitude and longitude in degrees) a declaration
/// may name. Their ellipsoids differ from WGS 84's by less than 1e-5 in
/// the metres per degree, which the conversion on WGS 84 leaves.
pub const GEOGRAPHIC: [u16; 5] = [4326, 4269, 4258, 4283, 4617];

/// The placement of a grid whose file names no CRS, in its own units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Undeclared {
    /// Pixel scale across and down.
    pub scale: [f64; 2],
    /// The grid's north-west corner (x, y): longitude and latitude if the
    /// units are degrees.
    pub corner: [f64; 2],
    /// Rows, down.
    pub rows: usize,
}

impl Undeclared {
    /// The latitude of the middle row, if the units are degrees.
    fn centre_lat(&self) -> f64 {
        self.corner[1] - self.rows as f64 / 2.0 * self.scale[1]
    }

    /// Whether the numbers are almost surely degrees: the corner within
    /// ±180 / ±90 and cells under 0.1 (no projected grid has 10 cm cells
    /// at a corner that close to its false origin).
    pub fn looks_like_degrees(&self) -> bool {
        let [x, y] = self.corner;
        x.abs() <= 180.0
            && y.abs() <= 90.0
            && self.centre_lat().abs() <= 90.0
            && self.scale[0] < 0.1
            && self.scale[1] < 0.1
    }

    /// The warning for a file at `path` whose numbers look like degrees.
    pub fn warning(&self, path: &std::path::Path) -> String {
        format!(
            "{}: the file names no CRS, and its corner ({}, {}) and cells of {} × {} look like \
             degrees, read as metres; declare the CRS with --crs EPSG:4326 or \
             `crs = \"EPSG:4326\"` in the scene's [terrain]",
            path.display(),
            self.corner[0],
            self.corner[1],
            self.scale[0],
            self.scale[1]
        )
    }
}

/// The EPSG code of a declaration `EPSG:n`.
pub fn parse(crs: &str) -> Result<u16, String> {
    crs.trim()
        .strip_prefix("EPSG:")
        .and_then(|c| c.parse::<u16>().ok())
        .filter(|&c| c > 0)
        .ok_or_else(|| format!("'{crs}': give the CRS as EPSG:<code>, such as EPSG:4326"))
}

/// The place of a map whose file names no CRS, once `declared` names it:
/// its pixel scale and corner in the declared CRS's units. The no-data
/// value is not known here; unpacked, no-data is NaN.
pub fn declared_place(
    declared: &str,
    undeclared: Option<&Undeclared>,
) -> Option<super::place::Place> {
    let code = parse(declared).ok()?;
    let u = undeclared?;
    Some(super::place::Place::from_epsg(
        code,
        GEOGRAPHIC.contains(&code),
        u.scale,
        u.corner,
        None,
    ))
}

/// The cell size in metres and the CRS's name when `declared` is the CRS
/// of a map whose file names `file_crs` (or none, placed by `undeclared`),
/// with cells of `cell` as read. A geographic CRS converts the degrees
/// at the middle row's latitude; any other EPSG code is taken as a
/// projected CRS in metres, the cells kept. A file that names another
/// CRS is not overruled.
pub fn declare(
    declared: &str,
    file_crs: Option<&str>,
    undeclared: Option<&Undeclared>,
    cell: [f64; 2],
) -> Result<([f64; 2], String), String> {
    let code = parse(declared)?;
    let name = format!("EPSG:{code}");
    if let Some(f) = file_crs {
        return if f == name {
            Ok((cell, name))
        } else {
            Err(format!(
                "the file names its CRS, {f}; the declared {name} differs"
            ))
        };
    }
    if !GEOGRAPHIC.contains(&code) {
        return Ok((cell, name));
    }
    let u = undeclared.ok_or_else(|| {
        format!(
            "{name} is geographic, but the file has no pixel scale and tie point to place \
             its degrees"
        )
    })?;
    let lat = u.centre_lat();
    if !(lat.is_finite() && lat.abs() <= 90.0) {
        return Err(format!("centre latitude {lat}° is not on the globe"));
    }
    let [mx, my] = metres_per_degree(lat);
    Ok(([u.scale[0] * mx, u.scale[1] * my], name))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(corner: [f64; 2], scale: f64) -> Undeclared {
        Undeclared {
            scale: [scale, scale],
            corner,
            rows: 100,
        }
    }

    /// 15″ cells at 46° N look like degrees; 30 m cells, or a corner past
    /// ±180 / ±90, do not; cells of exactly 0.1 do not.
    #[test]
    fn degrees_are_recognised_by_corner_and_cell() {
        assert!(grid([10.0, 46.0], 1.0 / 240.0).looks_like_degrees());
        assert!(grid([-180.0, -89.0], 0.01).looks_like_degrees());
        assert!(!grid([10.0, 46.0], 30.0).looks_like_degrees());
        assert!(!grid([10.0, 46.0], 0.1).looks_like_degrees());
        assert!(!grid([500_000.0, 46.0], 0.01).looks_like_degrees());
        assert!(!grid([10.0, 91.0], 0.01).looks_like_degrees());
        assert!(!grid([180.5, 46.0], 0.01).looks_like_degrees());
    }

    /// A geographic declaration converts at the middle row's latitude; a
    /// projected one keeps the cells; a file's own CRS must agree.
    #[test]
    fn a_declared_crs_converts_degrees_and_respects_the_file() {
        let u = grid([10.0, 46.0], 0.01);
        let (cell, name) = declare("EPSG:4326", None, Some(&u), [0.01, 0.01]).unwrap();
        let [mx, my] = metres_per_degree(45.5);
        assert_eq!((cell, name.as_str()), ([0.01 * mx, 0.01 * my], "EPSG:4326"));
        assert!(
            (cell[0] - 781.6).abs() < 0.1 && (cell[1] - 1111.4).abs() < 0.1,
            "{cell:?}"
        );
        assert_eq!(
            declare("EPSG:32633", None, Some(&u), [0.01, 0.01]).unwrap(),
            ([0.01, 0.01], "EPSG:32633".to_string())
        );
        assert_eq!(
            declare("EPSG:4326", Some("EPSG:4326"), None, [5.0, 5.0]).unwrap(),
            ([5.0, 5.0], "EPSG:4326".to_string())
        );
        let e = declare("EPSG:4326", Some("EPSG:32633"), None, [5.0, 5.0]).unwrap_err();
        assert!(e.contains("EPSG:32633") && e.contains("differs"), "{e}");
        let e = declare("EPSG:4326", None, None, [5.0, 5.0]).unwrap_err();
        assert!(e.contains("no pixel scale and tie point"), "{e}");
        for bad in ["4326", "EPSG:", "EPSG:x", "EPSG:0", "WGS84"] {
            assert!(parse(bad).unwrap_err().contains("EPSG:<code>"), "{bad}");
        }
    }
}
