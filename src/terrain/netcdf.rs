//! netCDF grids with CF conventions (GEBCO, ETOPO 2022 and many national
//! and ocean grids ship this way): the classic format in its three
//! versions, CDF-1, CDF-2 (64-bit offsets) and CDF-5 (64-bit data), per
//! Unidata's "NetCDF Classic Format Specification".
//!
//! Read here rather than through the `netcdf3` crate (0.6.1): that crate
//! sizes its lists from the header's counts before it has read the bytes
//! that would hold them (`Vec::with_capacity(num_of_dims)`), so a forged
//! count aborts the process, and it reads a variable only whole, where a
//! pack of a map larger than memory reads a band of rows at a time. The
//! classic format is a short, fixed layout (big-endian counts, names,
//! attributes and variable offsets, then the data row-major), so every
//! count is checked against the bytes left in the file before anything is
//! allocated from it. netCDF-4 files are HDF5 and get an error that says
//! how to rewrite them in the classic format.
//!
//! Which variable, its axes and its values follow the CF conventions
//! (1.10): a height or depth `standard_name`, else the only grid; the
//! last two dimensions are the grid's, `lat`/`lon` in either order and
//! either direction (a south-to-north grid is flipped to north first);
//! degrees become metres at the centre latitude on WGS 84, as for
//! geographic GeoTIFFs; `scale_factor` and `add_offset` apply, and
//! `_FillValue` (or the type's default fill), `missing_value` and
//! `valid_min`/`valid_max`/`valid_range` become no-data.

use super::tiff_file::metres_per_degree;
use crate::error::{Error, Result};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// `standard_name`s read as heights, and the one read as a depth (negated).
const HEIGHT_NAMES: [&str; 5] = [
    "height_above_mean_sea_level",
    "altitude",
    "height",
    "surface_altitude",
    "height_above_reference_ellipsoid",
];
const DEPTH_NAME: &str = "sea_floor_depth_below_geoid";

/// Attribute payloads longer than this are skipped, not held: no CF
/// attribute this reader uses comes near it.
const MAX_ATTR_BYTES: u64 = 1 << 20;

/// A netCDF external type (the classic format's `nc_type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum NcType {
    Byte,
    Char,
    Short,
    Int,
    Float,
    Double,
    UByte,
    UShort,
    UInt,
    Int64,
    UInt64,
}

impl NcType {
    fn of(code: u64, version: u8) -> std::result::Result<Self, String> {
        use NcType::*;
        let t = match code {
            1 => Byte,
            2 => Char,
            3 => Short,
            4 => Int,
            5 => Float,
            6 => Double,
            7 => UByte,
            8 => UShort,
            9 => UInt,
            10 => Int64,
            11 => UInt64,
            _ => return Err(format!("type code {code} is not a netCDF type")),
        };
        if code > 6 && version != 5 {
            return Err(format!("type {t:?} exists only in CDF-5 files"));
        }
        Ok(t)
    }

    fn size(self) -> u64 {
        use NcType::*;
        match self {
            Byte | Char | UByte => 1,
            Short | UShort => 2,
            Int | UInt | Float => 4,
            Double | Int64 | UInt64 => 8,
        }
    }

    /// The value of big-endian bytes `b` (exactly `size()` of them).
    fn value(self, b: &[u8]) -> f64 {
        use NcType::*;
        let a = |n: usize| -> [u8; 8] {
            let mut x = [0u8; 8];
            x[..n].copy_from_slice(&b[..n]);
            x
        };
        match self {
            Byte => b[0] as i8 as f64,
            Char | UByte => b[0] as f64,
            Short => i16::from_be_bytes([b[0], b[1]]) as f64,
            UShort => u16::from_be_bytes([b[0], b[1]]) as f64,
            Int => i32::from_be_bytes([b[0], b[1], b[2], b[3]]) as f64,
            UInt => u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Float => f32::from_be_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Double => f64::from_be_bytes(a(8)),
            Int64 => i64::from_be_bytes(a(8)) as f64,
            UInt64 => u64::from_be_bytes(a(8)) as f64,
        }
    }

    /// The netCDF library's default fill value, which reads as no-data
    /// where a variable declares no `_FillValue`. Bytes have none: the
    /// library does not check them (NetCDF Users Guide, "Fill Values").
    fn default_fill(self) -> Option<f64> {
        use NcType::*;
        match self {
            Byte | Char => None,
            Short => Some(-32767.0),
            Int => Some(-2147483647.0),
            Float => Some(f32::from_bits(0x7cf0_0000) as f64),
            Double => Some(9.969_209_968_386_869e36),
            UByte => Some(255.0),
            UShort => Some(65535.0),
            UInt => Some(4294967295.0),
            Int64 => Some(-9223372036854775806.0),
            UInt64 => Some(18446744073709551614.0),
        }
    }

