//! The text of the contract's OBJ files, built fast without changing a byte.
//!
//! `crease deep apply` writes one OBJ per frame; formatting its numbers with `format!("{}")` was most of the
//! CPU time of the default apply. Two things make it cheap while keeping the files byte-identical to what
//! `{}` writes (shortest digits that read back to the same f64, never an exponent, so every reader gets the
//! exact positions back):
//! - the `vt` and `f` lines never change within a model, so they are formatted once ([`ObjText`]);
//! - the `v` numbers go through ryu (shortest round-trip digits, like std's) and are reshaped to std's
//!   notation; the one case where the two may choose different digits — a value exactly halfway between two
//!   shortest candidates — is detected exactly and handed to std ([`push_f64`]).

use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use std::io::Write;

/// First line of every contract OBJ.
pub const HEADER: &str = "# crease deep: coarse mesh with the normal map's UV layout\n";

/// The constant part of a contract OBJ (the `vt` and `f` lines of one layout), formatted once; each frame adds
/// its `v` lines in front.
#[derive(Debug, Clone)]
pub struct ObjText {
    tail: Vec<u8>,
    n_vertices: usize,
}

impl ObjText {
    /// `uv` per layout corner, `corners` per triangle (indices into `uv`), faces `f v/vt` 1-based.
    pub fn new(topo: &Topology, uv: &[[f64; 2]], corners: &[[u32; 3]]) -> Self {
        let mut tail = Vec::with_capacity(40 * uv.len() + 48 * topo.n_triangles());
        for t in uv {
            tail.extend_from_slice(b"vt ");
            push_f64(&mut tail, t[0]);
            tail.push(b' ');
            push_f64(&mut tail, t[1]);
            tail.push(b'\n');
        }
        let mut ints = itoa_buf();
        for (tri, c) in topo.triangles().iter().zip(corners) {
            tail.push(b'f');
            for k in 0..3 {
                tail.push(b' ');
                push_u64(&mut tail, &mut ints, tri[k] as u64 + 1);
                tail.push(b'/');
                push_u64(&mut tail, &mut ints, c[k] as u64 + 1);
            }
            tail.push(b'\n');
        }
        ObjText {
            tail,
            n_vertices: topo.n_vertices(),
        }
    }

    /// The header and `v` lines of one frame, into `head` (cleared first); the file is `head` then
    /// [`ObjText::tail`].
    pub fn head(&self, positions: &[V3], head: &mut Vec<u8>) {
        debug_assert_eq!(positions.len(), self.n_vertices);
        head.clear();
        head.reserve(HEADER.len() + 64 * positions.len());
        head.extend_from_slice(HEADER.as_bytes());
        for p in positions {
            head.extend_from_slice(b"v ");
            push_f64(head, p[0]);
            head.push(b' ');
            push_f64(head, p[1]);
            head.push(b' ');
            push_f64(head, p[2]);
            head.push(b'\n');
        }
    }

    /// The `vt` and `f` lines.
    pub fn tail(&self) -> &[u8] {
        &self.tail
    }

    /// The whole file of one frame (for callers that write a single OBJ).
    pub fn file(&self, positions: &[V3]) -> Vec<u8> {
        let mut bytes = Vec::new();
        self.head(positions, &mut bytes);
        bytes.extend_from_slice(&self.tail);
        bytes
    }
}

fn itoa_buf() -> [u8; 20] {
    [0; 20]
}

/// Appends the decimal digits of `v` (what `{}` writes for an integer).
fn push_u64(out: &mut Vec<u8>, buf: &mut [u8; 20], mut v: u64) {
    let mut i = buf.len();
    loop {
        i -= 1;
        buf[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    out.extend_from_slice(&buf[i..]);
}

/// Appends `x` exactly as `format!("{x}")` writes it: the shortest digits that read back to `x`, in plain
/// decimal notation (`0.0001`, `1`, `-0`, `1000000000000000000000`).
pub fn push_f64(out: &mut Vec<u8>, x: f64) {
    if !x.is_finite() {
        let _ = write!(out, "{x}");
        return;
    }
    let mut buf = ryu::Buffer::new();
    let s = buf.format_finite(x).as_bytes();
    // ryu writes plain decimals for 1e-5 ≤ |x| < 1e16 (and 0), with ".0" after an integer; std never does.
    if s.contains(&b'e') || may_tie(x) && is_tie(x, s) {
        let _ = write!(out, "{x}");
        return;
    }
    let s = s.strip_suffix(b".0").unwrap_or(s);
    out.extend_from_slice(s);
}

/// `x = m · 2^e` with `m` odd (`None` for zero).
fn odd_mantissa(x: f64) -> Option<(u64, i32)> {
    let bits = x.abs().to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i32;
    let frac = bits & ((1u64 << 52) - 1);
    let (m, e) = if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1u64 << 52), exp - 1075)
    };
    if m == 0 {
        return None;
    }
    let tz = m.trailing_zeros();
    Some((m >> tz, e + tz as i32))
}

