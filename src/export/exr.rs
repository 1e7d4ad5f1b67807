//! 32-bit float OpenEXR layers through the `exr` crate: the depth buffer,
//! the clipmap's toroids and the effects' textures, in a format every
//! image tool opens, with the f32 bits kept (lossless compression).

use crate::error::{Error, Result};
use exr::prelude::*;
use std::path::Path;

/// One named layer of f32 channels, rows top first.
#[derive(Clone, Debug, PartialEq)]
pub struct FloatLayer {
    /// The layer's name (`depth`, `level3`, `lightmap1`, ...).
    pub name: String,
    /// Samples across.
    pub width: usize,
    /// Samples down.
    pub height: usize,
    /// Each channel's name and its `width × height` samples.
    pub channels: Vec<(String, Vec<f32>)>,
}

impl FloatLayer {
    /// A one-channel layer.
    pub fn single(name: &str, channel: &str, width: usize, height: usize, data: Vec<f32>) -> Self {
        FloatLayer {
            name: name.into(),
            width,
            height,
            channels: vec![(channel.into(), data)],
        }
    }

    /// The channel named `name`.
    pub fn channel(&self, name: &str) -> Option<&[f32]> {
        self.channels
            .iter()
            .find(|c| c.0 == name)
            .map(|c| c.1.as_slice())
    }
}

/// The EXR file of `layers` (at least one), as bytes.
pub fn write(layers: &[FloatLayer]) -> Result<Vec<u8>> {
    let bad = |e: String| Error::value("OpenEXR", e);
    let mut out: Layers<AnyChannels<FlatSamples>> = SmallVec::new();
    let (mut w, mut h) = (1, 1);
    for l in layers {
        let list = l
            .channels
            .iter()
            .map(|(name, data)| AnyChannel::new(name.as_str(), FlatSamples::F32(data.clone())))
            .collect();
        out.push(Layer::new(
            (l.width, l.height),
            LayerAttributes::named(l.name.as_str()),
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(list),
        ));
        (w, h) = (w.max(l.width), h.max(l.height));
    }
    let image = Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions((w, h))),
        out,
    );
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| bad(e.to_string()))?;
    Ok(bytes.into_inner())
}

/// The layers of the EXR `bytes` (the file `path`); a channel that is not
/// 32-bit float is an error, since terraclip writes no other.
pub fn read(path: &Path, bytes: &[u8]) -> Result<Vec<FloatLayer>> {
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| Error::file(path, format!("unreadable OpenEXR: {e}")))?;
    image
        .layer_data
        .into_iter()
        .map(|l| {
            let name = l
                .attributes
                .layer_name
                .as_ref()
                .map_or(String::new(), |n| n.to_string());
            let channels = l
                .channel_data
                .list
                .into_iter()
                .map(|c| match c.sample_data {
                    FlatSamples::F32(v) => Ok((c.name.to_string(), v)),
                    _ => Err(Error::file(
                        path,
                        format!("layer '{name}', channel '{}': not 32-bit float", c.name),
                    )),
                })
                .collect::<Result<_>>()?;
            Ok(FloatLayer {
                name,
                width: l.size.0,
                height: l.size.1,
                channels,
            })
        })
        .collect()
}
