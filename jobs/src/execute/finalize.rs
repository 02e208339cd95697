//! The finalize task: write the output sequence in the input's layout from the stored positions, the previews,
//! and `report.json` — last, so that its presence means the output is complete (the same contract as
//! `crease run`). A stale report from an earlier run is removed first, so it never vouches for outputs this run
//! is still rewriting.

use super::env::{storage_err, TaskEnv};
use super::phase_times::Lap;
use super::position::FrameTimings;
use super::weights::WindowRecord;
use crate::error::{JobError, TaskError};
use crate::plan::inspect::{output_files, output_sink, writes_frames};
use crate::report::{
    AnchorsSource, FoldDetection, JobReport, LostAreaJudgement, SecondsPerFrame, SequenceLengths,
    Summary, VsRest,
};
use crate::spec::FoldSpec;
use crate::storage::keys;
use crease_core::mesh::{Frame, FrameSource};
use crease_core::metrics::StretchAccumulator;
use crease_core::rest_stretch::{self, RestLengths, RestStretchAccumulator};
use crease_core::shape::ShapeAccumulator;
use crease_core::spacetime::deform::StageTimings;
use crease_core::spacetime::weights::WindowStats;
use crease_core::spacetime::DeformReport;
use crease_core::{preview, render};
use serde_json::{json, Value};
use std::time::Instant;

