//! The one line `crease` prints for an error. anyhow's `{:#}` joins every cause of the chain, and a cause
//! whose own message already quotes its source (crease-core's `path: No such file or directory`) would then
//! print the operating system's words twice; a cause already said is left out.

pub fn one_line(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let s = cause.to_string();
        if s.is_empty() || out.contains(&s) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&s);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::one_line;
    use anyhow::Context;

    #[test]
    fn the_os_reason_is_said_once() {
        let io = std::fs::read("/no/such/crease/file").unwrap_err();
        let core = crease_core::Error::io("/no/such/crease/file", io);
        let e = Err::<(), _>(core).context("reading the input").unwrap_err();
        let text = one_line(&e);
        assert_eq!(
            text.matches("No such file or directory").count(),
            1,
            "{text}"
        );
        assert!(
            text.starts_with("reading the input: /no/such/crease/file"),
            "{text}"
        );
        // Different causes are all kept.
        let e = anyhow::anyhow!("inner").context("middle").context("outer");
        assert_eq!(one_line(&e), "outer: middle: inner");
    }
}
