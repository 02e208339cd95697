//! Held-out evaluation over training directories: leave one sequence out (each directory in turn is scored by
//! a model trained on the others), or split (each directory's first half trains, its second half is scored);
//! extra cases scored by the model trained on every directory; and the training-motions curve (the pose
//! path's error against the number of sequences trained on).

use super::{frames_to_score, score_capture, score_shapes, Score};
use crate::apply::CoarseDetail;
use crate::model::Model;
use crate::train::{fit, layout_for, load_training_dir, train, TrainParams, TrainingSequence};
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::{Frame, Sequence};
use crease_core::progress::Progress;
use crease_core::{Error, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A case scored by the model trained on every directory (captures only: it may have no pose file).
#[derive(Debug, Clone)]
pub struct ExtraCase {
    pub name: String,
    pub dir: PathBuf,
    pub captures: Vec<String>,
}

#[derive(Debug, Clone)]
pub struct EvalParams {
    pub train: TrainParams,
    /// Score every `step`-th frame.
    pub step: usize,
    /// Capture folders of each directory to score the coarse path on (e.g. `captured`); missing ones are
    /// skipped.
    pub captures: Vec<String>,
    /// Numbers of training sequences of the training-motions curve (empty: no curve).
    pub motions: Vec<usize>,
    pub extra: Vec<ExtraCase>,
    /// Train on each directory's first half and score its second half, instead of leaving one out.
    pub split: bool,
    /// Names of the directories to hold out (empty: every one).
    pub held_out: Vec<String>,
    /// Where the trained models are written (one folder per held-out directory).
    pub work: PathBuf,
    /// Table 1 in spirit ([`super::table1`]) on the last directory held out, with this cGAN.
    pub table1: Option<crate::cgan::CganConfig>,
    /// Frame (1-based) of the Fig. 11 strip written for every held-out directory, into `strips`.
    pub strip: Option<usize>,
    pub strips: PathBuf,
}

#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub held_out: String,
    pub trained_on: Vec<String>,
    pub train_s: f64,
    pub pose: Option<Score>,
    pub captures: Vec<(String, Score)>,
    /// Held-out figures the detail model measured on its own validation sequence while training.
    pub detail_validation: [f64; 2],
}

#[derive(Debug, Clone, Serialize)]
pub struct CurvePoint {
    pub held_out: String,
    pub motions: usize,
    pub score: Score,
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct Report {
    pub rows: Vec<Row>,
    pub extra: Vec<Row>,
    pub curve: Vec<CurvePoint>,
    /// (held-out directory, rows).
    pub table1: Option<(String, Vec<super::table1::Table1Row>)>,
}

fn name_of(dir: &Path) -> String {
    dir.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| dir.display().to_string())
}

/// The frames of `dir/name` when that folder exists, checked against the ground truth's topology and count.
fn load_capture(dir: &Path, name: &str, gt: &TrainingSequence) -> Result<Option<Vec<Frame>>> {
    let path = dir.join(name);
    if !path.exists() {
        return Ok(None);
    }
    let seq = Sequence::load(open_sequence(&path)?.source.as_ref())?;
    if seq.topology.triangles() != gt.topology.triangles() || seq.frames.len() != gt.fine.len() {
        return Err(Error::mesh(format!(
            "{}: {} frames of {} vertices do not match gt's {} of {}",
            path.display(),
            seq.frames.len(),
            seq.topology.n_vertices(),
            gt.fine.len(),
            gt.topology.n_vertices()
        )));
    }
    Ok(Some(seq.frames))
}

fn first_half(s: &TrainingSequence) -> TrainingSequence {
    let n = s.fine.len() / 2;
    TrainingSequence {
        dir: s.dir.clone(),
        topology: s.topology.clone(),
        fine: s.fine[..n].to_vec(),
        poses: s.poses[..n].to_vec(),
        pose_names: s.pose_names.clone(),
    }
}

/// A held-out sequence's pose-path score (when it has poses) and its coarse-path score per capture folder.
type SequenceScores = (Option<Score>, Vec<(String, Score)>);

