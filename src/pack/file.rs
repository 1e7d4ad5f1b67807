//! The `.tcz` file: a versioned header that says what the pack holds, an
//! index of every tile, then the tiles.
//!
//! ```text
//! "TCZPACK\0"             8 bytes, the magic
//! version                 u32 LE (4; 3 is read where ratio-coded)
//! header length           u32 LE
//! header CRC-32           u32 LE
//! header                  JSON: map size, cell size, filter, bound, tile, levels
//! index                   per level (finest first), per tile (row-major):
//!                         offset u64 LE (from the file's start), length u32 LE,
//!                         CRC-32 of the tile's bytes u32 LE
//! tiles
//! ```
//!
//! JSON keeps the header readable with any tool; the index is binary so a
//! reader finds any tile without parsing the others, and each tile's CRC
//! turns a flipped bit into an error that names the tile instead of wrong
//! heights.

use super::codec::{Coder, Packed, PackedLevel, Predictor, Quant};
use crate::error::{write_atomic, Error, Result};
use crate::pyramid::{Filter, PyramidLevel};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The first bytes of every pack.
pub const MAGIC: &[u8; 8] = b"TCZPACK\0";
/// The version this build writes: 5 brought the fitted predictor (its
/// tiles' side streams begin with their weights; a header that names it
/// is version 5's), 4 coded the fast coder's symbols with zstd. A
/// ratio-coded pack is the same in 3, 4 and 5 but for that (two
/// interleaved ANS streams under 14-bit models decoded through lookup
/// tables), so this build reads all three; 2 had one stream, 1 had 24-bit
/// models.
pub const VERSION: u32 = 5;
/// The oldest version this build reads, and only ratio-coded: 3's fast
/// coder was pcodec.
pub const OLDEST: u32 = 3;
/// Bytes of one index entry.
const ENTRY: usize = 16;

/// One level in the header.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct LevelSpec {
    width: usize,
    height: usize,
    quant: Quant,
    range: [f32; 2],
}

/// What a pack holds, as its header says.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Header {
    /// Metres per cell of level 0, x and y.
    pub cell_size: [f64; 2],
    /// The filter the pyramid's coarser levels were made with.
    pub filter: String,
    /// Every sample of every level is within this of that pyramid (metres;
    /// 0 is lossless).
    pub max_error: f64,
    /// Tile side in samples.
    pub tile: usize,
    /// The tiles' entropy stage. Absent from ratio-coded packs, so their
    /// headers are as before there was a choice.
    #[serde(default, skip_serializing_if = "Coder::is_default")]
    pub coder: Coder,
    /// `fitted` where the finer levels' tiles carry fitted prediction
    /// weights; absent otherwise (lifting, or upsampling, which the levels'
    /// quantisation says), so other packs' headers are as before.
    #[serde(default, skip_serializing_if = "Predictor::is_implied")]
    predictor: Predictor,
    /// What was packed (a file name, or the scene's procedural terrain).
    pub source: String,
    levels: Vec<LevelSpec>,
    /// Where the map lies (CRS, position, no-data value), where the input
    /// said: `unpack` writes it back. Absent from packs of maps that say
    /// nothing, so their headers are as before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub place: Option<crate::terrain::place::Place>,
}

impl Header {
    /// Level 0's width and height.
    pub fn size(&self) -> [usize; 2] {
        self.levels.first().map_or([0, 0], |l| [l.width, l.height])
    }
    /// How level `l` is quantised.
    pub fn level_quant(&self, l: usize) -> Option<Quant> {
        self.levels.get(l).map(|s| s.quant)
    }
    /// What the finer levels are predicted from.
    pub fn predictor(&self) -> Predictor {
        if self
            .levels
            .iter()
            .any(|l| matches!(l.quant, Quant::Upsampled { .. }))
        {
            Predictor::Upsampled
        } else {
            self.predictor
        }
    }
    /// Says what the finer levels are predicted from: only
    /// [`Predictor::Fitted`] is written; the others read from the levels.
    pub fn set_predictor(&mut self, p: Predictor) {
        self.predictor = p;
    }
    /// Level 0's least and greatest valid height, as decoded.
    pub fn range(&self) -> [f32; 2] {
        self.levels.first().map_or([0.0, 0.0], |l| l.range)
    }
    /// Levels in the pack.
    pub fn levels(&self) -> usize {
        self.levels.len()
    }
    /// Level `l`'s width and height.
    pub fn level_size(&self, l: usize) -> [usize; 2] {
        [self.levels[l].width, self.levels[l].height]
    }
    /// Level `l`'s least and greatest valid height, as decoded.
    pub fn level_range(&self, l: usize) -> [f32; 2] {
        self.levels[l].range
    }
    /// Level `l`'s tiles across and down.
    pub fn tiles_of(&self, l: usize) -> [usize; 2] {
        let [w, h] = self.level_size(l);
        [w.div_ceil(self.tile), h.div_ceil(self.tile)]
    }
}

