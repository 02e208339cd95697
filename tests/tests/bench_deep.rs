//! `crease bench --deep` at a tiny size: it runs, reports the inference steps (the default model's detail
//! filter, the rasterised map, the generator at each size), the writing and the training step, and refuses
//! nonsense. Timings are only checked to be measured (positive, finite), never against a bound.
#![cfg(feature = "deep")]

use std::process::Command;

#[test]
fn bench_deep_reports_rasterisation_forward_and_training_times() {
    let tmp = tempfile::tempdir().unwrap();
    let json = tmp.path().join("deep.json");
    let o = Command::new(crease_e2e::bin())
        .args([
            "bench",
            "--deep",
            "--threads",
            "1",
            "--deep-resolution",
            "64",
        ])
        .args([
            "--deep-filters",
            "4,2",
            "--repeats",
            "2",
            "--deep-train-steps",
            "1",
        ])
        .args(["--json", json.to_str().unwrap()])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("generator forward"), "{out}");
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let d = &doc["deep"];
    assert_eq!(d["resolution"], 64);
    assert_eq!(d["threads"], 1);
    assert_eq!(d["vertices"], 80 * 92, "the sleeve-sized tube");
    for key in [
        "raster_ms",
        "forward_ms",
        "train_step_ms",
        "training_s",
        "detail_map_ms",
        "encode_frame_ms",
        "write_files_ms",
        "sync_frame_ms",
        "frame_bytes",
    ] {
        let v = d[key].as_f64().unwrap_or(f64::NAN);
        assert!(v.is_finite() && v > 0.0, "{key} = {v}");
    }
    // Both generator sizes, in the order asked, each with its own forward and training times.
    let gens = d["generators"].as_array().unwrap();
    assert_eq!(gens.len(), 2);
    for (g, filters) in gens.iter().zip([4, 2]) {
        assert_eq!(g["filters"], filters);
        for key in ["forward_ms", "train_step_ms", "training_s"] {
            let v = g[key].as_f64().unwrap_or(f64::NAN);
            assert!(v.is_finite() && v > 0.0, "{filters} filters: {key} = {v}");
        }
    }
    assert_eq!(d["filters"], 4);
    assert_eq!(d["png_encoders"].as_array().unwrap().len(), 5);
    let write = d["encode_frame_ms"].as_f64().unwrap() + d["write_files_ms"].as_f64().unwrap();
    assert!((d["write_frame_ms"].as_f64().unwrap() - write).abs() < 1e-9);
    assert!(out.contains("target ≤ 50 ms"), "{out}");
    let coverage = d["coverage"].as_f64().unwrap();
    assert!(coverage > 0.1 && coverage <= 1.0, "coverage {coverage}");
    // Per frame: the detail model's map and the generator's forward pass.
    let sum = d["detail_map_ms"].as_f64().unwrap() + d["forward_ms"].as_f64().unwrap();
    assert!((d["per_frame_ms"].as_f64().unwrap() - sum).abs() < 1e-9);

    // A resolution the generator cannot take is a clear error, not a panic.
    let o = Command::new(crease_e2e::bin())
        .args([
            "bench",
            "--deep",
            "--deep-resolution",
            "48",
            "--repeats",
            "1",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("resolution") && err.contains("48"), "{err}");
}