/// Scores `model` on `seq` (frames `frames`): its pose path when the directory has a pose file, and its
/// coarse path on each capture folder present.
fn score_sequence(
    model: &Model,
    seq: &TrainingSequence,
    captures: &[String],
    frames: &[usize],
    with_pose: bool,
) -> Result<SequenceScores> {
    let pose_path = seq.dir.join("pose.json");
    let pose = if with_pose && pose_path.exists() {
        let shapes = crate::apply::pose_shapes(model, &pose_path, model.manifest.regressor, None)?;
        Some(score_shapes(
            &model.topology,
            &model.layout,
            model.manifest.resolution,
            &shapes,
            &seq.fine,
            frames,
        ))
    } else {
        None
    };
    let mut out = Vec::new();
    for name in captures {
        if let Some(c) = load_capture(&seq.dir, name, seq)? {
            let path = seq.dir.join(name);
            // Both paths `apply --coarse` can take (the model's default is one of them).
            for (label, detail) in [
                (format!("{name}, learned filter"), CoarseDetail::Model),
                (format!("{name}, relief"), CoarseDetail::Relief),
                (format!("{name}, blend"), CoarseDetail::Blend),
            ] {
                out.push((
                    label,
                    score_capture(model, &c, &path, &seq.fine, frames, detail)?,
                ));
            }
        }
    }
    Ok((pose, out))
}

