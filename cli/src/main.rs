//! `crease`: puts fine, temporally coherent folds back into captured garment mesh sequences.

mod arg_errors;
mod bench;
mod certs;
mod client;
mod cluster;
#[cfg(feature = "deep")]
mod deep;
mod error_text;
mod eval;
mod export;
mod farm;
#[cfg(test)]
mod help_tree;
mod limits_args;
mod local;
mod logging;
mod logs;
mod progress;
mod refine;
mod run;
mod run_args;
mod run_spec;
mod security_args;
mod threads;
mod tuning;
mod urls;
mod view;
mod watch;
#[cfg(not(feature = "deep"))]
mod without_deep;
#[cfg(not(feature = "deep"))]
use without_deep as deep;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "crease",
    version,
    about = "Space-time wrinkling of captured garment sequences (Popa et al. 2009)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Wrinkle a sequence with an anchors file; with no --input, generate the demo and run on it.
    Run(run::RunArgs),
    /// List the tuning keys `run --set` and a job spec's [tuning] table take (defaults, ranges, meanings).
    Tuning(tuning::TuningArgs),
    /// Write the procedural demo sequence (OBJ frames) and its anchors file.
    Demo(run::DemoArgs),
    /// Fold fidelity of a result against ground truth, beside the captured baseline (docs/fidelity.md).
    Eval(eval::EvalArgs),
    /// Paper-scale benchmark: seconds per frame per stage, peak memory, both weight modes.
    Bench(bench::BenchArgs),
    /// Run the coordinator: job queue (SQLite), scheduler and gRPC service.
    Coordinator(cluster::CoordinatorArgs),
    /// Run a worker that registers with a coordinator and executes its tasks.
    Worker(cluster::WorkerArgs),
    /// Submit a job (job.toml, or --input/--output flags); prints the job id.
    Submit(cluster::SubmitArgs),
    /// Status of one job (or all jobs).
    Status(cluster::StatusArgs),
    /// Follow a job's progress until it ends, riding out coordinator restarts; the exit status says how it ended.
    #[command(after_help = watch::EXIT_CODES)]
    Watch(watch::WatchArgs),
    /// Cancel a job.
    Cancel(cluster::JobArgs),
    /// Clear a job's worker blocklist (see `status`): its tasks may go to those workers again.
    Unblock(cluster::UnblockArgs),
    /// List the coordinator's jobs.
    Jobs(cluster::JobsArgs),
    /// Log tail of a job's task attempts (all tasks, or one).
    Logs(logs::LogsArgs),
    /// Write a development CA and coordinator/worker certificates for TLS.
    Certs(certs::CertsArgs),
    /// Farm tasks: `crease task run` runs one task of a job's graph with no coordinator.
    Task(farm::TaskArgs),
    /// Write a job's task graph for a render farm (OpenJD, Flamenco, OpenCue).
    ExportJob(farm::ExportJobArgs),
    /// Write a sequence as GLB, USD, MDD or PC2.
    Export(export::ExportArgs),
    /// DeepWrinkles (Lähner et al. 2018): register templates to scans, train, apply.
    Deep(deep::DeepArgs),
    /// Bake a detailed sequence into normal maps on its coarse input (the layout `crease deep apply` writes).
    Bake(deep::BakeArgs),
    /// Refine a sequence by the shading of its calibrated images (after `run`, or on a capture).
    Refine(refine::RefineArgs),
    /// Show an output folder (or any sequence) in the browser: the dashboard's 3D viewer and report.
    View(view::ViewArgs),
}

fn lossy(args: &[std::ffi::OsString]) -> Vec<String> {
    args.iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect()
}

fn main() {
    let args_os: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let matches = match threads::add_to(Cli::command()).try_get_matches_from(&args_os) {
        Ok(m) => m,
        Err(e) => match arg_errors::negative_value(&e, &lossy(&args_os)) {
            Some(msg) => {
                eprintln!("error: {msg}");
                std::process::exit(2);
            }
            None => e.exit(),
        },
    };
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let threads = threads::requested(&matches).unwrap_or_else(|e| {
        eprintln!("error: {e:#}");
        std::process::exit(2);
    });
    if let Some(n) = threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("error: cannot set up {n} threads: {e}");
            std::process::exit(2);
        }
    }
    let result = run_command(cli.command);
    if let Err(e) = result {
        eprintln!("error: {}", error_text::one_line(&e));
        let code = e.downcast_ref::<watch::Ended>().map_or(1, |end| end.code);
        std::process::exit(code);
    }
}

/// Runs one subcommand.
fn run_command(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Run(a) => run::run(a),
        Command::Tuning(a) => tuning::tuning(a),
        Command::Demo(a) => run::demo(a),
        Command::Eval(a) => eval::eval(a),
        Command::Bench(a) => bench::bench(a),
        Command::Coordinator(a) => cluster::coordinator(a),
        Command::Worker(a) => cluster::worker(a),
        Command::Submit(a) => cluster::submit(a),
        Command::Status(a) => cluster::status(a),
        Command::Watch(a) => watch::watch(a),
        Command::Cancel(a) => cluster::cancel(a),
        Command::Unblock(a) => cluster::unblock(a),
        Command::Jobs(a) => cluster::jobs(a),
        Command::Logs(a) => logs::logs(a),
        Command::Certs(a) => certs::certs(a),
        Command::Task(a) => farm::task(a),
        Command::ExportJob(a) => farm::export_job_cmd(a),
        Command::Export(a) => export::export_cmd(a),
        Command::Deep(a) => deep::deep(a),
        Command::Bake(a) => deep::bake(a),
        Command::View(a) => view::view(a),
        Command::Refine(a) => refine::refine(a),
    }
}
