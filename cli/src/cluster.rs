//! Cluster subcommands: `crease coordinator`, `crease worker`, `crease submit`, `crease status`,
//! `crease watch`, `crease cancel`, `crease jobs`. The client commands are written once against
//! [`JobClient`], so they behave the same against a remote coordinator and in single-node mode.

use crate::progress::CliProgress;
use anyhow::{bail, Context, Result};
use clap::Args;
use crease_coordinator::{CoordinatorConfig, JobClient, RemoteClient, Scheduler};
use crease_proto as pb;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

const DEFAULT_COORDINATOR: &str = "http://127.0.0.1:7070";

pub(crate) fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")
}

/// Resolves on SIGTERM or Ctrl-C.
pub async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = term.recv() => {}
                    _ = tokio::signal::ctrl_c() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

#[derive(Args, Debug)]
pub struct CoordinatorArgs {
    /// Address to listen on (port 0 = any free port; the bound address is printed).
    #[arg(long, default_value = "127.0.0.1:7070")]
    pub listen: SocketAddr,
    /// Queue file (SQLite). Jobs survive a restart of the coordinator.
    #[arg(long, default_value = "crease-queue.sqlite")]
    pub db: PathBuf,
    /// Heartbeat interval asked of workers, in milliseconds.
    #[arg(long, default_value_t = 1000)]
    pub heartbeat_ms: u64,
    /// A worker silent this long (milliseconds) is lost and its tasks run elsewhere.
    #[arg(long, default_value_t = 5000)]
    pub worker_timeout_ms: u64,
    /// Seconds a job with work left waits for a worker before it fails.
    #[arg(long, default_value_t = 120.0)]
    pub grace_secs: f64,
    /// Failed attempts of one job on one worker after which that worker gets no more of the job's tasks.
    #[arg(long, default_value_t = 2)]
    pub blacklist_after: u32,
    /// First retry delay in milliseconds (doubles per attempt).
    #[arg(long, default_value_t = 200)]
    pub retry_backoff_ms: u64,
    /// Serve the web dashboard and its JSON API here (HTTPS with --tls-cert; client token with
    /// --client-tokens-file). See docs/dashboard.md.
    #[arg(long, env = "CREASE_HTTP_LISTEN")]
    pub http_listen: Option<SocketAddr>,
    #[command(flatten)]
    pub obs: crate::logging::ObsArgs,
    #[command(flatten)]
    pub security: crate::security_args::CoordinatorSecurityArgs,
    #[command(flatten)]
    pub limits: crate::limits_args::LimitsArgs,
}

pub fn coordinator(a: CoordinatorArgs) -> Result<()> {
    crate::logging::init(&a.obs)?;
    let (server_security, worker_channel) = a.security.load()?;
    if !(a.grace_secs.is_finite() && a.grace_secs >= 0.0) {
        bail!(
            "--grace-secs must be a non-negative number, got {}",
            a.grace_secs
        );
    }
    let mut config = CoordinatorConfig {
        db: Some(a.db.clone()),
        heartbeat_interval: Duration::from_millis(a.heartbeat_ms.max(10)),
        worker_timeout: Duration::from_millis(a.worker_timeout_ms.max(20)),
        no_worker_grace: Duration::from_secs_f64(a.grace_secs),
        blacklist_after: a.blacklist_after.max(1),
        retry_backoff: Duration::from_millis(a.retry_backoff_ms),
        server_security,
        worker_channel,
        ..CoordinatorConfig::default()
    };
    a.limits.apply(&mut config)?;
    // Before the queue is opened: recovery would requeue the running tasks of a coordinator already on it.
    let mut lock =
        crease_coordinator::queue_lock::QueueLock::acquire(&a.db, &a.listen.to_string())?;
    runtime()?.block_on(async move {
        let scheduler = Scheduler::open(config)
            .with_context(|| format!("opening the queue {}", a.db.display()))?;
        let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
        tokio::spawn(async move {
            shutdown_signal().await;
            let _ = stop_tx.send(true);
        });
        let mut graceful = stop_rx.clone();
        let observed = std::sync::Arc::clone(&scheduler);
        let (addr, serve) = crease_coordinator::server::serve(scheduler, a.listen, async move {
            let _ = graceful.changed().await;
        })
        .await
        .with_context(|| format!("listening on {}", a.listen))?;
        lock.record(&addr.to_string())
            .with_context(|| format!("writing the lock file {}", lock.path().display()))?;
        tracing::info!(
            address = %addr,
            "coordinator listening on {addr} (queue {})",
            a.db.display()
        );
        if let Some(at) = a.http_listen {
            let (bound, _) = crease_dashboard::serve(std::sync::Arc::clone(&observed), at)
                .await
                .with_context(|| format!("serving the dashboard on --http-listen {at}"))?;
            let scheme = if observed.config().server_security.tls.is_some() {
                "https"
            } else {
                "http"
            };
            tracing::info!(address = %bound, "dashboard listening on {scheme}://{bound}/");
        }
        if let Some(at) = a.obs.metrics_listen {
            // Ready while the queue is open and the gRPC server has not begun to shut down.
            let stopping = stop_rx.clone();
            let (bound, _) = crease_telemetry::http::serve(
                at,
                std::sync::Arc::new(move || observed.metrics_text()),
                std::sync::Arc::new(move || !*stopping.borrow()),
            )
            .await
            .with_context(|| format!("serving metrics on {at}"))?;
            tracing::info!(address = %bound, "metrics listening on {bound}");
        }
        // Open WatchJob streams would hold a graceful shutdown forever: give them a moment, then stop anyway
        // (the queue is in SQLite, so nothing is lost).
        let mut forced = stop_rx;
        tokio::select! {
            r = serve => r.context("coordinator gRPC server")?,
            _ = async {
                let _ = forced.changed().await;
                tokio::time::sleep(Duration::from_secs(3)).await;
            } => tracing::info!("coordinator: closing the remaining client streams"),
        }
        tracing::info!("coordinator stopped");
        Ok(())
    })
}

