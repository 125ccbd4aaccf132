//! The seeded mutator: one input = a seed file changed by 1–8 mutations, all drawn from a PCG
//! stream seeded by (run seed, target, input index), so input `i` of a run can be rebuilt alone.
//!
//! Byte-level mutations (AFL's havoc stage, in spirit): bit flips, "interesting" bytes and
//! 16/32/64-bit integers in either byte order, random inserts, deletes, chunk duplication and
//! repetition, splices from another seed, truncation. Text formats add structure-aware ones
//! that keep most of the file valid so the parser goes deep: a number token replaced by NaN,
//! ±inf, huge, negative, zero or an integer at a type's edge; lines deleted, duplicated,
//! swapped, truncated or taken from another seed; a token of the target's dictionary (YAML
//! anchors and aliases, brackets, keywords…) inserted or repeated thousands of times (deep
//! nesting); a line repeated (duplicate YAML keys, extra records).

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// Longest input the mutator produces (bytes).
pub const MAX_LEN: usize = 1 << 20;

/// The random stream of input `index` of target `target` in run `seed`.
pub fn input_rng(seed: u64, target: &str, index: u64) -> Pcg64 {
    let mut h = blake3::Hasher::new();
    h.update(b"vfxgraph-fuzz-v1");
    h.update(&seed.to_le_bytes());
    h.update(target.as_bytes());
    h.update(&index.to_le_bytes());
    let mut s = [0u8; 32];
    s.copy_from_slice(h.finalize().as_bytes());
    Pcg64::from_seed(s)
}

/// Which family of mutations suits a format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Text: structure-aware text mutations most of the time, byte mutations sometimes.
    Text,
    /// Binary: byte mutations only.
    Binary,
    /// No mutation: input `i` is the decimal text of `i` (the harness's self-test target,
    /// [`crate::targets::probe`]).
    Index,
}

/// Replacements for a number token: the values that break naive parsers.
const NUMBERS: &[&str] = &[
    "NaN",
    "nan",
    "inf",
    "-inf",
    "infinity",
    "1e308",
    "-1e308",
    "1e309",
    "1e-320",
    "-0",
    "0",
    "-1",
    "1",
    "2",
    "255",
    "256",
    "65535",
    "65536",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "9223372036854775808",
    "-9223372036854775808",
    "-9223372036854775809",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999",
    "1e10",
    "0.5",
    "-0.5",
    "0x10",
    "1_000",
    "",
];

const INTERESTING_8: &[u8] = &[0, 1, 0x7f, 0x80, 0xff, 0xfe, b'\n', b' ', b'0', b'-'];
const INTERESTING_32: &[u32] = &[
    0,
    1,
    2,
    0x7f,
    0x80,
    0xff,
    0x100,
    0x7fff,
    0x8000,
    0xffff,
    0x10000,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
];

/// Makes one mutated input from `seeds` (at least one) with the target's `dict`.
pub fn mutate(rng: &mut Pcg64, seeds: &[Vec<u8>], kind: Kind, dict: &[&str]) -> Vec<u8> {
    let mut data = seeds[rng.random_range(0..seeds.len())].clone();
    let n = 1 + (rng.random::<u32>().trailing_zeros() as usize).min(7);
    for _ in 0..n {
        let text = kind == Kind::Text && rng.random_bool(0.8);
        if text {
            text_mutation(rng, &mut data, seeds, dict);
        } else {
            byte_mutation(rng, &mut data, seeds);
        }
        data.truncate(MAX_LEN);
    }
    data
}

/// A position in `0..=len`.
fn pos(rng: &mut Pcg64, len: usize) -> usize {
    rng.random_range(0..=len)
}

/// A range inside `0..len` of at most `max` bytes (empty when `len` is 0).
fn range(rng: &mut Pcg64, len: usize, max: usize) -> std::ops::Range<usize> {
    if len == 0 {
        return 0..0;
    }
    let a = rng.random_range(0..len);
    let l = rng.random_range(1..=max.clamp(1, len - a));
    a..a + l
}

/// A count from 1 to `max`, log-uniform (small counts common, large ones possible).
fn count(rng: &mut Pcg64, max: usize) -> usize {
    let bits = usize::BITS - max.leading_zeros();
    let k = rng.random_range(0..bits);
    rng.random_range(1..=(1usize << k).min(max))
}

