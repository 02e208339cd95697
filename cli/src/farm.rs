//! `crease task run` (one planned task on a farm node, no coordinator) and `crease export-job` (the job's task
//! graph as an OpenJD template, a Flamenco job type or an OpenCue job spec). See docs/farms.md.

use crate::client::runtime;
use crate::progress::CliProgress;
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use crease_jobs::farm::{
    check_farm_paths, export_job, farm_graph, run_farm_task, CueIdentity, Farm, FarmCommand,
    TaskRef, DEFAULT_BLOCK_SLOTS,
};
use crease_jobs::{inspect_input, ExecContext, JobSpec};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Exit status of a failed task that another attempt may fix (storage or I/O trouble): sysexits' EX_TEMPFAIL.
/// Any other failure exits with 1.
pub const EXIT_RETRYABLE: i32 = 75;

#[derive(Args, Debug)]
pub struct TaskArgs {
    #[command(subcommand)]
    command: TaskCommand,
}

#[derive(Subcommand, Debug)]
enum TaskCommand {
    /// Run one task of a job's graph against its storage, with no coordinator (for farms).
    Run(TaskRunArgs),
}

#[derive(Args, Debug)]
pub struct TaskRunArgs {
    /// The job file (TOML, or JSON with a .json extension); its local paths must be absolute.
    #[arg(long)]
    job: PathBuf,
    /// Task key in the graph (`position/f000004`, `weights/w0001`, `finalize`; block slots
    /// `weights/w0001/slot0of4`).
    #[arg(long, conflicts_with_all = ["stage", "index"], required_unless_present = "stage")]
    task: Option<String>,
    /// Stage of the task (fold-steps, fold-phases, fold-detect, fold-settle, fold-merge, fold-files, fold-plot,
    /// weights, reduce, position, finalize), with --index.
    #[arg(long, requires = "index")]
    stage: Option<String>,
    /// 0-based index of the task within --stage (how farms that number tasks name one).
    #[arg(long, requires = "stage")]
    index: Option<usize>,
    /// Block slots per window used when the job was exported (fold detection in per-anchor mode).
    #[arg(long, default_value_t = DEFAULT_BLOCK_SLOTS)]
    block_slots: usize,
    /// Local cache for remote inputs (default: a directory under the system temp dir).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// No progress lines.
    #[arg(long)]
    quiet: bool,
}

pub fn task(a: TaskArgs) -> Result<()> {
    match a.command {
        TaskCommand::Run(r) => task_run(r),
    }
}

fn read_job(path: &Path) -> Result<JobSpec> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the job file {}", path.display()))?;
    let spec = if path.extension().is_some_and(|e| e == "json") {
        JobSpec::from_json_str(&text)
    } else {
        JobSpec::from_toml_str(&text)
    }
    .with_context(|| format!("job file {}", path.display()))?;
    check_farm_paths(&spec).with_context(|| format!("job file {}", path.display()))?;
    Ok(spec)
}

fn task_run(a: TaskRunArgs) -> Result<()> {
    let job = read_job(&a.job)?;
    let task = match (a.task, a.stage, a.index) {
        (Some(k), _, _) => TaskRef::Key(k),
        (None, Some(stage), Some(index)) => TaskRef::Index {
            stage,
            index,
            block_slots: a.block_slots,
        },
        _ => bail!("give --task KEY, or --stage and --index"),
    };
    let progress = Arc::new(CliProgress::new(a.quiet));
    let ctx = ExecContext {
        progress: progress.clone(),
        cache_dir: a
            .cache_dir
            .unwrap_or_else(|| std::env::temp_dir().join("crease-task-cache")),
    };
    let clock = std::time::Instant::now();
    let result = runtime()?.block_on(run_farm_task(&job, &task, &ctx));
    match result {
        Ok(run) => {
            if run.ran.is_empty() {
                progress.println(&format!(
                    "task {}: no anchor blocks fall in this slot; nothing to do",
                    run.key
                ));
            }
            for (key, out) in &run.ran {
                progress.println(&format!(
                    "task {key} done in {:.2}s: {} key(s) written under {}",
                    out.work_seconds,
                    out.written.len(),
                    job.output
                ));
            }
            progress.println(&format!(
                "farm task {} finished in {:.2}s",
                run.key,
                clock.elapsed().as_secs_f64()
            ));
            Ok(())
        }
        Err(e) => {
            let retry = e.retryable();
            eprintln!(
                "error: {e} ({})",
                if retry {
                    "retryable: another attempt may succeed"
                } else {
                    "not retryable: the job, the task or the data must change"
                }
            );
            std::process::exit(if retry { EXIT_RETRYABLE } else { 1 });
        }
    }
}

#[derive(Args, Debug)]
pub struct ExportJobArgs {
    /// The job file (TOML, or JSON with a .json extension); its local paths must be absolute.
    job: PathBuf,
    /// Farm format: openjd (AWS Deadline Cloud), flamenco or opencue.
    #[arg(long)]
    to: String,
    /// Where to write the farm job (default: next to the job file, named after the job).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Block slots per window when folds are detected in per-anchor mode (the anchor count, and with it the
    /// number of blocks, is only known after detection; a slot runs every S-th block).
    #[arg(long, default_value_t = DEFAULT_BLOCK_SLOTS)]
    block_slots: usize,
    /// The crease executable as the farm nodes see it.
    #[arg(long, default_value = "crease")]
    crease_exe: String,
    /// The job file as the farm nodes see it (default: this job file's absolute path).
    #[arg(long)]
    job_path_on_farm: Option<String>,
    /// OpenCue show.
    #[arg(long, default_value = "crease")]
    show: String,
    /// OpenCue shot (default: the job name).
    #[arg(long)]
    shot: Option<String>,
    /// OpenCue user (default: $USER).
    #[arg(long)]
    user: Option<String>,
}

pub fn export_job_cmd(a: ExportJobArgs) -> Result<()> {
    let farm: Farm = a.to.parse()?;
    let job = read_job(&a.job)?;
    let info = runtime()?
        .block_on(inspect_input(&job))
        .with_context(|| format!("job file {}", a.job.display()))?;
    let graph = farm_graph(&job, &info, a.block_slots)?;
    let job_file = match a.job_path_on_farm {
        Some(p) => p,
        None => std::path::absolute(&a.job)
            .with_context(|| format!("resolving {}", a.job.display()))?
            .display()
            .to_string(),
    };
    let cmd = FarmCommand {
        exe: a.crease_exe,
        job_file,
    };
    let cue = CueIdentity {
        show: a.show,
        shot: a.shot.unwrap_or_else(|| job.display_name()),
        user: a
            .user
            .or_else(|| std::env::var("USER").ok())
            .unwrap_or_else(|| "crease".into()),
    };
    let text = export_job(farm, &job, &graph, &cmd, &cue);
    let out = a.out.unwrap_or_else(|| {
        a.job
            .parent()
            .unwrap_or(Path::new("."))
            .join(farm.file_name(&job))
    });
    crease_core::fsutil::write_atomic(&out, text.as_bytes())?;
    let stages: Vec<String> = graph
        .stages
        .iter()
        .map(|s| format!("{} {}", s.stage.name(), s.tasks.len()))
        .collect();
    eprintln!(
        "wrote {} ({} tasks in {} stages: {})",
        out.display(),
        graph.n_tasks(),
        graph.stages.len(),
        stages.join(", ")
    );
    Ok(())
}
