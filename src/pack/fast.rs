//! The fast coder's tile: the same residual symbols as the ratio coder's
//! (prediction, quantisation and escapes are shared), entropy-coded by
//! pcodec instead of by ANS under per-context models.
//!
//! ```text
//! flags                   u8 (0, MIXED or ALL_NODATA, as the ratio coder's)
//! side-stream length      u32 LE
//! no-data count           u32 LE
//! no-data mask            MIXED only: one bit a sample, row-major, LSB first
//! side stream             escapes' values, as the ratio coder's
//! symbols                 pcodec's wrapped format: its header, one chunk's
//!                         metadata, one page of the tile's n symbols (u16)
//! ```
//!
//! pcodec was chosen over a coder of our own: it is pure Rust, keeps a
//! format across releases, and decodes a page in batches of 256 numbers
//! by table-driven bin lookups, where ANS decodes one symbol at a time
//! through one state. The wrapped format (not the standalone one) leaves
//! the count of numbers to us, which the tile's rectangle gives, so no
//! count read from the file sizes anything.

use pco::wrapped::{FileCompressor, FileDecompressor};
use pco::{ChunkConfig, DeltaSpec, ModeSpec};

/// Bytes before the mask: flags, side-stream length, no-data count.
pub(crate) const HEADER: usize = 1 + 4 + 4;

/// pcodec's configuration: residuals are already decorrelated, so no
/// delta encoding, and the classic mode (bins only), which decodes fastest
/// and spends no encode time searching for multipliers that residuals do
/// not have.
fn config() -> ChunkConfig {
    ChunkConfig::default()
        .with_delta_spec(DeltaSpec::NoOp)
        .with_mode_spec(ModeSpec::Classic)
}

/// A tile's bytes from its no-data `flags` and `count`, its mask, side
/// stream and symbols in coding order.
pub(crate) fn encode(
    flags: u8,
    count: u32,
    nodata: &[bool],
    side: &[u8],
    sym: &[usize],
) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER + side.len() + sym.len() / 2);
    out.push(flags);
    out.extend_from_slice(&(side.len() as u32).to_le_bytes());
    out.extend_from_slice(&count.to_le_bytes());
    if flags == super::codec::MIXED {
        let mut bits = vec![0u8; nodata.len().div_ceil(8)];
        for (i, _) in nodata.iter().enumerate().filter(|(_, &b)| b) {
            bits[i / 8] |= 1 << (i % 8);
        }
        out.extend_from_slice(&bits);
    }
    out.extend_from_slice(side);
    let nums: Vec<u16> = sym.iter().map(|&s| s as u16).collect();
    // Writing to a Vec fails only on a bug (a count pcodec refuses).
    let fc = FileCompressor::default();
    let out = fc.write_header(out).expect("pcodec writes to a Vec");
    let mut cc = fc
        .chunk_compressor(&nums, &config())
        .expect("pcodec takes any u16 numbers");
    let mut out = cc.write_meta(out).expect("pcodec writes to a Vec");
    for page in 0..cc.n_per_page().len() {
        out = cc.write_page(page, out).expect("pcodec writes to a Vec");
    }
    out
}

/// A fast tile's parts, checked against its `n` samples.
pub(crate) struct Parts<'a> {
    pub flags: u8,
    pub count: u32,
    pub mask: &'a [u8],
    pub side: &'a [u8],
    pub coded: &'a [u8],
}

/// Splits `bytes`, a tile of `n` samples, into its parts.
pub(crate) fn parts(bytes: &[u8], n: usize) -> Result<Parts<'_>, String> {
    if bytes.len() < HEADER {
        return Err(format!(
            "{} bytes, shorter than the {HEADER}-byte header",
            bytes.len()
        ));
    }
    let le =
        |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let flags = bytes[0];
    let (side_len, count) = (le(1) as usize, le(5));
    let mask_len = if flags == super::codec::MIXED {
        n.div_ceil(8)
    } else {
        0
    };
    let rest = &bytes[HEADER..];
    if mask_len > rest.len() || side_len > rest.len() - mask_len {
        return Err(format!(
            "no-data mask of {mask_len} bytes and side stream of {side_len} bytes do not fit the tile's {} bytes",
            rest.len()
        ));
    }
    let (mask, rest) = rest.split_at(mask_len);
    let (side, coded) = rest.split_at(side_len);
    Ok(Parts {
        flags,
        count,
        mask,
        side,
        coded,
    })
}