fn byte_mutation(rng: &mut Pcg64, data: &mut Vec<u8>, seeds: &[Vec<u8>]) {
    let len = data.len();
    match rng.random_range(0..11) {
        0 if len > 0 => {
            let i = rng.random_range(0..len);
            data[i] ^= 1 << rng.random_range(0..8);
        }
        1 if len > 0 => {
            let i = rng.random_range(0..len);
            data[i] = INTERESTING_8[rng.random_range(0..INTERESTING_8.len())];
        }
        2 if len >= 2 => {
            let v = INTERESTING_32[rng.random_range(0..INTERESTING_32.len())];
            let width = [2usize, 4, 8][rng.random_range(0..3)].min(len);
            let mut bytes = (v as u64).to_le_bytes();
            if rng.random_bool(0.5) {
                // Sign-extend: -1, -2 … as wide integers.
                if v & 0x8000_0000 != 0 {
                    bytes = (v as i32 as i64).to_le_bytes();
                }
            }
            let mut b = bytes[..width].to_vec();
            if rng.random_bool(0.5) {
                b.reverse();
            }
            let i = rng.random_range(0..=len - width);
            data[i..i + width].copy_from_slice(&b);
        }
        3 => {
            let at = pos(rng, len);
            let k = count(rng, 32);
            let ins: Vec<u8> = (0..k).map(|_| rng.random()).collect();
            data.splice(at..at, ins);
        }
        4 if len > 0 => {
            let r = range(rng, len, (len / 4).max(1));
            data.drain(r);
        }
        5 if len > 0 => {
            // Duplicate a chunk somewhere else.
            let r = range(rng, len, 256);
            let chunk = data[r].to_vec();
            let at = pos(rng, len);
            data.splice(at..at, chunk);
        }
        6 if len > 0 => {
            // Repeat a short chunk many times in place.
            let r = range(rng, len, 8);
            let chunk = data[r.clone()].to_vec();
            let k = count(rng, 4096);
            let rep: Vec<u8> = chunk
                .iter()
                .copied()
                .cycle()
                .take(chunk.len() * k)
                .collect();
            data.splice(r.end..r.end, rep);
        }
        7 => {
            // Splice: a chunk of another seed over or into this one.
            let other = &seeds[rng.random_range(0..seeds.len())];
            if !other.is_empty() {
                let r = range(rng, other.len(), 4096);
                let chunk = other[r].to_vec();
                let at = pos(rng, len);
                if rng.random_bool(0.5) {
                    let end = (at + chunk.len()).min(len);
                    data.splice(at..end, chunk);
                } else {
                    data.splice(at..at, chunk);
                }
            }
        }
        8 if len > 0 => {
            data.truncate(rng.random_range(0..len));
        }
        9 if len > 0 => {
            let r = range(rng, len, 16);
            for b in &mut data[r] {
                *b = rng.random();
            }
        }
        _ => {
            if len > 0 {
                let i = rng.random_range(0..len);
                data[i] = data[i]
                    .wrapping_add(rng.random_range(1..=35))
                    .wrapping_sub(17);
            }
        }
    }
}

/// Byte ranges of number-like tokens (digits with signs, dots, exponents).
fn number_tokens(data: &[u8]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < data.len() {
        let start = i;
        let mut digit = false;
        while i < data.len() && matches!(data[i], b'0'..=b'9' | b'.' | b'-' | b'+' | b'e' | b'E') {
            digit |= data[i].is_ascii_digit();
            i += 1;
        }
        if digit {
            out.push(start..i);
        }
        if i == start {
            i += 1;
        }
    }
    out
}

/// Byte ranges of the lines (without their `\n`).
fn lines(data: &[u8]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &b) in data.iter().enumerate() {
        if b == b'\n' {
            out.push(start..i);
            start = i + 1;
        }
    }
    if start < data.len() {
        out.push(start..data.len());
    }
    out
}

