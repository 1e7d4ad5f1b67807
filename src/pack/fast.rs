//! The fast coder's tile: the same residual symbols as the ratio coder's
//! (prediction, quantisation and escapes are shared), entropy-coded by
//! zstd instead of by ANS under per-context models.
//!
//! ```text
//! flags                   u8 (0, MIXED or ALL_NODATA, as the ratio coder's)
//! side-stream length      u32 LE
//! no-data count           u32 LE
//! no-data mask            MIXED only: one bit a sample, row-major, LSB first
//! side stream             escapes' values, as the ratio coder's
//! symbols                 one zstd frame of the tile's n symbols in coding
//!                         order, each as its zigzagged residual z (0..=510,
//!                         the escape 511): n bytes of z's low byte, then n
//!                         of its high byte only where some z is 256 or more
//! ```
//!
//! zstd (the `zstd` crate, bindings to the reference C library) was chosen
//! over pcodec, which coded these symbols before: on the same symbols of
//! jacksboro and etopo5 at E = 1 m its frames decode 2.2 to 4.4 times
//! faster (Huffman-coded literals, decoded four streams at a time, and runs
//! of equal bytes as matches) for a size within 1.5 % either way
//! (docs/explanation/pack-codecs.md). Writing no entropy coder of our own
//! keeps a fuzzed, widely deployed decoder between a hostile file and the
//! heights. Zigzag keeps the common small residuals in the low byte, so a
//! smooth tile's high bytes are all zero and are not written at all.

use super::model::{ESCAPE, K, SYMBOLS};

/// Bytes before the mask: flags, side-stream length, no-data count.
pub(crate) const HEADER: usize = 1 + 4 + 4;

/// zstd's level. Measured on jacksboro and etopo5 at E = 1 m (whole
/// pyramids, 2026-12-07): 15 makes frames within 0.2 % of 19's in a third
/// of the encode time (etopo5 1.4 s against 4.0 s on two threads), and
/// they decode as fast. Below 15 zstd searches less: at 12 etopo5's
/// frames are 1.5 % larger and jacksboro decodes 1.2 times slower, at 3
/// jacksboro's pack is 11 % larger.
const LEVEL: i32 = 15;

/// A symbol's code: the zigzagged residual, and the escape after them all.
fn zig(s: usize) -> u16 {
    if s == ESCAPE {
        return ESCAPE as u16;
    }
    let r = s as i32 - K as i32;
    ((r << 1) ^ (r >> 31)) as u16
}