pub fn finalize(env: &TaskEnv) -> Result<(Value, Vec<String>), TaskError> {
    let mut lap = Lap::start();
    let job = env.job;
    let params = &env.params;
    env.delete(keys::REPORT)?;
    // A worker killed in the middle of a put (an earlier attempt of this task, or of any task before it) leaves
    // the put's staging file beside the object; the output must hold only what the job wrote.
    env.out
        .remove_put_leftovers()
        .map_err(|e| storage_err(JobError::storage_failure(env.out.uri(), &e)))?;
    let opened = env.open_input()?;
    let (mean_edge, scales) = super::position::first_edge_and_scales(env, &opened, "finalize")?;
    let source: &dyn FrameSource = opened.source.as_ref();
    let topo = source.topology().clone();
    let n = source.n_frames();
    lap.lap("finalize: open input, clear the output");
    let anchors = env.anchors(n, topo.n_triangles())?;
    lap.lap("finalize: read the anchors");
    let core_err = |what: &str| {
        let what = what.to_string();
        move |e| TaskError::from_core(&format!("finalize: {what}"), e)
    };

    let out_dir = env.output_dir("finalize")?;
    let dir = out_dir.path.clone();
    // Frame-per-file layouts were written frame by frame by the positioning tasks; a point cache is one file
    // and is written here.
    let mut sink = if writes_frames(job, &opened.layout) {
        None
    } else {
        Some(output_sink(job, &opened.layout, &topo, n, &dir).map_err(core_err("output"))?)
    };
    let keep = crate::plan::detect::preview_frames(job, n);
    let mut timings = StageTimings {
        stretch_passes: vec![0.0; params.stretch_passes],
        ..Default::default()
    };
    let mut seq_stretch = vec![StretchAccumulator::default(); params.stretch_passes + 1];
    let mut frame_stretch = vec![Vec::new(); n];
    let mut frame_lost_share = vec![None; n];
    let mut frame_relief_share = vec![None; n];
    let mut kept: Vec<(usize, Frame, Frame)> = Vec::new();
    // "Shape kept" (docs/fidelity.md): every output frame against its input frame, measured by the positioning task
    // and merged here in frame order (the same figures for any chunking and any number of workers).
    let mut shape_kept = ShapeAccumulator::default();
    // Stretch against the least-compressed captured edge lengths (crease_core::rest_stretch): the rest lengths
    // need every input frame, so they are measured here, where the whole sequence is, on every output frame.
    let rest_lengths = RestLengths::of_sequence(source).map_err(core_err("rest lengths"))?;
    lap.lap("finalize: rest lengths (reads every input frame)");
    let mut vs_rest = RestStretchAccumulator::default();
    env.progress().begin("finalize", n as u64);
    for (t, stretch_of_t) in frame_stretch.iter_mut().enumerate() {
        env.check_cancelled()?;
        // Positions are read back for the stretch against the rest lengths, a point cache written here and the
        // preview frames. Frame-per-file layouts were written by the positioning tasks.
        {
            let key = keys::positions(t);
            let (shape, data) = env.get_npy::<f64>(&key)?;
            if shape != [topo.n_vertices(), 3] {
                return Err(TaskError::fatal(format!(
                    "{}: shape {shape:?}, expected ({}, 3)",
                    env.out.describe(&key),
                    topo.n_vertices()
                )));
            }
            let out: Frame = data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
            vs_rest.add_frame(&rest_lengths, &out);
            if let Some(sink) = sink.as_mut() {
                let tw = Instant::now();
                sink.write_frame(t, &out).map_err(core_err("output"))?;
                timings.write += tw.elapsed().as_secs_f64();
            }
            if keep.contains(&t) {
                let rest = source.read_frame(t).map_err(core_err("preview"))?;
                kept.push((t, rest, out));
            }
        }

        let key = keys::frame_stretch(t);
        let (_, words) = env.get_npy::<u64>(&key)?;
        let mut at = 0;
        for acc in seq_stretch.iter_mut() {
            let (a, used) = StretchAccumulator::from_words(&words[at..]).ok_or_else(|| {
                TaskError::fatal(format!(
                    "{}: not {} stretch accumulators",
                    env.out.describe(&key),
                    params.stretch_passes + 1
                ))
            })?;
            at += used;
            acc.merge(&a);
            stretch_of_t.push(a.stats());
        }
        let (shape, used) = ShapeAccumulator::from_words(&words[at..]).ok_or_else(|| {
            TaskError::fatal(format!(
                "{}: no shape accumulator after the {} stretch accumulators",
                env.out.describe(&key),
                params.stretch_passes + 1
            ))
        })?;
        shape_kept.merge(&shape);
        let share = words.get(at + used).ok_or_else(|| {
            TaskError::fatal(format!(
                "{}: no lost-area judgement after the shape accumulator",
                env.out.describe(&key)
            ))
        })?;
        frame_lost_share[t] = Some(f64::from_bits(*share)).filter(|s| !s.is_nan());
        let relief = words.get(at + used + 1).ok_or_else(|| {
            TaskError::fatal(format!(
                "{}: no relief share after the lost-area judgement",
                env.out.describe(&key)
            ))
        })?;
        frame_relief_share[t] = Some(f64::from_bits(*relief)).filter(|s| !s.is_nan());
        let ft: FrameTimings = env.get_json(&keys::frame_timings(t))?;
        timings.symbolic += ft.symbolic;
        timings.read += ft.read;
        timings.blend += ft.blend;
        timings.factor += ft.factor;
        timings.position += ft.position;
        timings.metrics += ft.metrics;
        for (k, s) in ft.passes.iter().enumerate() {
            if let Some(x) = timings.stretch_passes.get_mut(k) {
                *x += s;
            }
        }
        env.progress().advance("finalize", 1);
    }
    lap.lap("finalize: frames (positions, stretch, previews' input frames)");
    let names: Vec<String> = match sink.as_mut() {
        Some(sink) => sink
            .finish()
            .map_err(core_err("output"))?
            .iter()
            .filter_map(|p| p.file_name().map(|f| f.to_string_lossy().into_owned()))
            .collect(),
        None => output_files(job, &opened.layout, n),
    };
    let mut missing = Vec::new();
    for name in &names {
        if !env.block_on(env.out.exists(name)).map_err(storage_err)? {
            missing.push(name.clone());
        }
    }
    if !missing.is_empty() {
        return Err(TaskError::fatal(format!(
            "finalize: {} output frame file(s) missing from {} although their positioning tasks succeeded: {}",
            missing.len(),
            job.output,
            missing.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
        )));
    }
    let windows: Vec<WindowStats> = (0..env.windows(n).len())
        .map(|k| {
            env.get_json::<WindowRecord>(&keys::window_stats(k))
                .map(Into::into)
        })
        .collect::<Result<_, _>>()?;
    timings.weights = windows.iter().map(|w| w.seconds).sum();

    lap.lap("finalize: output files checked, window stats");
    let t_preview = Instant::now();
    let focus = kept.first().and_then(|(_, rest, _)| {
        let anchored = kept
            .iter()
            .flat_map(|(t, _, _)| anchors.frame(*t).iter().map(|a| a.triangle));
        preview::fold_focus(&topo, rest, anchored)
    });
    let img = preview::before_after(&topo, &kept, job.preview.size, 0.10, focus);
    render::save_png(&img, &dir.join(keys::PREVIEW)).map_err(core_err("preview"))?;
    render::save_png(
        &preview::stretch_plot(&frame_stretch, 900, 420),
        &dir.join(keys::STRETCH_PLOT),
    )
    .map_err(core_err("stretch plot"))?;
    let preview_seconds = t_preview.elapsed().as_secs_f64();
    lap.lap("finalize: previews");

    let mut written = names;
    written.push(keys::PREVIEW.into());
    written.push(keys::STRETCH_PLOT.into());
    out_dir.upload(env)?;
    written.extend(super::export::write_exports(env, &topo, n)?);

    let report = DeformReport {
        params: params.clone(),
        frames: n,
        vertices: topo.n_vertices(),
        triangles: topo.n_triangles(),
        anchors: anchors.total(),
        windows,
        stretch: seq_stretch.iter().map(|a| a.stats()).collect(),
        frame_stretch,
        frame_lost_share,
        frame_relief_share,
        timings,
    };
    let first = report.stretch.first().copied().unwrap_or_default();
    let last = report.stretch.last().copied().unwrap_or_default();
    let per_frame = |s: f64| s / n as f64;
    let t = &report.timings;
    let anchors_file = match &job.folds {
        FoldSpec::None => None,
        FoldSpec::Anchors { uri } => Some(AnchorsSource::File(uri.clone())),
        #[allow(unreachable_patterns)]
        other => Some(AnchorsSource::Detected {
            detected: other.kind().into(),
            file: env.out.describe(keys::ANCHORS),
        }),
    };
    let fold_detection: Option<FoldDetection> =
        if crate::plan::detect::granularity(&job.folds).is_some() {
            Some(env.get_json(keys::FOLD_SUMMARY)?)
        } else {
            None
        };
    // Every key this run owns (crate::plan::stale): the next run on this output removes those it does not write.
    let mut manifest = env.block_on(crate::plan::stale::owned_now(&env.out));
    if manifest.is_empty() {
        manifest = written.clone();
        manifest.push(keys::REPORT.into());
    }
    let doc = JobReport {
        complete: true,
        crease_version: env!("CARGO_PKG_VERSION").into(),
        job: job.display_name(),
        input: job.input.clone(),
        input_layout: opened.layout.kind().into(),
        anchors_file,
        fold_detection,
        output: job.output.clone(),
        output_files: written.iter().map(|k| env.out.describe(k)).collect(),
        preview: vec![env.out.describe(keys::PREVIEW), env.out.describe(keys::STRETCH_PLOT)],
        parameters: params.clone(),
        partition: job.partition.clone(),
        summary: Summary {
            frames: n,
            vertices: topo.n_vertices(),
            triangles: topo.n_triangles(),
            anchors: report.anchors,
            stretch_reference:
                "per triangle, max(s1 - 1, 1 - s2) against the captured triangle of the same frame".into(),
            stretch_after_positioning: first,
            stretch_final: last,
            stretch_vs_rest: VsRest {
                reference: rest_stretch::REFERENCE.into(),
                output: vs_rest.stats(),
            },
            shape_kept: shape_kept.stats(),
            scales: Some(SequenceLengths {
                mean_edge,
                detail: scales.detail,
                detail_given: params.relief.scale > 0.0,
                screen: scales.screen,
                shape: scales.ending.shape_scale,
            }),
            lost_area: LostAreaJudgement::of_frames(
                &report.frame_lost_share,
                &report.frame_relief_share,
            ),
            seconds_per_frame: SecondsPerFrame {
                weights: per_frame(t.weights),
                blend: per_frame(t.blend),
                factor: per_frame(t.factor),
                position: per_frame(t.position),
                stretch_passes: t.stretch_passes.iter().map(|s| per_frame(*s)).collect(),
            },
            timings_note: "work seconds summed over tasks (report.timings.wall is 0: the job's wall time is in the coordinator's record)".into(),
            preview_seconds,
        },
        report,
        manifest,
    };
    let text = doc
        .to_text()
        .map_err(|e| TaskError::fatal(format!("finalize: report: {e}")))?;
    env.put(keys::REPORT, text)?;
    written.push(keys::REPORT.into());
    lap.lap("finalize: exports, report");
    Ok((
        json!({ "frames": n, "stretch_final": last, "anchors": doc.report.anchors }),
        written,
    ))
}