fn text_mutation(rng: &mut Pcg64, data: &mut Vec<u8>, seeds: &[Vec<u8>], dict: &[&str]) {
    match rng.random_range(0..9) {
        0..=2 => {
            let toks = number_tokens(data);
            if toks.is_empty() {
                return byte_mutation(rng, data, seeds);
            }
            let r = toks[rng.random_range(0..toks.len())].clone();
            let new: Vec<u8> = if rng.random_bool(0.85) {
                NUMBERS[rng.random_range(0..NUMBERS.len())]
                    .as_bytes()
                    .to_vec()
            } else {
                // A nearby integer or the number with its last digit changed.
                let v: i64 = rng.random_range(-3..300);
                v.to_string().into_bytes()
            };
            data.splice(r, new);
        }
        3 => {
            let ls = lines(data);
            if ls.is_empty() {
                return;
            }
            let l = ls[rng.random_range(0..ls.len())].clone();
            match rng.random_range(0..4) {
                0 => {
                    let end = (l.end + 1).min(data.len());
                    data.drain(l.start..end);
                }
                1 => {
                    // Duplicate the line (duplicate keys, extra records), k times.
                    let mut line = data[l.clone()].to_vec();
                    line.push(b'\n');
                    let k = count(rng, 64);
                    let rep: Vec<u8> = line.iter().copied().cycle().take(line.len() * k).collect();
                    data.splice(l.start..l.start, rep);
                }
                2 => {
                    let cut = rng.random_range(l.start..=l.end);
                    data.drain(cut..l.end);
                }
                _ => {
                    let m = ls[rng.random_range(0..ls.len())].clone();
                    let (a, b) = if l.start <= m.start { (l, m) } else { (m, l) };
                    if a.end <= b.start {
                        let (la, lb) = (data[a.clone()].to_vec(), data[b.clone()].to_vec());
                        data.splice(b, la);
                        data.splice(a, lb);
                    }
                }
            }
        }
        4 => {
            // A line of another seed inserted at a line start.
            let other = &seeds[rng.random_range(0..seeds.len())];
            let ol = lines(other);
            if ol.is_empty() {
                return;
            }
            let mut line = other[ol[rng.random_range(0..ol.len())].clone()].to_vec();
            line.push(b'\n');
            let ls = lines(data);
            let at = if ls.is_empty() {
                0
            } else {
                ls[rng.random_range(0..ls.len())].start
            };
            data.splice(at..at, line);
        }
        5 | 6 if !dict.is_empty() => {
            let tok = dict[rng.random_range(0..dict.len())].as_bytes();
            let at = pos(rng, data.len());
            data.splice(at..at, tok.iter().copied());
        }
        7 if !dict.is_empty() => {
            // A dictionary token repeated many times (deep nesting, long lists).
            let tok = dict[rng.random_range(0..dict.len())].as_bytes();
            let k = count(rng, 20_000);
            let rep: Vec<u8> = tok.iter().copied().cycle().take(tok.len() * k).collect();
            let at = pos(rng, data.len());
            data.splice(at..at, rep);
        }
        _ => byte_mutation(rng, data, seeds),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_depends_only_on_seed_target_and_index() {
        let seeds = vec![b"a: 1\nb: [2, 3.5]\n".to_vec(), b"x y z\n1 2 3\n".to_vec()];
        let make = |s, t: &str, i| mutate(&mut input_rng(s, t, i), &seeds, Kind::Text, &["&a "]);
        assert_eq!(make(1, "t", 5), make(1, "t", 5));
        let distinct: std::collections::HashSet<Vec<u8>> =
            (0..200).map(|i| make(1, "t", i)).collect();
        assert!(
            distinct.len() > 150,
            "only {} distinct inputs of 200",
            distinct.len()
        );
        assert_ne!(make(1, "t", 5), make(2, "t", 5));
        assert_ne!(make(1, "t", 5), make(1, "u", 5));
    }

    #[test]
    fn number_tokens_and_lines_are_found() {
        let t = b"Frame 12\n-1.5e3 x 7\n";
        let toks: Vec<&[u8]> = number_tokens(t).into_iter().map(|r| &t[r]).collect();
        assert_eq!(toks, [&b"12"[..], b"-1.5e3", b"7"]);
        assert_eq!(lines(t), [0..8, 9..19]);
        assert_eq!(lines(b"a\nb"), [0..1, 2..3]);
    }
}
