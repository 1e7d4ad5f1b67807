//! ESRI ASCII grids (`.asc`): a header of `ncols`, `nrows`, `xllcorner` or
//! `xllcenter`, `yllcorner` or `yllcenter`, `cellsize` (or `dx`/`dy`) and an
//! optional `NODATA_value`, then rows from north to south.

use super::{check_dimensions, named, Heightmap};
use crate::error::{Error, Result};
use std::path::Path;

pub(super) fn read(path: &Path) -> Result<Heightmap> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    named(path, parse(&text))
}

fn parse(text: &str) -> std::result::Result<Heightmap, String> {
    let mut tokens = text.split_ascii_whitespace().peekable();
    let (mut ncols, mut nrows, mut cell, mut dx, mut dy, mut nodata) =
        (None, None, None, None, None, None);
    while let Some(&key) = tokens.peek() {
        if key.parse::<f64>().is_ok() {
            break;
        }
        let key = key.to_ascii_lowercase();
        tokens.next();
        let value = tokens
            .next()
            .ok_or_else(|| format!("header key '{key}' has no value"))?;
        let num = || -> std::result::Result<f64, String> {
            value
                .parse::<f64>()
                .map_err(|_| format!("header '{key}' value '{value}' is not a number"))
        };
        match key.as_str() {
            "ncols" => ncols = Some(num()?),
            "nrows" => nrows = Some(num()?),
            "cellsize" => cell = Some(num()?),
            "dx" => dx = Some(num()?),
            "dy" => dy = Some(num()?),
            "nodata_value" => nodata = Some(num()? as f32),
            "xllcorner" | "yllcorner" | "xllcenter" | "yllcenter" => {
                num()?;
            }
            _ => return Err(format!("unknown header key '{key}'")),
        }
    }
    let dim = |v: Option<f64>, name: &str| -> std::result::Result<u64, String> {
        let v = v.ok_or_else(|| format!("header lacks '{name}'"))?;
        if v.fract() != 0.0 || !(0.0..=1e12).contains(&v) {
            return Err(format!("'{name}' must be a whole number, got {v}"));
        }
        Ok(v as u64)
    };
    let (w, h) = (dim(ncols, "ncols")?, dim(nrows, "nrows")?);
    check_dimensions(w, h)?;
    let cs = [
        dx.or(cell).ok_or("header lacks 'cellsize'")?,
        dy.or(cell).ok_or("header lacks 'cellsize'")?,
    ];
    let mut values = Vec::with_capacity((w * h) as usize);
    for (i, tok) in tokens.enumerate() {
        if i as u64 >= w * h {
            return Err(format!("more than {w}×{h} values"));
        }
        let v: f32 = tok
            .parse()
            .map_err(|_| format!("value {} ('{tok}') is not a number", i + 1))?;
        values.push(v);
    }
    if (values.len() as u64) < w * h {
        return Err(format!(
            "truncated: {} of {} values present",
            values.len(),
            w * h
        ));
    }
    Heightmap::from_values(w as usize, h as usize, values, nodata, cs, "asc")
}

#[cfg(test)]
mod tests {
    #[test]
    fn parses_header_and_nodata() {
        let t = "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n1 2 3\n4 -9999 6\n";
        let h = super::parse(t).unwrap();
        assert_eq!((h.width(), h.height()), (3, 2));
        assert_eq!(h.nodata_count(), 1);
        assert_eq!(h.cell_size, [30.0, 30.0]);
        assert_eq!(h.get(2, 1), 6.0);
    }
    #[test]
    fn truncated_is_an_error() {
        let t = "ncols 3\nnrows 2\ncellsize 1\n1 2 3 4";
        assert!(super::parse(t).unwrap_err().contains("truncated"));
    }
}
