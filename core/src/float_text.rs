//! Number text in the form Rust's `Display` writes (`{}`), built without the formatting machinery.
//!
//! Why: the output frames (OBJ/PLY, one line per vertex), the control lines and the deep contract's OBJs are
//! megabytes of float text per frame, and `write!(out, "{v}")` spent most of their writing time in `fmt`.
//! `Display` writes a float as the shortest decimal that reads back to the same value (the closest one when
//! several have that length), never with an exponent (`0.0000001`, `100`, `-0`). Ryū (the `ryu` crate) finds the
//! same digits much faster but lays them out differently (`1e-7`, `1.0`), so they are rewritten here into
//! `Display`'s layout. The one case where the two may choose different digits — a value exactly halfway between
//! two shortest candidates — is detected exactly and handed to `Display` ([`is_tie`]). The tests compare with
//! `format!("{v}")` on millions of values (f64 and f32, every exponent, the midpoints, the special values), so
//! files keep their bytes.

use std::fmt::Display;

/// Appends `v` as `format!("{v}")` would.
#[inline]
pub fn push_f64(out: &mut Vec<u8>, v: f64) {
    push_float(out, v, v.is_finite(), || {
        odd_mantissa(v.to_bits() & !(1 << 63), 52, 1075)
    });
}

/// Appends `v` as `format!("{v}")` would (the shortest text that reads back as the same `f32`).
#[inline]
pub fn push_f32(out: &mut Vec<u8>, v: f32) {
    push_float(out, v, v.is_finite(), || {
        odd_mantissa(u64::from(v.to_bits() & !(1 << 31)), 23, 150)
    });
}

/// Ryū's digits of `v` in `Display`'s layout, or `Display` itself where they may differ (non-finite values,
/// midpoints); `odd` gives `|v| = m · 2^e`, m odd ([`odd_mantissa`]).
#[inline]
fn push_float<F: ryu::Float + Display>(
    out: &mut Vec<u8>,
    v: F,
    finite: bool,
    odd: impl FnOnce() -> Option<(u64, i32)>,
) {
    if !finite {
        return push_display(out, v);
    }
    let mut buf = ryu::Buffer::new();
    let decimal = Decimal::parse(buf.format_finite(v).as_bytes());
    if is_tie(&decimal, odd()) {
        return push_display(out, v);
    }
    decimal.push(out);
}