fn train_and_load(
    seqs: &[TrainingSequence],
    params: &TrainParams,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<(Model, f64)> {
    let t0 = Instant::now();
    train(seqs, params, dir, progress)?;
    let secs = t0.elapsed().as_secs_f64();
    Ok((Model::load(dir)?, secs))
}

/// Runs the evaluation over `dirs`.
pub fn evaluate(dirs: &[PathBuf], p: &EvalParams, progress: &dyn Progress) -> Result<Report> {
    let seqs: Vec<TrainingSequence> = dirs
        .iter()
        .map(|d| load_training_dir(d))
        .collect::<Result<_>>()?;
    if !p.split && seqs.len() < 2 {
        return Err(Error::param(
            "data",
            "leaving one sequence out needs at least two directories (or --split)",
        ));
    }
    let mut report = Report::default();
    let last_held = (0..seqs.len())
        .rev()
        .find(|&i| p.held_out.is_empty() || p.held_out.contains(&name_of(&seqs[i].dir)));
    if let Some(n) = p
        .held_out
        .iter()
        .find(|n| !seqs.iter().any(|s| &name_of(&s.dir) == *n))
    {
        return Err(Error::param(
            "held_out",
            format!("{n} is not the name of a --data directory"),
        ));
    }
    for (i, held) in seqs.iter().enumerate() {
        let name = name_of(&held.dir);
        if !p.held_out.is_empty() && !p.held_out.contains(&name) {
            continue;
        }
        let (train_seqs, frames): (Vec<TrainingSequence>, Vec<usize>) = if p.split {
            let n = held.fine.len();
            (vec![first_half(held)], frames_to_score(n / 2..n, p.step))
        } else {
            (
                seqs.iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, s)| s.clone())
                    .collect(),
                frames_to_score(0..held.fine.len(), p.step),
            )
        };
        progress.note(&format!(
            "{name}: training on {} sequence(s)",
            train_seqs.len()
        ));
        let (model, train_s) = train_and_load(
            &train_seqs,
            &p.train,
            &p.work.join(format!("held_out_{name}")),
            progress,
        )?;
        let (pose, captures) = score_sequence(&model, held, &p.captures, &frames, true)?;
        let first_capture = p
            .captures
            .iter()
            .find_map(|c| load_capture(&held.dir, c, held).transpose().map(|f| (c, f)));
        if let (Some(frame), Some((cname, frames))) = (p.strip, &first_capture) {
            let frames = frames
                .as_ref()
                .map_err(|e| Error::param("captures", e.to_string()))?;
            let t = frame.clamp(1, frames.len()) - 1;
            crease_core::fsutil::create_dir_all(&p.strips)?;
            super::strip::write_strip(
                &model,
                frames,
                &held.dir.join(cname),
                &held.fine[t],
                t,
                &p.strips.join(format!("fig11_{name}_frame{}.png", t + 1)),
            )?;
        }
        if let (Some(cfg), true) = (&p.table1, Some(i) == last_held && !p.split) {
            let capture = match first_capture {
                Some((_, f)) => f?,
                None => {
                    return Err(Error::param(
                        "captures",
                        format!("Table 1 needs a capture of {name} (--captures)"),
                    ))
                }
            };
            let rows =
                super::table1::table1(&model, &train_seqs, held, &capture, cfg, p.step, progress)?;
            report.table1 = Some((name.clone(), rows));
        }
        report.rows.push(Row {
            held_out: name,
            trained_on: train_seqs.iter().map(|s| name_of(&s.dir)).collect(),
            train_s,
            pose,
            captures,
            detail_validation: [
                model.detail.spec.held_out_capture_deg,
                model.detail.spec.held_out_model_deg,
            ],
        });
    }
    if !p.extra.is_empty() && !p.split {
        let (model, train_s) = train_and_load(&seqs, &p.train, &p.work.join("all"), progress)?;
        for case in &p.extra {
            let gt = Sequence::load(open_sequence(&case.dir.join("gt"))?.source.as_ref())?;
            let seq = TrainingSequence {
                dir: case.dir.clone(),
                topology: gt.topology,
                poses: Vec::new(),
                fine: gt.frames,
                pose_names: None,
            };
            let frames = frames_to_score(0..seq.fine.len(), p.step);
            let (_, captures) = score_sequence(&model, &seq, &case.captures, &frames, false)?;
            report.extra.push(Row {
                held_out: case.name.clone(),
                trained_on: seqs.iter().map(|s| name_of(&s.dir)).collect(),
                train_s,
                pose: None,
                captures,
                detail_validation: [
                    model.detail.spec.held_out_capture_deg,
                    model.detail.spec.held_out_model_deg,
                ],
            });
        }
    }
    for &m in &p.motions {
        for (i, held) in seqs.iter().enumerate() {
            if m == 0 || m >= seqs.len() {
                continue;
            }
            if !p.held_out.is_empty() && !p.held_out.contains(&name_of(&held.dir)) {
                continue;
            }
            // The next m sequences after the held-out one, cyclically: every sequence is used equally often.
            let others: Vec<TrainingSequence> = (1..=m)
                .map(|k| seqs[(i + k) % seqs.len()].clone())
                .collect();
            let fitted = fit(&others, &p.train, progress)?;
            let topo = &held.topology;
            let mean = crate::subspace::unflatten(&fitted.subspace.mean);
            let layout = layout_for(p.train.uv.as_deref(), topo, &mean)?;
            let coeffs = fitted.coefficients(p.train.regressor, &held.poses)?;
            let shapes: Vec<Frame> = coeffs
                .iter()
                .map(|c| p.train.pose_lowpass.shape(topo, &fitted.subspace, c))
                .collect();
            let frames = frames_to_score(0..held.fine.len(), p.step);
            let score = score_shapes(
                topo,
                &layout,
                p.train.resolution,
                &shapes,
                &held.fine,
                &frames,
            );
            progress.note(&format!(
                "curve: {} from {m} motion(s): {:.2}° / {:.2} mm",
                name_of(&held.dir),
                score.map_deg,
                score.shape_mm
            ));
            report.curve.push(CurvePoint {
                held_out: name_of(&held.dir),
                motions: m,
                score,
            });
        }
    }
    Ok(report)
}

