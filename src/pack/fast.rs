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
//! code width              u8: 2, 4, 8 or 16 bits
//! symbols                 one zstd frame of the tile's n symbols in coding
//!                         order, each as its zigzagged residual z (0..=510,
//!                         the escape 511): at 2 and 4 bits, 4 and 2 codes
//!                         a byte, the first in the low bits; at 8, a byte
//!                         each; at 16, the n low bytes, then the n high
//! ```
//!
//! zstd (the `zstd` crate, bindings to the reference C library) was chosen
//! over pcodec, which coded these symbols before: on the same symbols of
//! jacksboro and etopo5 at E = 1 m its frames decode 2.2 to 4.4 times
//! faster (Huffman-coded literals, decoded four streams at a time, and runs
//! of equal bytes as matches) for a size within 1.5 % either way
//! (docs/explanation/pack-codecs.md). Writing no entropy coder of our own
//! keeps a fuzzed, widely deployed decoder between a hostile file and the
//! heights. Zigzag keeps the common small residuals in small codes, and a
//! tile takes the narrowest width that holds its largest: Huffman spends at
//! least a bit a byte, so a smooth tile whose residuals are mostly 0 and
//! ±1 packs four codes a byte (jacksboro's pack at E = 4 m 6 % smaller and
//! a procedural map's at 1 m 8 % smaller than a byte a code).

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
    let bits = width(z.iter().fold(0, |m, &z| m.max(z)));
    let planes: Vec<u8> = match bits {
        16 => z
            .iter()
            .map(|&z| z as u8)
            .chain(z.iter().map(|&z| (z >> 8) as u8))
            .collect(),
        _ => z
            .chunks(8 / bits as usize)
            .map(|c| {
                c.iter()
                    .enumerate()
                    .fold(0u8, |b, (j, &z)| b | (z as u8) << (j * bits as usize))
            })
            .collect(),
    };
    out.push(bits);
    // Compressing a slice in memory fails only on a bug.
    let frame = zstd::bulk::compress(&planes, LEVEL).expect("zstd compresses a slice");
    out.extend_from_slice(&frame);
    out
}