impl Header {
    /// The header of `levels` (width, height, quantisation, decoded range;
    /// finest first).
    pub(crate) fn new(
        cell_size: [f64; 2],
        filter: &str,
        max_error: f64,
        tile: usize,
        source: &str,
        levels: impl IntoIterator<Item = (usize, usize, Quant, [f32; 2])>,
    ) -> Self {
        Header {
            cell_size,
            filter: filter.to_string(),
            max_error,
            tile,
            coder: Coder::Ratio,
            predictor: Predictor::Lifting,
            source: source.to_string(),
            levels: levels
                .into_iter()
                .map(|(width, height, quant, range)| LevelSpec {
                    width,
                    height,
                    quant,
                    range,
                })
                .collect(),
            place: None,
        }
    }
}

/// Everything before the tiles: magic, version, `header`, and the index of
/// tiles given as (length, CRC-32), finest level first and row-major,
/// which are to follow the prefix in that order.
pub(crate) fn prefix(header: &Header, tiles: &[(u32, u32)]) -> Result<Vec<u8>> {
    let json = serde_json::to_vec(header).map_err(|e| Error::value("pack", e.to_string()))?;
    let start = 20 + json.len() + ENTRY * tiles.len();
    let mut out = Vec::with_capacity(start);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&json).to_le_bytes());
    out.extend_from_slice(&json);
    let mut at = start as u64;
    for &(len, crc) in tiles {
        out.extend_from_slice(&at.to_le_bytes());
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(&crc.to_le_bytes());
        at += len as u64;
    }
    Ok(out)
}

/// Writes `packed` to `path` (through a temporary file and a rename).
pub fn write(
    path: &Path,
    packed: &Packed,
    cell_size: [f64; 2],
    filter: &str,
    source: &str,
) -> Result<u64> {
    let mut header = Header::new(
        cell_size,
        filter,
        packed.max_error,
        packed.tile,
        source,
        packed
            .levels
            .iter()
            .map(|l| (l.width, l.height, l.quant, l.range)),
    );
    header.coder = packed.coder;
    header.set_predictor(packed.predictor);
    let tiles: Vec<&Vec<u8>> = packed.levels.iter().flat_map(|l| &l.tiles).collect();
    let index: Vec<(u32, u32)> = tiles
        .iter()
        .map(|t| (t.len() as u32, crc32fast::hash(t)))
        .collect();
    let mut out = prefix(&header, &index)?;
    for t in &tiles {
        out.extend_from_slice(t);
    }
    write_atomic(path, &out)?;
    Ok(out.len() as u64)
}

/// Whether the file at `path` starts like a pack (false if unreadable:
/// the reader it is then given reports why).
pub fn is_pack_file(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|_| is_pack(&head))
}

/// Whether `bytes` start like a pack.
pub fn is_pack(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Reads the pack at `path`: its header, and every tile checked against
/// its index entry and CRC. Errors name the file, and the tile where one
/// is at fault.
pub fn read(path: &Path) -> Result<(Header, Packed)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&bytes).map_err(|r| Error::file(path, r))
}

/// Reads only the header of the pack at `path` (checked, but not the
/// tiles): what a caller needs to know of a pack without decoding it.
pub fn read_header(path: &Path) -> Result<Header> {
    use std::io::Read;
    let io = |e| Error::io(path, e);
    let mut f = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::with_capacity(20);
    f.by_ref().take(20).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() == 20 {
        let len = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]);
        f.take(len as u64).read_to_end(&mut bytes).map_err(io)?;
    }
    Ok(parse_header(&bytes).map_err(|r| Error::file(path, r))?.0)
}

