//! What a coordinator refuses at submit (jobs over its size limits, locations outside its storage roots), and
//! how a job ends when its storage fails underneath it: a full disk (a real one: a small tmpfs mounted in a
//! user + mount namespace) or an S3 endpoint nobody listens on. Either way the job's tasks fail with "storage
//! full at …" / "storage unreachable at …" naming the location, and `report.json` (written last) never
//! exists, so nothing half-written is presented as complete.

mod common;

use common::*;
use crease_jobs::plan::limits::admit;
use crease_jobs::{plan, JobLimits, Storage, StorageRoots, TaskError};
use std::path::Path;
use std::process::Command;
use std::sync::OnceLock;

/// An S3 endpoint on a loopback port nobody listens on, set once for this test binary.
fn dead_endpoint() -> &'static str {
    static EP: OnceLock<String> = OnceLock::new();
    EP.get_or_init(|| {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let ep = format!("http://127.0.0.1:{port}");
        for (k, v) in [
            ("AWS_ACCESS_KEY_ID", "CREASETESTKEY"),
            ("AWS_SECRET_ACCESS_KEY", "crease-limits-secret-0d1e"),
            ("AWS_REGION", "us-east-1"),
            ("AWS_ENDPOINT_URL", ep.as_str()),
            ("AWS_ALLOW_HTTP", "true"),
            ("CREASE_STORAGE_TIMEOUT_SECS", "5"),
            ("CREASE_STORAGE_RETRIES", "1"),
        ] {
            std::env::set_var(k, v);
        }
        ep
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jobs_over_a_limit_are_refused_naming_the_limit_and_the_value() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 400, 5);
    let spec = job(&input, Some(&anchors), &root.path().join("out"), "");
    let roots = StorageRoots::default();
    let info = admit(&spec, &roots, &JobLimits::default()).await.unwrap();
    assert_eq!(info.n_frames, 5);

    let frames = JobLimits {
        max_frames: Some(4),
        ..Default::default()
    };
    let e = admit(&spec, &roots, &frames).await.unwrap_err().to_string();
    assert!(
        e.contains("--max-job-frames") && e.contains("5 frames") && e.contains("at most 4"),
        "{e}"
    );

    let vertices = JobLimits {
        max_vertices: Some(info.n_vertices - 1),
        ..Default::default()
    };
    let e = admit(&spec, &roots, &vertices)
        .await
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("--max-job-vertices") && e.contains(&format!("{} vertices", info.n_vertices)),
        "{e}"
    );
    // Exactly at the limits is accepted.
    let at = JobLimits {
        max_frames: Some(5),
        max_vertices: Some(info.n_vertices),
        max_input_bytes: Some(JobLimits::input_mib(1)),
    };
    admit(&spec, &roots, &at).await.unwrap();

    // The size limit is checked from metadata before the input is read: a 2 MiB input is refused at 1 MiB.
    std::fs::write(input.join("padding.bin"), vec![0u8; 2 * 1024 * 1024]).unwrap();
    let size = JobLimits {
        max_input_bytes: Some(JobLimits::input_mib(1)),
        ..Default::default()
    };
    let e = admit(&spec, &roots, &size).await.unwrap_err().to_string();
    assert!(
        e.contains("--max-job-input-mib") && e.contains(" MiB (2") && e.contains("at most 1 MiB"),
        "{e}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn locations_outside_the_storage_roots_are_refused_naming_the_field() {
    let root = tempfile::tempdir().unwrap();
    let data = root.path().join("data");
    std::fs::create_dir_all(&data).unwrap();
    let (input, anchors) = fixture(&data, 300, 4);
    let outside = root.path().join("data-evil");
    std::fs::create_dir_all(&outside).unwrap();
    let roots = StorageRoots::new(&[data.display().to_string()]).unwrap();
    let limits = JobLimits::default();
    admit(
        &job(&input, Some(&anchors), &data.join("out"), ""),
        &roots,
        &limits,
    )
    .await
    .unwrap();
    std::os::unix::fs::symlink(&outside, data.join("link-out")).unwrap();
    let evil_anchors = outside.join("anchors.json");
    std::fs::copy(&anchors, &evil_anchors).unwrap();
    for (field, spec) in [
        (
            "output",
            job(&input, Some(&anchors), &outside.join("out"), ""),
        ),
        (
            "output",
            job(&input, Some(&anchors), &data.join("link-out/out"), ""),
        ),
        (
            "folds.uri",
            job(&input, Some(&evil_anchors), &data.join("out2"), ""),
        ),
        (
            "input",
            job(
                &data.join("../data-evil"),
                Some(&anchors),
                &data.join("out3"),
                "",
            ),
        ),
    ] {
        let e = admit(&spec, &roots, &limits).await.unwrap_err().to_string();
        assert!(
            e.contains(&format!("`{field}`")) && (e.contains("outside") || e.contains("..")),
            "{field}: {e}"
        );
    }
    assert!(!outside.join("out").exists());
    assert!(!outside.join("out/report.json").exists());
}

