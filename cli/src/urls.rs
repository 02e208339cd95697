//! Coordinator and worker URLs are checked when the command line is parsed: a URL without a scheme
//! (`127.0.0.1:7070`) would otherwise reach the gRPC layer, fail to connect and be retried forever by a worker.

/// Accepts `http://HOST:PORT` and `https://HOST:PORT` (clap value parser).
pub fn parse(s: &str) -> Result<String, String> {
    let rest = s
        .strip_prefix("http://")
        .or_else(|| s.strip_prefix("https://"))
        .ok_or_else(|| {
            if s.contains("://") {
                format!("`{s}` has an unsupported scheme: use http:// or https://")
            } else {
                format!("`{s}` has no scheme: write http://{s} (or https://{s} with --tls-ca)")
            }
        })?;
    if rest.is_empty() || rest.starts_with('/') || rest.starts_with(':') {
        return Err(format!("`{s}` names no host"));
    }
    Ok(s.to_string())
}

#[cfg(test)]
mod tests {
    use super::parse;

    #[test]
    fn a_scheme_and_a_host_are_required() {
        assert_eq!(
            parse("http://127.0.0.1:7070").as_deref(),
            Ok("http://127.0.0.1:7070")
        );
        assert!(parse("https://coord.example:7070").is_ok());
        let bare = parse("127.0.0.1:7070").unwrap_err();
        assert!(
            bare.contains("no scheme") && bare.contains("http://127.0.0.1:7070"),
            "{bare}"
        );
        assert!(parse("ftp://x:1")
            .unwrap_err()
            .contains("unsupported scheme"));
        assert!(parse("http://").unwrap_err().contains("no host"));
    }
}
