//! What a tuning key's value is and which values it may take: read from a job spec (a TOML or JSON value) or
//! from `--set key=TEXT`, both checked by the same rules so that the two give the same spec.

use serde_json::Value;

/// One end of a number's range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bound {
    /// The end itself is allowed.
    Closed(f64),
    /// Values up to, but not including, the end.
    Open(f64),
    /// No end: any finite number on that side.
    Free,
}

/// The type and range of a key.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// A finite number between `lo` and `hi` (a whole number is read as a number).
    Number { lo: Bound, hi: Bound },
    /// A whole number from `lo` to `hi`.
    Count { lo: u64, hi: u64 },
    /// `true` or `false`.
    Switch,
    /// One of these names.
    Choice(&'static [&'static str]),
    /// A non-empty list of numbers, each between `lo` and `hi` (`1,1.5,2.5` on the command line).
    Numbers { lo: Bound, hi: Bound },
    /// A list of 0-based frame numbers (`0,10` on the command line; may be empty).
    Frames,
    /// A whole number up to `hi`, or nothing (the default: chosen automatically).
    Optional { hi: u64 },
}

impl Kind {
    /// The value as the spec will hold it, or why it is not one of this kind's values (the message does not
    /// name the key; the caller does).
    pub fn check(&self, v: &Value) -> Result<Value, String> {
        match *self {
            Kind::Number { lo, hi } => {
                let x = number(v)?;
                in_range(x, lo, hi)?;
                Ok(Value::from(x))
            }
            Kind::Count { lo, hi } => {
                let n = whole(v)?;
                if n < lo || n > hi {
                    return Err(format!("must be {}, got {n}", count_range(lo, hi)));
                }
                Ok(Value::from(n))
            }
            Kind::Switch => v
                .as_bool()
                .map(Value::Bool)
                .ok_or_else(|| format!("must be true or false, got {v}")),
            Kind::Choice(names) => match v.as_str() {
                Some(s) if names.contains(&s) => Ok(Value::from(s)),
                _ => Err(format!("must be one of {}, got {v}", names.join(", "))),
            },
            Kind::Numbers { lo, hi } => {
                let items = v
                    .as_array()
                    .ok_or_else(|| format!("must be a list of numbers, got {v}"))?;
                if items.is_empty() {
                    return Err("needs at least one number".into());
                }
                let mut out = Vec::with_capacity(items.len());
                for item in items {
                    let x = number(item)?;
                    in_range(x, lo, hi)?;
                    out.push(Value::from(x));
                }
                Ok(Value::Array(out))
            }
            Kind::Frames => {
                let items = v
                    .as_array()
                    .ok_or_else(|| format!("must be a list of frame numbers, got {v}"))?;
                items
                    .iter()
                    .map(|i| whole(i).map(Value::from))
                    .collect::<Result<Vec<_>, _>>()
                    .map(Value::Array)
            }
            Kind::Optional { hi } => {
                if v.is_null() {
                    return Ok(Value::Null);
                }
                let n = whole(v)?;
                if n > hi {
                    return Err(format!("must be at most {hi}, got {n}"));
                }
                Ok(Value::from(n))
            }
        }
    }

    /// The value `--set key=TEXT` gives, checked as [`Kind::check`] checks a spec's value.
    pub fn parse(&self, text: &str) -> Result<Value, String> {
        let t = text.trim();
        let num = |s: &str| -> Result<Value, String> {
            match s.trim().parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(Value::from(x)),
                _ => Err(format!("`{s}` is not a finite number")),
            }
        };
        let whole = |s: &str| -> Result<Value, String> {
            s.trim()
                .parse::<u64>()
                .map(Value::from)
                .map_err(|_| format!("`{s}` is not a whole number ≥ 0"))
        };
        let list = |f: &dyn Fn(&str) -> Result<Value, String>| -> Result<Value, String> {
            if t.is_empty() {
                return Ok(Value::Array(Vec::new()));
            }
            t.split(',')
                .map(f)
                .collect::<Result<_, _>>()
                .map(Value::Array)
        };
        let v = match self {
            Kind::Number { .. } => num(t)?,
            Kind::Count { .. } | Kind::Optional { .. } => whole(t)?,
            Kind::Switch => match t {
                "true" => Value::Bool(true),
                "false" => Value::Bool(false),
                _ => return Err(format!("`{t}` is not true or false")),
            },
            Kind::Choice(_) => Value::from(t),
            Kind::Numbers { .. } => list(&num)?,
            Kind::Frames => list(&whole)?,
        };
        self.check(&v)
    }

    /// The type and range as the key listing shows them.
    pub fn describe(&self) -> String {
        match *self {
            Kind::Number { lo, hi } => format!("number {}", number_range(lo, hi)),
            Kind::Count { lo, hi } => format!("whole number {}", count_range(lo, hi)),
            Kind::Switch => "true or false".into(),
            Kind::Choice(names) => format!("one of {}", names.join(", ")),
            Kind::Numbers { lo, hi } => format!("list of numbers {}", number_range(lo, hi)),
            Kind::Frames => "list of frames (0-based)".into(),
            Kind::Optional { hi } => format!("whole number ≤ {hi}, or unset"),
        }
    }

    /// A value (a default) as a user writes it after `--set key=`.
    pub fn show(&self, v: &Value) -> String {
        match v {
            Value::Null => "unset (automatic)".into(),
            Value::String(s) => s.clone(),
            Value::Array(items) => items
                .iter()
                .map(|i| self.show(i))
                .collect::<Vec<_>>()
                .join(","),
            other => other.to_string(),
        }
    }
}

