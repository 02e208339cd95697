//! Job spec names: a field is spelled as its tuning key names it (`c_s`, `cg_max_iterations`, `theta0_deg`), and
//! the older short names (`cg_max_iter`, `theta0`, `canny_radii`) and the nested `coefficients` table are read
//! too. Errors name the field at fault.

use crease_jobs::{FoldSpec, JobError, JobSpec};

const HEAD: &str = "input = \"/in\"\noutput = \"/out\"\n";

fn spec(body: &str) -> Result<JobSpec, JobError> {
    JobSpec::from_toml_str(&format!("{HEAD}{body}"))
}

fn field(e: JobError) -> String {
    match e {
        JobError::Spec { field, .. } => field,
        other => panic!("not a spec error: {other}"),
    }
}

#[test]
fn flag_names_and_long_names_mean_the_same() {
    let short = spec("[deform]\nc_s = 0.7\nc_a = 12.0\ncg_tol = 1e-4\ncg_max_iter = 50\n").unwrap();
    let long = spec(
        "[deform]\ncg_tolerance = 1e-4\ncg_max_iterations = 50\n[deform.coefficients]\nc_s = 0.7\nc_a = 12.0\n",
    )
    .unwrap();
    assert_eq!(short.deform, long.deform);
    assert_eq!(short.deform.coefficients.c_s, 0.7);
    assert_eq!(
        short.deform.coefficients.c_t, 0.5,
        "unset coefficients keep their defaults"
    );
    assert_eq!(short.deform.cg_max_iterations, 50);
    // What a coordinator stores (serde_json of the spec) reads back the same.
    let stored = serde_json::to_string(&short).unwrap();
    assert_eq!(JobSpec::from_json_str(&stored).unwrap(), short);

    let stretch = |k: &str| match spec(&format!(
        "[folds]\nkind = \"stretch\"\n[folds.params]\n{k} = 25.0\n"
    ))
    .unwrap()
    .folds
    {
        FoldSpec::Stretch { params, .. } => params.theta0_deg,
        other => panic!("{other:?}"),
    };
    assert_eq!(stretch("theta0"), 25.0);
    assert_eq!(stretch("theta0_deg"), 25.0);
    let video = spec("[folds]\nkind = \"video\"\ncameras = \"/c.json\"\n[folds.params]\ncanny_radii = [1.0, 2.0]\nwide_angle = 20.0\n")
        .unwrap();
    match video.folds {
        FoldSpec::Video { params, .. } => {
            assert_eq!(params.radii, vec![1.0, 2.0]);
            assert_eq!(params.wide_angle_deg, 20.0);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn errors_name_the_field() {
    let twice = spec("[deform]\nc_s = 0.7\n[deform.coefficients]\nc_s = 0.8\n").unwrap_err();
    assert!(
        twice.to_string().contains("`c_s` is given twice"),
        "{twice}"
    );
    assert_eq!(
        field(spec("[deform]\nc_s = -1.0\n").unwrap_err()),
        "deform.c_s"
    );
    assert_eq!(
        field(spec("[deform]\ncs = 1.0\n").unwrap_err()),
        "deform.cs"
    );
    let no_output = JobSpec::from_toml_str("name = \"x\"\ninput = \"/in\"\n").unwrap_err();
    assert_eq!(field(no_output), "output");
    let no_input = JobSpec::from_json_str("{\"name\": \"x\", \"output\": \"/o\"}").unwrap_err();
    assert_eq!(field(no_input), "input");
}