#[derive(Args, Debug)]
pub struct WorkerArgs {
    /// Coordinator URL (http:// or https://).
    #[arg(long, env = "CREASE_COORDINATOR", default_value = DEFAULT_COORDINATOR, value_parser = crate::urls::parse)]
    pub coordinator: String,
    /// Address of this worker's gRPC server (port 0 = any free port).
    #[arg(long, default_value = "127.0.0.1:0")]
    pub listen: SocketAddr,
    /// URL the coordinator reaches this worker at (default: http://<bound address>).
    #[arg(long, value_parser = crate::urls::parse)]
    pub advertise: Option<String>,
    /// Name shown in logs (default: worker-<pid>).
    #[arg(long)]
    pub name: Option<String>,
    /// Tasks run at the same time.
    #[arg(long, default_value_t = 1)]
    pub capacity: u32,
    /// Cache for remote inputs (default: a directory under the system temp dir).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Memory (MiB) for the window cache: what the weight-block tasks of one window share (its operator,
    /// anchors and block workspaces), kept between tasks; least recently used windows go first; 0 turns it off.
    #[arg(long, default_value_t = crease_jobs::window_cache::DEFAULT_BUDGET_BYTES >> 20)]
    pub window_cache_mb: u64,
    /// Memory (MiB) per opened input for its parsed frames, kept between tasks (the strain limiter, positioning
    /// and finalize read the same frames); least recently read frames go first; 0 turns it off.
    #[arg(long, default_value_t = crease_jobs::frame_cache::DEFAULT_BUDGET_BYTES >> 20)]
    pub frame_cache_mb: u64,
    /// On SIGTERM, seconds running tasks may take to finish before they are handed back.
    #[arg(long, default_value_t = 30.0)]
    pub drain_secs: f64,
    /// Protocol version to announce (testing only).
    #[arg(long, hide = true, default_value_t = crease_proto::PROTOCOL_VERSION)]
    pub protocol_version: u32,
    #[command(flatten)]
    pub obs: crate::logging::ObsArgs,
    #[command(flatten)]
    pub security: crate::security_args::WorkerSecurityArgs,
}

pub fn worker(a: WorkerArgs) -> Result<()> {
    crate::logging::init(&a.obs)?;
    let security = a.security.load()?;
    if a.capacity == 0 {
        bail!("--capacity must be at least 1");
    }
    if !(a.drain_secs.is_finite() && a.drain_secs >= 0.0) {
        bail!(
            "--drain-secs must be a non-negative number, got {}",
            a.drain_secs
        );
    }
    crease_jobs::window_cache::set_budget(a.window_cache_mb.saturating_mul(1 << 20));
    crease_jobs::frame_cache::set_budget(a.frame_cache_mb.saturating_mul(1 << 20));
    let name = a
        .name
        .unwrap_or_else(|| format!("worker-{}", std::process::id()));
    let cache_dir = a.cache_dir.unwrap_or_else(|| {
        std::env::temp_dir().join(format!("crease-worker-cache-{}", std::process::id()))
    });
    let config = crease_worker::WorkerConfig {
        coordinator: a.coordinator,
        listen: a.listen,
        advertise: a.advertise,
        name,
        capacity: a.capacity,
        cache_dir,
        drain_timeout: Duration::from_secs_f64(a.drain_secs),
        protocol_version: a.protocol_version,
        log: true,
        metrics_listen: a.obs.metrics_listen,
    };
    runtime()?.block_on(crease_worker::run_with(config, security, shutdown_signal()))?;
    Ok(())
}

