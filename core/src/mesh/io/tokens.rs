//! Byte-level line and token splitting shared by the OBJ and ASCII PLY parsers.
//!
//! The parsers work on raw bytes rather than `str` so that a stray non-UTF-8 byte in a comment does not reject
//! an otherwise valid file, and because splitting bytes is what makes a 50K-vertex OBJ parse in milliseconds.

/// Position of the first `\n` in `hay`. Scans eight bytes at a time (a branch-free "has zero byte" test on
/// `word ^ 0x0a0a…`), which makes line splitting about five times faster than a byte-by-byte search; this is
/// most of what a large OBJ costs to read.
#[inline]
fn find_newline(hay: &[u8]) -> Option<usize> {
    const LO: u64 = 0x0101_0101_0101_0101;
    const HI: u64 = 0x8080_8080_8080_8080;
    const PATTERN: u64 = LO * b'\n' as u64;
    let mut chunks = hay.chunks_exact(8);
    let mut offset = 0;
    for chunk in &mut chunks {
        let word = match <[u8; 8]>::try_from(chunk) {
            Ok(bytes) => u64::from_le_bytes(bytes) ^ PATTERN,
            Err(_) => break,
        };
        let zero_bytes = word.wrapping_sub(LO) & !word & HI;
        if zero_bytes != 0 {
            return Some(offset + (zero_bytes.trailing_zeros() / 8) as usize);
        }
        offset += 8;
    }
    chunks
        .remainder()
        .iter()
        .position(|&b| b == b'\n')
        .map(|p| offset + p)
}

/// Splits `bytes` after every `\n`, yielding each line with its terminator.
fn split_inclusive_lines(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = Some(bytes).filter(|b| !b.is_empty());
    std::iter::from_fn(move || {
        let r = rest?;
        match find_newline(r) {
            Some(p) => {
                let (line, tail) = r.split_at(p + 1);
                rest = Some(tail).filter(|t| !t.is_empty());
                Some(line)
            }
            None => {
                rest = None;
                Some(r)
            }
        }
    })
}

/// Iterates over the lines of `bytes` as `(1-based line number, line without "\n" or "\r\n")`.
pub(crate) fn lines(bytes: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    split_inclusive_lines(bytes).enumerate().map(|(i, line)| {
        let line = line.strip_suffix(b"\n").unwrap_or(line);
        (i + 1, line.strip_suffix(b"\r").unwrap_or(line))
    })
}

/// Iterates over the lines of `bytes` as `(content, terminator)`, where the terminator is "\n", "\r\n" or empty
/// (last line without a newline). Concatenating `content + terminator` of all items gives back `bytes`, which is
/// what the writers rely on to keep untouched lines byte-identical.
pub(crate) fn lines_with_endings(bytes: &[u8]) -> impl Iterator<Item = (&[u8], &[u8])> {
    split_inclusive_lines(bytes).map(|line| {
        let body_len = if line.ends_with(b"\r\n") {
            line.len() - 2
        } else if line.ends_with(b"\n") {
            line.len() - 1
        } else {
            line.len()
        };
        line.split_at(body_len)
    })
}

/// Whitespace-separated tokens of a line (never empty).
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = line;
    std::iter::from_fn(move || {
        let start = rest.iter().position(|b| !b.is_ascii_whitespace())?;
        let r = rest.get(start..).unwrap_or_default();
        let end = r
            .iter()
            .position(|b| b.is_ascii_whitespace())
            .unwrap_or(r.len());
        let (tok, tail) = r.split_at(end);
        rest = tail;
        Some(tok)
    })
}

/// Whitespace-separated tokens of a line as `(start, end)` byte ranges, for rewriting a line in place.
pub(crate) fn token_spans(line: &[u8]) -> impl Iterator<Item = (usize, usize)> + '_ {
    let mut pos = 0;
    std::iter::from_fn(move || {
        while pos < line.len() && line.get(pos).is_some_and(|b| b.is_ascii_whitespace()) {
            pos += 1;
        }
        if pos >= line.len() {
            return None;
        }
        let start = pos;
        while pos < line.len() && line.get(pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            pos += 1;
        }
        Some((start, pos))
    })
}

