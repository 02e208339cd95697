use super::*;
use crate::spec::FoldSpec;

fn spec(folds: &str, tuning: &str) -> Result<JobSpec, JobError> {
    JobSpec::from_toml_str(&format!(
        "input = \"/in\"\noutput = \"/out\"\n{folds}\n[tuning]\n{tuning}\n"
    ))
}

const STRETCH: &str = "[folds]\nkind = \"stretch\"\n";
const VIDEO: &str = "[folds]\nkind = \"video\"\ncameras = \"/c.json\"\n";

fn spec_err(r: Result<JobSpec, JobError>) -> (String, String) {
    match r {
        Err(JobError::Spec { field, msg }) => (field, msg),
        other => panic!("expected a spec error, got {other:?}"),
    }
}

/// Every key is unique, names a field the spec has, defaults to a value of its own type and range, and (for a
/// choice) every name it lists is a value the field takes.
#[test]
fn the_registry_describes_the_spec() {
    let mut seen = std::collections::HashSet::new();
    for k in KNOBS {
        assert!(seen.insert(k.key), "{} twice", k.key);
        assert!(
            ["deform", "partition", "stretch", "video"].contains(&k.group()),
            "{}",
            k.key
        );
        let d = k.default_value();
        assert_eq!(
            k.kind.check(&d).as_ref(),
            Ok(&d),
            "{}: default {d} is outside its own range",
            k.key
        );
        if let Kind::Choice(names) = k.kind {
            for name in names {
                let folds = match k.group() {
                    "stretch" => STRETCH,
                    "video" => VIDEO,
                    _ => "",
                };
                let s = spec(folds, &format!("{} = \"{name}\"", k.key));
                // `pinning = "vertex"` needs the screen off: a check across fields, not the value's type.
                if let Err(e) = s {
                    let (field, _) = spec_err(Err(e));
                    assert_eq!(field, "deform.pinning", "{}: {name}", k.key);
                }
            }
        }
    }
    // Each key's spec path is where a plain table sets the same field.
    let t = spec(
        STRETCH,
        "stretch.theta0_deg = 20\ndeform.c_s = 0.5\npartition.frames_per_chunk = 3",
    )
    .unwrap();
    let plain = JobSpec::from_toml_str(
        "input = \"/in\"\noutput = \"/out\"\n[folds]\nkind = \"stretch\"\n[folds.params]\ntheta0_deg = 20\n\
         [deform]\nc_s = 0.5\n[partition]\nframes_per_chunk = 3\n",
    )
    .unwrap();
    assert_eq!(t, plain);
    assert_eq!(
        find("video.front_vertex").unwrap().spec_path(),
        "folds.front_vertex"
    );
    assert_eq!(
        find("video.radii").unwrap().spec_path(),
        "folds.params.radii"
    );
}

/// `--set key=TEXT` and a `[tuning]` table give the same spec, for keys of every type.
#[test]
fn set_and_the_tuning_table_give_the_same_spec() {
    let pairs = [
        ("deform.c_s", "0.8", "0.8"),
        ("deform.window", "12", "12"),
        ("deform.stretch_rotation", "polar", "\"polar\""),
        ("deform.strain_limit", "0", "0"),
        ("partition.anchor_block", "64", "64"),
        ("video.radii", "1,2.5", "[1, 2.5]"),
        ("video.skip_border", "true", "true"),
        ("video.views", "front-back", "\"front-back\""),
        ("video.front_vertex", "3", "3"),
        ("video.back_vertex", "7", "7"),
        ("video.overlay_frames", "0,2", "[0, 2]"),
        ("video.temporal_radius", "0", "0"),
    ];
    let toml: String = pairs
        .iter()
        .map(|(k, _, v)| format!("{k} = {v}\n"))
        .collect();
    let from_toml = spec(VIDEO, &toml).unwrap();
    let mut built = JobSpec::new("/in", "/out");
    built.folds = FoldSpec::Video {
        cameras: "/c.json".into(),
        images: None,
        params: Default::default(),
        front_vertex: None,
        back_vertex: None,
        first_image_number: None,
        overlay_frames: Vec::new(),
    };
    for (k, text, _) in pairs {
        built.tuning.set_text(k, text).unwrap();
    }
    let from_set = built.resolved().unwrap();
    assert_eq!(from_set, from_toml);
    assert!(from_set.tuning.is_empty());
    assert_eq!(from_set.deform.coefficients.c_s, 0.8);
    assert_eq!(from_set.partition.anchor_block, 64);
    match &from_set.folds {
        FoldSpec::Video {
            params,
            front_vertex,
            overlay_frames,
            ..
        } => {
            assert_eq!(params.radii, vec![1.0, 2.5]);
            assert_eq!(params.views, crease_core::folds::video::Views::FrontBack);
            assert_eq!(*front_vertex, Some(3));
            assert_eq!(overlay_frames, &vec![0, 2]);
        }
        other => panic!("{other:?}"),
    }
    // Nested tables are the same keys; JSON reads as TOML does.
    let nested = spec(VIDEO, "[tuning.deform]\nc_s = 0.8\nwindow = 12\n").unwrap();
    assert_eq!(nested.deform.window, 12);
    let json = JobSpec::from_json_str(
        r#"{"input": "/in", "output": "/out", "tuning": {"deform.c_s": 0.8, "deform": {"window": 12}}}"#,
    )
    .unwrap();
    assert_eq!(json.deform, nested.deform);
    // What the coordinator stores reads back as the same spec.
    let stored = serde_json::to_string(&from_set).unwrap();
    assert_eq!(JobSpec::from_json_str(&stored).unwrap(), from_set);
}