#[derive(Args, Debug)]
pub struct ClientArgs {
    /// Coordinator URL (http:// or https://).
    #[arg(long, env = "CREASE_COORDINATOR", default_value = DEFAULT_COORDINATOR, value_parser = crate::urls::parse)]
    pub coordinator: String,
    #[command(flatten)]
    pub security: crate::security_args::ClientSecurityArgs,
}

impl ClientArgs {
    /// Connects with the TLS and token flags.
    pub async fn connect(&self) -> Result<RemoteClient> {
        Ok(RemoteClient::connect_with(&self.coordinator, &self.security.load()?).await?)
    }
}

#[derive(Args, Debug)]
pub struct SubmitArgs {
    /// Job spec (TOML, or JSON when the name ends in .json). Or give --input and --output instead.
    pub job: Option<PathBuf>,
    #[command(flatten)]
    pub client: ClientArgs,
    /// Input sequence (without a job file).
    #[arg(long)]
    pub input: Option<String>,
    /// Output location (without a job file).
    #[arg(long)]
    pub output: Option<String>,
    /// Anchors file (without a job file; omit for no folds).
    #[arg(long)]
    pub anchors: Option<String>,
    /// Weight mode (without a job file): fused or per-anchor.
    #[arg(long)]
    pub mode: Option<crease_core::spacetime::WeightMode>,
    /// Priority (without a job file; higher runs first).
    #[arg(long)]
    pub priority: Option<i32>,
    /// Client token for idempotent submission (without a job file).
    #[arg(long)]
    pub client_token: Option<String>,
    /// Follow the job until it ends, as `crease watch` does (same exit status: see `crease watch --help`).
    #[arg(long)]
    pub watch: bool,
    #[command(flatten)]
    pub reconnect: crate::watch::ReconnectArgs,
}

/// Absolute form of a plain path (URIs with a scheme are left alone), so the coordinator and workers do not
/// depend on the submitter's working directory.
fn absolute(uri: &str) -> String {
    if uri.contains("://") {
        return uri.to_string();
    }
    std::path::absolute(uri)
        .map(|p| p.display().to_string())
        .unwrap_or_else(|_| uri.to_string())
}

pub fn submit(a: SubmitArgs) -> Result<()> {
    let (text, format) = match (&a.job, &a.input, &a.output) {
        (Some(path), None, None) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading the job spec {}", path.display()))?;
            let json = path.extension().is_some_and(|e| e == "json");
            (text, if json { "json" } else { "toml" })
        }
        (None, Some(input), Some(output)) => {
            let mut spec = crease_jobs::JobSpec::new(absolute(input), absolute(output));
            if let Some(an) = &a.anchors {
                spec.folds = crease_jobs::FoldSpec::Anchors { uri: absolute(an) };
            }
            if let Some(m) = a.mode {
                spec.deform.mode = m;
            }
            if let Some(p) = a.priority {
                spec.priority = p;
            }
            spec.client_token = a.client_token.clone();
            (serde_json::to_string(&spec)?, "json")
        }
        (Some(_), _, _) => bail!("give either a job file or --input/--output, not both"),
        _ => bail!("give a job file (crease submit job.toml) or both --input and --output"),
    };
    runtime()?.block_on(async move {
        let client = a.client.connect().await?;
        let (id, created) = match &a.job {
            // The coordinator sees only the text: name the file it came from.
            Some(path) => client
                .submit(text, format)
                .await
                .with_context(|| format!("job spec {}", path.display()))?,
            None => client.submit(text, format).await?,
        };
        if created {
            eprintln!("submitted {id}");
        } else {
            eprintln!("{id} was already submitted with this client token");
        }
        println!("{id}");
        if a.watch {
            let progress = CliProgress::new(false);
            let status =
                crate::watch::follow_remote(&a.client, &a.reconnect, &id, &progress).await?;
            crate::watch::finish(&status)?;
        }
        Ok(())
    })
}

#[derive(Args, Debug)]
pub struct StatusArgs {
    /// Job id (all jobs when omitted).
    pub job: Option<String>,
    #[command(flatten)]
    pub client: ClientArgs,
    /// List every task of the job.
    #[arg(long)]
    pub tasks: bool,
    /// Machine-readable output.
    #[arg(long)]
    pub json: bool,
}

pub fn status(a: StatusArgs) -> Result<()> {
    runtime()?.block_on(async move {
        let client = a.client.connect().await?;
        match &a.job {
            Some(id) => {
                let s = client.status(id, a.tasks || a.json).await?;
                if a.json {
                    println!("{}", serde_json::to_string_pretty(&status_json(&s))?);
                } else {
                    print_status(&s, a.tasks);
                }
            }
            None => print_jobs(&client.list().await?, a.json)?,
        }
        Ok(())
    })
}

