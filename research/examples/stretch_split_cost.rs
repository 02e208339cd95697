//! What splitting the stretch detector into tasks costs in computation: the streaming run against the split
//! stages run one after the other in this process (steps, phases, tracing chunks, reconcile + finish), on the
//! compressed sleeve of `crease bench --stretch-folds-only`, back to back, checking the anchors are identical.
//! No storage or network: the cluster adds its own transfer costs on top.
//!
//! `cargo run --release -p crease-research --example stretch_split_cost -- [triangles] [frames] [chunk] [warm-up]`

use crease_core::folds::stretch::split::{
    reconcile, steps, trace_chunk, ChunkTracer, Pass, PhaseCode, Phases, StepRecord,
};
use crease_core::folds::stretch::StretchDetector;
use crease_core::folds::FoldDetector;
use crease_core::mesh::FrameSource;
use crease_core::progress::NoProgress;
use crease_core::synth;
use std::collections::HashMap;
use std::time::Instant;

fn main() -> crease_core::Result<()> {
    let arg = |i: usize, d: usize| {
        std::env::args()
            .nth(i)
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let (size, frames, chunk, warm_up) = (arg(1, 100_000), arg(2, 8), arg(3, 2), arg(4, 3));
    let seq = synth::compressed_tube(size, frames, 0.3, -1.0)?;
    let n = seq.n_frames();
    let nt = seq.topology.n_triangles();
    let det = StretchDetector::default();
    let per = |t: Instant| t.elapsed().as_secs_f64() / n as f64;

    let t = Instant::now();
    let (direct, _) = det.detect_with_artifacts(&seq, 0..n, &NoProgress)?;
    let streaming = per(t);

    let t = Instant::now();
    let mut records: HashMap<usize, Vec<StepRecord>> = HashMap::new();
    for c in 0..n.div_ceil(4 * chunk) {
        let r = c * 4 * chunk..((c + 1) * 4 * chunk).min(n);
        for (k, rec) in steps(&seq, r.clone(), &det.params, &NoProgress)?
            .into_iter()
            .enumerate()
        {
            records.insert(r.start + k, rec);
        }
    }
    let t_steps = per(t);
    let t = Instant::now();
    let mut codes: HashMap<(usize, bool), Vec<PhaseCode>> = HashMap::new();
    Phases {
        n_frames: n,
        n_triangles: nt,
        params: &det.params,
    }
    .run(
        |t| Ok(records[&t].clone()),
        |t, pass, c| {
            codes.insert((t, pass == Pass::Forward), c);
            Ok(())
        },
        &NoProgress,
    )?;
    let t_phases = per(t);
    let get = |t: usize| {
        (
            codes.get(&(t, true)).cloned(),
            codes.get(&(t, false)).cloned(),
        )
    };
    let t = Instant::now();
    let mut chunks = Vec::new();
    for c in 0..n.div_ceil(chunk) {
        let r = c * chunk..((c + 1) * chunk).min(n);
        let mut tracer = ChunkTracer::new(&det, &seq)?;
        chunks.push(trace_chunk(
            &mut tracer,
            r,
            warm_up,
            |t| Ok(get(t)),
            &NoProgress,
        )?);
    }
    let t_trace = per(t);
    let t = Instant::now();
    let mut tracer = ChunkTracer::new(&det, &seq)?;
    let (out, retraced) = reconcile(chunks.into_iter().map(Ok), n, |t, seeds| {
        tracer.set_seeds(seeds);
        let (f, b) = get(t);
        tracer.trace(t, f.as_deref(), b.as_deref())
    })?;
    let (split, _) = det.finish(&seq, out.into_iter().map(|f| f.anchors).collect(), &[])?;
    let t_merge = per(t);
    let same = serde_json::to_string(&split).ok() == serde_json::to_string(&direct).ok();
    println!(
        "{nt} triangles, {n} frames, tracing chunks of {chunk} (warm-up {warm_up}); seconds per frame"
    );
    println!("streaming run        {streaming:.3}");
    println!("split: steps         {t_steps:.3}");
    println!("split: phases        {t_phases:.3}");
    println!("split: tracing       {t_trace:.3}");
    println!("split: merge         {t_merge:.3}  ({retraced} frames traced again)");
    println!(
        "split total          {:.3}  ({:.2}x the streaming run)",
        t_steps + t_phases + t_trace + t_merge,
        (t_steps + t_phases + t_trace + t_merge) / streaming
    );
    println!("anchors identical: {same}");
    if !same {
        std::process::exit(1);
    }
    Ok(())
}