    fn short_name(self) -> &'static str {
        use NcType::*;
        match self {
            Byte => "i8",
            Char => "char",
            Short => "i16",
            Int => "i32",
            Float => "f32",
            Double => "f64",
            UByte => "u8",
            UShort => "u16",
            UInt => "u32",
            Int64 => "i64",
            UInt64 => "u64",
        }
    }
}

#[derive(Clone, Debug)]
enum Value {
    Text(String),
    Numbers(Vec<f64>),
    /// Longer than [`MAX_ATTR_BYTES`]: skipped.
    Skipped,
}

#[derive(Clone, Debug)]
struct Dim {
    name: String,
    /// 0 for the record (unlimited) dimension.
    len: u64,
}

#[derive(Clone, Debug)]
struct Var {
    name: String,
    dims: Vec<usize>,
    attrs: Vec<(String, Value)>,
    ty: NcType,
    begin: u64,
}

impl Var {
    fn attr(&self, name: &str) -> Option<&Value> {
        self.attrs.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }
    fn text(&self, name: &str) -> Option<&str> {
        match self.attr(name) {
            Some(Value::Text(s)) => Some(s.trim_end_matches('\0').trim()),
            _ => None,
        }
    }
    fn numbers(&self, name: &str) -> Option<&[f64]> {
        match self.attr(name) {
            Some(Value::Numbers(v)) => Some(v),
            _ => None,
        }
    }
}

/// The header: dimensions, variables and the record count.
struct Header {
    /// Read through libnetcdf (netCDF-4): there are no offsets.
    library: bool,
    version: u8,
    numrecs: u64,
    dims: Vec<Dim>,
    vars: Vec<Var>,
}

/// A big-endian reader over the file that knows how many bytes are left,
/// so no count read from the file sizes an allocation the file could not
/// fill.
struct Cursor<'a> {
    r: std::io::BufReader<&'a std::fs::File>,
    pos: u64,
    len: u64,
}

impl Cursor<'_> {
    fn bytes(&mut self, n: u64, what: &str) -> std::result::Result<Vec<u8>, String> {
        if n > self.len - self.pos {
            return Err(format!(
                "{what}: {n} bytes at offset {} run past the file's {} bytes",
                self.pos, self.len
            ));
        }
        let mut b = vec![0u8; n as usize];
        self.r
            .read_exact(&mut b)
            .map_err(|e| format!("{what}: {e}"))?;
        self.pos += n;
        Ok(b)
    }
    fn skip(&mut self, n: u64, what: &str) -> std::result::Result<(), String> {
        if n > self.len - self.pos {
            return Err(format!(
                "{what}: {n} bytes at offset {} run past the file's {} bytes",
                self.pos, self.len
            ));
        }
        self.r
            .seek_relative(n as i64)
            .map_err(|e| format!("{what}: {e}"))?;
        self.pos += n;
        Ok(())
    }
    fn u32(&mut self, what: &str) -> std::result::Result<u64, String> {
        let b = self.bytes(4, what)?;
        Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as u64)
    }
    fn u64(&mut self, what: &str) -> std::result::Result<u64, String> {
        let b = self.bytes(8, what)?;
        Ok(u64::from_be_bytes(b.try_into().expect("8 bytes")))
    }
    /// A count or size: 32 bits in CDF-1 and CDF-2, 64 in CDF-5.
    fn count(&mut self, version: u8, what: &str) -> std::result::Result<u64, String> {
        if version == 5 {
            self.u64(what)
        } else {
            self.u32(what)
        }
    }
    /// A name, padded to 4 bytes.
    fn name(&mut self, version: u8, what: &str) -> std::result::Result<String, String> {
        let n = self.count(version, what)?;
        let b = self.bytes(n, what)?;
        self.skip(n.next_multiple_of(4) - n, what)?;
        String::from_utf8(b).map_err(|_| format!("{what}: not UTF-8"))
    }
    /// A list's tag and element count; `ABSENT` is two zeros.
    fn list(&mut self, version: u8, tag: u64, what: &str) -> std::result::Result<u64, String> {
        let t = self.u32(what)?;
        let n = self.count(version, what)?;
        match t {
            0 if n == 0 => Ok(0),
            0 => Err(format!("{what}: an absent list with {n} elements")),
            t if t == tag => Ok(n),
            t => Err(format!("{what}: tag {t:#x}, expected {tag:#x}")),
        }
    }
    fn attrs(
        &mut self,
        version: u8,
        what: &str,
    ) -> std::result::Result<Vec<(String, Value)>, String> {
        let n = self.list(version, 0x0C, what)?;
        let mut out = Vec::new();
        for i in 0..n {
            let name = self.name(version, &format!("{what} {i}'s name"))?;
            let field = format!("{what} '{name}'");
            let ty = NcType::of(self.u32(&field)?, version).map_err(|r| format!("{field}: {r}"))?;
            let count = self.count(version, &field)?;
            let bytes = count
                .checked_mul(ty.size())
                .ok_or_else(|| format!("{field}: {count} values overflow"))?;
            let padded = bytes.next_multiple_of(4);
            let value = if bytes > MAX_ATTR_BYTES {
                self.skip(padded, &field)?;
                Value::Skipped
            } else {
                let b = self.bytes(bytes, &field)?;
                self.skip(padded - bytes, &field)?;
                if ty == NcType::Char {
                    Value::Text(String::from_utf8_lossy(&b).into_owned())
                } else {
                    Value::Numbers(
                        b.chunks_exact(ty.size() as usize)
                            .map(|c| ty.value(c))
                            .collect(),
                    )
                }
            };
            out.push((name, value));
        }
        Ok(out)
    }
}