#[derive(Args, Debug)]
pub struct JobArgs {
    /// Job id, as `crease submit` printed it (`crease jobs` lists them).
    pub job: String,
    #[command(flatten)]
    pub client: ClientArgs,
}

pub fn cancel(a: JobArgs) -> Result<()> {
    runtime()?.block_on(async move {
        let client = a.client.connect().await?;
        let state = client.cancel(&a.job).await?;
        println!("{} {state}", a.job);
        Ok(())
    })
}

#[derive(Args, Debug)]
pub struct UnblockArgs {
    /// The job whose worker blocklist to clear.
    pub job: String,
    /// Clear only this worker (an id such as `w3`, as `crease status JOB` lists it); default: every worker.
    #[arg(long)]
    pub worker: Option<String>,
    #[command(flatten)]
    pub client: ClientArgs,
}

/// `crease unblock`: the job's tasks may go to the cleared workers again.
pub fn unblock(a: UnblockArgs) -> Result<()> {
    runtime()?.block_on(async move {
        let client = a.client.connect().await?;
        let cleared = client.unblock(&a.job, a.worker.as_deref()).await?;
        match (cleared.is_empty(), &a.worker) {
            (true, Some(w)) => println!("{}: worker {w} was not blocklisted", a.job),
            (true, None) => println!("{}: no worker was blocklisted", a.job),
            (false, _) => println!("{}: cleared {}", a.job, cleared.join(", ")),
        }
        Ok(())
    })
}

#[derive(Args, Debug)]
pub struct JobsArgs {
    #[command(flatten)]
    pub client: ClientArgs,
    /// Machine-readable output (a JSON array of job statuses).
    #[arg(long)]
    pub json: bool,
}

pub fn jobs(a: JobsArgs) -> Result<()> {
    runtime()?.block_on(async move {
        let client = a.client.connect().await?;
        print_jobs(&client.list().await?, a.json)
    })
}

pub use crate::watch::follow;

fn status_json(s: &pb::JobStatus) -> serde_json::Value {
    serde_json::json!({
        "job_id": s.job_id, "name": s.name, "state": s.state, "priority": s.priority,
        "tasks_total": s.tasks_total, "tasks_done": s.tasks_done, "tasks_running": s.tasks_running,
        "tasks_failed": s.tasks_failed, "message": s.message, "output": s.output,
        "work_seconds": s.work_seconds,
        "blocked_workers": s.blocked_workers.iter().map(|b| serde_json::json!({
            "worker": b.worker, "failures": b.failures, "reasons": b.reasons,
        })).collect::<Vec<_>>(),
        "tasks": s.tasks.iter().map(|t| serde_json::json!({
            "key": t.key, "kind": t.kind, "state": t.state, "attempts": t.attempts,
            "last_error": t.last_error, "worker": t.worker, "work_seconds": t.work_seconds,
        })).collect::<Vec<_>>(),
        "running": s.running.iter().map(|r| serde_json::json!({
            "key": r.key, "kind": r.kind, "worker": r.worker, "stage": r.stage, "done": r.done, "total": r.total,
        })).collect::<Vec<_>>(),
    })
}

fn print_status(s: &pb::JobStatus, tasks: bool) {
    println!(
        "{} `{}` {}: {}/{} tasks done, {} running, {} failed{}",
        s.job_id,
        s.name,
        s.state,
        s.tasks_done,
        s.tasks_total,
        s.tasks_running,
        s.tasks_failed,
        if s.message.is_empty() {
            String::new()
        } else {
            format!(" — {}", s.message)
        }
    );
    for b in &s.blocked_workers {
        println!(
            "  blocklisted: worker {} ({} failure(s) of this job's tasks; `crease unblock {} --worker {}` clears it)",
            b.worker, b.failures, s.job_id, b.worker
        );
        for r in &b.reasons {
            println!("    {r}");
        }
    }
    for r in &s.running {
        let progress = if r.total > 0 {
            format!(
                ": {} {}/{} ({:.0}%)",
                r.stage,
                r.done,
                r.total,
                100.0 * r.done as f64 / r.total as f64
            )
        } else {
            String::new()
        };
        println!("  running {} on {}{progress}", r.key, r.worker);
    }
    if tasks {
        for t in &s.tasks {
            println!(
                "  {:<28} {:<10} attempts {} {}",
                t.key, t.state, t.attempts, t.last_error
            );
        }
    }
}

fn print_jobs(jobs: &[pb::JobStatus], json: bool) -> Result<()> {
    if json {
        let v: Vec<_> = jobs.iter().map(status_json).collect();
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else if jobs.is_empty() {
        println!("no jobs");
    } else {
        for s in jobs {
            print_status(s, false);
        }
    }
    Ok(())
}
