//! `crease`: puts fine, temporally coherent folds back into captured garment mesh sequences.

mod bench;
mod bench_cluster;
mod certs;
mod cluster;
mod eval;
mod export;
mod farm;
mod folds_stretch;
mod folds_video;
mod limits_args;
mod local;
mod logging;
mod logs;
mod progress;
mod run;
mod security_args;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "crease",
    version,
    about = "Space-time wrinkling of captured garment sequences (Popa et al. 2009)"
)]
struct Cli {
    /// Worker threads for the numerics (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Wrinkle a sequence with an anchors file; with no --input, generate the demo and run on it.
    Run(run::RunArgs),
    /// Write the procedural demo sequence (OBJ frames) and its anchors file.
    Demo(run::DemoArgs),
    /// Fold fidelity of a result against ground truth (DESIGN.md §9), beside the captured baseline.
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
    /// Follow a job's progress until it ends.
    Watch(cluster::JobArgs),
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
}

fn main() {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
        {
            eprintln!("error: cannot set up {n} threads: {e}");
            std::process::exit(2);
        }
    }
    let result = match cli.command {
        Command::Run(a) => run::run(a),
        Command::Demo(a) => run::demo(a),
        Command::Eval(a) => eval::eval(a),
        Command::Bench(a) => bench::bench(a),
        Command::Coordinator(a) => cluster::coordinator(a),
        Command::Worker(a) => cluster::worker(a),
        Command::Submit(a) => cluster::submit(a),
        Command::Status(a) => cluster::status(a),
        Command::Watch(a) => cluster::watch(a),
        Command::Cancel(a) => cluster::cancel(a),
        Command::Unblock(a) => cluster::unblock(a),
        Command::Jobs(a) => cluster::jobs(a),
        Command::Logs(a) => logs::logs(a),
        Command::Certs(a) => certs::certs(a),
        Command::Task(a) => farm::task(a),
        Command::ExportJob(a) => farm::export_job_cmd(a),
        Command::Export(a) => export::export_cmd(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