/// A cheap necessary condition for a tie: a midpoint has at most 18 significant digits ending in 5, so it is
/// N · 10^q with N odd and below 10^19; equal to m · 2^e (m odd) it needs e = q and m · 5^(−q) = N, hence
/// 5^(−e) < 10^19, e ≥ −27. (Values with e ≥ 0 are integers: below 2^53 their digits are exact, so no tie;
/// above, the full test decides.)
fn may_tie(x: f64) -> bool {
    matches!(odd_mantissa(x), Some((_, e)) if e >= -27)
}

/// Whether `x` lies exactly halfway between `s` (ryu's plain-decimal digits of `x`) and the number one unit
/// away in its last digit: there "shortest, then closest" has two answers and ryu and std may pick differently.
fn is_tie(x: f64, s: &[u8]) -> bool {
    let Some((m, e)) = odd_mantissa(x) else {
        return false;
    };
    // The digits as an integer D and the exponent of its last digit: |x| ≈ D · 10^last.
    let (mut d, mut frac_digits, mut seen_point, mut n_digits) = (0u64, 0i32, false, 0u32);
    for &c in s {
        match c {
            b'-' => {}
            b'.' => seen_point = true,
            c @ b'0'..=b'9' => {
                if d == 0 && c == b'0' {
                    if seen_point {
                        frac_digits += 1;
                    }
                    continue;
                }
                n_digits += 1;
                if n_digits > 18 {
                    return false; // not a shortest representation (cannot happen)
                }
                d = d * 10 + (c - b'0') as u64;
                if seen_point {
                    frac_digits += 1;
                }
            }
            _ => return false, // an exponent: not the plain form this is called with
        }
    }
    // Trailing zeros of an integer part ("100.0") carry no digits: strip them into the exponent.
    let mut last = -frac_digits;
    while d != 0 && d % 10 == 0 {
        d /= 10;
        last += 1;
    }
    // The midpoints are (10·D ± 5) · 10^(last − 1), odd multiples of a power of ten.
    let q = last - 1;
    if e != q {
        return false;
    }
    let equals = |n: u128| -> bool {
        let (mut lhs, rhs) = if q < 0 {
            (m as u128, n)
        } else {
            (n, m as u128)
        };
        for _ in 0..q.unsigned_abs() {
            lhs = match lhs.checked_mul(5) {
                Some(v) if v <= rhs => v,
                _ => return false,
            };
        }
        lhs == rhs
    };
    let d = d as u128;
    equals(10 * d + 5) || (d > 0 && equals(10 * d - 5))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn std_text(x: f64) -> String {
        format!("{x}")
    }

    fn ours(x: f64) -> String {
        let mut v = Vec::new();
        push_f64(&mut v, x);
        String::from_utf8(v).unwrap()
    }

    #[test]
    fn numbers_are_written_as_std_writes_them() {
        let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut ties = 0;
        for i in 0..400_000u64 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let u = (s >> 11) as f64 / (1u64 << 53) as f64;
            let x = match i % 8 {
                0 => f64::from_bits(s),
                1 => u - 0.5,
                2 => u * 1e-3,
                3 => (s % 100_000) as f64 / 1000.0,
                // Exact midpoints between two shortest candidates (ryu and std round these differently).
                4 => (s >> 12) as f64 + 0.5,
                5 => ((s >> 16) | (1 << 44)) as f64 + ((s & 7) | 1) as f64 / 8.0,
                6 => (u as f32) as f64 * 0.3,
                _ => f64::from_bits(s) * 1e-300,
            };
            if x.is_finite()
                && may_tie(x)
                && is_tie(x, ryu::Buffer::new().format_finite(x).as_bytes())
            {
                ties += 1;
            }
            assert_eq!(ours(x), std_text(x), "{x:e} (bits {:#x})", x.to_bits());
        }
        // The midpoint cases really occurred (the test would not see a broken tie rule otherwise).
        assert!(ties > 1000, "{ties} ties");
        for x in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            100.0,
            1e-5,
            9.99e-6,
            1e15,
            1e16,
            1e21,
            0.1,
            0.3,
            2.5,
            5e-324,
            -5e-324,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            9_007_199_254_740_993.0,
            233_115_890_514_796.12,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            assert_eq!(ours(x), std_text(x), "{x:e}");
        }
    }

    #[test]
    fn integers_are_written_as_std_writes_them() {
        let mut buf = itoa_buf();
        for v in [
            0u64,
            1,
            9,
            10,
            99,
            100,
            7360,
            14560,
            u32::MAX as u64,
            u64::MAX,
        ] {
            let mut out = Vec::new();
            push_u64(&mut out, &mut buf, v);
            assert_eq!(String::from_utf8(out).unwrap(), v.to_string());
        }
    }
}
