//! The stretch detector run as separate stages (steps in chunks → phases → tracing chunks → reconcile →
//! finish) gives the streaming run's anchors and `folds.png` bit for bit, whatever the chunking and warm-up.

use crease_core::folds::stretch::split::{
    overlay_frame, reconcile, steps, trace_chunk, ChunkTracer, Pass, PhaseCode, Phases, StepRecord,
    TracedChunk,
};
use crease_core::folds::stretch::{StretchDetector, StretchParams};
use crease_core::folds::FoldDetector;
use crease_core::mesh::{FrameSource, Sequence};
use crease_core::progress::NoProgress;
use crease_core::synth;
use crease_core::vec3;
use std::collections::HashMap;

fn ranges(n: usize, size: usize) -> Vec<std::ops::Range<usize>> {
    (0..n.div_ceil(size))
        .map(|c| c * size..((c + 1) * size).min(n))
        .collect()
}

type Codes = (Option<Vec<PhaseCode>>, Option<Vec<PhaseCode>>);

/// The split run: returns (anchors JSON per frame, folds.png bytes, frames traced again by reconcile).
fn split_run(
    det: &StretchDetector,
    source: &dyn FrameSource,
    step_chunk: usize,
    trace_size: usize,
    warm_up: usize,
) -> (String, Vec<Vec<u8>>, usize) {
    let n = source.n_frames();
    let nt = source.topology().n_triangles();
    let mut records: HashMap<usize, Vec<StepRecord>> = HashMap::new();
    for r in ranges(n, step_chunk) {
        for (k, rec) in steps(source, r.clone(), &det.params, &NoProgress)
            .unwrap()
            .into_iter()
            .enumerate()
        {
            records.insert(r.start + k, rec);
        }
    }
    let mut fwd: HashMap<usize, Vec<PhaseCode>> = HashMap::new();
    let mut bwd: HashMap<usize, Vec<PhaseCode>> = HashMap::new();
    Phases {
        n_frames: n,
        n_triangles: nt,
        params: &det.params,
    }
    .run(
        |t| Ok(records[&t].clone()),
        |t, pass, codes| {
            match pass {
                Pass::Forward => fwd.insert(t, codes),
                Pass::Backward => bwd.insert(t, codes),
            };
            Ok(())
        },
        &NoProgress,
    )
    .unwrap();
    let codes = |t: usize| -> Codes { (fwd.get(&t).cloned(), bwd.get(&t).cloned()) };
    let chunks: Vec<TracedChunk> = ranges(n, trace_size)
        .into_iter()
        .map(|r| {
            // A fresh tracer per chunk, as on another worker.
            let mut tracer = ChunkTracer::new(det, source).unwrap();
            trace_chunk(&mut tracer, r, warm_up, |t| Ok(codes(t)), &NoProgress).unwrap()
        })
        .collect();
    let mut tracer = ChunkTracer::new(det, source).unwrap();
    let (frames, retraced) = reconcile(chunks.into_iter().map(Ok), n, |t, seeds| {
        tracer.set_seeds(seeds);
        let (f, b) = codes(t);
        tracer.trace(t, f.as_deref(), b.as_deref())
    })
    .unwrap();
    let mut shown = Vec::new();
    for f in &frames {
        let (a, b) = codes(f.anchors.frame);
        if let Some(o) = overlay_frame(&mut tracer, f, a.as_deref(), b.as_deref()).unwrap() {
            shown.push(o);
        }
    }
    let (out, artifacts) = det
        .finish(
            source,
            frames.into_iter().map(|f| f.anchors).collect(),
            &shown,
        )
        .unwrap();
    (
        serde_json::to_string(&out).unwrap(),
        artifacts.into_iter().map(|a| a.bytes).collect(),
        retraced,
    )
}

fn check(seq: &Sequence, params: StretchParams, what: &str) {
    let n = seq.frames.len();
    let det = StretchDetector {
        params,
        overlay_frames: vec![1, n / 2, n - 1],
        overlay_size: 96,
    };
    let (direct, artifacts) = det.detect_with_artifacts(seq, 0..n, &NoProgress).unwrap();
    let direct = serde_json::to_string(&direct).unwrap();
    let direct_png: Vec<Vec<u8>> = artifacts.into_iter().map(|a| a.bytes).collect();
    assert_eq!(direct_png.len(), 1, "{what}: folds.png drawn");
    assert!(
        direct.matches("\"triangle\"").count() > 20,
        "{what}: folds found"
    );
    let mut retraced_somewhere = false;
    for (steps_per, trace_per, warm_up) in [
        (n, n, 0),
        (1, 1, 0),
        (3, 2, 0),
        (4, 5, 2),
        (2, 3, 4),
        (5, 1, 1),
    ] {
        let (json, png, retraced) = split_run(&det, seq, steps_per, trace_per, warm_up);
        assert!(
            json == direct,
            "{what}: anchors differ (steps {steps_per}, trace {trace_per}, warm-up {warm_up})"
        );
        assert!(png == direct_png, "{what}: folds.png differs");
        if trace_per == n {
            assert_eq!(retraced, 0, "{what}: one chunk is exact");
        }
        retraced_somewhere |= retraced > 0;
    }
    if det.params.seed_memory {
        // Cold chunk starts in the middle of folds: the reconcile must have had work to do.
        assert!(retraced_somewhere, "{what}: reconcile never traced again");
    } else {
        // Without the seed memory a frame's folds are its own: every chunk is exact as traced.
        assert!(
            !retraced_somewhere,
            "{what}: traced again without a seed memory"
        );
    }
}

fn with_memory() -> StretchParams {
    StretchParams {
        seed_memory: true,
        ..Default::default()
    }
}

#[test]
fn split_detection_is_the_streaming_run_for_any_chunking() {
    let mut env = vec![0.0];
    env.extend((1..=6).map(|i| i as f64 / 6.0));
    env.extend([1.0, 1.0]);
    env.extend((1..=4).map(|i| 1.0 - i as f64 / 4.0));
    let seq = synth::compressed_sheet(24, 24, 0.1, 0.5, (0.35, 0.65), 0.12, 0.03, &env).unwrap();
    check(&seq, StretchParams::default(), "compressed sheet");
    check(&seq, with_memory(), "compressed sheet, seed memory");
    // Transients: a frame pulled back to an earlier one's shape, and a vertex lifted for one frame. The split
    // run's phase task must resume the references the streaming run resumes.
    let mut frames = seq.frames.clone();
    frames[4] = frames[2].clone();
    let v = frames[7].len() / 2 + 3;
    let edge = vec3::norm(vec3::sub(frames[7][0], frames[7][1]));
    frames[7][v][2] += edge;
    let jittered = Sequence::new(seq.topology.clone(), frames).unwrap();
    check(
        &jittered,
        StretchParams::default(),
        "compressed sheet with transients",
    );
    let (demo, _) = synth::demo(&synth::DemoSpec {
        triangles: 900,
        frames: 9,
        ..Default::default()
    })
    .unwrap();
    check(&demo, StretchParams::default(), "demo");
    check(&demo, with_memory(), "demo, seed memory");
}