/// The symbol of code `z` (at most 511): [`zig`] undone, branch-free so
/// that the loop over a tile vectorises.
fn unzig(z: u16) -> u16 {
    let r = i32::from(z >> 1) ^ -i32::from(z & 1);
    let s = (r + K as i32) as u16;
    if z == ESCAPE as u16 {
        ESCAPE as u16
    } else {
        s
    }
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
    let z: Vec<u16> = sym.iter().map(|&s| zig(s)).collect();
    let mut planes: Vec<u8> = z.iter().map(|&z| z as u8).collect();
    if z.iter().any(|&z| z > 0xff) {
        planes.extend(z.iter().map(|&z| (z >> 8) as u8));
    }
    // Compressing a slice in memory fails only on a bug.
    let frame = zstd::bulk::compress(&planes, LEVEL).expect("zstd compresses a slice");
    out.extend_from_slice(&frame);
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

/// The planes a thread's tiles decode into, kept from tile to tile.
#[derive(Default)]
pub(crate) struct Decoder {
    planes: Vec<u8>,
}

thread_local! {
    /// A thread's zstd decoder, kept for the thread's life: making one
    /// allocates and clears its tables, which made once a row of tiles
    /// was 4 % of a fast decode of jacksboro.
    static ZSTD: std::cell::RefCell<Option<zstd::bulk::Decompressor<'static>>> =
        const { std::cell::RefCell::new(None) };
}

/// Decodes the `n` symbols of `coded` into `sym`, with `dec`'s buffers.
/// The frame must hold exactly n or 2n bytes. zstd decodes in one shot
/// into a buffer of 2n that the tile's rectangle sizes, never the frame's
/// header: a frame that says it is larger is zstd's error, and one-shot
/// decoding keeps no window of its own, so a forged window size allocates
/// nothing either.
pub(crate) fn symbols(
    coded: &[u8],
    n: usize,
    dec: &mut Decoder,
    sym: &mut Vec<u16>,
) -> Result<(), String> {
    let broken = |e: std::io::Error| format!("coded symbols broken: {e}");
    // zstd writes every byte it reports, so the buffer is only sized.
    dec.planes.resize(2 * n, 0);
    let got = ZSTD.with_borrow_mut(|z| {
        let zstd = match z {
            Some(z) => z,
            none => none.insert(zstd::bulk::Decompressor::new()?),
        };
        zstd.decompress_to_buffer(coded, &mut dec.planes[..])
    });
    let got = got.map_err(broken)?;
    let (lo, hi) = dec.planes.split_at(n);
    sym.resize(n, 0);
    match got {
        _ if got == n => {
            for (s, &l) in sym.iter_mut().zip(lo) {
                *s = unzig(u16::from(l));
            }
        }
        _ if got == 2 * n => {
            for ((s, &l), &h) in sym.iter_mut().zip(lo).zip(hi) {
                *s = unzig(u16::from(l) | u16::from(h) << 8);
            }
            // A high byte past 1 is a code past the escape (511). A fold
            // with no early exit, so it vectorises.
            let top = hi.iter().fold(0, |m, &h| m.max(h));
            if top > 1 {
                let i = hi.iter().position(|&h| h > 1).unwrap_or(0);
                let z = u16::from(lo[i]) | u16::from(hi[i]) << 8;
                return Err(format!(
                    "symbol code {z} at sample {i} does not exist (the codes end at {})",
                    SYMBOLS - 1
                ));
            }
        }
        _ => {
            return Err(format!(
                "coded symbols hold {got} bytes, not the tile's {n} samples (or twice that)"
            ))
        }
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

    /// `coded`'s symbols for a tile of `n` samples.
    fn decode(coded: &[u8], n: usize) -> Result<Vec<u16>, String> {
        let mut out = Vec::new();
        symbols(coded, n, &mut Decoder::default(), &mut out).map(|()| out)
    }

    #[test]
    fn every_symbol_has_a_code_and_small_residuals_the_small_ones() {
        let codes: Vec<u16> = (0..SYMBOLS).map(zig).collect();
        let mut sorted = codes.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..SYMBOLS as u16).collect::<Vec<_>>());
        for (s, &z) in codes.iter().enumerate() {
            assert_eq!(unzig(z) as usize, s, "code {z}");
        }
        // Residual 0, −1, +1, −2 … take codes 0, 1, 2, 3 …: |r| ≤ 127 fits
        // the low byte, and the escape is the last code.
        let k = K as usize;
        assert_eq!([zig(k), zig(k - 1), zig(k + 1), zig(k - 2)], [0, 1, 2, 3]);
        assert_eq!([zig(k + 127), zig(k - 128), zig(k + 128)], [254, 255, 256]);
        assert_eq!((zig(0), zig(ESCAPE)), (509, 511));
    }

    #[test]
    fn only_a_tile_with_a_large_code_writes_the_high_bytes() {
        let n = 500;
        let k = K as usize;
        let small: Vec<usize> = (0..n).map(|i| k - 128 + i % 256).collect();
        let mut large = small.clone();
        large[99] = k + 128;
        for (sym, planes) in [(&small, n), (&large, 2 * n)] {
            let bytes = encode(0, 0, &[false; 500], &[], sym);
            let p = parts(&bytes, n).unwrap();
            let raw = zstd::bulk::decompress(p.coded, 4 * n).unwrap();
            assert_eq!(raw.len(), planes);
            let got = decode(p.coded, n).unwrap();
            assert_eq!(got.iter().map(|&s| s as usize).collect::<Vec<_>>(), *sym);
        }
    }

    #[test]
    fn a_side_stream_that_runs_past_the_tile_is_an_error() {
        let (n, side) = (40, [7u8; 5]);
        let sym: Vec<usize> = (0..n).map(|i| 255 + i % 3).collect();
        let bytes = tile(n, &side, &sym);
        let p = parts(&bytes, n).unwrap();
        assert_eq!((p.mask.len(), p.side, p.flags), (5, &side[..], MIXED));
        let out = decode(p.coded, n).unwrap();
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
        // The whole rest as the side stream leaves no symbols: nothing
        // decoded, an error, not a panic.
        let mut b = bytes.clone();
        b[1..5].copy_from_slice(&(room as u32).to_le_bytes());
        let p = parts(&b, n).unwrap();
        let e = decode(p.coded, n).unwrap_err();
        assert!(e.contains("hold 0 bytes, not the tile's 40 samples"), "{e}");
    }

    #[test]
    fn codes_past_the_escape_wrong_lengths_and_bytes_after_the_frame_are_errors() {
        let n = 300;
        let good: Vec<usize> = (0..n).map(|i| 250 + i % 11).collect();
        let bytes = encode(0, 0, &[false; 300], &[], &good);
        let p = parts(&bytes, n).unwrap();
        decode(p.coded, n).unwrap();
        // One byte more after the frame.
        let mut longer = p.coded.to_vec();
        longer.push(0);
        let e = decode(&longer, n).unwrap_err();
        assert!(e.contains("coded symbols broken"), "{e}");
        // Fewer or more samples than coded: the frame is not the length
        // the tile's rectangle says.
        let e = decode(p.coded, n - 1).unwrap_err();
        assert!(
            e.contains("hold 300 bytes, not the tile's 299 samples"),
            "{e}"
        );
        let e = decode(p.coded, n + 1).unwrap_err();
        assert!(e.contains("hold 300 bytes, not the tile's 301"), "{e}");
        // Half the samples reads the frame as two planes, whose "high
        // bytes" (the second half's codes, up to 10) make codes past the
        // escape; a frame longer than
        // two planes does not fit the buffer, which zstd refuses.
        let e = decode(p.coded, n / 2).unwrap_err();
        assert!(e.contains("does not exist"), "{e}");
        let e = decode(p.coded, n / 2 - 1).unwrap_err();
        assert!(e.contains("coded symbols broken"), "{e}");
        // A code past the escape (a high byte of 2), which no encoder
        // writes: a frame made by hand.
        let mut planes = vec![0u8; 2 * n];
        planes[n + 7] = 2;
        let forged = zstd::bulk::compress(&planes, 1).unwrap();
        let e = decode(&forged, n).unwrap_err();
        assert!(
            e.contains("symbol code 512 at sample 7 does not exist"),
            "{e}"
        );
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
