//! The soak: the cluster's crash tolerance measured on loopback. A coordinator and workers run as child
//! processes (of the `crease` executable under test); several client threads submit small jobs concurrently with
//! `crease submit --watch` (one process per job, as a user on the farm would), while a chaos thread SIGKILLs
//! random workers at random times and starts them again. Every job must end `done` with the same bytes as a
//! single-node `crease run` of its input, whatever partition the job used and however often its tasks were
//! interrupted.
//!
//! The kills are bounded (`--kills` within `--kill-window-secs`) and each job allows more attempts per task than
//! there are kills, so the cluster can always finish: a job that still fails or differs is a bug, not bad luck.
//! Only processes this harness started are ever signalled, and every child is killed when its handle drops,
//! so a deadline or an error leaves nothing running.
//!
//! `--secure` runs the cluster as production does: TLS on every gRPC connection (certificates from
//! `crease certs`), bearer tokens for clients (two accepted tokens, as during a rotation, the clients split
//! between them) and a worker token. Either way the coordinator serves Prometheus metrics, and the soak ends by
//! scraping them: the queue must be empty, nothing running, and the coordinator's count of done jobs must be
//! the harness's own.

use anyhow::{bail, Context, Result};
use clap::Args;
use crease_core::synth::{self, DemoSpec};
use crease_e2e::{try_free_port, try_output_files, Proc};
use serde_json::json;
use std::ffi::{OsStr, OsString};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct SoakArgs {
    /// Jobs submitted.
    #[arg(long, default_value_t = 50)]
    pub jobs: usize,
    /// Concurrent clients submitting them.
    #[arg(long, default_value_t = 5)]
    pub clients: usize,
    /// Worker processes.
    #[arg(long, default_value_t = 3)]
    pub workers: usize,
    /// Most worker kills (SIGKILL, then a restart) during the soak.
    #[arg(long, default_value_t = 10)]
    pub kills: usize,
    /// The kills happen at random times within this many seconds of the start of the submissions.
    #[arg(long, default_value_t = 15.0)]
    pub kill_window_secs: f64,
    /// Seed of the chaos schedule and of the clients' pacing.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Keep the soak's files (inputs, references, outputs, queue, logs) in this new directory.
    #[arg(long)]
    pub keep: Option<PathBuf>,
    /// The soak fails if its jobs have not all ended after this many seconds.
    #[arg(long, default_value_t = 600.0)]
    pub deadline_secs: f64,
    /// Run the soak's cluster in the production configuration: TLS everywhere (a CA from `crease certs`),
    /// client tokens (two, in rotation) and a worker token.
    #[arg(long)]
    pub secure: bool,
}

/// Deformation settings shared by the references and the jobs: short windows so even four frames give several
/// windows, cross-fades and (per-anchor) reduce tasks.
const WINDOW: usize = 3;
const SHIFT: usize = 2;
const PREVIEW_SIZE: u32 = 64;

/// The distinct inputs: sizes, frame counts, anchor sets and weight modes differ so the jobs' task graphs do.
struct CaseDef {
    name: &'static str,
    triangles: usize,
    frames: usize,
    mode: &'static str,
    /// Random anchors per frame (seeded); `None` = the demo's own fold anchors.
    random_anchors: Option<usize>,
    /// Anchor columns per weight block (per-anchor mode). Part of the arithmetic (blocks are summed in block
    /// order), so the reference uses the same value; it only changes the task graph between cases.
    anchor_block: usize,
}

const CASES: [CaseDef; 4] = [
    CaseDef {
        name: "tube600-demo-fused",
        triangles: 600,
        frames: 4,
        mode: "fused",
        random_anchors: None,
        anchor_block: 32,
    },
    CaseDef {
        name: "tube1200-demo-per-anchor",
        triangles: 1200,
        frames: 5,
        mode: "per-anchor",
        random_anchors: None,
        anchor_block: 32,
    },
    CaseDef {
        name: "tube2000-random-per-anchor",
        triangles: 2000,
        frames: 6,
        mode: "per-anchor",
        random_anchors: Some(24),
        anchor_block: 16,
    },
    CaseDef {
        name: "tube900-random-fused",
        triangles: 900,
        frames: 5,
        mode: "fused",
        random_anchors: Some(40),
        anchor_block: 32,
    },
];

/// Frames per positioning task the jobs cycle through; the reference uses `crease run`'s own (4), so equal
/// bytes also mean this partition does not matter.
const FRAMES_PER_CHUNK: [usize; 3] = [1, 2, 3];

struct Case {
    def: &'static CaseDef,
    input: PathBuf,
    anchors: PathBuf,
    reference: PathBuf,
    anchors_total: usize,
    reference_seconds: f64,
}

/// splitmix64: a seeded, dependency-free generator for the chaos schedule.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// The worker processes by slot, each with its generation (restarts so far); `None` while one is down.
type Workers = Mutex<Vec<(Option<Proc>, u32)>>;