fn header(file: &std::fs::File, len: u64, path: &Path) -> std::result::Result<Header, String> {
    let mut c = Cursor {
        r: std::io::BufReader::new(file),
        pos: 0,
        len,
    };
    let magic = c.bytes(4.min(len), "magic")?;
    let version = match magic.as_slice() {
        [b'C', b'D', b'F', v @ (1 | 2 | 5)] => *v,
        [b'C', b'D', b'F', v] => {
            return Err(format!(
                "magic: netCDF classic version {v} is not 1, 2 or 5"
            ))
        }
        [0x89, b'H', b'D', b'F'] => {
            #[cfg(feature = "netcdf4")]
            return hdf::header(path);
            #[cfg(not(feature = "netcdf4"))]
            return Err(format!(
                "magic: a netCDF-4 (HDF5) file, which this build does not read (one with \
                 `--features netcdf4` does, given libnetcdf-dev); rewrite it in the classic \
                 format with `nccopy -k classic {} out.nc` (`-k cdf5` past 4 GiB a variable)",
                path.display()
            ));
        }
        _ => return Err("magic: not a netCDF file (no 'CDF' signature)".into()),
    };
    let numrecs = c.count(version, "numrecs")?;
    let ndims = c.list(version, 0x0A, "dimension list")?;
    let mut dims = Vec::new();
    for i in 0..ndims {
        let name = c.name(version, &format!("dimension {i}'s name"))?;
        let len = c.count(version, &format!("dimension '{name}'"))?;
        dims.push(Dim { name, len });
    }
    c.attrs(version, "global attribute")?;
    let nvars = c.list(version, 0x0B, "variable list")?;
    let mut vars = Vec::new();
    for i in 0..nvars {
        let name = c.name(version, &format!("variable {i}'s name"))?;
        let field = format!("variable '{name}'");
        let rank = c.count(version, &field)?;
        let mut ids = Vec::new();
        for _ in 0..rank {
            let id = c.count(version, &field)?;
            if id >= dims.len() as u64 {
                return Err(format!(
                    "{field}: dimension id {id}, but the file has {} dimensions",
                    dims.len()
                ));
            }
            ids.push(id as usize);
        }
        let attrs = c.attrs(version, &format!("{field}'s attribute"))?;
        let ty = NcType::of(c.u32(&field)?, version).map_err(|r| format!("{field}: {r}"))?;
        let _vsize = c.count(version, &field)?;
        let begin = if version == 1 {
            c.u32(&field)?
        } else {
            c.u64(&field)?
        };
        vars.push(Var {
            name,
            dims: ids,
            attrs,
            ty,
            begin,
        });
    }
    Ok(Header {
        library: false,
        version,
        numrecs,
        dims,
        vars,
    })
}

/// An axis of the grid: its coordinate values' first value and step.
#[derive(Clone, Copy, Debug)]
struct Axis {
    first: f64,
    step: f64,
}

/// What the header says about the grid variable chosen: where its samples
/// are and how to turn them into heights.
#[derive(Clone, Debug)]
pub(super) struct Grid {
    path: PathBuf,
    /// The variable's name.
    pub variable: String,
    pub width: usize,
    pub height: usize,
    pub cell_size: [f64; 2],
    pub crs: Option<String>,
    pub undeclared: Option<super::crs::Undeclared>,
    /// Where the grid lies, where its axes and grid mapping say.
    pub place: Option<super::place::Place>,
    pub format: String,
    ty: NcType,
    begin: u64,
    /// Read through libnetcdf (a netCDF-4 file), not from `begin`.
    library: bool,
    /// The variable's leading dimensions (each of length 1).
    #[cfg_attr(not(feature = "netcdf4"), allow(dead_code))]
    leading: usize,
    /// The file's samples are (x, y), not (y, x): the first grid dimension
    /// is longitude.
    transposed: bool,
    flip_y: bool,
    flip_x: bool,
    scale: f64,
    offset: f64,
    negate: bool,
    fills: Vec<f64>,
    valid: [f64; 2],
}

/// The CF ways an axis says it is latitude or longitude.
struct AxisWords {
    units: [&'static str; 6],
    standard_name: &'static str,
    names: &'static [&'static str],
}

const LATITUDE: AxisWords = AxisWords {
    units: [
        "degrees_north",
        "degree_north",
        "degrees_N",
        "degree_N",
        "degreesN",
        "degreeN",
    ],
    standard_name: "latitude",
    names: &["lat", "latitude"],
};

