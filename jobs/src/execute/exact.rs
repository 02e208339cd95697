//! Serde helper: f64 as its shortest round-trip decimal string. JSON numbers would be fine to read by eye, but
//! serde_json's default float parser may differ from the written value in the last bit, and statistics merged
//! from sidecars must equal the single-machine figures exactly.

use serde::{Deserialize, Deserializer, Serializer};

pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&format!("{v:?}"))
}

pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    let text = String::deserialize(d)?;
    text.parse().map_err(serde::de::Error::custom)
}