/// Unknown keys, bad values and keys of another fold source are refused naming the key, from a spec and from
/// `--set` alike.
#[test]
fn bad_keys_and_values_name_the_key() {
    let cases: [(&str, &str, &str, &str); 10] = [
        (
            "",
            "deform.c_z = 1",
            "tuning.deform.c_z",
            "not a tuning key",
        ),
        (
            "",
            "deform.theta0_deg = 1",
            "tuning.deform.theta0_deg",
            "stretch.theta0_deg",
        ),
        ("", "deform.c_a = 0", "tuning.deform.c_a", "> 0"),
        (
            "",
            "deform.window = 2.5",
            "tuning.deform.window",
            "whole number",
        ),
        (
            "",
            "deform.mode = \"magic\"",
            "tuning.deform.mode",
            "fused, per-anchor",
        ),
        (
            "",
            "stretch.alpha = 1",
            "tuning.stretch.alpha",
            "stretch folds only",
        ),
        (
            STRETCH,
            "stretch.theta0_deg = 95",
            "tuning.stretch.theta0_deg",
            "(0, 90)",
        ),
        (
            VIDEO,
            "video.radii = []",
            "tuning.video.radii",
            "at least one",
        ),
        (
            "",
            "deform.release_share = 1.5",
            "tuning.deform.release_share",
            "[0, 1]",
        ),
        (
            "",
            "deform.operator_block = 7",
            "tuning.deform.operator_block",
            "was removed",
        ),
    ];
    for (folds, line, field, want) in cases {
        let (f, msg) = spec_err(spec(folds, line));
        assert_eq!(f, field, "{line}: {msg}");
        assert!(msg.contains(want), "{line}: {msg}");
    }
    let mut t = Tuning::default();
    let e = t.set_text("deform.c_s", "abc").unwrap_err();
    assert!(e.contains("deform.c_s") && e.contains("`abc`"), "{e}");
    let e = t.set_text("video.nope", "1").unwrap_err();
    assert!(e.contains("video.nope"), "{e}");
    t.set_text("deform.c_s", "1").unwrap();
    assert!(t.set_text("deform.c_s", "2").unwrap_err().contains("twice"));
    // A check across fields names the field; `key_of_field` gives the key a `--set` user wrote.
    let (field, msg) = spec_err(spec(STRETCH, "stretch.min_shrink = 3"));
    assert_eq!(field, "folds.params.min_shrink", "{msg}");
    let s = spec(STRETCH, "").unwrap();
    assert_eq!(key_of_field(&s, &field), Some("stretch.min_shrink"));
    assert_eq!(key_of_field(&s, "deform.shift"), Some("deform.shift"));
    assert_eq!(key_of_field(&s, "folds.front_vertex"), None);
}

/// A spec naming a removed field says what became of it.
#[test]
fn removed_fields_say_why() {
    for (table, line, field) in [
        ("[deform]", "operator_block = 7", "operator_block"),
        (
            "[deform]",
            "projection_order = \"around\"",
            "projection_order",
        ),
        ("[folds.params]", "all_views = true", "all_views"),
        ("[folds.params]", "flattening = \"lscm\"", "flattening"),
    ] {
        let folds = if table == "[deform]" { "" } else { VIDEO };
        let text = format!("input = \"/in\"\noutput = \"/out\"\n{folds}{table}\n{line}\n");
        let err = JobSpec::from_toml_str(&text).unwrap_err().to_string();
        assert!(
            err.contains(&format!("`{field}` was removed:")),
            "{line}: {err}"
        );
    }
}

/// docs/tuning.md is the registry's page, and every row of its tables has its four cells.
#[test]
fn the_tuning_page_is_the_registry() {
    let generated = markdown::page();
    for row in generated.lines().filter(|l| l.starts_with("| `")) {
        let cells = row.replace("\\|", "").matches('|').count();
        assert!(cells == 5 || cells == 3, "a `|` breaks the row: {row}");
    }
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/tuning.md");
    let page = std::fs::read_to_string(path).unwrap_or_default();
    assert!(
        page == generated,
        "docs/tuning.md differs from the registry: regenerate it with `crease tuning --markdown > docs/tuning.md`"
    );
}