const LONGITUDE: AxisWords = AxisWords {
    units: [
        "degrees_east",
        "degree_east",
        "degrees_E",
        "degree_E",
        "degreesE",
        "degreeE",
    ],
    standard_name: "longitude",
    names: &["lon", "long", "longitude"],
};

/// Whether the dimension `name`, with coordinate variable `v`, is the
/// axis `words` describes: by its units, its standard_name or its name.
fn is_axis(words: &AxisWords, name: &str, v: Option<&Var>) -> bool {
    let text = |a: &str| v.and_then(|v| v.text(a)).unwrap_or("");
    words.units.contains(&text("units"))
        || text("standard_name") == words.standard_name
        || words.names.contains(&name.to_ascii_lowercase().as_str())
}

/// Whether `v` can be a map: numeric, with two dimensions of at least 2
/// samples after any leading ones of length 1.
fn is_grid(h: &Header, v: &Var) -> bool {
    let len = |d: usize| match h.dims[d].len {
        0 => h.numrecs,
        n => n,
    };
    v.ty != NcType::Char
        && v.dims.len() >= 2
        && v.dims[..v.dims.len() - 2].iter().all(|&d| len(d) == 1)
        && v.dims[v.dims.len() - 2..].iter().all(|&d| len(d) >= 2)
}

/// Opens `path`'s header and picks the grid: `variable` if given, else
/// by CF `standard_name`, else the only grid. `check` is the size limit
/// (whole map or by rows).
pub(super) fn open(
    path: &Path,
    variable: Option<&str>,
    check: fn(u64, u64) -> std::result::Result<(), String>,
) -> Result<(Grid, std::fs::File)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let h = header(&file, len, path).map_err(|r| Error::file(path, r))?;
    let grid = choose(path, &h, variable, len, &file, check).map_err(|r| Error::file(path, r))?;
    Ok((grid, file))
}

