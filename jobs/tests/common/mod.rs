//! Shared helpers: a small synthetic input written to disk, the single-machine reference run, and an
//! in-process "cluster" that executes every task of a job's plan itself, in a chosen valid order.

#![allow(dead_code)]

use crease_core::folds::AnchorSet;
use crease_core::mesh::io::{create_sink, open_sequence};
use crease_core::progress::{NoProgress, Progress};
use crease_core::spacetime::{deform, DeformParams, DeformReport};
use crease_core::synth::{self, DemoSpec};
use crease_jobs::{
    execute, expand, inspect_input, plan, ExecContext, InputInfo, JobSpec, TaskDef, TaskError,
    TaskOutput,
};
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Writes a demo sequence (numbered OBJ frames) and its anchors file under `root`; returns (input dir, anchors).
pub fn fixture(root: &Path, triangles: usize, frames: usize) -> (PathBuf, PathBuf) {
    let (seq, anchors) = synth::demo(&DemoSpec {
        triangles,
        frames,
        ..Default::default()
    })
    .unwrap();
    synth::write_demo(root, &seq, &anchors).unwrap()
}

/// `crease run`'s computation: deform() from the input through the layout's sink into `out`.
pub fn reference(
    input: &Path,
    anchors: Option<&Path>,
    params: &DeformParams,
    out: &Path,
) -> DeformReport {
    let opened = open_sequence(input).unwrap();
    let source = opened.source.as_ref();
    let n = source.n_frames();
    let set = match anchors {
        Some(a) => AnchorSet::read(a, n, source.topology().n_triangles()).unwrap(),
        None => AnchorSet::empty(n),
    };
    let mut sink = create_sink(&opened.layout, out).unwrap();
    let (report, _) = deform(source, &set, params, sink.as_mut(), &NoProgress, &[]).unwrap();
    sink.finish().unwrap();
    report
}

/// A job spec for `input` → `output`, with TOML `extra` appended (deform / partition tables).
pub fn job(input: &Path, anchors: Option<&Path>, output: &Path, extra: &str) -> JobSpec {
    let folds = match anchors {
        Some(a) => format!(
            "[folds]\nkind = \"anchors\"\nuri = {:?}\n",
            a.display().to_string()
        ),
        None => String::new(),
    };
    let text = format!(
        "name = \"test\"\ninput = {:?}\noutput = {:?}\n{extra}\n{folds}",
        input.display().to_string(),
        output.display().to_string()
    );
    JobSpec::from_toml_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// How the in-process runner picks among ready tasks.
#[derive(Clone, Copy)]
pub struct Order {
    /// 0: the plan's order; otherwise a seed for a random pick among the ready tasks.
    pub seed: u64,
    /// Every `rerun`-th executed task runs a second time later (0: never).
    pub rerun: usize,
}

pub const PLAN_ORDER: Order = Order { seed: 0, rerun: 0 };

fn lcg(s: &mut u64) -> u64 {
    *s = s
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    *s >> 33
}

pub fn ctx(cache: &Path) -> ExecContext {
    ExecContext {
        progress: Arc::new(NoProgress),
        cache_dir: cache.to_path_buf(),
    }
}

/// Results of running a whole job in process.
pub struct Run {
    pub info: InputInfo,
    pub tasks: Vec<TaskDef>,
    pub outcomes: BTreeMap<String, Result<TaskOutput, TaskError>>,
    /// Keys in execution order (reruns appear twice).
    pub executed: Vec<String>,
}

/// Plans `spec` and executes every task whose dependencies succeeded, in a valid topological order chosen by
/// `order`, expanding the graph as the coordinator would. Failed tasks are recorded; their dependants never run.
pub async fn run_job(spec: &JobSpec, cache: &Path, order: Order) -> Run {
    let info = inspect_input(spec).await.unwrap();
    let mut tasks = plan(spec, &info).unwrap();
    let ctx = ctx(cache);
    let mut done: HashSet<String> = HashSet::new();
    let mut failed: HashSet<String> = HashSet::new();
    let mut outcomes = BTreeMap::new();
    let mut executed = Vec::new();
    let mut reruns: Vec<TaskDef> = Vec::new();
    let mut seed = order.seed;
    loop {
        let ready: Vec<usize> = (0..tasks.len())
            .filter(|&i| {
                let t = &tasks[i];
                !done.contains(&t.key)
                    && !failed.contains(&t.key)
                    && t.deps.iter().all(|d| done.contains(d))
            })
            .collect();
        if ready.is_empty() {
            break;
        }
        let pick = if order.seed == 0 {
            ready[0]
        } else {
            ready[(lcg(&mut seed) as usize) % ready.len()]
        };
        let task = tasks[pick].clone();
        let result = execute(&task.spec, &ctx).await;
        executed.push(task.key.clone());
        if order.rerun > 0 && executed.len() % order.rerun == 0 {
            reruns.push(task.clone());
        }
        match &result {
            Ok(out) => {
                done.insert(task.key.clone());
                if task.expands {
                    let more = expand(spec, &info, &task.key, out).unwrap();
                    tasks.extend(more);
                }
            }
            Err(_) => {
                failed.insert(task.key.clone());
            }
        }
        outcomes.insert(task.key.clone(), result);
        // Re-run a task executed earlier while others are in flight, like a duplicate after a lost worker.
        if executed.len() % 5 == 0 {
            if let Some(again) = reruns.pop() {
                let r = execute(&again.spec, &ctx).await;
                assert!(r.is_ok(), "re-running {} failed: {:?}", again.key, r.err());
                executed.push(again.key);
            }
        }
    }
    for again in reruns {
        let r = execute(&again.spec, &ctx).await;
        assert!(r.is_ok(), "re-running {} failed: {:?}", again.key, r.err());
        executed.push(again.key);
    }
    Run {
        info,
        tasks,
        outcomes,
        executed,
    }
}

/// Every regular file under `dir` (relative path → bytes), skipping `skip` names and hidden directories.
pub fn files(dir: &Path, skip: &[&str]) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || skip.contains(&name.as_str()) || !e.path().is_file() {
            continue;
        }
        out.insert(name, std::fs::read(e.path()).unwrap());
    }
    out
}

/// A progress sink that reports cancellation once `after` units of work were advanced.
pub struct CancelAfter {
    pub after: u64,
    pub seen: std::sync::atomic::AtomicU64,
}

impl Progress for CancelAfter {
    fn advance(&self, _stage: &str, n: u64) {
        self.seen.fetch_add(n, std::sync::atomic::Ordering::SeqCst);
    }
    fn cancelled(&self) -> bool {
        self.seen.load(std::sync::atomic::Ordering::SeqCst) >= self.after
    }
}
