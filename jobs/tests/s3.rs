//! Object storage end to end against a real S3-compatible server (`moto_server`, see `moto/mod.rs`): a job
//! whose input, anchors and output are all `s3://` URLs, run in process task by task (in a shuffled order with
//! reruns), writes the same bytes as the single-machine reference run; keys cannot leave their prefix; errors
//! name the URI and never carry the credentials.

mod common;
mod moto;

use common::*;
use crease_jobs::{final_outputs, JobSpec, Storage};
use moto::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn s3_input_anchors_and_output_match_the_local_run() {
    moto();
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 900, 9);
    let base = format!("s3://{BUCKET}/e2e");
    let seq = Storage::open(&format!("{base}/capture/seq")).unwrap();
    assert!(seq.local_path().is_none());
    for (name, bytes) in files(&input, &[]) {
        seq.put(&name, bytes).await.unwrap();
    }
    let capture = Storage::open(&format!("{base}/capture")).unwrap();
    capture
        .put("anchors.json", std::fs::read(&anchors).unwrap())
        .await
        .unwrap();
    assert_eq!(capture.list("seq").await.unwrap().len(), 9);

    let spec = JobSpec::from_toml_str(&format!(
        "input = \"{base}/capture/seq\"\noutput = \"{base}/out/job\"\n\
         [folds]\nkind = \"anchors\"\nuri = \"{base}/capture/anchors.json\"\n\
         [deform]\nmode = \"per-anchor\"\nwindow = 5\nshift = 3\n[partition]\nanchor_block = 25\nframes_per_chunk = 2\n"
    ))
    .unwrap();
    let run = run_job(
        &spec,
        &root.path().join("cache"),
        Order { seed: 29, rerun: 4 },
    )
    .await;
    for (k, r) in &run.outcomes {
        assert!(r.is_ok(), "task {k} failed: {:?}", r.as_ref().err());
    }
    let reference_dir = root.path().join("reference");
    reference(&input, Some(&anchors), &spec.params(), &reference_dir);
    let out = Storage::open(&spec.output).unwrap();
    let expected = files(&reference_dir, &[]);
    assert!(expected.len() >= 9, "{:?}", expected.keys());
    for (name, bytes) in expected {
        assert!(out.get(&name).await.unwrap() == bytes, "{name} differs");
    }
    for key in final_outputs(&spec, &run.info) {
        assert!(out.exists(&key).await.unwrap(), "{key} missing");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&out.get("report.json").await.unwrap()).unwrap();
    assert_eq!(report["complete"], true);
    let keys = out.list("").await.unwrap();
    assert!(
        keys.iter()
            .any(|k| k.starts_with(".crease-work/positions/")),
        "{keys:?}"
    );
    // Nothing was written beside the job's prefix.
    let bucket = Storage::open(&format!("s3://{BUCKET}")).unwrap();
    for k in bucket.list("e2e").await.unwrap() {
        assert!(
            k.starts_with("e2e/capture/") || k.starts_with("e2e/out/job/"),
            "{k}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn s3_keys_cannot_leave_their_prefix_and_errors_hide_credentials() {
    moto();
    let store = Storage::open(&format!("s3://{BUCKET}/confined/job")).unwrap();
    store.put("ok.txt", b"fine".to_vec()).await.unwrap();
    for bad in [
        "../escape.txt",
        "a/../../escape.txt",
        "%2e%2e/escape.txt",
        "a%2f..%2f..%2fescape.txt",
        "..\\escape.txt",
        "/escape.txt",
        "a//b",
    ] {
        let e = store.put(bad, b"x".to_vec()).await.unwrap_err().to_string();
        assert!(e.contains("invalid key"), "{bad}: {e}");
        assert!(store.get(bad).await.is_err(), "{bad}");
    }
    let bucket = Storage::open(&format!("s3://{BUCKET}")).unwrap();
    let all = bucket.list("").await.unwrap();
    assert!(all.iter().all(|k| !k.contains("escape")), "{all:?}");
    assert!(all.contains(&"confined/job/ok.txt".to_string()), "{all:?}");

    // A spec whose URI walks out of its prefix is refused before anything is read.
    for (field, toml) in [
        (
            "input",
            format!("input = \"s3://{BUCKET}/data/../secret\"\noutput = \"s3://{BUCKET}/o\"\n"),
        ),
        (
            "output",
            format!("input = \"s3://{BUCKET}/i\"\noutput = \"s3://{BUCKET}/data/%2E%2E/x\"\n"),
        ),
        (
            "folds.uri",
            format!(
                "input = \"s3://{BUCKET}/i\"\noutput = \"s3://{BUCKET}/o\"\n\
                 [folds]\nkind = \"anchors\"\nuri = \"s3://{BUCKET}/a//b.json\"\n"
            ),
        ),
    ] {
        let e = JobSpec::from_toml_str(&toml).unwrap_err().to_string();
        assert!(e.contains(&format!("`{field}`")), "{field}: {e}");
    }

    // Errors name the URI; neither they nor anything else we print carry the secret key.
    let missing = format!("s3://{BUCKET}/no/such/input");
    let mut spec = JobSpec::from_toml_str(&format!(
        "input = \"{missing}\"\noutput = \"s3://{BUCKET}/o2\"\n"
    ))
    .unwrap();
    let e = crease_jobs::inspect_input(&spec)
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains(&missing), "{e}");
    assert!(!e.contains(SECRET_KEY), "{e}");
    spec.output = "s3://no-such-bucket-crease/out".into();
    spec.input = format!("s3://{BUCKET}/e2e-missing");
    let no_bucket = Storage::open(&spec.output)
        .unwrap()
        .put("x", b"x".to_vec())
        .await
        .unwrap_err()
        .to_string();
    assert!(
        no_bucket.contains("s3://no-such-bucket-crease/out/x"),
        "{no_bucket}"
    );
    assert!(!no_bucket.contains(SECRET_KEY), "{no_bucket}");
    assert!(!format!("{store:?}").contains(SECRET_KEY));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn large_files_are_uploaded_in_parts_and_read_back_identically() {
    moto();
    let dir = tempfile::tempdir().unwrap();
    // 12 MiB and a bit: two 5 MiB parts and a short last one.
    let mut seed = 0x2545f4914f6cdd1du64;
    let data: Vec<u8> = (0..(12 << 20) + 123)
        .map(|_| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed as u8
        })
        .collect();
    let file = dir.path().join("take.pc2");
    std::fs::write(&file, &data).unwrap();
    let store = Storage::open(&format!("s3://{BUCKET}/multipart/job")).unwrap();
    store.put_file("take.pc2", &file).await.unwrap();
    assert!(store.get("take.pc2").await.unwrap() == data);
    // S3 gives objects assembled from parts an e-tag ending in `-<number of parts>`.
    let url = url::Url::parse(&format!("s3://{BUCKET}/multipart/job/take.pc2")).unwrap();
    let (raw, path) = crease_jobs::storage::remote_store(&url).unwrap();
    let meta = object_store::ObjectStoreExt::head(raw.as_ref(), &path)
        .await
        .unwrap();
    let etag = meta.e_tag.unwrap_or_default();
    assert!(
        etag.trim_matches('"').ends_with("-3"),
        "e-tag {etag}: not a 3-part upload"
    );
    // A small file takes the single-PUT path.
    std::fs::write(dir.path().join("small.obj"), b"v 0 0 0\n").unwrap();
    store
        .put_file("small.obj", &dir.path().join("small.obj"))
        .await
        .unwrap();
    assert_eq!(&store.get("small.obj").await.unwrap()[..], b"v 0 0 0\n");
    // An upload that cannot complete leaves no object behind and names the URI.
    let nowhere = Storage::open("s3://no-such-bucket-crease/multipart").unwrap();
    let e = nowhere
        .put_file("take.pc2", &file)
        .await
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("s3://no-such-bucket-crease/multipart/take.pc2"),
        "{e}"
    );
    assert!(!e.contains(SECRET_KEY), "{e}");
    // A missing source file is named too.
    let e = store
        .put_file("x", &dir.path().join("missing.pc2"))
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.pc2"), "{e}");
    assert!(!store.exists("x").await.unwrap());
}