/// The one test that runs inside a user + mount namespace (see [`disk_full_fails_the_job_and_leaves_no_report`]).
const INNER: &str = "CREASE_TEST_TMPFS_DIR";

#[test]
fn disk_full_fails_the_job_and_leaves_no_report() {
    if let Ok(dir) = std::env::var(INNER) {
        disk_full_inner(Path::new(&dir));
        println!("disk-full inner test ran on a tmpfs at {dir}");
        return;
    }
    // Re-run this test in a new user and mount namespace with two small tmpfs: a 192 KiB one for a job's
    // output, a 96 KiB one for a worker's cache.
    let root = tempfile::tempdir().unwrap();
    let mnt = root.path().join("small-disks");
    std::fs::create_dir_all(mnt.join("out")).unwrap();
    std::fs::create_dir_all(mnt.join("cache")).unwrap();
    let exe = std::env::current_exe().unwrap();
    let out = Command::new("unshare")
        .args(["--user", "--map-root-user", "--mount", "sh", "-c"])
        .arg(r#"mount -t tmpfs -o size=192k crease-out "$DIR/out" && mount -t tmpfs -o size=96k crease-cache "$DIR/cache" && exec "$EXE" --exact disk_full_fails_the_job_and_leaves_no_report --nocapture --test-threads 1"#)
        .env("DIR", &mnt)
        .env("EXE", &exe)
        .env(INNER, &mnt)
        .output()
        .expect("run unshare (util-linux)");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success() && text.contains("disk-full inner test ran"),
        "the disk-full test needs `unshare --user --map-root-user --mount` (unprivileged user namespaces) to \
         mount a small tmpfs; it failed:\n{text}"
    );
}

fn disk_full_inner(disks: &Path) {
    let mnt = &disks.join("out");
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let root = tempfile::tempdir().unwrap();
        let (input, anchors) = fixture(root.path(), 900, 9);
        let out = mnt.join("job");
        let spec = job(
            &input,
            Some(&anchors),
            &out,
            "[partition]\nframes_per_chunk = 3\n",
        );
        // The submit-time probe fits; the job's files do not.
        let run = run_job(&spec, &root.path().join("cache"), PLAN_ORDER).await;
        let failures: Vec<(&String, &TaskError)> = run
            .outcomes
            .iter()
            .filter_map(|(k, r)| r.as_ref().err().map(|e| (k, e)))
            .collect();
        assert!(!failures.is_empty(), "the job fit in 192 KiB?");
        println!("first failure: {}", failures[0].1);
        for (key, e) in &failures {
            assert!(
                e.reason.contains("storage full at ")
                    && e.reason.contains(&mnt.display().to_string()),
                "{key}: {e}"
            );
            assert!(
                !e.retryable(),
                "{key}: a full output volume is not retryable: {e}"
            );
        }
        assert!(
            !run.executed.iter().any(|k| k == "finalize"),
            "finalize ran after a failure: {:?}",
            run.executed
        );
        assert!(!out.join("report.json").exists());
        // No temporary file of a failed atomic write is left behind.
        let leftovers: Vec<_> = walk(&out)
            .into_iter()
            .filter(|p| {
                let name = p.file_name().unwrap_or_default().to_string_lossy();
                name.contains(".tmp") || name.contains('#')
            })
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");

        // The worker's own disk is full (its cache, where remote outputs are staged): retryable, since another
        // worker may have room; the message names the cache.
        let cache = disks.join("cache");
        let mut spec = spec.clone();
        spec.output = "memory://full-cache/job".into();
        let run = run_job(&spec, &cache, PLAN_ORDER).await;
        let failures: Vec<(&String, &TaskError)> = run
            .outcomes
            .iter()
            .filter_map(|(k, r)| r.as_ref().err().map(|e| (k, e)))
            .collect();
        assert!(!failures.is_empty(), "the staged outputs fit in 96 KiB?");
        println!("first cache failure: {}", failures[0].1);
        for (key, e) in &failures {
            assert!(
                e.reason.contains("storage full at ")
                    && e.reason.contains(&cache.display().to_string()),
                "{key}: {e}"
            );
            assert!(
                e.retryable(),
                "{key}: a full worker cache is retryable: {e}"
            );
        }
        let out = Storage::open(&spec.output).unwrap();
        assert!(!out.exists("report.json").await.unwrap());
    });
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut v = Vec::new();
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                v.extend(walk(&p));
            } else {
                v.push(p);
            }
        }
    }
    v
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unreachable_s3_endpoint_fails_at_submit_and_in_tasks_naming_the_url() {
    let ep = dead_endpoint();
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 300, 4);
    let remote_out = "s3://crease-nowhere/jobs/out";
    let mut spec = job(&input, Some(&anchors), &root.path().join("local-out"), "");
    spec.output = remote_out.into();
    // Submit: the output probe fails, naming the URI and the endpoint, within the retry budget.
    let e = admit(&spec, &StorageRoots::default(), &JobLimits::default())
        .await
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("storage unreachable at {remote_out}")) && e.contains(ep),
        "{e}"
    );
    assert!(!e.contains("crease-limits-secret"), "{e}");

    // Tasks (the storage went away after the submit): every attempt fails retryably with the same message,
    // so the coordinator retries it and then fails the job; finalize never runs.
    let local = job(&input, Some(&anchors), &root.path().join("local-out"), "");
    let info = crease_jobs::inspect_input(&local).await.unwrap();
    let tasks = plan(&spec, &info).unwrap();
    let ctx = ctx(&root.path().join("cache"));
    let first = tasks.iter().find(|t| t.deps.is_empty()).unwrap();
    let e = crease_jobs::execute(&first.spec, &ctx).await.unwrap_err();
    assert!(e.retryable(), "{e}");
    assert!(
        e.reason
            .contains(&format!("storage unreachable at {remote_out}"))
            && e.reason.contains(ep),
        "{e}"
    );
    let fin = tasks.iter().find(|t| t.key == "finalize").unwrap();
    let e = crease_jobs::execute(&fin.spec, &ctx).await.unwrap_err();
    assert!(e.reason.contains("storage unreachable"), "{e}");
    let out = Storage::open(remote_out).unwrap();
    assert!(out.exists("report.json").await.is_err());
}