/// Reads the pack at `path` and decodes every level (finest first). Errors
/// name the file, and the level and tile at fault.
pub fn read_levels(path: &Path) -> Result<(Header, Vec<PyramidLevel>)> {
    let [w, h] = read_header(path)?.size();
    crate::terrain::check_dimensions(w as u64, h as u64).map_err(|r| {
        Error::file(
            path,
            format!("too large to decode whole ({r}); a clipmap scene without shadows or normal-map decodes it tile by tile"),
        )
    })?;
    let (header, packed) = read(path)?;
    let levels = packed
        .decode()
        .map_err(|e| Error::file(path, e.to_string()))?;
    Ok((header, levels))
}

/// The pack a scene's terrain names, if its `file` is one (by its first
/// bytes; cheap, so every session can ask).
pub fn pack_path(spec: &crate::terrain::Spec, base_dir: &Path) -> Option<PathBuf> {
    let path = base_dir.join(spec.file.as_ref()?);
    is_pack_file(&path).then_some(path)
}

/// The cell size a scene gets from a pack's header: its own override,
/// else the pack's.
pub fn cell_size(spec: &crate::terrain::Spec, header: &Header) -> [f64; 2] {
    spec.cell_size
        .as_ref()
        .map_or(header.cell_size, |c| c.pair())
}

/// The pack at `path` decoded whole, as a scene's terrain.
pub fn read_terrain(spec: &crate::terrain::Spec, path: &Path) -> Result<PackTerrain> {
    let (header, levels) = read_levels(path)?;
    let filter = Filter::parse(&header.filter).map_err(|r| Error::file(path, r))?;
    Ok(PackTerrain {
        levels,
        cell_size: cell_size(spec, &header),
        filter,
    })
}

/// A scene's terrain read from a pack ([`read_terrain`]).
pub struct PackTerrain {
    /// The decoded levels, finest first.
    pub levels: Vec<PyramidLevel>,
    /// Metres per cell of level 0 (the scene's override, else the pack's).
    pub cell_size: [f64; 2],
    /// The filter the levels were made with.
    pub filter: Filter,
}

/// The header and where the index starts, from the file's first bytes.
pub(crate) fn parse_header(bytes: &[u8]) -> std::result::Result<(Header, usize), String> {
    if !is_pack(bytes) {
        return Err("not a terraclip pack (no TCZPACK magic)".into());
    }
    if bytes.len() < 20 {
        return Err(format!("{} bytes: the file is cut short", bytes.len()));
    }
    let u32_at =
        |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let version = u32_at(8);
    if !(OLDEST..=VERSION).contains(&version) {
        return Err(format!(
            "pack version {version}; this build reads versions {OLDEST} to {VERSION} \
             (pack the map again with this build)"
        ));
    }
    let len = u32_at(12) as usize;
    let json = bytes
        .get(20..20 + len)
        .ok_or_else(|| format!("header of {len} bytes runs past the end of the file"))?;
    if crc32fast::hash(json) != u32_at(16) {
        return Err("header checksum mismatch (the header is damaged)".into());
    }
    let header: Header =
        serde_json::from_slice(json).map_err(|e| format!("header is not valid: {e}"))?;
    check_header(&header)?;
    if version < 5 && header.predictor == Predictor::Fitted {
        return Err(format!(
            "pack version {version} names the fitted predictor, which version 5 brought"
        ));
    }
    if version < 4 && header.coder == Coder::Fast {
        return Err(format!(
            "pack version {version} with the fast coder, whose tiles older builds coded with \
             pcodec; this build codes them with zstd and reads only version {VERSION}'s \
             (pack the map again with this build)"
        ));
    }
    Ok((header, 20 + len))
}

/// One tile's index entry: where its bytes are, and their CRC-32.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Entry {
    pub offset: u64,
    pub len: u32,
    pub crc: u32,
}

/// The name errors give tile `t` of level `l` (`nx` tiles across).
pub(crate) fn tile_name(l: usize, t: usize, nx: usize) -> String {
    format!("level {l} tile ({}, {})", t % nx, t / nx)
}

