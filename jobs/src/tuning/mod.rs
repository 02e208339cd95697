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
pub mod removed;
pub mod table;

use crate::error::JobError;
use crate::spec::JobSpec;
pub use kind::{Bound, Kind};
pub use registry::{find, Knob, KNOBS};
pub use removed::{removed, REMOVED};
pub use table::Tuning;

impl Tuning {
    /// Sets `key` from `--set key=TEXT` (`text` read by the key's type); a key given twice is an error.
    pub fn set_text(&mut self, key: &str, text: &str) -> Result<(), String> {
        let knob = find(key).ok_or_else(|| unknown_key(key))?;
        let v = knob.kind.parse(text).map_err(|m| format!("`{key}`: {m}"))?;
        self.insert(key, v)
    }
}

impl JobSpec {
    /// The spec with its tuning keys applied ([`apply`]), validated: what a spec built in code (`crease run`)
    /// goes through before it is submitted, as a parsed one does.
    pub fn resolved(mut self) -> Result<Self, JobError> {
        apply(&mut self)?;
        self.validate()?;
        Ok(self)
    }
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
    for (key, value) in tuning.into_entries() {
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
