//! Tuning keys: every setting of a job that is not one of its inputs, in one registry ([`registry::KNOBS`]:
//! name, type, range, meaning; defaults read from the spec's own), set in a job spec's `[tuning]` table or with
//! `crease run --set key=value`. Both are read by the same rules ([`kind::Kind`]) and applied by [`apply`] when
//! the spec is read, so they give the same spec; errors name the key.
//!
//! A key is `group.field`: the spec field it sets keeps its name (`deform.c_s` is `[deform] c_s`,
//! `stretch.theta0_deg` is `folds.params.theta0_deg` of a stretch job), so the tables of older specs still
//! read as before and `[tuning]` is applied over them.

pub mod kind;
pub mod markdown;
pub mod registry;

use crate::error::JobError;
use crate::spec::JobSpec;
pub use kind::{Bound, Kind};
pub use registry::{find, Knob, KNOBS};
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

    /// Sets `key` from `--set key=TEXT` (`text` read by the key's type); a key given twice is an error.
    pub fn set_text(&mut self, key: &str, text: &str) -> Result<(), String> {
        let knob = find(key).ok_or_else(|| unknown_key(key))?;
        let v = knob.kind.parse(text).map_err(|m| format!("`{key}`: {m}"))?;
        self.insert(key, v)
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

/// Settings that were removed, with what replaced them: an old spec naming one gets this reason instead of a
/// bare "unknown field".
pub const REMOVED: &[(&str, &str)] = &[
    (
        "projection_order",
        "the shape projection follows the last stretch pass (the other orders measured worse)",
    ),
    (
        "operator_block",
        "every frame is positioned with its own operator (a shared one measured no faster)",
    ),
    (
        "flattening",
        "patches are unfolded, with LSCM where one folds over (LSCM everywhere measured slower and no better)",
    ),
    (
        "contrast_thresholds",
        "the Canny thresholds hold at every radius (dividing them by the radius measured worse)",
    ),
    ("all_views", "replaced by `views = \"all\"`"),
    (
        "cover_views",
        "replaced by `views = \"cover\"` (true) or `views = \"front-back\"` (false)",
    ),
];

/// The reason a removed field is gone, for an error message about `field`.
pub fn removed(field: &str) -> Option<&'static str> {
    let last = field.rsplit('.').next().unwrap_or(field);
    REMOVED
        .iter()
        .find(|(f, _)| *f == last)
        .map(|(_, why)| *why)
}

/// Why `key` is not a tuning key, with the key meant where that is clear.
pub fn unknown_key(key: &str) -> String {
    if let Some(why) = removed(key) {
        return format!("`{key}` was removed: {why}");
    }
    let field = key.rsplit('.').next().unwrap_or(key);
    let near: Vec<&str> = KNOBS
        .iter()
        .filter(|k| k.field() == field || k.field().trim_end_matches("_deg") == field)
        .map(|k| k.key)
        .collect();
    if near.is_empty() {
        format!("`{key}` is not a tuning key (`crease tuning` lists them)")
    } else {
        format!(
            "`{key}` is not a tuning key; did you mean {}?",
            near.iter()
                .map(|k| format!("`{k}`"))
                .collect::<Vec<_>>()
                .join(" or ")
        )
    }
}

/// Sets every key of `spec.tuning` on the field it names and empties the table, so that a spec read twice (the
/// coordinator stores and reads specs back) is the same spec. Errors name `tuning.<key>`.
pub fn apply(spec: &mut JobSpec) -> Result<(), JobError> {
    let tuning = std::mem::take(&mut spec.tuning);
    for (key, value) in tuning.0 {
        let field = format!("tuning.{key}");
        let knob = find(&key).ok_or_else(|| JobError::spec(&field, unknown_key(&key)))?;
        let v = knob
            .kind
            .check(&value)
            .map_err(|m| JobError::spec(&field, m))?;
        let folds = spec.folds.kind();
        let slot = (knob.access)(spec).ok_or_else(|| {
            JobError::spec(
                &field,
                format!(
                    "applies to {} folds only, and this job's folds are `{folds}`",
                    knob.group()
                ),
            )
        })?;
        slot.put(v).map_err(|m| JobError::spec(&field, m))?;
    }
    Ok(())
}

/// The tuning key of a spec field (`folds.params.theta0_deg` of a stretch job is `stretch.theta0_deg`), so that
/// a check of the whole spec (a range that depends on another field) can name the key a user of `--set` gave.
pub fn key_of_field(spec: &JobSpec, field: &str) -> Option<&'static str> {
    let field = field.strip_prefix("tuning.").unwrap_or(field);
    KNOBS.iter().find_map(|k| {
        let ours = match k.group() {
            "stretch" | "video" if k.group() != spec.folds.kind() => return None,
            _ => k.spec_path(),
        };
        (ours == field || k.key == field).then_some(k.key)
    })
}

#[cfg(test)]
mod tests;
