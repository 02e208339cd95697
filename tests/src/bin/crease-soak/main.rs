//! `crease-soak`: the chaos/soak harness. It lives with the end-to-end tests, not in the user's `crease`
//! binary, and drives a `crease` executable as child processes (coordinator, workers, clients), exactly as an
//! operator's farm would; see [`harness`] for what it checks.

mod harness;

use anyhow::{bail, Context, Result};
use clap::Parser;
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    name = "crease-soak",
    about = "Soak test: concurrent clients submit small jobs to a loopback cluster while workers are killed \
             and restarted at random; every output is compared with a single-node run"
)]
struct Cli {
    #[command(flatten)]
    soak: harness::SoakArgs,
    /// The `crease` executable to test (default: the one beside this program, i.e. the same cargo build).
    #[arg(long)]
    crease: Option<PathBuf>,
    /// Also write the summary as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = run(&cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: &Cli) -> Result<()> {
    let exe = match &cli.crease {
        Some(p) => p.clone(),
        None => {
            let me = std::env::current_exe().context("locating crease-soak itself")?;
            me.with_file_name(format!("crease{}", std::env::consts::EXE_SUFFIX))
        }
    };
    if !exe.is_file() {
        bail!(
            "no crease executable at {} (build it with `cargo build --release -p crease`, or pass --crease PATH)",
            exe.display()
        );
    }
    harness::soak(&cli.soak, &exe, cli.json.as_deref())
}
