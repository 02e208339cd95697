//! A negative number given to a flag that takes a count (`--frames -3`) reaches clap as an unknown argument, a
//! missing value or a digit-parsing failure; all of them read like parser internals. This rewrites them into a
//! sentence that names the flag and what it takes.

use clap::error::{ContextKind, ContextValue};

fn is_negative_number(v: &str) -> bool {
    v.len() > 1 && v.starts_with('-') && v[1..].parse::<f64>().is_ok()
}

/// The message for a negative value given to a flag that does not take one, or None for any other error.
pub fn negative_value(err: &clap::Error, args: &[String]) -> Option<String> {
    let ctx = |kind| match err.get(kind) {
        Some(ContextValue::String(s)) => Some(s.clone()),
        _ => None,
    };
    // "-3" (taken for a flag of its own) or "--frames <FRAMES>" (the flag whose value was missing or bad).
    let arg = ctx(ContextKind::InvalidArg)?;
    let value = ctx(ContextKind::InvalidValue);
    let flag_named = arg.split_whitespace().next().unwrap_or("").to_string();
    for (i, a) in args.iter().enumerate() {
        let (flag, v) = match a.split_once('=') {
            Some((f, v)) if f.starts_with("--") => (f.to_string(), v.to_string()),
            _ => (a.clone(), args.get(i + 1).cloned().unwrap_or_default()),
        };
        if !flag.starts_with("--") || !is_negative_number(&v) {
            continue;
        }
        if arg == v || flag_named == flag || value.as_deref() == Some(v.as_str()) {
            return Some(format!("{flag} takes a number ≥ 0, got {v}"));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::is_negative_number;

    #[test]
    fn negative_numbers() {
        assert!(is_negative_number("-3") && is_negative_number("-0.5"));
        assert!(
            !is_negative_number("-") && !is_negative_number("--frames") && !is_negative_number("3")
        );
    }
}