/// The soak's directory: removed at the end unless the user asked to keep it.
struct Scratch {
    dir: PathBuf,
    keep: bool,
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !self.keep {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// Settings from the environment that would configure the soak's processes behind its back (another
/// cluster's TLS files or tokens, a fixed metrics port every worker would fight over, JSON logs): the harness
/// gives each process exactly the flags it means. CREASE_LOG stays, for debugging.
const FOREIGN_ENV: [&str; 14] = [
    "CREASE_COORDINATOR",
    "CREASE_TLS_CERT",
    "CREASE_TLS_KEY",
    "CREASE_TLS_CA",
    "CREASE_CLIENT_TOKENS_FILE",
    "CREASE_WORKER_TOKEN_FILE",
    "CREASE_WORKER_TLS_DOMAIN",
    "CREASE_TOKEN",
    "CREASE_TOKEN_FILE",
    "CREASE_METRICS_LISTEN",
    "CREASE_LOG_FORMAT",
    "CREASE_MAX_MESSAGE_MIB",
    "CREASE_STORAGE_ROOTS",
    "CREASE_CACHE_DIR",
];

/// `exe` as a child of the harness, with none of [`FOREIGN_ENV`].
fn crease(exe: &Path) -> Command {
    let mut cmd = Command::new(exe);
    for var in FOREIGN_ENV {
        cmd.env_remove(var);
    }
    cmd
}

/// The files of a `--secure` soak and the flags each kind of process gets from them. Tokens are random per
/// soak, live only in 0600 files and are never printed.
struct Security {
    certs: PathBuf,
    /// Both user tokens: what the coordinator accepts.
    client_tokens: PathBuf,
    /// One user token per file; client `c` presents `user_tokens[c % 2]`, so both are in use at once.
    user_tokens: [PathBuf; 2],
    worker_token: PathBuf,
}

impl Security {
    /// Certificates from `crease certs` (a child process, as an operator would run it) and fresh tokens.
    fn create(exe: &Path, dir: &Path) -> Result<Self> {
        let certs = dir.join("certs");
        let o = crease(exe)
            .arg("certs")
            .arg("--out")
            .arg(&certs)
            .output()
            .context("starting `crease certs`")?;
        if !o.status.success() {
            bail!(
                "`crease certs --out {}` failed: {}",
                certs.display(),
                String::from_utf8_lossy(&o.stderr).trim()
            );
        }
        let secrets = dir.join("secrets");
        crease_core::fsutil::create_dir_all(&secrets)?;
        let (a, b, w) = (random_token()?, random_token()?, random_token()?);
        let s = Security {
            certs,
            client_tokens: secrets.join("client-tokens"),
            user_tokens: [secrets.join("user-token-a"), secrets.join("user-token-b")],
            worker_token: secrets.join("worker-token"),
        };
        write_secret(
            &s.client_tokens,
            &format!("# two accepted user tokens, as during a rotation\n{a}\n{b}\n"),
        )?;
        write_secret(&s.user_tokens[0], &format!("{a}\n"))?;
        write_secret(&s.user_tokens[1], &format!("{b}\n"))?;
        write_secret(&s.worker_token, &format!("{w}\n"))?;
        Ok(s)
    }

    fn cert(&self, name: &str) -> OsString {
        self.certs.join(name).into_os_string()
    }

    fn coordinator_args(&self) -> Vec<OsString> {
        vec![
            "--tls-cert".into(),
            self.cert("coordinator.pem"),
            "--tls-key".into(),
            self.cert("coordinator.key"),
            "--tls-ca".into(),
            self.cert("ca.pem"),
            "--client-tokens-file".into(),
            self.client_tokens.clone().into_os_string(),
            "--worker-token-file".into(),
            self.worker_token.clone().into_os_string(),
        ]
    }

    fn worker_args(&self) -> Vec<OsString> {
        vec![
            "--tls-ca".into(),
            self.cert("ca.pem"),
            "--tls-cert".into(),
            self.cert("worker.pem"),
            "--tls-key".into(),
            self.cert("worker.key"),
            "--worker-token-file".into(),
            self.worker_token.clone().into_os_string(),
        ]
    }

    fn client_args(&self, client: usize) -> Vec<OsString> {
        vec![
            "--tls-ca".into(),
            self.cert("ca.pem"),
            "--token-file".into(),
            self.user_tokens[client % 2].clone().into_os_string(),
        ]
    }
}

/// 128 random bits, hex: a token nobody can guess, without a random-number dependency.
fn random_token() -> Result<String> {
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .context("reading /dev/urandom for a soak token")?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Writes a token file readable by its owner only (the coordinator warns about anything looser).
fn write_secret(path: &Path, text: &str) -> Result<()> {
    let mut opts = std::fs::OpenOptions::new();
    opts.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        opts.mode(0o600);
    }
    opts.open(path)
        .and_then(|mut f| f.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))
}

/// What the harness shares with its client and chaos threads.
struct Ctx {
    exe: PathBuf,
    url: String,
    security: Option<Security>,
    logs: PathBuf,
    t0: Instant,
    deadline: Instant,
    ended: AtomicUsize,
}

impl Ctx {
    fn elapsed(&self) -> f64 {
        self.t0.elapsed().as_secs_f64()
    }
    fn log(&self, msg: &str) {
        eprintln!("[soak {:>6.1}s] {msg}", self.elapsed());
    }
    /// A client command (`submit`, `status`, `watch`, ...) of client `c` against the soak's coordinator.
    fn client_cmd<S: AsRef<OsStr>>(&self, c: usize, args: &[S]) -> Command {
        let mut cmd = crease(&self.exe);
        cmd.args(args).args(["--coordinator", &self.url]);
        if let Some(s) = &self.security {
            cmd.args(s.client_args(c));
        }
        cmd
    }
}

struct JobPlan {
    index: usize,
    case: usize,
    partition: (usize, usize),
    spec: PathBuf,
    output: PathBuf,
}

#[derive(Default)]
struct JobResult {
    index: usize,
    client: usize,
    case: usize,
    id: String,
    state: String,
    message: String,
    submitted_at: f64,
    latency: Option<f64>,
    tasks: u64,
    retried: u64,
    identical: bool,
    differs: Vec<String>,
    partition: (usize, usize),
    output: PathBuf,
}

pub fn soak(a: &SoakArgs, exe: &Path, json_out: Option<&Path>) -> Result<()> {
    if a.jobs == 0 || a.clients == 0 || a.workers == 0 {
        bail!("--jobs, --clients and --workers must each be at least 1");
    }
    if !(a.kill_window_secs.is_finite() && a.kill_window_secs > 0.0) {
        bail!(
            "--kill-window-secs must be a positive number, got {}",
            a.kill_window_secs
        );
    }
    if !(a.deadline_secs.is_finite() && a.deadline_secs > 0.0) {
        bail!(
            "--deadline-secs must be a positive number, got {}",
            a.deadline_secs
        );
    }
    let scratch = match &a.keep {
        Some(dir) => {
            if dir.exists() && std::fs::read_dir(dir).map_or(true, |mut d| d.next().is_some()) {
                bail!(
                    "--keep {}: the directory exists and is not empty; give a new one",
                    dir.display()
                );
            }
            Scratch {
                dir: std::path::absolute(dir)
                    .with_context(|| format!("--keep {}", dir.display()))?,
                keep: true,
            }
        }
        None => Scratch {
            dir: std::env::temp_dir().join(format!("crease-soak-{}", std::process::id())),
            keep: false,
        },
    };
    let dir = scratch.dir.clone();
    let logs = dir.join("logs");
    crease_core::fsutil::create_dir_all(&logs)?;
    let exe = exe.to_path_buf();

    eprintln!(
        "soak: preparing {} inputs in {}",
        CASES.len(),
        dir.display()
    );
    let cases = prepare_cases(&exe, &dir)?;
    for c in &cases {
        eprintln!(
            "soak: {:<28} {:>5} triangles, {} frames, {:>4} anchors, {:<10} reference `crease run` {:.2}s",
            c.def.name, c.def.triangles, c.def.frames, c.anchors_total, c.def.mode, c.reference_seconds
        );
    }

    // Enough attempts per task (and failures per job) that even every kill landing on one task cannot fail it.
    let max_attempts = a.kills as u32 + 3;
    let max_failures = (a.kills as u32 + 3).max(10);
    let plans = write_job_specs(&dir, &cases, a, max_attempts, max_failures)?;

    let security = if a.secure {
        Some(Security::create(&exe, &dir)?)
    } else {
        None
    };
    let (coordinator, url, metrics_addr) = start_coordinator(&exe, &dir, &logs, security.as_ref())?;
    let t0 = Instant::now();
    let ctx = Arc::new(Ctx {
        exe: exe.clone(),
        url: url.clone(),
        security,
        logs: logs.clone(),
        t0,
        deadline: t0 + Duration::from_secs_f64(a.deadline_secs),
        ended: AtomicUsize::new(0),
    });
    let workers: Arc<Workers> = Arc::new(Mutex::new(Vec::new()));
    for i in 0..a.workers {
        let p = spawn_worker(&ctx, &dir, i, 0)?;
        workers.lock().unwrap().push((Some(p), 0));
    }
    ctx.log(&format!(
        "coordinator at {url} ({}; metrics on {metrics_addr}), {} workers, {} jobs from {} clients, up to {} \
         kills within {:.0}s (seed {})",
        transport(a.secure),
        a.workers,
        a.jobs,
        a.clients,
        a.kills,
        a.kill_window_secs,
        a.seed
    ));

    let stop = Arc::new(AtomicBool::new(false));
    let chaos = {
        let (ctx, workers, stop, dir) = (ctx.clone(), workers.clone(), stop.clone(), dir.clone());
        let (kills, window, seed) = (a.kills, a.kill_window_secs, a.seed);
        std::thread::spawn(move || chaos(&ctx, &dir, &workers, &stop, kills, window, seed))
    };

    let mut per_client: Vec<Vec<JobPlan>> = (0..a.clients).map(|_| Vec::new()).collect();
    for p in plans {
        per_client[p.index % a.clients].push(p);
    }
    let total = a.jobs;
    let clients: Vec<_> = per_client
        .into_iter()
        .enumerate()
        .map(|(c, jobs)| {
            let ctx = ctx.clone();
            let seed = a.seed.wrapping_mul(1000).wrapping_add(c as u64);
            std::thread::spawn(move || client(&ctx, c, jobs, seed, total))
        })
        .collect();
    let mut results: Vec<JobResult> = Vec::new();
    let mut client_error = None;
    for h in clients {
        match h.join() {
            Ok(Ok(r)) => results.extend(r),
            Ok(Err(e)) => client_error = Some(e),
            Err(_) => client_error = Some(anyhow::anyhow!("a client thread panicked")),
        }
    }
    let wall = ctx.elapsed();
    stop.store(true, Ordering::SeqCst);
    let kills = chaos
        .join()
        .map_err(|_| anyhow::anyhow!("the chaos thread panicked"))??;
    if let Some(e) = client_error {
        return Err(e);
    }
    results.sort_by_key(|r| r.index);

    // Final state and retries from the coordinator; outputs against the references.
    for r in &mut results {
        if r.id.is_empty() {
            continue;
        }
        let s = job_status(&ctx, r.client, &r.id)?;
        let state = s["state"].as_str().unwrap_or("?").to_string();
        r.message = s["message"].as_str().unwrap_or("").to_string();
        if r.state == "unfinished" {
            // Past the deadline: keep it counted as unfinished, saying where the coordinator had it.
            r.message = format!("{state} at the deadline {}", r.message);
        } else {
            r.state = state;
        }
        let tasks = s["tasks"].as_array().cloned().unwrap_or_default();
        r.tasks = tasks.len() as u64;
        r.retried = tasks
            .iter()
            .map(|t| t["attempts"].as_u64().unwrap_or(0).saturating_sub(1))
            .sum();
        if r.state == "done" {
            r.differs = compare(&cases[r.case].reference, &r.output)?;
            r.identical = r.differs.is_empty();
        }
    }
    // Everything has ended, so the coordinator's own view must agree: nothing queued or running, and as many
    // done jobs as the clients saw (the queue file is new, so it holds only this soak's jobs).
    let metrics = scrape_metrics(&metrics_addr)?;
    workers.lock().unwrap().clear();
    drop(coordinator);

    let summary = summarise(
        a,
        &cases,
        &results,
        &kills,
        &metrics,
        wall,
        &dir,
        scratch.keep,
    );
    print_summary(&summary, &results, &cases);
    if let Some(path) = json_out {
        crease_core::fsutil::write_atomic(
            path,
            serde_json::to_string_pretty(&summary)?.as_bytes(),
        )?;
    }
    let done = summary["done"].as_u64().unwrap_or(0);
    if metrics.jobs_done != done || metrics.queue_depth != 0 || metrics.tasks_running != 0 {
        bail!(
            "soak: the coordinator's metrics disagree with the end of the soak: crease_jobs{{state=\"done\"}} \
             {} (the clients saw {done} done), crease_queue_depth {}, crease_tasks_running {} (both must be 0)",
            metrics.jobs_done,
            metrics.queue_depth,
            metrics.tasks_running
        );
    }
    let bad = summary["failed"].as_u64().unwrap_or(0)
        + summary["unfinished"].as_u64().unwrap_or(0)
        + summary["mismatched"].as_u64().unwrap_or(0);
    if bad > 0 {
        bail!(
            "soak: {bad} of {} jobs did not complete with the reference's bytes (logs: {})",
            a.jobs,
            if scratch.keep {
                logs.display().to_string()
            } else {
                "rerun with --keep DIR".into()
            }
        );
    }
    Ok(())
}

/// Writes each case's input and anchors, and its single-node reference with `crease run`.
fn prepare_cases(exe: &Path, dir: &Path) -> Result<Vec<Case>> {
    let mut cases = Vec::new();
    for (k, def) in CASES.iter().enumerate() {
        let root = dir.join("cases").join(def.name);
        let spec = DemoSpec {
            triangles: def.triangles,
            frames: def.frames,
            ..Default::default()
        };
        let (seq, demo_anchors) = synth::demo(&spec)?;
        let anchors = match def.random_anchors {
            Some(n) => synth::random_anchors(&seq.topology, &seq.frames, n, 100 + k as u64)?,
            None => demo_anchors,
        };
        let (input, anchors_path) = synth::write_demo(&root, &seq, &anchors)?;
        let reference = root.join("reference");
        let t = Instant::now();
        let o = Command::new(exe)
            .arg("run")
            .arg("--input")
            .arg(&input)
            .arg("--anchors")
            .arg(&anchors_path)
            .arg("--out")
            .arg(&reference)
            .args(["--mode", def.mode])
            .args(["--set", &format!("deform.window={WINDOW}")])
            .args(["--set", &format!("deform.shift={SHIFT}")])
            .args([
                "--set",
                &format!("partition.anchor_block={}", def.anchor_block),
            ])
            .args(["--preview-size", &PREVIEW_SIZE.to_string()])
            .args(["--quiet", "--local-workers", "1"])
            .output()
            .context("starting `crease run` for a reference")?;
        if !o.status.success() {
            bail!(
                "reference `crease run` for {} failed: {}",
                def.name,
                String::from_utf8_lossy(&o.stderr)
            );
        }
        cases.push(Case {
            def,
            input,
            anchors: anchors_path,
            reference,
            anchors_total: anchors.total(),
            reference_seconds: t.elapsed().as_secs_f64(),
        });
    }
    Ok(cases)
}

fn write_job_specs(
    dir: &Path,
    cases: &[Case],
    a: &SoakArgs,
    max_attempts: u32,
    max_failures: u32,
) -> Result<Vec<JobPlan>> {
    let specs = dir.join("specs");
    crease_core::fsutil::create_dir_all(&specs)?;
    // Distinct per run and per job, so every submission is a new job (and a resubmission the same one).
    let run_token = format!(
        "{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_millis())
            .unwrap_or(0)
    );
    let mut plans = Vec::new();
    for index in 0..a.jobs {
        let case = index % cases.len();
        let partition = (
            cases[case].def.anchor_block,
            FRAMES_PER_CHUNK[(index / cases.len()) % FRAMES_PER_CHUNK.len()],
        );
        let c = &cases[case];
        let output = dir.join("out").join(format!("job-{index:03}"));
        let spec = json!({
            "name": format!("soak-{index:03}-{}", c.def.name),
            "input": c.input.display().to_string(),
            "output": output.display().to_string(),
            "client_token": format!("soak-{run_token}-{index}"),
            "max_task_attempts": max_attempts,
            "max_task_failures_per_job": max_failures,
            "folds": { "kind": "anchors", "uri": c.anchors.display().to_string() },
            "deform": { "mode": c.def.mode, "window": WINDOW, "shift": SHIFT },
            "partition": { "anchor_block": partition.0, "frames_per_chunk": partition.1 },
            "preview": { "size": PREVIEW_SIZE },
        });
        let path = specs.join(format!("job-{index:03}.json"));
        crease_core::fsutil::write_atomic(&path, serde_json::to_string_pretty(&spec)?.as_bytes())?;
        plans.push(JobPlan {
            index,
            case,
            partition,
            spec: path,
            output,
        });
    }
    Ok(plans)
}

fn transport(secure: bool) -> &'static str {
    if secure {
        "TLS, client and worker tokens"
    } else {
        "plaintext, no tokens"
    }
}

