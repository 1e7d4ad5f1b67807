//! PNG and TGA heightmaps through the `image` crate: 8- and 16-bit grayscale
//! (alpha 0 marks no-data), or RGB whose channels are equal. A 16-bit PNG with
//! a JSON sidecar is decoded to metres with the sidecar's offset and scale.

use super::{check_dimensions, named, sidecar, Heightmap, Lattice, MAX_SIDE, MAX_TEXELS};
use crate::error::{Error, Result};
use image::DynamicImage;
use std::path::Path;

pub(super) fn read(path: &Path) -> Result<Heightmap> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    // TGA has no magic number, so the format comes from the extension.
    let format = image::ImageFormat::from_path(path)
        .map_err(|e| Error::file(path, format!("cannot decode image: {e}")))?;
    let mut reader = image::ImageReader::with_format(std::io::BufReader::new(file), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE as u32);
    limits.max_image_height = Some(MAX_SIDE as u32);
    limits.max_alloc = Some(MAX_TEXELS * 8);
    reader.limits(limits);
    let decode_err = |e: image::ImageError| Error::file(path, format!("cannot decode image: {e}"));
    // The header's size is checked before any pixel is decoded, so a file
    // that claims more texels than a heightmap may have costs nothing.
    let decoder = reader.into_decoder().map_err(decode_err)?;
    let (hw, hh) = image::ImageDecoder::dimensions(&decoder);
    named(path, check_dimensions(hw as u64, hh as u64))?;
    let img = DynamicImage::from_decoder(decoder).map_err(decode_err)?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let kind = if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("tga"))
    {
        "tga"
    } else {
        "png"
    };
    let (values, bits) = luma_values(&img).map_err(|r| Error::file(path, r))?;
    let side = sidecar::find(path);
    let (values, cell, nodata, format, lattice) = match side {
        Some((side_path, s)) if bits == 16 && s.png16.is_some() => {
            s.check_dims(&side_path, w, h)?;
            let p = s.png16.clone().expect("checked above");
            let decoded = values
                .into_iter()
                .map(|v| (p.png16_offset_m + v as f64 * p.png16_scale_m_per_unit) as f32)
                .collect();
            (
                decoded,
                s.cell_size(),
                s.nodata.map(|v| v as f32),
                format!("{kind}16+sidecar"),
                Lattice {
                    offset: p.png16_offset_m,
                    scale: p.png16_scale_m_per_unit,
                },
            )
        }
        _ => (
            values,
            [1.0, 1.0],
            None,
            format!("{kind}{bits}"),
            Lattice {
                offset: 0.0,
                scale: 1.0,
            },
        ),
    };
    let mut map = named(
        path,
        Heightmap::from_values(w, h, values, nodata, cell, &format),
    )?;
    map.lattice = Some(lattice);
    Ok(map)
}

/// Grey values of an image as f32 (NaN where alpha is 0), with the bit depth.
fn luma_values(img: &DynamicImage) -> std::result::Result<(Vec<f32>, u32), String> {
    fn grey<const N: usize, T: Copy + Into<f32> + PartialEq>(
        px: &[T],
        alpha: bool,
    ) -> std::result::Result<Vec<f32>, String> {
        px.chunks_exact(N)
            .map(|c| {
                let colour = if alpha { N - 1 } else { N };
                if c[..colour].iter().any(|&v| v != c[0]) {
                    return Err("colour image: expected single-band grayscale heights".into());
                }
                let transparent = alpha && c[N - 1].into() == 0.0;
                Ok(if transparent { f32::NAN } else { c[0].into() })
            })
            .collect()
    }
    Ok(match img {
        DynamicImage::ImageLuma8(b) => (grey::<1, u8>(b.as_raw(), false)?, 8),
        DynamicImage::ImageLumaA8(b) => (grey::<2, u8>(b.as_raw(), true)?, 8),
        DynamicImage::ImageRgb8(b) => (grey::<3, u8>(b.as_raw(), false)?, 8),
        DynamicImage::ImageRgba8(b) => (grey::<4, u8>(b.as_raw(), true)?, 8),
        DynamicImage::ImageLuma16(b) => (grey::<1, u16>(b.as_raw(), false)?, 16),
        DynamicImage::ImageLumaA16(b) => (grey::<2, u16>(b.as_raw(), true)?, 16),
        DynamicImage::ImageRgb16(b) => (grey::<3, u16>(b.as_raw(), false)?, 16),
        DynamicImage::ImageRgba16(b) => (grey::<4, u16>(b.as_raw(), true)?, 16),
        other => return Err(format!("unsupported pixel type {:?}", other.color())),
    })
}
