//! Token files: one token per line, so a new token can be added beside the old one while clients move over
//! (rotation), then the old line removed. Blank lines and `#` comments are ignored, surrounding whitespace is
//! trimmed. Errors name the flag, the file and the line, never the token.

use crate::secret::Secret;
use crate::NetError;
use std::path::Path;

/// Reads the tokens of `path` (given with `flag`); at least one is required.
pub fn load(flag: &'static str, path: &Path) -> Result<Vec<Secret>, NetError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| NetError::file(flag, path, format!("cannot read the token file: {e}")))?;
    warn_if_readable_by_others(flag, path);
    parse(flag, path, &text)
}

fn parse(flag: &'static str, path: &Path, text: &str) -> Result<Vec<Secret>, NetError> {
    let mut tokens = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        if !t.bytes().all(|b| b.is_ascii_graphic()) {
            return Err(NetError::file(
                flag,
                path,
                format!(
                    "line {}: a token may contain only printable ASCII characters without spaces",
                    i + 1
                ),
            ));
        }
        tokens.push(Secret::new(t));
    }
    if tokens.is_empty() {
        return Err(NetError::file(
            flag,
            path,
            "the token file holds no token (blank lines and # comments are ignored)",
        ));
    }
    Ok(tokens)
}

/// A token given directly (CREASE_TOKEN): the same rules as one line of a file.
pub fn from_env(var: &'static str, value: &str) -> Result<Secret, NetError> {
    let t = value.trim();
    if t.is_empty() || !t.bytes().all(|b| b.is_ascii_graphic()) {
        return Err(NetError::Config(format!(
            "{var}: a token must be non-empty printable ASCII without spaces"
        )));
    }
    Ok(Secret::new(t))
}

#[cfg(unix)]
fn warn_if_readable_by_others(flag: &str, path: &Path) {
    use std::os::unix::fs::PermissionsExt;
    if let Ok(m) = std::fs::metadata(path) {
        if m.permissions().mode() & 0o077 != 0 {
            tracing::warn!(
                file = %path.display(),
                "{flag}: the token file is readable by other users; chmod 600 it"
            );
        }
    }
}

#[cfg(not(unix))]
fn warn_if_readable_by_others(_flag: &str, _path: &Path) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blank_lines_comments_and_whitespace_are_ignored() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("tokens");
        std::fs::write(
            &p,
            "# rotation: new first\n\n  new-token  \n\told-token\r\n   \n# end\n",
        )
        .unwrap();
        let t = load("--client-tokens-file", &p).unwrap();
        let exposed: Vec<&str> = t.iter().map(Secret::expose).collect();
        assert_eq!(exposed, ["new-token", "old-token"]);
    }

    #[test]
    fn an_empty_file_is_an_error_naming_flag_and_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("empty-tokens");
        std::fs::write(&p, "# nothing here\n\n   \n").unwrap();
        let e = load("--worker-token-file", &p).unwrap_err().to_string();
        assert!(e.contains("--worker-token-file"), "{e}");
        assert!(e.contains("empty-tokens"), "{e}");
        assert!(e.contains("no token"), "{e}");
    }

    #[test]
    fn a_missing_file_is_an_error_naming_flag_and_file() {
        let e = load("--token-file", Path::new("/nonexistent/crease-tokens"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("--token-file"), "{e}");
        assert!(e.contains("/nonexistent/crease-tokens"), "{e}");
    }

    #[test]
    fn a_token_with_inner_spaces_is_refused_without_being_echoed() {
        let e = parse("--token-file", Path::new("t"), "ok\nsecret with space\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2"), "{e}");
        assert!(!e.contains("secret with space"), "{e}");
    }

    #[test]
    fn env_tokens_follow_the_same_rules() {
        assert_eq!(from_env("CREASE_TOKEN", " abc \n").unwrap().expose(), "abc");
        assert!(from_env("CREASE_TOKEN", "  ").is_err());
        let e = from_env("CREASE_TOKEN", "a b").unwrap_err().to_string();
        assert!(e.contains("CREASE_TOKEN") && !e.contains("a b"), "{e}");
    }
}