/// An object store with a byte quota: once it is used up, puts fail with the error a full disk gives
/// (ENOSPC), as an S3-compatible server in front of a full volume or an exhausted quota would.
#[derive(Debug)]
struct QuotaStore {
    inner: object_store::memory::InMemory,
    left: std::sync::Mutex<u64>,
}

impl std::fmt::Display for QuotaStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "QuotaStore")
    }
}

mod quota {
    use super::QuotaStore;
    use futures::stream::BoxStream;
    use object_store::path::Path;
    use object_store::{
        CopyOptions, GetOptions, GetResult, ListResult, MultipartUpload, ObjectMeta, ObjectStore,
        PutMultipartOptions, PutOptions, PutPayload, PutResult, Result,
    };

    #[async_trait::async_trait]
    impl ObjectStore for QuotaStore {
        async fn put_opts(
            &self,
            location: &Path,
            payload: PutPayload,
            opts: PutOptions,
        ) -> Result<PutResult> {
            {
                let mut left = self.left.lock().unwrap();
                let n = payload.content_length() as u64;
                if n > *left {
                    return Err(object_store::Error::Generic {
                        store: "QuotaStore",
                        source: Box::new(std::io::Error::from_raw_os_error(28)),
                    });
                }
                *left -= n;
            }
            self.inner.put_opts(location, payload, opts).await
        }
        async fn put_multipart_opts(
            &self,
            _location: &Path,
            _opts: PutMultipartOptions,
        ) -> Result<Box<dyn MultipartUpload>> {
            Err(object_store::Error::NotImplemented {
                operation: "put_multipart_opts".into(),
                implementer: "QuotaStore".into(),
            })
        }
        async fn get_opts(&self, location: &Path, options: GetOptions) -> Result<GetResult> {
            self.inner.get_opts(location, options).await
        }
        fn delete_stream(
            &self,
            locations: BoxStream<'static, Result<Path>>,
        ) -> BoxStream<'static, Result<Path>> {
            self.inner.delete_stream(locations)
        }
        fn list(&self, prefix: Option<&Path>) -> BoxStream<'static, Result<ObjectMeta>> {
            self.inner.list(prefix)
        }
        async fn list_with_delimiter(&self, prefix: Option<&Path>) -> Result<ListResult> {
            self.inner.list_with_delimiter(prefix).await
        }
        async fn copy_opts(&self, from: &Path, to: &Path, options: CopyOptions) -> Result<()> {
            self.inner.copy_opts(from, to, options).await
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_object_store_fails_the_job_and_leaves_no_report() {
    let root = tempfile::tempdir().unwrap();
    let (input, anchors) = fixture(root.path(), 900, 9);
    crease_jobs::storage::register_store(
        "memory://quota-full",
        std::sync::Arc::new(QuotaStore {
            inner: object_store::memory::InMemory::new(),
            left: std::sync::Mutex::new(200 * 1024),
        }),
    );
    let mut spec = job(&input, Some(&anchors), &root.path().join("unused"), "");
    spec.output = "memory://quota-full/job".into();
    let run = run_job(&spec, &root.path().join("cache"), PLAN_ORDER).await;
    let failures: Vec<(&String, &TaskError)> = run
        .outcomes
        .iter()
        .filter_map(|(k, r)| r.as_ref().err().map(|e| (k, e)))
        .collect();
    assert!(!failures.is_empty(), "the job fit in 200 KiB?");
    for (key, e) in &failures {
        assert!(
            e.reason
                .contains("storage full at memory://quota-full/job/"),
            "{key}: {e}"
        );
        assert!(!e.retryable(), "{key}: {e}");
    }
    assert!(!run.executed.iter().any(|k| k == "finalize"));
    let out = Storage::open(&spec.output).unwrap();
    assert!(!out.exists("report.json").await.unwrap());
}