/// The index after the header (which ends at `at`) of a file of
/// `file_len` bytes whose first bytes are `bytes` (the whole file, or
/// exactly through the index): per level, each tile's entry, checked to lie
/// inside the file; and where the tiles end, which must be the file's end
/// ([`check_end`]).
pub(crate) fn parse_index(
    bytes: &[u8],
    header: &Header,
    mut at: usize,
    file_len: u64,
) -> std::result::Result<(Vec<Vec<Entry>>, u64), String> {
    let mut next = index_end(header, at, file_len)?;
    let mut out = Vec::with_capacity(header.levels.len());
    let mut total = 0u64;
    // Tiles follow the index in its order, each where the one before ends
    // (the first where the index ends): an entry elsewhere overlaps
    // another tile or leaves unread bytes.
    let mut prev = None;
    for (l, spec) in header.levels.iter().enumerate() {
        let (nx, ny) = (
            spec.width.div_ceil(header.tile),
            spec.height.div_ceil(header.tile),
        );
        let mut entries = Vec::with_capacity(nx * ny);
        for t in 0..nx * ny {
            let entry = bytes
                .get(at..at + ENTRY)
                .ok_or_else(|| format!("{}: the index is cut short", tile_name(l, t, nx)))?;
            at += ENTRY;
            let e = Entry {
                offset: u64::from_le_bytes(entry[..8].try_into().expect("8 bytes")),
                len: u32::from_le_bytes(entry[8..12].try_into().expect("4 bytes")),
                crc: u32::from_le_bytes(entry[12..16].try_into().expect("4 bytes")),
            };
            if e.offset
                .checked_add(e.len as u64)
                .is_none_or(|end| end > file_len)
            {
                return Err(format!(
                    "{}: {} bytes at offset {} run past the end of the file ({file_len} bytes)",
                    tile_name(l, t, nx),
                    e.len,
                    e.offset
                ));
            }
            if e.offset != next {
                // The entry before may be the liar: a length that is wrong
                // leaves that tile's bytes unlike its checksum. Name it,
                // where `bytes` hold that tile (the whole file's do; a
                // reader that reads only the index names the offset).
                let held = |p: &Entry| p.offset + p.len as u64 <= bytes.len() as u64;
                if let Some((pl, pt, pnx, p)) = prev.filter(|(_, _, _, p)| held(p)) {
                    tile_bytes(bytes, p, || tile_name(pl, pt, pnx))?;
                }
                return Err(format!(
                    "{}: offset {} is not where the tile before it ends ({next}): \
                     tiles overlap or leave a gap",
                    tile_name(l, t, nx),
                    e.offset
                ));
            }
            next += e.len as u64;
            total += e.len as u64;
            prev = Some((l, t, nx, e));
            entries.push(e);
        }
        out.push(entries);
    }
    Ok((out, total + at as u64))
}

/// Where the index after a header ending at `at` ends, checked to lie in
/// a file of `file_len` bytes: the header's sizes say how many entries
/// follow, and the file must hold them before anything is sized from them
/// (a forged header can claim 2^40 tiles in a file of 2 KB).
pub(crate) fn index_end(
    header: &Header,
    at: usize,
    file_len: u64,
) -> std::result::Result<u64, String> {
    let entries = (0..header.levels())
        .map(|l| {
            let [nx, ny] = header.tiles_of(l);
            nx as u64 * ny as u64
        })
        .try_fold(0u64, |a, n| a.checked_add(n));
    let room = file_len.saturating_sub(at as u64);
    match entries.and_then(|n| n.checked_mul(ENTRY as u64)) {
        Some(need) if need <= room => Ok(at as u64 + need),
        _ => Err(format!(
            "index: the header's {} levels of {}² tiles need {} entries of {ENTRY} bytes, \
             more than the {room} bytes after the header",
            header.levels.len(),
            header.tile,
            entries.map_or("over 2^64".into(), |n| n.to_string())
        )),
    }
}

/// `tile`, the bytes of entry `e`, checked against its CRC.
pub(crate) fn checked_tile(
    tile: &[u8],
    e: Entry,
    name: impl Fn() -> String,
) -> std::result::Result<&[u8], String> {
    if crc32fast::hash(tile) != e.crc {
        return Err(format!(
            "{}: checksum mismatch (the tile is damaged)",
            name()
        ));
    }
    Ok(tile)
}

/// The tiles end the file: anything after them is damage, not data.
pub(crate) fn check_end(end: u64, file_len: u64) -> std::result::Result<(), String> {
    if end != file_len {
        return Err(format!(
            "{file_len} bytes, but the header, index and tiles take {end}"
        ));
    }
    Ok(())
}

/// The bytes of `e` in `bytes` (the whole file), checked against its CRC.
pub(crate) fn tile_bytes(
    bytes: &[u8],
    e: Entry,
    name: impl Fn() -> String,
) -> std::result::Result<&[u8], String> {
    let tile = bytes
        .get(e.offset as usize..e.offset as usize + e.len as usize)
        .ok_or_else(|| format!("{}: the tile runs past the end of the file", name()))?;
    checked_tile(tile, e, name)
}