/// Appends the decimal digits of `v` (what `{}` writes for an unsigned integer).
#[inline]
pub fn push_u64(out: &mut Vec<u8>, mut v: u64) {
    let mut buf = [0u8; 20];
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

fn push_display(out: &mut Vec<u8>, v: impl Display) {
    use std::io::Write;
    // Writing to a Vec cannot fail.
    let _ = write!(out, "{v}");
}

/// A finite value's decimal digits as Ryū wrote them: `|v| ≈ 0.d₁d₂…dₙ × 10^point`, no leading or trailing
/// zeros in `digits` (none at all for zero).
struct Decimal {
    negative: bool,
    digits: [u8; 24],
    len: usize,
    point: i32,
}

impl Decimal {
    /// Reads Ryū's text of a finite float (`-1.25e-7`, `0.001`, `12.0`, `1e16`).
    fn parse(s: &[u8]) -> Decimal {
        let (negative, s) = match s.split_first() {
            Some((b'-', rest)) => (true, rest),
            _ => (false, s),
        };
        let (mantissa, exponent) = match s.iter().position(|&c| c == b'e') {
            Some(i) => (&s[..i], parse_exponent(&s[i + 1..])),
            None => (s, 0),
        };
        let mut d = Decimal {
            negative,
            digits: [0; 24],
            len: 0,
            point: 0,
        };
        let mut point = None;
        let mut seen = 0i32; // digits read, leading zeros included
        for &c in mantissa {
            if c == b'.' {
                point = Some(seen);
                continue;
            }
            seen += 1;
            if d.len == 0 && c == b'0' {
                // A leading zero moves the point left.
                d.point -= 1;
                continue;
            }
            if d.len < d.digits.len() {
                d.digits[d.len] = c;
                d.len += 1;
            }
        }
        d.point += point.unwrap_or(seen) + exponent;
        while d.len > 0 && d.digits[d.len - 1] == b'0' {
            d.len -= 1;
        }
        d
    }

    fn digits(&self) -> &[u8] {
        &self.digits[..self.len]
    }

    /// `Display`'s layout: plain decimal, no exponent, no `.0`, `-0` for negative zero.
    fn push(&self, out: &mut Vec<u8>) {
        if self.negative {
            out.push(b'-');
        }
        let digits = self.digits();
        if digits.is_empty() {
            out.push(b'0');
            return;
        }
        let (len, point) = (digits.len() as i32, self.point);
        if point <= 0 {
            out.extend_from_slice(b"0.");
            out.extend(std::iter::repeat_n(b'0', (-point) as usize));
            out.extend_from_slice(digits);
        } else if point >= len {
            out.extend_from_slice(digits);
            out.extend(std::iter::repeat_n(b'0', (point - len) as usize));
        } else {
            out.extend_from_slice(&digits[..point as usize]);
            out.push(b'.');
            out.extend_from_slice(&digits[point as usize..]);
        }
    }
}

fn parse_exponent(s: &[u8]) -> i32 {
    let (sign, s) = match s.split_first() {
        Some((b'-', rest)) => (-1, rest),
        Some((b'+', rest)) => (1, rest),
        _ => (1, s),
    };
    sign * s
        .iter()
        .fold(0i32, |e, &c| e * 10 + i32::from(c.wrapping_sub(b'0')))
}

/// `|v| = m · 2^e` with `m` odd, from the magnitude's bits (`None` for zero): `frac_bits` stored mantissa bits,
/// `bias` the exponent bias plus `frac_bits` (1075 for f64, 150 for f32).
fn odd_mantissa(bits: u64, frac_bits: u32, bias: i32) -> Option<(u64, i32)> {
    let exp = (bits >> frac_bits) as i32;
    let frac = bits & ((1u64 << frac_bits) - 1);
    let (m, e) = if exp == 0 {
        (frac, 1 - bias)
    } else {
        (frac | (1u64 << frac_bits), exp - bias)
    };
    if m == 0 {
        return None;
    }
    let tz = m.trailing_zeros();
    Some((m >> tz, e + tz as i32))
}

/// Whether the value `m · 2^e` (`odd`) lies exactly halfway between `d` (its shortest digits) and the number
/// one unit away in their last digit: there "shortest, then closest" has two answers and Ryū and `Display` may
/// pick differently.
///
/// The midpoints are N · 10^q with N = 10·D ± 5 (odd) and q one below the last digit's exponent; equal to
/// m · 2^e with m odd, that needs e = q and m = N · 5^q (q ≥ 0) or m · 5^(−q) = N (q < 0).
fn is_tie(d: &Decimal, odd: Option<(u64, i32)>) -> bool {
    let Some((m, e)) = odd else {
        return false;
    };
    let digits = d.digits();
    if digits.is_empty() || digits.len() > 18 {
        return false; // zero, or not a shortest representation (cannot happen)
    }
    let q = d.point - digits.len() as i32 - 1;
    if e != q {
        return false;
    }
    let big_d = digits
        .iter()
        .fold(0u128, |n, &c| n * 10 + u128::from(c - b'0'));
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
    equals(10 * big_d + 5) || equals(10 * big_d - 5)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ours64(v: f64) -> String {
        let mut out = Vec::new();
        push_f64(&mut out, v);
        String::from_utf8(out).unwrap()
    }

    fn ours32(v: f32) -> String {
        let mut out = Vec::new();
        push_f32(&mut out, v);
        String::from_utf8(out).unwrap()
    }

    fn tie64(v: f64) -> bool {
        let mut buf = ryu::Buffer::new();
        let d = Decimal::parse(buf.format_finite(v).as_bytes());
        is_tie(&d, odd_mantissa(v.to_bits() & !(1 << 63), 52, 1075))
    }

    fn tie32(v: f32) -> bool {
        let mut buf = ryu::Buffer::new();
        let d = Decimal::parse(buf.format_finite(v).as_bytes());
        is_tie(
            &d,
            odd_mantissa(u64::from(v.to_bits() & !(1 << 31)), 23, 150),
        )
    }

    /// A small xorshift generator: the same values on every run.
    struct Bits(u64);
    impl Bits {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
    }

    #[test]
    fn special_values_read_as_display_writes_them() {
        let values = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            0.3,
            0.5,
            2.5,
            100.0,
            1e-5,
            9.99e-6,
            1e-7,
            -1.5e-7,
            1e15,
            1e16,
            1e17,
            1e21,
            1.2345e21,
            1e22,
            123456.0,
            9007199254740992.0,
            9_007_199_254_740_993.0,
            233_115_890_514_796.12,
            0.30000000000000004,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            f64::EPSILON,
            5e-324,
            -5e-324,
            -f64::MIN_POSITIVE / 3.0,
            1e-17,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for v in values {
            assert_eq!(ours64(v), format!("{v}"), "{v:e}");
            let w = v as f32;
            assert_eq!(ours32(w), format!("{w}"), "{w:e}");
        }
        for w in [
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            f32::EPSILON,
            1e-45,
            -1e-45,
            16777216.0,
            16777217.0,
            0.1,
            3.4e38,
            1e-10,
        ] {
            assert_eq!(ours32(w), format!("{w}"), "{w:e}");
        }
    }

    #[test]
    fn random_values_read_as_display_writes_them() {
        let mut rng = Bits(0x9E37_79B9_7F4A_7C15);
        let (mut ties64, mut ties32) = (0, 0);
        for i in 0..1_500_000u32 {
            let bits = rng.next();
            let u = (bits >> 11) as f64 / (1u64 << 53) as f64;
            // Every bit pattern (all exponents), values in the ranges meshes hold, and exact midpoints between
            // two shortest candidates (Ryū and `Display` round these differently).
            let v = match i % 8 {
                0 => f64::from_bits(bits),
                1 => u * 20.0 - 10.0,
                2 => (u - 0.5) * 10f64.powi((i % 40) as i32 - 20),
                3 => (bits % 100_000) as f64 / 1000.0,
                4 => (bits >> 12) as f64 + 0.5,
                5 => ((bits >> 16) | (1 << 44)) as f64 + ((bits & 7) | 1) as f64 / 8.0,
                6 => (u as f32) as f64 * 0.3,
                _ => f64::from_bits(bits) * 1e-300,
            };
            if v.is_finite() && tie64(v) {
                ties64 += 1;
            }
            assert_eq!(ours64(v), format!("{v}"), "bits {:#x}", v.to_bits());
            let w = match i % 4 {
                0 => f32::from_bits(bits as u32),
                1 => v as f32,
                // f32 midpoints: 24-bit odd mantissas scaled into the exponents where they occur.
                _ => (((bits >> 40) as u32 | 1) as f32) * 2f32.powi((i % 24) as i32 - 12),
            };
            if w.is_finite() && tie32(w) {
                ties32 += 1;
            }
            assert_eq!(ours32(w), format!("{w}"), "bits {:#x}", w.to_bits());
        }
        // The midpoint cases really occurred (the test would not see a broken tie rule otherwise).
        assert!(ties64 > 1000 && ties32 > 100, "{ties64} / {ties32} ties");
    }

    #[test]
    fn integers_are_written_as_display_writes_them() {
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
            push_u64(&mut out, v);
            assert_eq!(String::from_utf8(out).unwrap(), v.to_string());
        }
    }
}