fn choose(
    path: &Path,
    h: &Header,
    variable: Option<&str>,
    file_len: u64,
    file: &std::fs::File,
    check: fn(u64, u64) -> std::result::Result<(), String>,
) -> std::result::Result<Grid, String> {
    let grids: Vec<&Var> = h.vars.iter().filter(|v| is_grid(h, v)).collect();
    let names = |vs: &[&Var]| {
        vs.iter()
            .map(|v| format!("'{}'", v.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let v = match variable {
        Some(want) => {
            let v = h.vars.iter().find(|v| v.name == want).ok_or_else(|| {
                format!(
                    "variable '{want}' is not in the file; its grids are {}",
                    if grids.is_empty() {
                        "none".into()
                    } else {
                        names(&grids)
                    }
                )
            })?;
            if !is_grid(h, v) {
                return Err(format!(
                    "variable '{want}': a {}-dimensional {:?} variable is not a map (two \
                     dimensions of at least 2 samples each, after any of length 1)",
                    v.dims.len(),
                    v.ty
                ));
            }
            v
        }
        None => {
            let named: Vec<&Var> = grids
                .iter()
                .copied()
                .filter(|v| {
                    v.text("standard_name")
                        .is_some_and(|s| HEIGHT_NAMES.contains(&s) || s == DEPTH_NAME)
                })
                .collect();
            match (named.as_slice(), grids.as_slice()) {
                ([one], _) => *one,
                ([], [one]) => *one,
                ([], []) => {
                    return Err(format!(
                        "no variable is a map (numeric, two dimensions); the variables are {}",
                        names(&h.vars.iter().collect::<Vec<_>>())
                    ))
                }
                ([], many) => {
                    return Err(format!(
                        "several variables could be the map ({}) and none has a height or \
                         depth standard_name; choose one with `variable = \"NAME\"` in the \
                         scene's [terrain] or --variable NAME",
                        names(many)
                    ))
                }
                (many, _) => {
                    return Err(format!(
                        "several variables name a height or depth ({}); choose one with \
                         `variable = \"NAME\"` in the scene's [terrain] or --variable NAME",
                        names(many)
                    ))
                }
            }
        }
    };
    let field = format!("variable '{}'", v.name);
    let r = v.dims.len();
    let (da, db) = (v.dims[r - 2], v.dims[r - 1]);
    if h.dims[da].len == 0 || h.dims[db].len == 0 {
        return Err(format!(
            "{field}: the record (unlimited) dimension is one of the map's axes, which \
             interleaves it with other variables; rewrite the file with fixed dimensions: \
             `nccopy -u {} out.nc`",
            path.display()
        ));
    }
    let coord = |d: usize| {
        h.vars
            .iter()
            .find(|c| c.name == h.dims[d].name && c.dims == [d] && c.ty != NcType::Char)
    };
    let (ca, cb) = (coord(da), coord(db));
    let transposed =
        is_axis(&LONGITUDE, &h.dims[da].name, ca) && is_axis(&LATITUDE, &h.dims[db].name, cb);
    let (dy, dx) = if transposed { (db, da) } else { (da, db) };
    let (cy, cx) = if transposed { (cb, ca) } else { (ca, cb) };
    let (height, width) = (h.dims[dy].len, h.dims[dx].len);
    check(width, height).map_err(|r| format!("{field}: {r}"))?;
    // The samples, row-major after the leading dimensions of length 1.
    let bytes = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(v.ty.size()))
        .ok_or_else(|| format!("{field}: {width}×{height} samples overflow"))?;
    if !h.library && (v.begin > file_len || bytes > file_len - v.begin) {
        return Err(format!(
            "{field}: its {bytes} bytes of data at offset {} (its 'begin') run past the \
             file's {file_len} bytes",
            v.begin
        ));
    }
    let axis = |c: Option<&Var>, n: u64| -> std::result::Result<Option<Axis>, String> {
        let Some(c) = c else { return Ok(None) };
        let what = format!("coordinate variable '{}'", c.name);
        let vals = if h.library {
            #[cfg(feature = "netcdf4")]
            {
                hdf::coordinates(path, &c.name, n)
            }
            #[cfg(not(feature = "netcdf4"))]
            unreachable!("a library header needs the feature netcdf4")
        } else {
            read_values(file, file_len, c, n)
        }
        .map_err(|r| format!("{what}: {r}"))?;
        if vals.len() as u64 != n || n < 2 {
            return Err(format!(
                "{what}: {} values for a dimension of {n}",
                vals.len()
            ));
        }
        let step = (vals[vals.len() - 1] - vals[0]) / (vals.len() - 1) as f64;
        if !(step.is_finite() && step != 0.0) {
            return Err(format!("{what}: its first and last values give no spacing"));
        }
        // A grid's coordinates are evenly spaced; stored as f32 they are
        // rounded to half a unit in the last place of their magnitude
        // (7.6e-6 at 180 degrees), which moves a step by up to 0.4 % of a
        // 15" cell. 1 % admits that and refuses a grid that is not regular.
        for (i, p) in vals.windows(2).enumerate() {
            if ((p[1] - p[0]) - step).abs() > 0.01 * step.abs() {
                return Err(format!(
                    "{what}: not evenly spaced (step {} at index {i}, {} on average)",
                    p[1] - p[0],
                    step
                ));
            }
        }
        Ok(Some(Axis {
            first: vals[0],
            step,
        }))
    };
    let ay = axis(cy, height)?;
    let ax = axis(cx, width)?;
    let geographic = is_axis(&LATITUDE, &h.dims[dy].name, cy) && cy.is_some();
    let flip_y = ay.is_some_and(|a| a.step > 0.0);
    let flip_x = ax.is_some_and(|a| a.step < 0.0);
    let step = |a: Option<Axis>| a.map_or(1.0, |a| a.step.abs());
    let cell = [step(ax), step(ay)];
    // The grid's north-west corner in its own units: the first cell's
    // centre less half a cell, whichever way the axes run.
    let corner = |x: Axis, y: Axis| {
        [
            x.first.min(x.first + x.step * (width - 1) as f64) - cell[0] / 2.0,
            y.first.max(y.first + y.step * (height - 1) as f64) + cell[1] / 2.0,
        ]
    };
    let (cell_size, crs, undeclared) = match (ax, ay) {
        (Some(x), Some(y)) if geographic => {
            let lat = y.first + y.step * (height - 1) as f64 / 2.0;
            if !(lat.is_finite() && lat.abs() <= 90.0) {
                return Err(format!(
                    "coordinate variable '{}': centre latitude {lat} is not on the globe",
                    h.dims[dy].name
                ));
            }
            let _ = x;
            let [mx, my] = metres_per_degree(lat);
            let name = epsg(h, v).unwrap_or_else(|| "geographic".into());
            ([cell[0] * mx, cell[1] * my], Some(name), None)
        }
        (Some(x), Some(y)) => {
            let unit = cy.and_then(|c| c.text("units")).unwrap_or("");
            let metres = match unit {
                "m" | "metre" | "metres" | "meter" | "meters" => Some(1.0),
                "km" | "kilometre" | "kilometres" | "kilometer" | "kilometers" => Some(1000.0),
                _ => None,
            };
            let mapped = v.text("grid_mapping").is_some();
            match metres {
                Some(u) => (
                    [cell[0] * u, cell[1] * u],
                    mapped.then(|| epsg(h, v).unwrap_or_else(|| "projected".into())),
                    None,
                ),
                None => {
                    // Units unnamed: placed in its own units, which may be
                    // degrees ([`super::crs`] warns).
                    (
                        cell,
                        None,
                        Some(super::crs::Undeclared {
                            scale: cell,
                            corner: corner(x, y),
                            rows: height as usize,
                        }),
                    )
                }
            }
        }
        _ => ([1.0, 1.0], None, None),
    };
    let num = |name: &str| v.numbers(name).and_then(|n| n.first().copied());
    let mut fills: Vec<f64> = match num("_FillValue") {
        Some(f) => vec![f],
        None => v.ty.default_fill().into_iter().collect(),
    };
    fills.extend(v.numbers("missing_value").unwrap_or(&[]));
    let valid = match v.numbers("valid_range") {
        Some([lo, hi, ..]) => [*lo, *hi],
        _ => [
            num("valid_min").unwrap_or(f64::NEG_INFINITY),
            num("valid_max").unwrap_or(f64::INFINITY),
        ],
    };
    let scale = num("scale_factor").unwrap_or(1.0);
    let offset = num("add_offset").unwrap_or(0.0);
    if !(scale.is_finite() && scale != 0.0 && offset.is_finite()) {
        return Err(format!(
            "{field}: scale_factor {scale} and add_offset {offset} are not finite and non-zero"
        ));
    }
    let negate = v.text("standard_name") == Some(DEPTH_NAME);
    // Where the grid lies, for a pack to give back: a lat/lon grid in its
    // grid mapping's EPSG CRS (WGS 84's 4326 where it names none), a
    // projected one only where its EPSG code is named. No-data is the
    // first fill value as a height.
    let place = match (ax, ay, crs.as_deref()) {
        (Some(x), Some(y), Some(name)) => name
            .strip_prefix("EPSG:")
            .and_then(|c| c.parse::<u16>().ok())
            .or(geographic.then_some(4326))
            .map(|code| {
                // Metres per coordinate unit of a projected grid (km axes).
                let unit = if geographic {
                    1.0
                } else {
                    cell_size[0] / cell[0]
                };
                let nodata = fills
                    .first()
                    .map(|f| (f * scale + offset) * if negate { -1.0 } else { 1.0 })
                    .filter(|h| h.is_finite() && h.abs() <= f32::MAX as f64);
                let [w, n] = corner(x, y);
                super::place::Place::from_epsg(
                    code,
                    geographic,
                    [cell[0] * unit, cell[1] * unit],
                    [w * unit, n * unit],
                    nodata,
                )
            }),
        _ => None,
    };
    Ok(Grid {
        path: path.to_path_buf(),
        variable: v.name.clone(),
        width: width as usize,
        height: height as usize,
        cell_size,
        crs,
        undeclared,
        format: format!("netcdf{}-{}", h.version, v.ty.short_name()),
        ty: v.ty,
        begin: v.begin,
        library: h.library,
        leading: v.dims.len() - 2,
        transposed,
        flip_y,
        flip_x,
        scale,
        offset,
        negate,
        fills,
        valid,
        place,
    })
}

/// The EPSG code of `v`'s grid mapping, where it names one: GDAL writes the
/// CRS as WKT (`crs_wkt`, `spatial_ref`) whose last `AUTHORITY` is the
/// CRS's own; some writers give `epsg_code = "EPSG:n"`.
fn epsg(h: &Header, v: &Var) -> Option<String> {
    let m = h
        .vars
        .iter()
        .find(|m| Some(m.name.as_str()) == v.text("grid_mapping"))?;
    if let Some(c) = m.text("epsg_code") {
        let n = c.trim_start_matches("EPSG:").trim();
        return n.parse::<u32>().ok().map(|n| format!("EPSG:{n}"));
    }
    let wkt = m.text("crs_wkt").or_else(|| m.text("spatial_ref"))?;
    let tail = wkt.trim_end().strip_suffix("]]")?;
    let at = tail.rfind("AUTHORITY[\"EPSG\",\"")?;
    let code = tail[at..].trim_start_matches("AUTHORITY[\"EPSG\",\"");
    code.trim_end_matches('"')
        .parse::<u32>()
        .ok()
        .map(|n| format!("EPSG:{n}"))
}

/// The `n` values of the one-dimensional variable `c`, as f64.
fn read_values(
    file: &std::fs::File,
    file_len: u64,
    c: &Var,
    n: u64,
) -> std::result::Result<Vec<f64>, String> {
    let bytes = n * c.ty.size();
    if c.begin > file_len || bytes > file_len - c.begin {
        return Err(format!(
            "its {bytes} bytes at offset {} (its 'begin') run past the file's {file_len} bytes",
            c.begin
        ));
    }
    let mut b = vec![0u8; bytes as usize];
    let mut f = file;
    f.seek(SeekFrom::Start(c.begin))
        .and_then(|_| f.read_exact(&mut b))
        .map_err(|e| e.to_string())?;
    Ok(b.chunks_exact(c.ty.size() as usize)
        .map(|x| c.ty.value(x))
        .collect())
}

impl Grid {
    /// A raw sample as a height, or NaN for no-data.
    fn height_of(&self, raw: f64) -> f32 {
        if self.fills.contains(&raw) || raw < self.valid[0] || raw > self.valid[1] || raw.is_nan() {
            return f32::NAN;
        }
        let v = raw * self.scale + self.offset;
        let v = (if self.negate { -v } else { v }) as f32;
        // A finite f64 past f32's range becomes an infinity here.
        if v.is_finite() {
            v
        } else {
            f32::NAN
        }
    }

    /// The raw values of file rows `[f0, f1)` of the grid (of every row
    /// and column, in file order, for a transposed grid), as f64.
    fn file_block(&self, file: &std::fs::File, f0: usize, f1: usize) -> Result<Vec<f64>> {
        let (w, h) = (self.width, self.height);
        let bad = |e: String| {
            Error::file(
                &self.path,
                format!("variable '{}': reading its data: {e}", self.variable),
            )
        };
        let (first, n) = if self.transposed {
            (0, w * h)
        } else {
            (f0 * w, (f1 - f0) * w)
        };
        if self.library {
            #[cfg(feature = "netcdf4")]
            return hdf::block(self, first, n).map_err(bad);
        }
        let size = self.ty.size() as usize;
        let mut b = vec![0u8; n * size];
        let mut f = file;
        f.seek(SeekFrom::Start(self.begin + (first * size) as u64))
            .and_then(|_| f.read_exact(&mut b))
            .map_err(|e| bad(e.to_string()))?;
        Ok(b.chunks_exact(size).map(|c| self.ty.value(c)).collect())
    }

    /// Heights of map rows `[y0, y1)` (north first, west first), NaN where
    /// there is no data. A transposed grid reads the whole variable.
    pub fn read_rows(&self, file: &std::fs::File, y0: usize, y1: usize) -> Result<Vec<f32>> {
        let (w, h) = (self.width, self.height);
        // The file rows holding map rows [y0, y1): contiguous either way.
        let (f0, f1) = match (self.transposed, self.flip_y) {
            (true, _) => (0, h),
            (false, true) => (h - y1, h - y0),
            (false, false) => (y0, y1),
        };
        let raw = self.file_block(file, f0, f1)?;
        let mut out = Vec::with_capacity((y1 - y0) * w);
        for y in y0..y1 {
            let fy = if self.flip_y { h - 1 - y } else { y } - f0;
            for x in 0..w {
                let fx = if self.flip_x { w - 1 - x } else { x };
                // File order (x, y) when transposed: map row y is the
                // file's column y.
                let i = if self.transposed {
                    fx * h + fy
                } else {
                    fy * w + fx
                };
                out.push(self.height_of(raw[i]));
            }
        }
        Ok(out)
    }
}

/// Reads the grid of a netCDF file whole.
pub(super) fn read(path: &Path, variable: Option<&str>) -> Result<super::Heightmap> {
    let (g, file) = open(path, variable, super::check_dimensions)?;
    let values = g.read_rows(&file, 0, g.height)?;
    let mut map = super::named(
        path,
        super::Heightmap::from_values(g.width, g.height, values, None, g.cell_size, &g.format),
    )?;
    map.crs = g.crs;
    map.undeclared = g.undeclared;
    map.place = g.place;
    Ok(map)
}

/// A netCDF grid read a band of rows at a time.
pub struct NetcdfRows {
    grid: Grid,
    file: std::sync::Mutex<std::fs::File>,
}

/// The source for `path`'s grid (`variable`, or chosen by CF
/// conventions): by rows, or whole for a transposed grid (longitude
/// first, rare), whose rows are scattered through the file.
pub fn rows(path: &Path, variable: Option<&str>) -> Result<Box<dyn super::rows::RowSource>> {
    let (grid, file) = open(path, variable, super::check_side)?;
    if grid.transposed {
        return Ok(Box::new(super::rows::MapRows(read(path, variable)?)));
    }
    Ok(Box::new(NetcdfRows {
        grid,
        file: std::sync::Mutex::new(file),
    }))
}

impl super::rows::RowSource for NetcdfRows {
    fn size(&self) -> [usize; 2] {
        [self.grid.width, self.grid.height]
    }
    fn read_rows(&self, y0: usize, y1: usize) -> Result<Vec<f32>> {
        let file = self
            .file
            .lock()
            .map_err(|_| Error::file(&self.grid.path, "reader poisoned by an earlier failure"))?;
        self.grid.read_rows(&file, y0, y1)
    }
    fn cell_size(&self) -> [f64; 2] {
        self.grid.cell_size
    }
    fn georef(&self) -> (Option<String>, Option<super::crs::Undeclared>) {
        (self.grid.crs.clone(), self.grid.undeclared)
    }
    fn place(&self) -> Option<super::place::Place> {
        self.grid.place.clone()
    }
}

/// netCDF-4 (HDF5) files through libnetcdf and the `netcdf` crate, with
/// the feature `netcdf4`: the header is read into the same lists the
/// classic reader makes, so the variable, axes and values follow the same
/// rules; samples come through the library, converted to f64 by it. Not a
/// default: the crate links the system's libnetcdf (`apt install
/// libnetcdf-dev`), where a fresh clone needs nothing. The HDF5 parsing is
/// the library's, not checked here.
#[cfg(feature = "netcdf4")]
mod hdf {
    use super::*;
    use netcdf::types::{FloatType, IntType, NcVariableType};
    use netcdf::AttributeValue as A;

    fn value(a: A) -> Value {
        let n = |v: Vec<f64>| Value::Numbers(v);
        match a {
            A::Uchar(x) => n(vec![x as f64]),
            A::Uchars(x) => n(x.into_iter().map(f64::from).collect()),
            A::Schar(x) => n(vec![x as f64]),
            A::Schars(x) => n(x.into_iter().map(f64::from).collect()),
            A::Ushort(x) => n(vec![x as f64]),
            A::Ushorts(x) => n(x.into_iter().map(f64::from).collect()),
            A::Short(x) => n(vec![x as f64]),
            A::Shorts(x) => n(x.into_iter().map(f64::from).collect()),
            A::Uint(x) => n(vec![x as f64]),
            A::Uints(x) => n(x.into_iter().map(f64::from).collect()),
            A::Int(x) => n(vec![x as f64]),
            A::Ints(x) => n(x.into_iter().map(f64::from).collect()),
            A::Ulonglong(x) => n(vec![x as f64]),
            A::Ulonglongs(x) => n(x.into_iter().map(|v| v as f64).collect()),
            A::Longlong(x) => n(vec![x as f64]),
            A::Longlongs(x) => n(x.into_iter().map(|v| v as f64).collect()),
            A::Float(x) => n(vec![x as f64]),
            A::Floats(x) => n(x.into_iter().map(f64::from).collect()),
            A::Double(x) => n(vec![x]),
            A::Doubles(x) => n(x),
            A::Str(s) => Value::Text(s),
            A::Strs(s) => Value::Text(s.join("")),
        }
    }

    fn ty(t: NcVariableType) -> NcType {
        match t {
            NcVariableType::Int(IntType::I8) => NcType::Byte,
            NcVariableType::Int(IntType::U8) => NcType::UByte,
            NcVariableType::Int(IntType::I16) => NcType::Short,
            NcVariableType::Int(IntType::U16) => NcType::UShort,
            NcVariableType::Int(IntType::I32) => NcType::Int,
            NcVariableType::Int(IntType::U32) => NcType::UInt,
            NcVariableType::Int(IntType::I64) => NcType::Int64,
            NcVariableType::Int(IntType::U64) => NcType::UInt64,
            NcVariableType::Float(FloatType::F32) => NcType::Float,
            NcVariableType::Float(FloatType::F64) => NcType::Double,
            // Strings, compounds and the rest are no map.
            _ => NcType::Char,
        }
    }

    /// The header of a netCDF-4 file, as the classic reader's lists
    /// (version 4 names the format in `format`).
    pub(super) fn header(path: &Path) -> std::result::Result<Header, String> {
        let f = netcdf::open(path).map_err(|e| format!("netCDF-4: {e}"))?;
        let mut dims: Vec<Dim> = vec![];
        let mut vars = vec![];
        for v in f.variables() {
            let mut ids = vec![];
            for d in v.dimensions() {
                let name = d.name();
                let id = match dims.iter().position(|x| x.name == name) {
                    Some(i) => i,
                    None => {
                        dims.push(Dim {
                            name,
                            len: d.len() as u64,
                        });
                        dims.len() - 1
                    }
                };
                ids.push(id);
            }
            let attrs = v
                .attributes()
                .filter_map(|a| Some((a.name().to_string(), value(a.value().ok()?))))
                .collect();
            vars.push(Var {
                name: v.name(),
                dims: ids,
                attrs,
                ty: ty(v.vartype()),
                begin: 0,
            });
        }
        Ok(Header {
            library: true,
            version: 4,
            numrecs: 1,
            dims,
            vars,
        })
    }

    /// The `n` values of the coordinate variable `name`.
    pub(super) fn coordinates(
        path: &Path,
        name: &str,
        n: u64,
    ) -> std::result::Result<Vec<f64>, String> {
        let f = netcdf::open(path).map_err(|e| e.to_string())?;
        let v = f.variable(name).ok_or("gone")?;
        v.get_values::<f64, _>((vec![0], vec![n as usize]))
            .map_err(|e| e.to_string())
    }

    /// Raw values `first .. first + n` of the grid in file order (whole
    /// rows, or the whole grid), as f64.
    pub(super) fn block(g: &Grid, first: usize, n: usize) -> std::result::Result<Vec<f64>, String> {
        let f = netcdf::open(&g.path).map_err(|e| e.to_string())?;
        let v = f.variable(&g.variable).ok_or("gone")?;
        let inner = if g.transposed { g.height } else { g.width };
        let mut start = vec![0; g.leading];
        let mut count = vec![1; g.leading];
        start.extend([first / inner, 0]);
        count.extend([n / inner, inner]);
        v.get_values::<f64, _>((start, count))
            .map_err(|e| e.to_string())
    }
}
