//! The remote-storage path: input, anchors and output behind object-store URLs (process-wide `memory://`
//! stores), so inputs are fetched into the worker cache and outputs are staged and uploaded. The objects
//! written are byte-identical to the local reference run.

mod common;

use common::*;
use crease_jobs::{final_outputs, JobSpec, Storage};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn object_store_input_and_output_match_the_local_run() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 900, 9);
    let seq_store = Storage::open("memory://remote-in/capture/seq").unwrap();
    assert!(seq_store.local_path().is_none());
    for (name, bytes) in files(&input, &[]) {
        seq_store.put(&name, bytes).await.unwrap();
    }
    let in_store = Storage::open("memory://remote-in/capture").unwrap();
    in_store
        .put("anchors.json", std::fs::read(&anchors).unwrap())
        .await
        .unwrap();
    assert_eq!(in_store.list("seq").await.unwrap().len(), 9);

    let spec = JobSpec::from_toml_str(
        "input = \"memory://remote-in/capture/seq\"\noutput = \"memory://remote-out/job\"\n\
         [folds]\nkind = \"anchors\"\nuri = \"memory://remote-in/capture/anchors.json\"\n\
         [deform]\nmode = \"per-anchor\"\nwindow = 5\nshift = 3\n[partition]\nanchor_block = 25\nframes_per_chunk = 2\n",
    )
    .unwrap();
    let run = run_job(
        &spec,
        &root.path().join("cache"),
        Order { seed: 17, rerun: 3 },
    )
    .await;
    for (k, r) in &run.outcomes {
        assert!(r.is_ok(), "task {k} failed: {:?}", r.as_ref().err());
    }
    let reference_dir = root.path().join("reference");
    reference(&input, Some(&anchors), &spec.params(), &reference_dir);
    let out = Storage::open(&spec.output).unwrap();
    for (name, bytes) in files(&reference_dir, &[]) {
        assert!(out.get(&name).await.unwrap() == bytes, "{name} differs");
    }
    for key in final_outputs(&spec, &run.info) {
        assert!(out.exists(&key).await.unwrap(), "{key} missing");
    }
    let keys = out.list("").await.unwrap();
    assert!(
        keys.iter().any(|k| k.starts_with(".crease-work/weights/")),
        "{keys:?}"
    );
    // The worker cache serves an object again only while it is unchanged (here: same size, new content).
    let cache = root.path().join("cache");
    let uri = "memory://remote-in/capture/anchors.json";
    let first = crease_jobs::fetch_input_to_cache(uri, &cache)
        .await
        .unwrap();
    let len = std::fs::metadata(&first).unwrap().len() as usize;
    in_store.put("anchors.json", vec![b' '; len]).await.unwrap();
    let again = crease_jobs::fetch_input_to_cache(uri, &cache)
        .await
        .unwrap();
    assert_eq!(std::fs::read(&again).unwrap(), vec![b' '; len]);
    // A missing remote input is named at submit.
    let mut bad = spec.clone();
    bad.input = "memory://remote-in/capture/nothing-here".into();
    let e = crease_jobs::inspect_input(&bad)
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("memory://remote-in/capture/nothing-here"), "{e}");
}