/// Starts the coordinator on a free loopback port (retrying if another process takes the port first), with
/// metrics on any free port, and waits until it accepts connections and has logged its metrics address.
/// Returns it, its URL and that address.
fn start_coordinator(
    exe: &Path,
    dir: &Path,
    logs: &Path,
    security: Option<&Security>,
) -> Result<(Proc, String, String)> {
    let log_path = logs.join("coordinator.log");
    let scheme = if security.is_some() { "https" } else { "http" };
    for _ in 0..5 {
        let port = try_free_port().context("finding a free loopback port")?;
        let log = std::fs::File::create(&log_path)?;
        let mut cmd = crease(exe);
        cmd.args(["coordinator", "--listen", &format!("127.0.0.1:{port}")])
            .arg("--db")
            .arg(dir.join("queue.sqlite"))
            .args(["--heartbeat-ms", "200", "--worker-timeout-ms", "2000"])
            .args(["--retry-backoff-ms", "100"])
            .args(["--metrics-listen", "127.0.0.1:0"]);
        if let Some(s) = security {
            cmd.args(s.coordinator_args());
        }
        let mut p = Proc(
            cmd.stdout(Stdio::null())
                .stderr(log)
                .spawn()
                .context("starting the coordinator")?,
        );
        let addr: SocketAddr = ([127, 0, 0, 1], port).into();
        let start = Instant::now();
        let mut listening = false;
        while start.elapsed() < Duration::from_secs(30) {
            listening =
                listening || TcpStream::connect_timeout(&addr, Duration::from_millis(200)).is_ok();
            if listening {
                let text = std::fs::read_to_string(&log_path).unwrap_or_default();
                if let Some(metrics) = logged_address(&text, "metrics listening on ") {
                    return Ok((p, format!("{scheme}://127.0.0.1:{port}"), metrics));
                }
            }
            if p.0.try_wait()?.is_some() {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        p.kill();
        if listening {
            bail!(
                "the coordinator serves gRPC but logged no metrics address within 30 s (is CREASE_LOG below \
                 info?); see {}",
                log_path.display()
            );
        }
    }
    bail!("the coordinator did not start; see {}", log_path.display())
}

/// The `host:port` logged right after `marker` (text or JSON log lines).
fn logged_address(log: &str, marker: &str) -> Option<String> {
    let rest = log.split(marker).nth(1)?;
    let addr: String = rest
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | ':' | '[' | ']'))
        .collect();
    addr.contains(':').then_some(addr)
}

