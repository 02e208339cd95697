//! The key listing, as `crease tuning` prints it and as docs/tuning.md holds it (a test compares the page with
//! [`page`], so the documentation is the registry).

use super::registry::{Knob, KNOBS};
use super::REMOVED;

/// Each group's heading: what its keys tune.
const GROUPS: &[(&str, &str)] = &[
    ("deform", "the space-time deformation (Popa et al. 2009 §5)"),
    (
        "partition",
        "how a job is cut into tasks (any value gives the same output, except `anchor_block` in per-anchor mode)",
    ),
    (
        "stretch",
        "folds from the geometry alone (Chen 2011 ch. 4, `--folds stretch`); lengths in mean edge lengths",
    ),
    (
        "video",
        "folds from the capture video (Popa et al. 2009 §4, `--folds video`); distances in pixels of the full image",
    ),
];

const INTRO: &str = r#"# Tuning keys

Everything a run can be told besides its inputs is a tuning key. `crease run --help` lists only what changes
from shot to shot (input, output, the fold source and its files, the weight mode, the strain limit); the keys
below are set with `--set key=value` (repeatable) or in a job spec's `[tuning]` table, and both give the same
job:

```sh synopsis
crease run --input DIR --folds stretch --out OUT --set stretch.theta0_deg=25 --set deform.strain_limit=0.03
crease tuning            # this list
```

```toml runnable-spec
input = "/data/capture/sleeve"
output = "/data/out/sleeve"

[folds]
kind = "stretch"

[tuning]
stretch.theta0_deg = 25
deform.strain_limit = 0.03
```

A key names the spec field it sets: `deform.c_s` is `c_s` of the `[deform]` table, `partition.*` the fields
of `[partition]`, and `stretch.*` and `video.*` the fields of `[folds.params]` of a stretch or video job
(`video.front_vertex`, `back_vertex`, `first_image_number` and `overlay_frames` are fields of `[folds]`
itself). Those tables still work; `[tuning]` is applied after them, so a key set there wins. An unknown key, a
value of the wrong type or outside its range, and a fold source's key on a job whose folds come from elsewhere
are errors that name the key. Lists are written `1,1.5,2.5` after `--set` and `[1, 1.5, 2.5]` in a spec.

This page is generated from the registry of keys (`crease tuning --markdown`); a test checks that it matches.
"#;

/// docs/tuning.md.
pub fn page() -> String {
    let mut s = String::from(INTRO);
    for (group, about) in GROUPS {
        s.push_str(&format!("\n## {group}: {about}\n\n"));
        s.push_str("| key | type and range | default | meaning |\n|---|---|---|---|\n");
        for k in KNOBS.iter().filter(|k| k.group() == *group) {
            s.push_str(&format!(
                "| `{}` | {} | {} | {} |\n",
                k.key,
                cell(&k.kind.describe()),
                cell(&default_text(k)),
                cell(k.meaning)
            ));
        }
    }
    s.push_str(
        "\n## Removed settings\n\nA spec that names one of these fields is refused with the reason.\n\n\
         | field | why |\n|---|---|\n",
    );
    for (field, why) in REMOVED {
        s.push_str(&format!("| `{field}` | {why} |\n"));
    }
    s
}

/// The listing `crease tuning` prints: every key whose name starts with `prefix`.
pub fn listing(prefix: &str) -> String {
    let mut s = String::new();
    for k in KNOBS.iter().filter(|k| k.key.starts_with(prefix)) {
        s.push_str(&format!(
            "{} = {}    ({})\n    {}\n",
            k.key,
            default_text(k),
            k.kind.describe(),
            k.meaning
        ));
    }
    s
}

/// Text for a table cell: a `|` (as in |v|) would end the cell.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}

fn default_text(k: &Knob) -> String {
    k.kind.show(&k.default_value())
}