fn number(v: &Value) -> Result<f64, String> {
    match v.as_f64() {
        Some(x) if x.is_finite() => Ok(x),
        _ => Err(format!("must be a number, got {v}")),
    }
}

fn whole(v: &Value) -> Result<u64, String> {
    v.as_u64()
        .ok_or_else(|| format!("must be a whole number ≥ 0, got {v}"))
}

fn in_range(x: f64, lo: Bound, hi: Bound) -> Result<(), String> {
    let above = match lo {
        Bound::Closed(b) => x >= b,
        Bound::Open(b) => x > b,
        Bound::Free => true,
    };
    let below = match hi {
        Bound::Closed(b) => x <= b,
        Bound::Open(b) => x < b,
        Bound::Free => true,
    };
    if above && below {
        Ok(())
    } else {
        Err(format!("must be {}, got {x}", number_range(lo, hi)))
    }
}

fn number_range(lo: Bound, hi: Bound) -> String {
    match (lo, hi) {
        (Bound::Free, Bound::Free) => "(any)".into(),
        (Bound::Closed(a), Bound::Free) => format!("≥ {a}"),
        (Bound::Open(a), Bound::Free) => format!("> {a}"),
        (Bound::Free, Bound::Closed(b)) => format!("≤ {b}"),
        (Bound::Free, Bound::Open(b)) => format!("< {b}"),
        (lo, hi) => {
            let (l, a) = match lo {
                Bound::Closed(a) => ('[', a),
                Bound::Open(a) => ('(', a),
                Bound::Free => unreachable!(),
            };
            let (r, b) = match hi {
                Bound::Closed(b) => (']', b),
                Bound::Open(b) => (')', b),
                Bound::Free => unreachable!(),
            };
            format!("in {l}{a}, {b}{r}")
        }
    }
}

fn count_range(lo: u64, hi: u64) -> String {
    if hi == u64::MAX {
        format!("≥ {lo}")
    } else {
        format!("in {lo}..={hi}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn text_and_values_are_read_by_the_same_rules() {
        let k = Kind::Number {
            lo: Bound::Closed(0.0),
            hi: Bound::Open(1.0),
        };
        assert_eq!(k.parse("0.5").unwrap(), k.check(&json!(0.5)).unwrap());
        // A TOML integer is a number.
        assert_eq!(k.check(&json!(0)).unwrap(), json!(0.0));
        assert!(k.parse("1").unwrap_err().contains("in [0, 1)"));
        assert!(k
            .parse("nan")
            .unwrap_err()
            .contains("`nan` is not a finite number"));
        assert!(k.parse("x").unwrap_err().contains("`x`"));
        let c = Kind::Count { lo: 1, hi: 20 };
        assert_eq!(c.parse("3").unwrap(), json!(3));
        assert!(c.check(&json!(3.0)).unwrap_err().contains("whole number"));
        assert!(c.parse("0").unwrap_err().contains("in 1..=20"));
        let l = Kind::Numbers {
            lo: Bound::Closed(0.2),
            hi: Bound::Closed(20.0),
        };
        assert_eq!(l.parse("1,1.5").unwrap(), json!([1.0, 1.5]));
        assert!(l.parse("").unwrap_err().contains("at least one"));
        assert!(l.check(&json!([1, 30])).unwrap_err().contains("30"));
        assert_eq!(Kind::Frames.parse("").unwrap(), json!([]));
        assert_eq!(Kind::Frames.parse("0,4").unwrap(), json!([0, 4]));
        let ch = Kind::Choice(&["a", "b-c"]);
        assert_eq!(ch.parse("b-c").unwrap(), json!("b-c"));
        assert!(ch.parse("d").unwrap_err().contains("one of a, b-c"));
        assert_eq!(Kind::Switch.parse("true").unwrap(), json!(true));
        assert!(Kind::Switch.parse("yes").is_err());
        let o = Kind::Optional { hi: 10 };
        assert_eq!(o.check(&Value::Null).unwrap(), Value::Null);
        assert!(o.parse("11").is_err());
    }
}
