//! Object storage and admission limits with real processes: a coordinator and workers on 127.0.0.1 whose
//! `AWS_*` environment points at a local S3-compatible server (`moto_server`, see `jobs/tests/moto`), a job
//! read from and written to `s3://`, compared byte for byte with `crease run`; traversal attempts and jobs
//! over a limit refused at submit; a worker that cannot reach the object store failing the job with a
//! message naming the URL, and no `report.json`.

#[path = "../../jobs/tests/moto/mod.rs"]
mod moto;

use crease_e2e::*;
use crease_jobs::Storage;
use moto::*;
use std::path::Path;
use std::process::Command;

fn block_on<F: std::future::Future>(f: F) -> F::Output {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(f)
}

/// Copies every file of a local directory under the `s3://` prefix `uri`.
fn upload_dir(dir: &Path, uri: &str) {
    block_on(async {
        let s = Storage::open(uri).unwrap();
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_file() {
                let name = p.file_name().unwrap().to_string_lossy().into_owned();
                s.put(&name, std::fs::read(&p).unwrap()).await.unwrap();
            }
        }
    })
}

/// Copies the top-level objects under `uri` (the output files and `report.json`, not the intermediates) into
/// a local directory.
fn download(uri: &str, dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    block_on(async {
        let s = Storage::open(uri).unwrap();
        for key in s.list("").await.unwrap() {
            if !key.contains('/') {
                std::fs::write(dir.join(&key), s.get(&key).await.unwrap()).unwrap();
            }
        }
    })
}

#[test]
fn an_s3_job_on_a_cluster_writes_the_same_bytes_as_crease_run() {
    moto();
    let (dir, anchors) = setup();
    let d = dir.path();
    let base = format!("s3://{BUCKET}/cluster");
    upload_dir(&fixture(), &format!("{base}/in/sleeve"));
    block_on(async {
        Storage::open(&format!("{base}/in"))
            .unwrap()
            .put("anchors.json", std::fs::read(&anchors).unwrap())
            .await
            .unwrap()
    });
    local_run(
        &fixture(),
        &anchors,
        &d.join("reference"),
        "per-anchor",
        "1",
    );

    let c = Coordinator::start(d, &[]);
    let _w1 = c.worker("s3-a", &[]);
    let _w2 = c.worker("s3-b", &[]);
    let out = format!("{base}/out/job");
    let job = job_file(
        d,
        "s3",
        Path::new(&format!("{base}/in/sleeve")),
        Path::new(&format!("{base}/in/anchors.json")),
        Path::new(&out),
        "per-anchor",
        "",
    );
    let id = c.submit(&job);
    let s = c.wait_state(&id, &["done", "failed"]);
    assert_eq!(s["state"], "done", "{s}");
    download(&out, &d.join("downloaded"));
    assert_complete_and_identical(&d.join("reference"), &d.join("downloaded"));

    // The credentials appear nowhere: not in the job's status, not in the workers' logs.
    let mut seen = s.to_string();
    for name in ["s3-a", "s3-b"] {
        seen += &std::fs::read_to_string(d.join(format!("worker-{name}.log"))).unwrap();
    }
    assert!(!seen.contains(SECRET_KEY));
}