/// The report as markdown tables.
pub fn markdown(r: &Report) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let mut kinds: Vec<String> = Vec::new();
    for row in r.rows.iter().chain(&r.extra) {
        for (k, _) in &row.captures {
            if !kinds.contains(k) {
                kinds.push(k.clone());
            }
        }
    }
    if !r.rows.is_empty() {
        let _ = writeln!(
            s,
            "| held out | train (s) | pose: map (°) | pose: shape (mm) |{} detail validation (°, capture → model) |",
            kinds
                .iter()
                .map(|k| format!(" {k}: map (°) | {k}: own, mesh / map (°) | {k}: fallbacks |"))
                .collect::<String>()
        );
        let _ = writeln!(
            s,
            "|---|---|---|---|{}---|",
            "---|---|---|".repeat(kinds.len())
        );
    }
    let cell = |row: &Row, k: &str| -> String {
        match row.captures.iter().find(|(n, _)| n == k) {
            Some((_, c)) => format!(
                " {:.2} | {:.2} / {:.2} | {}/{} |",
                c.map_deg, c.input_deg, c.input_map_deg, c.fallback_frames, c.frames
            ),
            None => " | | |".into(),
        }
    };
    for row in r.rows.iter().chain(&r.extra) {
        let (pm, ps) = row
            .pose
            .as_ref()
            .map_or((String::new(), String::new()), |p| {
                (format!("{:.2}", p.map_deg), format!("{:.2}", p.shape_mm))
            });
        let _ = writeln!(
            s,
            "| {} | {:.0} | {pm} | {ps} |{} {:.2} → {:.2} |",
            row.held_out,
            row.train_s,
            kinds.iter().map(|k| cell(row, k)).collect::<String>(),
            row.detail_validation[0],
            row.detail_validation[1]
        );
    }
    if !r.rows.is_empty() {
        let n = r.rows.len() as f64;
        let mean = |f: &dyn Fn(&Row) -> Option<f64>| -> String {
            let v: Vec<f64> = r.rows.iter().filter_map(f).collect();
            if v.len() as f64 == n {
                format!("{:.2}", v.iter().sum::<f64>() / n)
            } else {
                String::new()
            }
        };
        let _ = writeln!(
            s,
            "| mean | | {} | {} |{} |",
            mean(&|r| r.pose.as_ref().map(|p| p.map_deg)),
            mean(&|r| r.pose.as_ref().map(|p| p.shape_mm)),
            kinds
                .iter()
                .map(|k| {
                    let f = |r: &Row| r.captures.iter().find(|(n, _)| n == k).map(|c| c.1.map_deg);
                    let g = |r: &Row| {
                        r.captures
                            .iter()
                            .find(|(n, _)| n == k)
                            .map(|c| c.1.input_deg)
                    };
                    let gm = |r: &Row| {
                        r.captures
                            .iter()
                            .find(|(n, _)| n == k)
                            .map(|c| c.1.input_map_deg)
                    };
                    let (g, gm) = (mean(&g), mean(&gm));
                    let own = if g.is_empty() {
                        String::new()
                    } else {
                        format!("{g} / {gm}")
                    };
                    format!(" {} | {own} | |", mean(&f))
                })
                .collect::<String>()
        );
    }
    if let Some((held, rows)) = &r.table1 {
        let _ = writeln!(
            s,
            "\nTable 1 in spirit ({held} held out)\n\n| input | temporal term | input map (°) | cGAN map (°) | data (L1) | temporal | training (s) |\n|---|---|---|---|---|---|---|"
        );
        for row in rows {
            let _ = writeln!(
                s,
                "| {} | {} | {:.2} | {:.2} | {:.4} | {:.4} | {:.0} |",
                row.input,
                if row.temporal { "yes" } else { "no" },
                row.input_deg,
                row.cgan_deg,
                row.data,
                row.temporal_term,
                row.training_s
            );
        }
    }
    if !r.curve.is_empty() {
        let mut ms: Vec<usize> = r.curve.iter().map(|c| c.motions).collect();
        ms.sort_unstable();
        ms.dedup();
        let _ = writeln!(
            s,
            "\n| training motions | pose: map (°), mean | pose: shape (mm), mean | held-out sequences |\n|---|---|---|---|"
        );
        for m in ms {
            let pts: Vec<&CurvePoint> = r.curve.iter().filter(|c| c.motions == m).collect();
            let n = pts.len() as f64;
            let _ = writeln!(
                s,
                "| {m} | {:.2} | {:.2} | {} |",
                pts.iter().map(|c| c.score.map_deg).sum::<f64>() / n,
                pts.iter().map(|c| c.score.shape_mm).sum::<f64>() / n,
                pts.len()
            );
        }
    }
    s
}
