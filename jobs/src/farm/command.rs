//! How a farm node invokes crease for one task: the executable and the job file, both paths on the farm's
//! shared storage as the nodes see them.

use super::graph::{FarmGraph, Stage};

/// The command line a farm task runs.
#[derive(Debug, Clone, PartialEq)]
pub struct FarmCommand {
    /// `crease` on the nodes' PATH, or an absolute path.
    pub exe: String,
    /// Absolute path of the job file on the nodes.
    pub job_file: String,
}

impl FarmCommand {
    /// Arguments (after the executable) that run task `index` of `stage`.
    pub fn stage_args(&self, graph: &FarmGraph, stage: Stage, index: &str) -> Vec<String> {
        let mut args = vec![
            "task".into(),
            "run".into(),
            "--job".into(),
            self.job_file.clone(),
            "--stage".into(),
            stage.name().into(),
            "--index".into(),
            index.into(),
        ];
        if graph.stage(Stage::Weights).is_some() {
            args.extend(["--block-slots".into(), graph.block_slots.to_string()]);
        }
        args
    }

    /// Arguments (after the executable) that run the task with key `key`.
    pub fn key_args(&self, key: &str) -> Vec<String> {
        vec![
            "task".into(),
            "run".into(),
            "--job".into(),
            self.job_file.clone(),
            "--task".into(),
            key.into(),
        ]
    }
}

/// POSIX shell quoting (single quotes), for farms whose command is one shell line.
pub fn shell_quote(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+=:,@#".contains(c))
    {
        return s.to_string();
    }
    format!("'{}'", s.replace('\'', r"'\''"))
}