#[test]
fn traversal_and_oversized_jobs_are_refused_at_submit() {
    let (dir, anchors) = setup();
    let d = dir.path();
    let data = d.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let input = data.join("sleeve");
    std::fs::create_dir_all(&input).unwrap();
    for e in std::fs::read_dir(fixture()).unwrap() {
        let p = e.unwrap().path();
        std::fs::copy(&p, input.join(p.file_name().unwrap())).unwrap();
    }
    std::fs::copy(&anchors, data.join("anchors.json")).unwrap();
    let anchors = data.join("anchors.json");
    let evil = d.join("data-evil");
    std::fs::create_dir_all(&evil).unwrap();
    std::os::unix::fs::symlink(&evil, data.join("escape")).unwrap();
    let root = data.display().to_string();
    let c = Coordinator::start(
        d,
        &[
            "--storage-root",
            &root,
            "--storage-root",
            "s3://farm/jobs",
            "--max-job-frames",
            "3",
        ],
    );
    let refused = |name: &str, input: &Path, anchors: &Path, out: &Path, want: &[&str]| {
        let job = job_file(d, name, input, anchors, out, "fused", "");
        let o = c.cli(&["submit", job.to_str().unwrap()]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{name} was accepted");
        for w in want {
            assert!(err.contains(w), "{name}: {err}");
        }
    };
    refused(
        "outside",
        &input,
        &anchors,
        &evil.join("out"),
        &["`output`", "outside"],
    );
    refused(
        "prefix",
        &input,
        &anchors,
        &d.join("data-evil/out"),
        &["`output`", "outside"],
    );
    refused(
        "symlink",
        &input,
        &anchors,
        &data.join("escape/out"),
        &["`output`", "outside"],
    );
    refused(
        "dotdot",
        &data.join("../data-evil"),
        &anchors,
        &data.join("o"),
        &["`input`", ".."],
    );
    refused(
        "s3-prefix",
        &input,
        &anchors,
        Path::new("s3://farm/jobs-evil/out"),
        &["`output`", "outside"],
    );
    refused(
        "s3-dotdot",
        &input,
        &anchors,
        Path::new("s3://farm/jobs/%2e%2e/secrets"),
        &["`output`"],
    );
    refused(
        "anchors",
        &input,
        &evil.join("anchors.json"),
        &data.join("o"),
        &["`folds.uri`", "outside"],
    );
    // Inside the roots, the frame limit is what refuses it.
    refused(
        "frames",
        &input,
        &anchors,
        &data.join("out"),
        &["--max-job-frames", "4 frames", "at most 3"],
    );
    assert!(!evil.join("out").exists() && !data.join("escape/out").exists());
    let o = c.cli(&["jobs", "--json"]);
    let jobs: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(jobs, serde_json::json!([]), "refused jobs were queued");

    // The other limits, from a second coordinator.
    let d2 = d.join("c2");
    std::fs::create_dir_all(&d2).unwrap();
    let c2 = Coordinator::start(
        &d2,
        &["--max-job-vertices", "100", "--max-job-input-mib", "4"],
    );
    let job = job_file(
        d,
        "vertices",
        &input,
        &anchors,
        &data.join("o2"),
        "fused",
        "",
    );
    let o = c2.cli(&["submit", job.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--max-job-vertices"), "{}", stderr(&o));
    std::fs::write(input.join("padding.bin"), vec![0u8; 5 << 20]).unwrap();
    let o = c2.cli(&["submit", job.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--max-job-input-mib"), "{}", stderr(&o));

    // A root that does not exist stops the coordinator at start, naming the flag (here from the environment).
    let o = Command::new(bin())
        .args(["coordinator", "--listen", "127.0.0.1:0", "--db"])
        .arg(d.join("never.sqlite"))
        .env(
            "CREASE_STORAGE_ROOTS",
            format!("{root},{}", d.join("missing").display()),
        )
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--storage-root"), "{}", stderr(&o));
}

#[test]
fn a_worker_that_cannot_reach_the_store_fails_the_job_naming_the_url() {
    moto();
    let (dir, anchors) = setup();
    let d = dir.path();
    let c = Coordinator::start(d, &["--retry-backoff-ms", "50"]);
    // The coordinator reaches the store (the submit's output probe passes); the worker's endpoint is a
    // closed port, as when the store goes away after the submit.
    let dead = format!("http://127.0.0.1:{}", closed_port());
    let _w = c.worker("cut-off", &[("AWS_ENDPOINT_URL", dead.as_str())]);
    let out = format!("s3://{BUCKET}/unreachable/out");
    let job = job_file(
        d,
        "unreachable",
        &fixture(),
        &anchors,
        Path::new(&out),
        "fused",
        "max_task_attempts = 2",
    );
    let id = c.submit(&job);
    let s = c.wait_state(&id, &["failed", "done"]);
    assert_eq!(s["state"], "failed", "{s}");
    let msg = s["message"].as_str().unwrap();
    assert!(
        msg.contains(&format!("storage unreachable at {out}")) && msg.contains(&dead),
        "{msg}"
    );
    assert!(!s.to_string().contains(SECRET_KEY));
    let report = block_on(async { Storage::open(&out).unwrap().exists("report.json").await });
    assert!(!report.unwrap(), "report.json exists for a failed job");
}
