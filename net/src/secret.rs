//! A secret string (a bearer token) that cannot leak through `{:?}` or `{}`, and a comparison whose time does
//! not depend on where two tokens first differ.

use subtle::{Choice, ConstantTimeEq};

/// A token or other secret. Debug and Display print `<redacted>`; [`Secret::expose`] is the only way out.
#[derive(Clone, PartialEq, Eq)]
pub struct Secret(String);

impl Secret {
    pub fn new(s: impl Into<String>) -> Self {
        Secret(s.into())
    }

    /// The secret itself, for putting on the wire.
    pub fn expose(&self) -> &str {
        &self.0
    }

    /// Constant-time equality with a presented value.
    pub fn matches(&self, presented: &[u8]) -> bool {
        ct_eq(self.0.as_bytes(), presented)
    }
}

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("<redacted>")
    }
}

impl std::fmt::Display for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("<redacted>")
    }
}

/// Equality in time that depends only on the longer length, not on the contents: every byte position is
/// compared (the shorter side padded) and the length check is folded in at the end.
pub fn ct_eq(a: &[u8], b: &[u8]) -> bool {
    let n = a.len().max(b.len());
    let mut same = Choice::from(1u8);
    for i in 0..n {
        let x = a.get(i).copied().unwrap_or(0);
        let y = b.get(i).copied().unwrap_or(0);
        same &= x.ct_eq(&y);
    }
    same &= (a.len() as u64).ct_eq(&(b.len() as u64));
    bool::from(same)
}

/// True when `presented` equals any of `accepted`; every candidate is compared (no early exit).
pub fn any_matches(accepted: &[Secret], presented: &[u8]) -> bool {
    let mut found = Choice::from(0u8);
    for s in accepted {
        found |= Choice::from(s.matches(presented) as u8);
    }
    bool::from(found)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debug_and_display_are_redacted() {
        let s = Secret::new("hunter2-very-secret");
        assert_eq!(format!("{s:?}"), "<redacted>");
        assert_eq!(format!("{s}"), "<redacted>");
        assert_eq!(format!("{:?}", Some(vec![s.clone()])), "Some([<redacted>])");
        assert_eq!(s.expose(), "hunter2-very-secret");
    }

    #[test]
    fn constant_time_compare_is_exact() {
        assert!(ct_eq(b"abc", b"abc"));
        assert!(ct_eq(b"", b""));
        assert!(!ct_eq(b"abc", b"abd"));
        assert!(!ct_eq(b"abc", b"ab"));
        assert!(!ct_eq(b"ab", b"abc"));
        // A prefix padded with zero bytes must not compare equal.
        assert!(!ct_eq(b"ab\0", b"ab"));
        assert!(!ct_eq(b"", b"\0"));
        let set = [Secret::new("old"), Secret::new("new")];
        assert!(any_matches(&set, b"new"));
        assert!(any_matches(&set, b"old"));
        assert!(!any_matches(&set, b"nope"));
        assert!(!any_matches(&[], b"new"));
    }
}