fn parse(bytes: &[u8]) -> std::result::Result<(Header, Packed), String> {
    let (header, at) = parse_header(bytes)?;
    let (index, end) = parse_index(bytes, &header, at, bytes.len() as u64)?;
    let mut levels = Vec::with_capacity(header.levels.len());
    for (l, (spec, entries)) in header.levels.iter().zip(&index).enumerate() {
        let nx = spec.width.div_ceil(header.tile);
        let tiles = entries
            .iter()
            .enumerate()
            .map(|(t, &e)| tile_bytes(bytes, e, || tile_name(l, t, nx)).map(<[u8]>::to_vec))
            .collect::<std::result::Result<_, _>>()?;
        levels.push(PackedLevel {
            width: spec.width,
            height: spec.height,
            quant: spec.quant,
            range: spec.range,
            tiles,
        });
    }
    // After the tiles' checksums, so a tile whose length lies is named.
    check_end(end, bytes.len() as u64)?;
    let packed = Packed {
        tile: header.tile,
        coder: header.coder,
        predictor: header.predictor(),
        max_error: header.max_error,
        levels,
    };
    Ok((header, packed))
}

/// Sizes that add up: each level the vertex-centred half of the one
/// before, a tile size a reader can hold, finite cell sizes and bound.
fn check_header(h: &Header) -> std::result::Result<(), String> {
    if h.levels.is_empty() {
        return Err("the header lists no level".into());
    }
    if !(2..=4096).contains(&h.tile) || h.tile % 2 != 0 {
        return Err(format!(
            "tile size {} is not even and within 2..=4096",
            h.tile
        ));
    }
    // Every reader needs the filter: the whole decode as much as the
    // tile-by-tile one, which refused a name the whole decode let through.
    Filter::parse(&h.filter).map_err(|r| format!("filter: {r}"))?;
    if !(h.max_error.is_finite() && h.max_error >= 0.0) {
        return Err(format!("max error {} is not finite and ≥ 0", h.max_error));
    }
    if !h.cell_size.iter().all(|c| c.is_finite() && *c > 0.0) {
        return Err(format!(
            "cell size {:?} is not finite and positive",
            h.cell_size
        ));
    }
    if let Some(p) = &h.place {
        p.check().map_err(|r| format!("place: {r}"))?;
    }
    let upsampled = h
        .levels
        .iter()
        .any(|l| matches!(l.quant, Quant::Upsampled { .. }));
    match (h.predictor, upsampled) {
        (Predictor::Upsampled, _) => {
            return Err(
                "predictor \"upsampled\": the levels' quantisation says so, \
                        and the header names only \"fitted\""
                    .into(),
            )
        }
        (Predictor::Fitted, true) => {
            return Err("predictor \"fitted\" with upsampled levels".into())
        }
        _ => {}
    }
    for (l, spec) in h.levels.iter().enumerate() {
        let fine = match spec.quant {
            Quant::Step { max_error } | Quant::Upsampled { max_error } => {
                max_error.is_finite() && max_error > 0.0
            }
            Quant::Lattice { offset, scale } => {
                offset.is_finite() && scale.is_finite() && scale > 0.0
            }
            Quant::Bits => true,
        };
        if !fine {
            return Err(format!(
                "level {l}'s quantisation {:?} is not usable",
                spec.quant
            ));
        }
        let [lo, hi] = spec.range;
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(format!(
                "level {l}'s range [{lo}, {hi}] is not two finite heights, least first"
            ));
        }
    }
    let [w, hh] = [h.levels[0].width, h.levels[0].height];
    crate::terrain::check_side(w as u64, hh as u64)?;
    for (l, pair) in h.levels.windows(2).enumerate() {
        let want = ((pair[0].width - 1) / 2 + 1, (pair[0].height - 1) / 2 + 1);
        if (pair[0].width, pair[0].height) == (1, 1) {
            return Err(format!(
                "level {} follows level {l}, which is 1×1: a pyramid ends at its first 1×1 level \
                 (the header lists {} levels)",
                l + 1,
                h.levels.len()
            ));
        }
        if (pair[1].width, pair[1].height) != want {
            return Err(format!(
                "level {} is {}×{}, not {}×{}, the half of level {l} ({}×{})",
                l + 1,
                pair[1].width,
                pair[1].height,
                want.0,
                want.1,
                pair[0].width,
                pair[0].height
            ));
        }
    }
    Ok(())
}