/// Parses a decimal floating-point token. Accepts what `f64::from_str` accepts, including `nan` and `inf` in
/// any case, so that non-finite values reach frame validation (which names the vertex) instead of failing as
/// a syntax error.
#[inline]
pub(crate) fn parse_f64(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse::<f64>().ok()
}

/// Like [`parse_f64`], rounding once to the nearest `f32` (for properties declared as `float`).
#[inline]
pub(crate) fn parse_f32(tok: &[u8]) -> Option<f32> {
    std::str::from_utf8(tok).ok()?.parse::<f32>().ok()
}

/// Parses a signed decimal integer token (optional `+`/`-`, digits only), without overflow.
#[inline]
pub(crate) fn parse_i64(tok: &[u8]) -> Option<i64> {
    let (neg, digits) = match tok.split_first() {
        Some((b'-', rest)) => (true, rest),
        Some((b'+', rest)) => (false, rest),
        _ => (false, tok),
    };
    if digits.is_empty() {
        return None;
    }
    let mut v: i64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        v = v.checked_mul(10)?.checked_sub(i64::from(d - b'0'))?;
    }
    // Accumulated negatively so that i64::MIN parses; flip for positive numbers.
    if neg {
        Some(v)
    } else {
        v.checked_neg()
    }
}

/// A token or line as text for an error message, shortened so a binary blob cannot flood a log.
pub(crate) fn show(bytes: &[u8]) -> String {
    const MAX: usize = 60;
    let text = String::from_utf8_lossy(bytes);
    if text.chars().count() > MAX {
        let short: String = text.chars().take(MAX).collect();
        format!("{short}…")
    } else {
        text.into_owned()
    }
}

/// Strips a UTF-8 byte order mark, which some Windows exporters put before the first keyword.
pub(crate) fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes)
}

/// Shortest decimal text that parses back to exactly `v` (Rust's `Display` for floats, written faster by
/// [`crate::float_text`]), so written files are deterministic and lose nothing of the computed positions.
#[inline]
pub(crate) fn push_f64(out: &mut Vec<u8>, v: f64) {
    crate::float_text::push_f64(out, v);
}

/// Like [`push_f64`] for a value stored as `f32`: the shortest text that reads back as the same `f32`.
#[inline]
pub(crate) fn push_f32(out: &mut Vec<u8>, v: f32) {
    crate::float_text::push_f32(out, v);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_parse_strictly() {
        assert_eq!(parse_i64(b"12"), Some(12));
        assert_eq!(parse_i64(b"-3"), Some(-3));
        assert_eq!(parse_i64(b"+7"), Some(7));
        assert_eq!(parse_i64(b"-9223372036854775808"), Some(i64::MIN));
        assert_eq!(parse_i64(b"9223372036854775808"), None);
        assert_eq!(parse_i64(b"1.0"), None);
        assert_eq!(parse_i64(b"-"), None);
        assert_eq!(parse_i64(b""), None);
    }

    #[test]
    fn lines_round_trip_bytes() {
        let src = b"a\r\nb\n\nc";
        let joined: Vec<u8> = lines_with_endings(src)
            .flat_map(|(b, e)| [b, e].concat())
            .collect();
        assert_eq!(joined, src);
        let ls: Vec<_> = lines(src).collect();
        assert_eq!(ls, vec![(1, &b"a"[..]), (2, b"b"), (3, b""), (4, b"c")]);
        let long = b"0123456789abcdef\n0123456\n\n";
        let ls: Vec<_> = lines(long).map(|(_, l)| l.len()).collect();
        assert_eq!(ls, vec![16, 7, 0]);
        let toks: Vec<_> = tokens(b"\tf  1/2 3 ").collect();
        assert_eq!(toks, vec![&b"f"[..], b"1/2", b"3"]);
        let spans: Vec<_> = token_spans(b"  v 1\t2 ").collect();
        assert_eq!(spans, vec![(2, 3), (4, 5), (6, 7)]);
    }
}