/// What the coordinator's `/metrics` said once every job had ended.
struct EndMetrics {
    retries: u64,
    failures: u64,
    jobs_done: u64,
    queue_depth: u64,
    tasks_running: u64,
}

/// `GET /metrics` over plain HTTP/1.1 (the endpoint is loopback and unauthenticated, by design: it carries no
/// job data), and the samples the soak reports.
fn scrape_metrics(addr: &str) -> Result<EndMetrics> {
    let what = format!("GET http://{addr}/metrics");
    let mut s = TcpStream::connect(addr).with_context(|| what.clone())?;
    s.set_read_timeout(Some(Duration::from_secs(10)))?;
    write!(
        s,
        "GET /metrics HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .with_context(|| what.clone())?;
    let mut reply = String::new();
    s.read_to_string(&mut reply).with_context(|| what.clone())?;
    let (head, body) = reply
        .split_once("\r\n\r\n")
        .with_context(|| format!("{what}: no HTTP response"))?;
    if head.split_whitespace().nth(1) != Some("200") {
        bail!(
            "{what}: {}",
            head.lines().next().unwrap_or("no status line")
        );
    }
    let sample = |series: &str| count_sample(body, series).with_context(|| what.clone());
    Ok(EndMetrics {
        retries: sample("crease_task_retries_total")?,
        failures: sample("crease_task_failures_total")?,
        jobs_done: sample("crease_jobs{state=\"done\"}")?,
        queue_depth: sample("crease_queue_depth")?,
        tasks_running: sample("crease_tasks_running")?,
    })
}

/// The value of the sample `series` (name and labels exactly as exposed) in Prometheus text, as a count.
fn count_sample(body: &str, series: &str) -> Result<u64> {
    let v = body
        .lines()
        .filter(|l| !l.starts_with('#'))
        .find_map(|l| l.rsplit_once(' ').filter(|(k, _)| *k == series))
        .with_context(|| format!("no sample `{series}`"))?
        .1;
    let x: f64 = v
        .parse()
        .with_context(|| format!("`{series}` has the value `{v}`"))?;
    if !(x.is_finite() && x >= 0.0 && x.fract() == 0.0) {
        bail!("`{series}` is {x}, not a count");
    }
    Ok(x as u64)
}

/// Starts worker `i` (generation `g` after `g` restarts) with one compute thread and one task at a time, so
/// several workers on a small machine share its cores instead of oversubscribing them.
fn spawn_worker(ctx: &Ctx, dir: &Path, i: usize, g: u32) -> Result<Proc> {
    let log = std::fs::File::create(ctx.logs.join(format!("worker-{i}-gen{g}.log")))?;
    let mut cmd = crease(&ctx.exe);
    cmd.args(["--threads", "1", "worker", "--coordinator", &ctx.url])
        .args(["--name", &format!("soak-w{i}-gen{g}")])
        .args(["--capacity", "1", "--drain-secs", "5"])
        .arg("--cache-dir")
        .arg(dir.join("cache").join(format!("w{i}")));
    if let Some(s) = &ctx.security {
        cmd.args(s.worker_args());
    }
    let child = cmd
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
        .context("starting a worker")?;
    Ok(Proc(child))
}

struct Kill {
    at: f64,
    worker: usize,
    generation: u32,
    pid: u32,
    down_ms: u64,
}

/// Kills random workers at random times (sorted uniform times within the window) and restarts each after a
/// short random pause; stops early once every job has ended.
fn chaos(
    ctx: &Ctx,
    dir: &Path,
    workers: &Workers,
    stop: &AtomicBool,
    kills: usize,
    window: f64,
    seed: u64,
) -> Result<Vec<Kill>> {
    let mut rng = Rng(seed ^ 0xC4A0_5000);
    let mut times: Vec<f64> = (0..kills)
        .map(|_| 0.3 + rng.unit() * (window - 0.3).max(0.0))
        .collect();
    times.sort_by(f64::total_cmp);
    let mut done = Vec::new();
    for at in times {
        while ctx.elapsed() < at {
            if stop.load(Ordering::SeqCst) {
                return Ok(done);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let n = workers.lock().unwrap().len();
        let i = rng.below(n);
        let down_ms = 100 + rng.below(900) as u64;
        let (pid, generation) = {
            let mut w = workers.lock().unwrap();
            let (proc, g) = &mut w[i];
            let Some(mut p) = proc.take() else { continue };
            let pid = p.0.id();
            p.kill();
            (pid, *g)
        };
        ctx.log(&format!(
            "SIGKILL worker {i} (generation {generation}, pid {pid}); restart in {down_ms} ms"
        ));
        done.push(Kill {
            at: ctx.elapsed(),
            worker: i,
            generation,
            pid,
            down_ms,
        });
        // The restart happens even if the jobs ended meanwhile: the cluster is left as it was found.
        std::thread::sleep(Duration::from_millis(down_ms));
        let p = spawn_worker(ctx, dir, i, generation + 1)?;
        let mut w = workers.lock().unwrap();
        w[i] = (Some(p), generation + 1);
    }
    Ok(done)
}

/// One job being followed by `crease submit --watch` (or, if that stream broke, by `crease watch`).
struct InFlight {
    plan: JobPlan,
    proc: Proc,
    started: Instant,
    submitted_at: f64,
    id: String,
    submits: u32,
}

/// A client: submits its jobs one after another with short random pauses, each as `crease submit --watch`
/// running concurrently with the others, and records when each ends.
fn client(
    ctx: &Ctx,
    c: usize,
    jobs: Vec<JobPlan>,
    seed: u64,
    total: usize,
) -> Result<Vec<JobResult>> {
    let mut rng = Rng(seed);
    let mut flying: Vec<InFlight> = Vec::new();
    let mut results = Vec::new();
    for plan in jobs {
        let pause = Instant::now() + Duration::from_millis(rng.below(150) as u64);
        while Instant::now() < pause {
            poll(ctx, c, &mut flying, &mut results, total)?;
            std::thread::sleep(Duration::from_millis(10));
        }
        let started = Instant::now();
        let submitted_at = ctx.elapsed();
        let proc = submit(ctx, c, &plan)?;
        flying.push(InFlight {
            plan,
            proc,
            started,
            submitted_at,
            id: String::new(),
            submits: 1,
        });
    }
    while !flying.is_empty() {
        if Instant::now() > ctx.deadline {
            for mut f in flying.drain(..) {
                // Its client process is stopped; the job id it printed is still in the pipe.
                f.proc.kill();
                read_id(&mut f);
                ctx.log(&format!(
                    "client {c}: job {} ({}) did not end before the deadline",
                    f.plan.index, f.id
                ));
                results.push(JobResult {
                    index: f.plan.index,
                    client: c,
                    case: f.plan.case,
                    id: f.id,
                    state: "unfinished".into(),
                    submitted_at: f.submitted_at,
                    partition: f.plan.partition,
                    output: f.plan.output,
                    ..Default::default()
                });
            }
            break;
        }
        poll(ctx, c, &mut flying, &mut results, total)?;
        std::thread::sleep(Duration::from_millis(10));
    }
    Ok(results)
}

fn submit(ctx: &Ctx, c: usize, plan: &JobPlan) -> Result<Proc> {
    let log = std::fs::File::create(ctx.logs.join(format!("client-job-{:03}.log", plan.index)))?;
    let child = ctx
        .client_cmd(
            c,
            &[
                OsStr::new("submit"),
                plan.spec.as_os_str(),
                OsStr::new("--watch"),
            ],
        )
        .stdout(Stdio::piped())
        .stderr(log)
        .spawn()
        .context("starting `crease submit`")?;
    Ok(Proc(child))
}

/// Collects the jobs whose client process ended: a clean exit is a done job; otherwise the coordinator's
/// status says whether the job ended (failed) or only the client's stream did (then follow it again).
fn poll(
    ctx: &Ctx,
    c: usize,
    flying: &mut Vec<InFlight>,
    results: &mut Vec<JobResult>,
    total: usize,
) -> Result<()> {
    let mut i = 0;
    while i < flying.len() {
        let Some(exit) = flying[i].proc.0.try_wait()? else {
            i += 1;
            continue;
        };
        let latency = flying[i].started.elapsed().as_secs_f64();
        let f = &mut flying[i];
        read_id(f);
        let state = if exit.success() {
            "done".to_string()
        } else if f.id.is_empty() {
            // Not even submitted: submit again (the client token makes a repeat harmless).
            if f.submits >= 3 {
                bail!(
                    "client {c}: job {} could not be submitted; see {}",
                    f.plan.index,
                    ctx.logs
                        .join(format!("client-job-{:03}.log", f.plan.index))
                        .display()
                );
            }
            f.submits += 1;
            f.proc = submit(ctx, c, &f.plan)?;
            i += 1;
            continue;
        } else {
            let s = job_status(ctx, c, &f.id)?;
            let state = s["state"].as_str().unwrap_or("?").to_string();
            if !matches!(state.as_str(), "done" | "failed" | "cancelled") {
                ctx.log(&format!(
                    "client {c}: lost the stream of {} ({state}); watching again",
                    f.id
                ));
                f.proc = Proc(
                    ctx.client_cmd(c, &["watch", &f.id])
                        .stdout(Stdio::null())
                        .stderr(Stdio::null())
                        .spawn()
                        .context("starting `crease watch`")?,
                );
                i += 1;
                continue;
            }
            state
        };
        let f = flying.swap_remove(i);
        let n = ctx.ended.fetch_add(1, Ordering::SeqCst) + 1;
        ctx.log(&format!(
            "client {c}: {} ({}) {state} in {latency:.2}s [{n}/{total} ended]",
            f.id,
            f.plan
                .spec
                .file_stem()
                .unwrap_or_default()
                .to_string_lossy(),
        ));
        results.push(JobResult {
            index: f.plan.index,
            client: c,
            case: f.plan.case,
            id: f.id,
            state,
            submitted_at: f.submitted_at,
            latency: Some(latency),
            partition: f.plan.partition,
            output: f.plan.output,
            ..Default::default()
        });
    }
    Ok(())
}

/// The job id `crease submit` printed first on its standard output, once the process has ended.
fn read_id(f: &mut InFlight) {
    if f.id.is_empty() {
        let mut out = String::new();
        if let Some(mut s) = f.proc.0.stdout.take() {
            let _ = s.read_to_string(&mut out);
        }
        f.id = out.lines().next().unwrap_or("").trim().to_string();
    }
}

/// The coordinator's view of job `id`, asked as client `c`.
fn job_status(ctx: &Ctx, c: usize, id: &str) -> Result<serde_json::Value> {
    let o = ctx
        .client_cmd(c, &["status", id, "--json"])
        .output()
        .context("running `crease status`")?;
    if !o.status.success() {
        bail!(
            "crease status {id}: {}",
            String::from_utf8_lossy(&o.stderr).trim()
        );
    }
    serde_json::from_slice(&o.stdout).with_context(|| format!("crease status {id}: not JSON"))
}

/// The files that differ between a reference and an output (or are missing from either); also requires the
/// output's report to say it is complete.
fn compare(reference: &Path, out: &Path) -> Result<Vec<String>> {
    let mut differs = Vec::new();
    let report: Option<serde_json::Value> = std::fs::read(out.join("report.json"))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok());
    if report.is_none_or(|r| r["complete"] != true) {
        differs.push("report.json (missing or not complete)".to_string());
    }
    let a = try_output_files(reference)
        .with_context(|| format!("reading the reference {}", reference.display()))?;
    let b =
        try_output_files(out).with_context(|| format!("reading the output {}", out.display()))?;
    for (k, v) in &a {
        if b.get(k) != Some(v) {
            differs.push(k.clone());
        }
    }
    differs.extend(b.keys().filter(|k| !a.contains_key(*k)).cloned());
    Ok(differs)
}

/// Nearest-rank percentile of sorted values.
fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

#[allow(clippy::too_many_arguments)]
fn summarise(
    a: &SoakArgs,
    cases: &[Case],
    results: &[JobResult],
    kills: &[Kill],
    m: &EndMetrics,
    wall: f64,
    dir: &Path,
    kept: bool,
) -> serde_json::Value {
    let done = results.iter().filter(|r| r.state == "done").count();
    let unfinished = a.jobs - results.iter().filter(|r| r.state != "unfinished").count();
    let failed = a.jobs - done - unfinished;
    let mismatched = results
        .iter()
        .filter(|r| r.state == "done" && !r.identical)
        .count();
    let mut lat: Vec<f64> = results
        .iter()
        .filter(|r| r.state == "done")
        .filter_map(|r| r.latency)
        .collect();
    lat.sort_by(f64::total_cmp);
    let mean = if lat.is_empty() {
        f64::NAN
    } else {
        lat.iter().sum::<f64>() / lat.len() as f64
    };
    let nan_null = |x: f64| if x.is_finite() { json!(x) } else { json!(null) };
    json!({
        "jobs": a.jobs, "clients": a.clients, "workers": a.workers, "seed": a.seed,
        "secure": a.secure, "transport": transport(a.secure),
        "kills_max": a.kills, "kill_window_secs": a.kill_window_secs,
        "done": done, "failed": failed, "unfinished": unfinished, "mismatched": mismatched,
        "kills": kills.len(),
        "tasks": results.iter().map(|r| r.tasks).sum::<u64>(),
        "tasks_retried": results.iter().map(|r| r.retried).sum::<u64>(),
        "wall_seconds": wall,
        "jobs_per_minute": done as f64 / (wall / 60.0),
        "latency_seconds": {
            "p50": nan_null(percentile(&lat, 50.0)), "p95": nan_null(percentile(&lat, 95.0)),
            "max": nan_null(lat.last().copied().unwrap_or(f64::NAN)), "mean": nan_null(mean),
        },
        "max_task_attempts": a.kills + 3,
        "metrics": {
            "task_retries_total": m.retries, "task_failures_total": m.failures, "jobs_done": m.jobs_done,
            "queue_depth": m.queue_depth, "tasks_running": m.tasks_running,
            "jobs_done_matches": m.jobs_done == done as u64,
        },
        "dir": if kept { json!(dir.display().to_string()) } else { json!(null) },
        "cases": cases.iter().map(|c| json!({
            "name": c.def.name, "triangles": c.def.triangles, "frames": c.def.frames, "mode": c.def.mode,
            "anchors": c.anchors_total, "input": c.input.display().to_string(),
            "anchors_file": c.anchors.display().to_string(), "reference": c.reference.display().to_string(),
            "reference_seconds": c.reference_seconds,
            "run_args": ["--mode", c.def.mode, "--set", format!("deform.window={WINDOW}"),
                "--set", format!("deform.shift={SHIFT}"), "--set", format!("partition.anchor_block={}", c.def.anchor_block),
                "--preview-size", PREVIEW_SIZE.to_string()],
        })).collect::<Vec<_>>(),
        "kill_log": kills.iter().map(|k| json!({
            "at_seconds": k.at, "worker": k.worker, "generation": k.generation, "pid": k.pid, "down_ms": k.down_ms,
        })).collect::<Vec<_>>(),
        "job_results": results.iter().map(|r| json!({
            "index": r.index, "id": r.id, "client": r.client, "case": cases[r.case].def.name, "state": r.state,
            "message": r.message, "submitted_at_seconds": r.submitted_at, "latency_seconds": r.latency,
            "tasks": r.tasks, "tasks_retried": r.retried, "identical": r.identical, "differs": r.differs,
            "output": r.output.display().to_string(),
            "partition": {"anchor_block": r.partition.0, "frames_per_chunk": r.partition.1},
            "reference": cases[r.case].reference.display().to_string(),
        })).collect::<Vec<_>>(),
    })
}

fn print_summary(s: &serde_json::Value, results: &[JobResult], cases: &[Case]) {
    let f = |k: &str| s["latency_seconds"][k].as_f64().unwrap_or(f64::NAN);
    let n = |k: &str| s[k].as_u64().unwrap_or(0);
    println!(
        "crease-soak: {} jobs from {} clients on {} workers, {} kills (at most {} within {}s), seed {}, {}",
        s["jobs"], s["clients"], s["workers"], s["kills"], s["kills_max"], s["kill_window_secs"], s["seed"],
        s["transport"].as_str().unwrap_or("?")
    );
    println!(
        "{:<28} {:>5} {:>5} {:>7} {:>9} {:>8}",
        "case", "jobs", "done", "tasks", "retried", "p50 s"
    );
    for (k, c) in cases.iter().enumerate() {
        let mine: Vec<&JobResult> = results.iter().filter(|r| r.case == k).collect();
        let mut lat: Vec<f64> = mine
            .iter()
            .filter(|r| r.state == "done")
            .filter_map(|r| r.latency)
            .collect();
        lat.sort_by(f64::total_cmp);
        println!(
            "{:<28} {:>5} {:>5} {:>7} {:>9} {:>8.2}",
            c.def.name,
            mine.len(),
            mine.iter().filter(|r| r.state == "done").count(),
            mine.iter().map(|r| r.tasks).sum::<u64>(),
            mine.iter().map(|r| r.retried).sum::<u64>(),
            percentile(&lat, 50.0)
        );
    }
    println!(
        "{:>5} {:>6} {:>10} {:>10} {:>6} {:>8} {:>8} {:>9} {:>7} {:>7} {:>7}",
        "done",
        "failed",
        "unfinished",
        "mismatched",
        "kills",
        "retried",
        "wall s",
        "jobs/min",
        "p50 s",
        "p95 s",
        "max s"
    );
    println!(
        "{:>5} {:>6} {:>10} {:>10} {:>6} {:>8} {:>8.1} {:>9.1} {:>7.2} {:>7.2} {:>7.2}",
        n("done"),
        n("failed"),
        n("unfinished"),
        n("mismatched"),
        n("kills"),
        n("tasks_retried"),
        s["wall_seconds"].as_f64().unwrap_or(f64::NAN),
        s["jobs_per_minute"].as_f64().unwrap_or(f64::NAN),
        f("p50"),
        f("p95"),
        f("max")
    );
    let m = |k: &str| s["metrics"][k].as_u64().unwrap_or(0);
    println!(
        "coordinator /metrics at the end: {:>10} {:>12} {:>14} {:>11} {:>13}",
        "jobs done", "retries_total", "failures_total", "queue_depth", "tasks_running"
    );
    println!(
        "{:>32} {:>10} {:>12} {:>14} {:>11} {:>13}",
        if s["metrics"]["jobs_done_matches"] == true {
            "(matches the clients)"
        } else {
            "(DIFFERS from the clients)"
        },
        m("jobs_done"),
        m("task_retries_total"),
        m("task_failures_total"),
        m("queue_depth"),
        m("tasks_running")
    );
    for r in results.iter().filter(|r| r.state != "done" || !r.identical) {
        println!(
            "  job {} ({}) {}: {}{}",
            r.index,
            r.id,
            r.state,
            r.message,
            if r.differs.is_empty() {
                String::new()
            } else {
                format!(" differs: {}", r.differs.join(", "))
            }
        );
    }
    println!(
        "latency = `crease submit --watch` start to exit (submit -> done) per job; jobs/min = done jobs / wall \
         minutes from the first submission; retried = task attempts beyond the first; retries_total = the \
         coordinator's requeued attempts (failed or handed back)"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_read_by_exact_series_and_anything_else_is_an_error() {
        let body = "# HELP crease_jobs Jobs by state\n# TYPE crease_jobs gauge\n\
                    crease_jobs{state=\"done\"} 50\ncrease_jobs{state=\"failed\"} 0\n\
                    crease_queue_depth 0\ncrease_task_retries_total 7\ncrease_tasks_running 1.5\n\
                    crease_task_failures_total NaN\n# EOF\n";
        assert_eq!(
            count_sample(body, "crease_jobs{state=\"done\"}").unwrap(),
            50
        );
        assert_eq!(count_sample(body, "crease_task_retries_total").unwrap(), 7);
        assert_eq!(count_sample(body, "crease_queue_depth").unwrap(), 0);
        let err = |series: &str| format!("{:#}", count_sample(body, series).unwrap_err());
        assert!(
            err("crease_jobs").contains("no sample"),
            "{}",
            err("crease_jobs")
        );
        assert!(err("crease_tasks_running").contains("not a count"));
        assert!(err("crease_task_failures_total").contains("not a count"));
    }

    #[test]
    fn the_metrics_address_is_found_in_text_and_json_logs() {
        let text =
            "2026-11-22T11:20:12Z  INFO crease::cluster: metrics listening on 127.0.0.1:46493 \
                    address=127.0.0.1:46493\n";
        assert_eq!(
            logged_address(text, "metrics listening on ").as_deref(),
            Some("127.0.0.1:46493")
        );
        let json = r#"{"fields":{"message":"metrics listening on 127.0.0.1:9100","address":"x"}}"#;
        assert_eq!(
            logged_address(json, "metrics listening on ").as_deref(),
            Some("127.0.0.1:9100")
        );
        assert_eq!(
            logged_address(
                "coordinator listening on 127.0.0.1:7070",
                "metrics listening on "
            ),
            None
        );
        assert_eq!(
            logged_address("metrics listening on \n", "metrics listening on "),
            None
        );
    }
}