/// Decodes the `n` symbols of `coded` into `sym`. pcodec's errors on
/// damaged bytes are passed on; bytes left after the page are an error.
pub(crate) fn symbols(coded: &[u8], n: usize, sym: &mut Vec<u16>) -> Result<(), String> {
    let broken = |e: pco::errors::PcoError| format!("coded symbols broken: {e}");
    let (fd, rest) = FileDecompressor::new(coded).map_err(broken)?;
    let (mut cd, rest) = fd.chunk_decompressor::<u16, _>(rest).map_err(broken)?;
    // pcodec writes all n (checked below), so the buffer is only sized.
    sym.resize(n, 0);
    let mut pd = cd.page_decompressor(rest, n).map_err(broken)?;
    let progress = pd.read(sym).map_err(broken)?;
    if progress.n_processed != n || !progress.finished {
        return Err(format!(
            "coded symbols end after {} of {n}",
            progress.n_processed
        ));
    }
    let left = pd.into_src();
    if !left.is_empty() {
        return Err(format!("{} coded bytes left over", left.len()));
    }
    // The largest symbol by a fold with no early exit (it vectorises; a
    // `find` was a tenth of a fast decode), then the first past the
    // alphabet named only when there is one.
    let top = sym.iter().fold(0, |m, &s| m.max(s));
    if top as usize >= super::model::SYMBOLS {
        let s = sym.iter().find(|&&s| s as usize >= super::model::SYMBOLS);
        return Err(format!("symbol {} does not exist", s.unwrap_or(&top)));
    }
    Ok(())
}

/// Gives `put` each of the first `n` no-data flags of `mask` with its
/// index in the tile; returns how many are set (the tile header's count
/// must agree: a flipped bit that the CRC was made to match is caught).
pub(crate) fn unmask(mask: &[u8], n: usize, mut put: impl FnMut(usize, bool)) -> u32 {
    let mut count = 0;
    for i in 0..n {
        let b = mask[i / 8] >> (i % 8) & 1 == 1;
        count += u32::from(b);
        put(i, b);
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pack::codec::MIXED;

    /// A tile of `n` samples with a mask, `side` bytes of side stream and
    /// the symbols `sym`.
    fn tile(n: usize, side: &[u8], sym: &[usize]) -> Vec<u8> {
        let nodata: Vec<bool> = (0..n).map(|i| i % 3 == 0).collect();
        let count = nodata.iter().filter(|&&b| b).count() as u32;
        encode(MIXED, count, &nodata, side, sym)
    }

    #[test]
    fn a_side_stream_that_runs_past_the_tile_is_an_error() {
        let (n, side) = (40, [7u8; 5]);
        let sym: Vec<usize> = (0..n).map(|i| 255 + i % 3).collect();
        let bytes = tile(n, &side, &sym);
        let p = parts(&bytes, n).unwrap();
        assert_eq!((p.mask.len(), p.side, p.flags), (5, &side[..], MIXED));
        let mut out = Vec::new();
        symbols(p.coded, n, &mut out).unwrap();
        assert_eq!(out.iter().map(|&s| s as usize).collect::<Vec<_>>(), sym);
        // Every side length from one past what the tile holds to past the
        // mask's length again: an error naming both, never a slice past
        // the end.
        let room = bytes.len() - HEADER - p.mask.len();
        for side_len in room + 1..=room + 2 * p.mask.len() + 1 {
            let mut b = bytes.clone();
            b[1..5].copy_from_slice(&(side_len as u32).to_le_bytes());
            let e = parts(&b, n).err().expect("refused");
            assert!(e.contains("do not fit"), "{e}");
        }
        // The whole rest as the side stream leaves no symbols: pcodec's
        // error, not a panic.
        let mut b = bytes.clone();
        b[1..5].copy_from_slice(&(room as u32).to_le_bytes());
        let p = parts(&b, n).unwrap();
        assert!(symbols(p.coded, n, &mut out).is_err());
    }

    #[test]
    fn symbols_past_the_alphabet_and_bytes_after_the_page_are_errors() {
        let n = 300;
        let good: Vec<usize> = (0..n).map(|i| 250 + i % 11).collect();
        let bytes = encode(0, 0, &[false; 300], &[], &good);
        let p = parts(&bytes, n).unwrap();
        let mut out = Vec::new();
        symbols(p.coded, n, &mut out).unwrap();
        // One byte more after the page.
        let mut longer = p.coded.to_vec();
        longer.push(0);
        let e = symbols(&longer, n, &mut out).unwrap_err();
        assert!(e.contains("left over"), "{e}");
        // Fewer samples than coded: the page does not end where the
        // tile's rectangle says.
        assert!(symbols(p.coded, n - 1, &mut out).is_err());
        // A symbol the models do not have (pcodec codes any u16).
        let mut bad = good.clone();
        bad[7] = crate::pack::model::SYMBOLS;
        let bytes = encode(0, 0, &[false; 300], &[], &bad);
        let p = parts(&bytes, n).unwrap();
        let e = symbols(p.coded, n, &mut out).unwrap_err();
        assert!(e.contains("symbol 512 does not exist"), "{e}");
    }

    #[test]
    fn the_mask_gives_each_flag_and_counts_them() {
        let n = 21;
        let nodata: Vec<bool> = (0..n).map(|i| i % 4 == 1 || i == 20).collect();
        let bytes = encode(MIXED, 6, &nodata, &[], &[255; 21]);
        let p = parts(&bytes, n).unwrap();
        let mut got = vec![false; n];
        let count = unmask(p.mask, n, |i, b| got[i] = b);
        assert_eq!((got, count), (nodata, 6));
    }
}