/// The fewest bits of 2, 4, 8 and 16 that hold codes up to `top`.
fn width(top: u16) -> u8 {
    match top {
        0..=3 => 2,
        4..=15 => 4,
        16..=255 => 8,
        _ => 16,
    }
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

/// Decodes the `n` symbols of `coded` (their width, then the frame) into
/// `sym`, with `dec`'s buffers. The frame must hold exactly the bytes of n
/// codes of that width. zstd decodes in one shot into a buffer of that
/// length, which the tile's rectangle sizes, never the frame's header: a
/// frame that says it is larger is zstd's error, and one-shot decoding
/// keeps no window of its own, so a forged window size allocates nothing
/// either.
pub(crate) fn symbols(
    coded: &[u8],
    n: usize,
    dec: &mut Decoder,
    sym: &mut Vec<u16>,
) -> Result<(), String> {
    let (&bits, frame) = coded
        .split_first()
        .ok_or("no coded symbols (not even their width)")?;
    let len = match bits {
        2 => n.div_ceil(4),
        4 => n.div_ceil(2),
        8 => n,
        16 => 2 * n,
        _ => {
            return Err(format!(
                "symbol codes {bits} bits wide do not exist (2, 4, 8 or 16)"
            ))
        }
    };
    let broken = |e: std::io::Error| format!("coded symbols broken: {e}");
    // zstd writes every byte it reports, so the buffer is only sized.
    dec.planes.resize(len, 0);
    let got = ZSTD.with_borrow_mut(|z| {
        let zstd = match z {
            Some(z) => z,
            none => none.insert(zstd::bulk::Decompressor::new()?),
        };
        zstd.decompress_to_buffer(frame, &mut dec.planes[..])
    });
    let got = got.map_err(broken)?;
    if got != len {
        return Err(format!(
            "coded symbols hold {got} bytes, not the {len} of {n} {bits}-bit codes"
        ));
    }
    sym.resize(n, 0);
    match bits {
        2 => unpack::<4>(&dec.planes, sym),
        4 => unpack::<2>(&dec.planes, sym),
        8 => {
            for (s, &l) in sym.iter_mut().zip(&dec.planes) {
                *s = unzig(u16::from(l));
            }
        }
        _ => {
            let (lo, hi) = dec.planes.split_at(n);
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
    }
    Ok(())
}

/// The symbols of `PER` codes a byte (each 8 / `PER` bits, the first in
/// the low bits) in `bytes` into `sym`; a last byte's unused codes are
/// ignored.
fn unpack<const PER: usize>(bytes: &[u8], sym: &mut [u16]) {
    let bits = 8 / PER;
    let mask = (1u8 << bits) - 1;
    let full = sym.len() / PER;
    let mut whole = sym.chunks_exact_mut(PER);
    for (c, &b) in (&mut whole).zip(bytes) {
        for (j, s) in c.iter_mut().enumerate() {
            *s = unzig(u16::from(b >> (j * bits) & mask));
        }
    }
    let rest = whole.into_remainder();
    if let Some(&b) = bytes.get(full) {
        for (j, s) in rest.iter_mut().enumerate() {
            *s = unzig(u16::from(b >> (j * bits) & mask));
        }
    }
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
    fn a_tile_takes_the_narrowest_width_of_its_codes_at_any_length() {
        let k = K as usize;
        // Symbols whose largest code is 3, 15, 255 and 256: each a width.
        for (top, bits, per) in [(k - 2, 2, 4.0), (k - 8, 4, 2.0), (k - 128, 8, 1.0)]
            .into_iter()
            .chain([(k + 128, 16, 0.5)])
        {
            for n in 1..=11 {
                // Every code up to the top, the top last.
                let mut sym: Vec<usize> = (0..n - 1).map(|i| k - i % 2).collect();
                sym.push(top);
                let bytes = encode(0, 0, &vec![false; n], &[], &sym);
                let p = parts(&bytes, n).unwrap();
                assert_eq!(p.coded[0], bits, "{n} samples");
                let raw = zstd::bulk::decompress(&p.coded[1..], 4 * n).unwrap();
                assert_eq!(raw.len(), (n as f64 / per).ceil() as usize);
                let got = decode(p.coded, n).unwrap();
                assert_eq!(
                    got.iter().map(|&s| s as usize).collect::<Vec<_>>(),
                    sym,
                    "{bits} bits, {n} samples"
                );
            }
        }
        assert_eq!([width(0), width(3), width(4), width(15)], [2, 2, 4, 4]);
        assert_eq!(
            [width(16), width(255), width(256), width(511)],
            [8, 8, 16, 16]
        );
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
        // The whole rest as the side stream leaves no symbols: an error,
        // not a panic.
        let mut b = bytes.clone();
        b[1..5].copy_from_slice(&(room as u32).to_le_bytes());
        let p = parts(&b, n).unwrap();
        let e = decode(p.coded, n).unwrap_err();
        assert!(e.contains("not even their width"), "{e}");
    }

    #[test]
    fn codes_past_the_escape_wrong_lengths_and_bytes_after_the_frame_are_errors() {
        let n = 300;
        // Residuals −15..=15: codes up to 30, a byte each.
        let good: Vec<usize> = (0..n).map(|i| 240 + i % 31).collect();
        let bytes = encode(0, 0, &[false; 300], &[], &good);
        let p = parts(&bytes, n).unwrap();
        assert_eq!(p.coded[0], 8);
        decode(p.coded, n).unwrap();
        // One byte more after the frame.
        let mut longer = p.coded.to_vec();
        longer.push(0);
        let e = decode(&longer, n).unwrap_err();
        assert!(e.contains("coded symbols broken"), "{e}");
        // Fewer or more samples than coded: the frame is not the length
        // the tile's rectangle says; one larger than the buffer is zstd's
        // error.
        let e = decode(p.coded, n + 1).unwrap_err();
        assert!(
            e.contains("hold 300 bytes, not the 301 of 301 8-bit codes"),
            "{e}"
        );
        let e = decode(p.coded, n - 1).unwrap_err();
        assert!(e.contains("coded symbols broken"), "{e}");
        // Another width read from the same frame: 4-bit codes want 150
        // bytes, 16-bit ones 600.
        for (bits, want) in [
            (4u8, "not the 150 of 300 4-bit"),
            (16, "not the 600 of 300 16-bit"),
        ] {
            let mut other = p.coded.to_vec();
            other[0] = bits;
            let e = decode(&other, n).unwrap_err();
            assert!(e.contains(want) || e.contains("broken"), "{bits}: {e}");
        }
        // A width that does not exist, and no width at all.
        let mut other = p.coded.to_vec();
        other[0] = 3;
        let e = decode(&other, n).unwrap_err();
        assert!(e.contains("codes 3 bits wide do not exist"), "{e}");
        let e = decode(&[], n).unwrap_err();
        assert!(e.contains("not even their width"), "{e}");
        // A code past the escape (a high byte of 2), which no encoder
        // writes: a frame made by hand.
        // Sample 3's high byte of 1 (code 256) is a code that exists.
        let mut planes = vec![0u8; 2 * n];
        planes[n + 3] = 1;
        planes[n + 7] = 2;
        let forged = [&[16u8][..], &zstd::bulk::compress(&planes, 1).unwrap()].concat();
        let e = decode(&forged, n).unwrap_err();
        assert!(
            e.contains("symbol code 512 at sample 7 does not exist"),
            "{e}"
        );
    }

    #[test]
    fn a_tile_cut_in_its_header_or_mask_is_an_error_and_its_count_reads_back() {
        let n = 40;
        let nodata: Vec<bool> = (0..n).map(|i| i % 3 == 0).collect();
        // A count whose four bytes differ, so each byte's place is read.
        let count = 0x0403_0201;
        let bytes = encode(MIXED, count, &nodata, &[9, 9], &[255; 40]);
        let p = parts(&bytes, n).unwrap();
        assert_eq!((p.count, p.mask.len(), p.side), (count, 5, &[9u8, 9][..]));
        // Cut inside the header: shorter than it, never a read past it.
        for len in 0..HEADER {
            let e = parts(&bytes[..len], n).err().expect("refused");
            assert!(e.contains("shorter than the 9-byte header"), "{len}: {e}");
        }
        // Cut inside the mask (the side stream's length says 2): the
        // mask does not fit, never a slice past the end.
        for len in HEADER..HEADER + 5 {
            let e = parts(&bytes[..len], n).err().expect("refused");
            assert!(e.contains("no-data mask of 5 bytes"), "{len}: {e}");
        }
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
