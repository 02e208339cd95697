//! Every flag, positional and verb of `crease` explains itself in `--help`: a walk over the whole clap tree
//! (as `main` builds it, `--threads` included) that names each argument without help text.

use crate::threads;
use crate::Cli;
use clap::{Command, CommandFactory};

fn missing_help(cmd: &Command, path: &str, out: &mut Vec<String>) {
    for arg in cmd.get_arguments() {
        let id = arg.get_id().as_str();
        if id == "help" || id == "version" {
            continue;
        }
        let has = |s: Option<&clap::builder::StyledStr>| {
            s.is_some_and(|s| !s.to_string().trim().is_empty())
        };
        if !has(arg.get_help()) && !has(arg.get_long_help()) {
            let name = match arg.get_long() {
                Some(l) => format!("--{l}"),
                None => format!("<{}>", id.to_uppercase()),
            };
            out.push(format!("{path} {name}"));
        }
    }
    for sub in cmd.get_subcommands() {
        let sub_path = format!("{path} {}", sub.get_name());
        if sub.get_about().is_none() && sub.get_long_about().is_none() && sub.get_name() != "help" {
            out.push(format!("{sub_path} (the verb itself)"));
        }
        missing_help(sub, &sub_path, out);
    }
}

#[test]
fn every_argument_has_help_text() {
    let cmd = threads::add_to(Cli::command());
    cmd.clone().debug_assert();
    let mut missing = Vec::new();
    missing_help(&cmd, "crease", &mut missing);
    assert!(
        missing.is_empty(),
        "arguments without help text:\n  {}",
        missing.join("\n  ")
    );
}

#[test]
fn threads_only_on_verbs_that_compute() {
    let cmd = threads::add_to(Cli::command());
    for sub in cmd.get_subcommands() {
        let has = sub.get_arguments().any(|a| a.get_long() == Some("threads"));
        let computes = threads::VERBS.contains(&sub.get_name());
        assert_eq!(has, computes, "`crease {}` --threads", sub.get_name());
    }
    for verb in ["submit", "status", "watch", "cancel", "jobs", "logs"] {
        assert!(!threads::VERBS.contains(&verb), "{verb}");
    }
}

fn parse(args: &[&str]) -> Result<Option<usize>, String> {
    let m = threads::add_to(Cli::command())
        .try_get_matches_from(args)
        .map_err(|e| e.to_string())?;
    threads::requested(&m).map_err(|e| e.to_string())
}

#[test]
fn threads_zero_and_client_verbs_are_refused() {
    assert_eq!(parse(&["crease", "run", "--threads", "3"]), Ok(Some(3)));
    assert_eq!(parse(&["crease", "--threads", "2", "worker"]), Ok(Some(2)));
    let zero = parse(&["crease", "run", "--threads", "0"]).unwrap_err();
    assert!(zero.contains("--threads"), "{zero}");
    assert!(parse(&["crease", "watch", "J", "--threads", "2"]).is_err());
    let before = parse(&["crease", "--threads", "2", "status"]).unwrap_err();
    assert!(
        before.contains("means nothing for `crease status`"),
        "{before}"
    );
}

/// `crease run --help` lists what changes from shot to shot; everything else is a tuning key (`--set`). The
/// flags, `--help` and `--threads` included, stay at most 30.
#[test]
fn run_has_at_most_thirty_flags() {
    let cmd = threads::add_to(Cli::command());
    let run = cmd.find_subcommand("run").expect("run");
    let flags: Vec<String> = run
        .get_arguments()
        .filter_map(|a| a.get_long().map(str::to_string))
        .collect();
    assert!(flags.len() <= 30, "{} flags: {flags:?}", flags.len());
    // Every flag sits under a heading but --help and --threads (clap's and the shared one).
    for a in run.get_arguments() {
        let id = a.get_id().as_str();
        if !["help", "threads"].contains(&id) {
            assert!(a.get_help_heading().is_some(), "--{id} has no heading");
        }
    }
}
