//! `--threads`: only the verbs that run numerics in this process take it (a client verb that talks to a
//! coordinator has no thread pool to size, and offering the flag there suggests it would change the job).
//!
//! The flag is added to those verbs' clap commands here rather than to each verb's argument struct, so the list
//! of verbs that take it lives in one place.

use anyhow::{bail, Result};
use clap::{Arg, ArgMatches, Command};

/// Verbs whose work runs on this process's rayon pool.
pub const VERBS: &[&str] = &["run", "demo", "eval", "bench", "coordinator", "worker"];

const ID: &str = "threads";

fn arg() -> Arg {
    Arg::new(ID)
        .long("threads")
        .value_name("N")
        .value_parser(clap::value_parser!(u32).range(1..=4096))
        .help("Worker threads for the numerics (at least 1; default: all cores)")
}

/// Adds `--threads` to the verbs in [`VERBS`] (and, for scripts written against older versions, before the
/// verb: `crease --threads N worker`).
pub fn add_to(cmd: Command) -> Command {
    let mut cmd = cmd.arg(
        arg().help("Worker threads for the numerics, given before a verb that computes (run, demo, eval, bench, coordinator, worker)"),
    );
    for verb in VERBS {
        cmd = cmd.mut_subcommand(*verb, |sub| sub.arg(arg()));
    }
    cmd
}

/// The thread count asked for, from either place; refused before a client verb, where it would mean nothing.
pub fn requested(matches: &ArgMatches) -> Result<Option<usize>> {
    let top = matches.get_one::<u32>(ID).copied();
    let (verb, sub) = match matches.subcommand() {
        Some(s) => s,
        None => return Ok(top.map(|n| n as usize)),
    };
    if !VERBS.contains(&verb) {
        if top.is_some() {
            bail!(
                "--threads means nothing for `crease {verb}` (it only talks to the coordinator); \
                 give it to the verbs that compute: {}",
                VERBS.join(", ")
            );
        }
        return Ok(None);
    }
    let own = sub.get_one::<u32>(ID).copied();
    Ok(own.or(top).map(|n| n as usize))
}
