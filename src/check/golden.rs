//! Golden images: every `<name>.toml` in a folder is rendered and compared
//! with `<name>.png`, exactly (0 pixels may differ), and its Depth32Float
//! buffer with the hash in `<name>.depth` (a surface that moved under an
//! unchanged colour, say behind fog, still fails). `bless` rewrites the
//! references, each through a temporary file and a rename. On a mismatch,
//! the actual image and a difference image can be written for inspection.

use crate::check::compare::{channels, difference_image};
use crate::error::{write_atomic, Error, Result};
use crate::render::{render, Image, RenderOptions};
use crate::scene::Scene;
use serde::Serialize;
use std::path::Path;

/// One scene's outcome.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct GoldenResult {
    /// The scene's file stem (`default` for `default.toml`).
    pub scene: String,
    /// Pixels whose RGBA differ (every pixel when the reference is missing).
    pub px_differ: usize,
    /// The depth buffer's hash ([`depth_hash`]), as 16 hex digits.
    pub depth_hash: String,
    /// Whether it equals the one in `<name>.depth` (false when that file
    /// is missing).
    pub depth_pass: bool,
    /// Colour and depth both match.
    pub pass: bool,
    /// True when `bless` wrote a new reference.
    pub blessed: bool,
}

/// The scene files of a golden folder, sorted ([`crate::scene::files_in`]).
pub use crate::scene::files_in as scenes;

/// Decodes a reference PNG (or any image the `image` crate reads, which
/// `compare` takes from other renderers) to RGBA8.
pub fn load_png(path: &Path) -> Result<(u32, u32, Vec<u8>)> {
    let img = image::open(path).map_err(|e| Error::file(path, format!("unreadable image: {e}")))?;
    let rgba = img.to_rgba8();
    Ok((rgba.width(), rgba.height(), rgba.into_raw()))
}

/// FNV-1a (64-bit) over the buffer's f32 bit patterns, little-endian, then
/// over its length: a fixed, dependency-free digest. It guards against
/// accidental change, not against an adversary.
pub fn depth_hash(depth: &[f32]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let bytes = depth
        .iter()
        .flat_map(|d| d.to_bits().to_le_bytes())
        .chain((depth.len() as u64).to_le_bytes());
    for b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// The `<name>.depth` line: the hash's name, its 16 hex digits and the
/// buffer's size.
fn depth_line(img: &Image) -> String {
    format!(
        "fnv1a64 {:016x} {}x{}\n",
        depth_hash(&img.depth),
        img.width,
        img.height
    )
}

/// Checks (or with `bless`, rewrites) one scene's reference.
pub fn check_one(
    scene_path: &Path,
    bless: bool,
    diff_dir: Option<&Path>,
    opts: &RenderOptions,
) -> Result<GoldenResult> {
    let scene = Scene::load(scene_path)?;
    let (img, _) = render(&scene, opts)?;
    let png = scene_path.with_extension("png");
    let name = scene_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let total = (img.width * img.height) as usize;
    let px_differ = if png.exists() {
        let (w, h, data) = load_png(&png)?;
        if (w, h) != (img.width, img.height) {
            total
        } else {
            let n = channels(&img.rgba, &data, 4).px_differ;
            if n > 0 {
                if let Some(dir) = diff_dir {
                    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
                    write_atomic(&dir.join(format!("{name}-actual.png")), &img.png()?)?;
                    let d = difference_image(&img, &data);
                    write_atomic(&dir.join(format!("{name}-diff.png")), &d.png()?)?;
                }
            }
            n
        }
    } else {
        total
    };
    let depth_file = scene_path.with_extension("depth");
    let line = depth_line(&img);
    let depth_pass = match std::fs::read_to_string(&depth_file) {
        Ok(text) => text == line,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
        Err(e) => return Err(Error::io(&depth_file, e)),
    };
    let blessed = bless && (px_differ > 0 || !depth_pass);
    if blessed {
        if px_differ > 0 {
            write_atomic(&png, &img.png()?)?;
        }
        if !depth_pass {
            write_atomic(&depth_file, line.as_bytes())?;
        }
    }
    Ok(GoldenResult {
        scene: name,
        px_differ,
        depth_hash: format!("{:016x}", depth_hash(&img.depth)),
        depth_pass,
        pass: (px_differ == 0 && depth_pass) || blessed,
        blessed,
    })
}

/// Checks every scene in `dir`.
pub fn check(
    dir: &Path,
    bless: bool,
    diff_dir: Option<&Path>,
    shard: crate::shard::Shard,
) -> Result<Vec<GoldenResult>> {
    scenes(dir)?
        .iter()
        .enumerate()
        .filter(|(k, _)| shard.owns(*k))
        .map(|(_, s)| check_one(s, bless, diff_dir, &RenderOptions::default()))
        .collect()
}
