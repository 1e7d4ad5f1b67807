//! What the fuzz harnesses share: a reproducible generator and the
//! byte- and token-level mutations they damage files with.

/// xorshift64*: the harness must be reproducible.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Byte-level mutations: truncation, bit flips, 32-bit fields overwritten
/// with extreme values (huge sizes in headers), appended garbage.
pub fn mutate(rng: &mut Rng, seed: &[u8]) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(3) {
        match rng.below(5) {
            0 => {
                let n = rng.below(b.len() + 1);
                b.truncate(n);
            }
            1 => {
                for _ in 0..1 + rng.below(8) {
                    if !b.is_empty() {
                        let i = rng.below(b.len());
                        b[i] ^= 1 << rng.below(8);
                    }
                }
            }
            2 => {
                // Header fields are near the start: aim there half the time.
                let span = if rng.below(2) == 0 {
                    b.len().min(64)
                } else {
                    b.len()
                };
                if span >= 4 {
                    let i = rng.below(span - 3);
                    let v: u32 = [u32::MAX, 0x7FFF_FFFF, 0, 0x0001_0000, 65_535][rng.below(5)];
                    let bytes = if rng.below(2) == 0 {
                        v.to_be_bytes()
                    } else {
                        v.to_le_bytes()
                    };
                    b[i..i + 4].copy_from_slice(&bytes);
                }
            }
            3 => {
                let n = rng.below(64);
                b.extend((0..n).map(|_| rng.next() as u8));
            }
            _ => {
                if !b.is_empty() {
                    let i = rng.below(b.len());
                    b[i] = rng.next() as u8;
                }
            }
        }
    }
    b
}

/// Token-level mutations of text files: numbers become NaN, inf, huge,
/// negative or no-data values, strings and keys change type or vanish.
pub fn mutate_text(rng: &mut Rng, seed: &str) -> String {
    let mut tokens: Vec<String> = seed
        .split_inclusive(|c: char| c.is_whitespace() || c == ',' || c == '=')
        .map(String::from)
        .collect();
    let swaps = [
        "nan",
        "inf",
        "-inf",
        "1e400",
        "-1",
        "0",
        "16",
        "1e12",
        "NaN",
        "\"x\"",
        "[]",
        "true",
        "-9999",
        "4294967297",
        "18446744073709551617",
        "{}",
        "",
        "0.0",
        "2.5",
    ];
    for _ in 0..1 + rng.below(3) {
        let i = rng.below(tokens.len());
        let tail: String = tokens[i]
            .chars()
            .rev()
            .take_while(|c| c.is_whitespace() || *c == ',' || *c == '=')
            .collect();
        let tail: String = tail.chars().rev().collect();
        tokens[i] = match rng.below(4) {
            0 => tail,
            _ => format!("{}{tail}", swaps[rng.below(swaps.len())]),
        };
    }
    let mut s: String = tokens.concat();
    if rng.below(4) == 0 {
        let n = rng.below(s.len() + 1);
        s = s.chars().take(n).collect();
    }
    s
}
