//! What the fuzz harnesses share: a reproducible generator and the
//! byte-, token- and tree-level mutations they damage files with.

use serde_json::{json, Value};

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

/// One edit of a JSON tree: a node chosen at random is changed for
/// another number, another string, fewer or more elements, a key removed
/// or unknown, or wrapped in an array or object.
pub fn edit_json(rng: &mut Rng, v: &mut Value) {
    let mut nodes = 0;
    count(v, &mut nodes);
    let target = rng.below(nodes);
    let mut at = 0;
    edit_at(rng, v, target, &mut at);
}

fn count(v: &Value, n: &mut usize) {
    *n += 1;
    match v {
        Value::Array(a) => a.iter().for_each(|v| count(v, n)),
        Value::Object(o) => o.values().for_each(|v| count(v, n)),
        _ => {}
    }
}

fn edit_at(rng: &mut Rng, v: &mut Value, target: usize, at: &mut usize) -> bool {
    if *at == target {
        edit_node(rng, v);
        return true;
    }
    *at += 1;
    match v {
        Value::Array(a) => a.iter_mut().any(|v| edit_at(rng, v, target, at)),
        Value::Object(o) => o.values_mut().any(|v| edit_at(rng, v, target, at)),
        _ => false,
    }
}

fn edit_node(rng: &mut Rng, v: &mut Value) {
    // Wrapping in another level of nesting, any node.
    if rng.below(12) == 0 {
        *v = if rng.below(2) == 0 {
            json!([v.clone()])
        } else {
            json!({ "v": v.clone() })
        };
        return;
    }
    match v {
        Value::Number(n) => {
            let x = n.as_f64().unwrap();
            let swaps = [
                0.0,
                -1.0,
                1.0,
                2.0,
                3.0,
                1e12,
                4294967297.0,
                1.8e19,
                -1e-30,
                1e39,
                3.4e38,
                x * 2.0,
                x + 1.0,
                x - 1.0,
                x / 2.0,
                x + 0.25,
                x * 0.999,
            ];
            let y = swaps[rng.below(swaps.len())];
            *v = if y.fract() == 0.0 && y.abs() < 1e15 && n.is_u64() && y >= 0.0 {
                json!(y as u64)
            } else {
                json!(y)
            };
        }
        Value::String(_) => {
            let s = [
                "",
                "x",
                "sinc-blackman:3",
                "box",
                "lanczos:3",
                "sinc-blackman:11",
            ];
            *v = match rng.below(4) {
                0 => json!(1),
                _ => json!(s[rng.below(s.len())]),
            };
        }
        Value::Array(a) => match rng.below(4) {
            0 if !a.is_empty() => {
                a.remove(rng.below(a.len()));
            }
            1 if !a.is_empty() => {
                let e = a[rng.below(a.len())].clone();
                a.insert(rng.below(a.len() + 1), e);
            }
            2 if a.len() >= 2 => {
                let (i, j) = (rng.below(a.len()), rng.below(a.len()));
                a.swap(i, j);
            }
            _ => a.push(json!(0)),
        },
        Value::Object(o) => {
            let keys: Vec<String> = o.keys().cloned().collect();
            match rng.below(3) {
                0 if !keys.is_empty() => {
                    o.remove(&keys[rng.below(keys.len())]);
                }
                1 if !keys.is_empty() => {
                    let k = &keys[rng.below(keys.len())];
                    let val = o.remove(k).unwrap();
                    o.insert(format!("{k}_"), val);
                }
                _ => {
                    o.insert("extra".into(), json!(1));
                }
            }
        }
        Value::Bool(b) => *b = !*b,
        Value::Null => *v = json!(0),
    }
}

/// `terraclip ARGS` (the binary of the test target being built): an exit
/// with a code, never a signal; a failure that names `file`, without a
/// panic (a comparison that fails is an exit of 1
/// with its report, not an error: it need not name the file).
pub fn cli_exits(args: &[&std::ffi::OsStr], file: &str) -> Result<(), String> {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_terraclip"))
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    match out.status.code() {
        None => Err(format!("killed by a signal: {:?}", out.status)),
        Some(0) => Ok(()),
        Some(_) if err.contains("panicked") => Err(format!("panicked: {err}")),
        Some(_) if err.contains(file) || err.contains("does not match") => Ok(()),
        Some(c) => Err(format!("exit {c} naming no {file}: {err}")),
    }
}
