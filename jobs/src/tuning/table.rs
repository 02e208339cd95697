//! The `[tuning]` table of a job spec as it is read: dotted keys and their values, not yet checked against the
//! registry (that happens when the spec is resolved, [`super::apply`]), so the spec can hold it without knowing
//! the keys.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;

/// The `[tuning]` table: key → value, in key order. Nested tables (`deform.c_s = 1` in TOML, `{"deform":
/// {"c_s": 1}}` in JSON) read as their dotted keys.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Tuning(BTreeMap<String, Value>);

impl Tuning {
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    pub fn iter(&self) -> impl Iterator<Item = (&String, &Value)> {
        self.0.iter()
    }

    /// The keys and values, in key order.
    pub fn into_entries(self) -> BTreeMap<String, Value> {
        self.0
    }

    /// Sets `key` to `value` (checked when the spec is read); a key given twice is an error.
    pub fn insert(&mut self, key: &str, value: Value) -> Result<(), String> {
        if self.0.insert(key.to_string(), value).is_some() {
            return Err(format!("`{key}` is given twice"));
        }
        Ok(())
    }

    fn flatten(prefix: &str, v: Value, out: &mut BTreeMap<String, Value>) -> Result<(), String> {
        match v {
            Value::Object(map) => {
                for (k, v) in map {
                    let key = if prefix.is_empty() {
                        k
                    } else {
                        format!("{prefix}.{k}")
                    };
                    Self::flatten(&key, v, out)?;
                }
                Ok(())
            }
            v if prefix.is_empty() => Err(format!("must be a table of keys, got {v}")),
            v => match out.insert(prefix.to_string(), v) {
                Some(_) => Err(format!("tuning key `{prefix}` is given twice")),
                None => Ok(()),
            },
        }
    }
}

impl<'de> Deserialize<'de> for Tuning {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = Value::deserialize(d)?;
        let mut out = BTreeMap::new();
        Tuning::flatten("", v, &mut out).map_err(serde::de::Error::custom)?;
        Ok(Tuning(out))
    }
}
