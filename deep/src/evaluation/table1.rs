//! Table 1 of the paper, in spirit, at the size this machine trains: the cGAN's held-out normal-map error when
//! its input is registration-quality (the detail model's normals on a capture) or a subspace reconstruction,
//! each with and without the temporal term of Eq. 4.
//!
//! The subspace input of a training sequence is its projection onto a subspace fitted on the other training
//! sequences (cross-fitted): projected onto a subspace that contains it, a training frame is reproduced almost
//! exactly and the generator would learn to change nothing. The held-out sequence is projected onto the
//! model's own subspace.

use crate::cgan::data::TrainingSet;
use crate::cgan::training::{train_generator, with_and_without};
use crate::cgan::CganConfig;
use crate::model::Model;
use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::world_from_vertex_normals;
use crate::subspace::Subspace;
use crate::train::TrainingSequence;
use crease_core::mesh::{geometry, Frame};
use crease_core::progress::Progress;
use crease_core::vec3::V3;
use crease_core::Result;
use serde::Serialize;

/// Subspace size of the reconstruction rows.
pub const SUBSPACE_K: usize = 200;

#[derive(Debug, Clone, Serialize)]
pub struct Table1Row {
    pub input: String,
    pub temporal: bool,
    /// Held-out map normal error (°) of the input map and of the cGAN's map.
    pub input_deg: f64,
    pub cgan_deg: f64,
    /// Held-out data term (mean |G(x) − y| per covered texel channel) and temporal term of Eq. 4.
    pub data: f64,
    pub temporal_term: f64,
    pub training_s: f64,
}

/// Input normals (one list per frame) of every training sequence and of the held-out one, per input kind.
struct Inputs {
    train: Vec<Vec<(Vec<V3>, Vec<V3>)>>,
    held: Vec<Vec<V3>>,
}

fn capture_inputs(
    model: &Model,
    train: &[TrainingSequence],
    held_capture: &[Frame],
    seed: u64,
) -> Inputs {
    let topo = &model.topology;
    Inputs {
        train: train
            .iter()
            .enumerate()
            .map(|(i, s)| crate::cgan::data::capture_normals(topo, &s.fine, &model.detail, seed, i))
            .collect(),
        held: {
            let gate = model
                .detail
                .surface_gate(topo, held_capture.iter().map(|f| f.as_slice()));
            held_capture
                .iter()
                .map(|c| {
                    let h = crease_core::shape::mean_edge_length(topo, c);
                    model.detail.normals(topo, c, h, gate).0
                })
                .collect()
        },
    }
}

fn subspace_inputs(
    model: &Model,
    train: &[TrainingSequence],
    held: &TrainingSequence,
) -> Result<Inputs> {
    let topo = &model.topology;
    let mut out = Vec::new();
    for (i, s) in train.iter().enumerate() {
        let others: Vec<&[V3]> = train
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .flat_map(|(_, o)| o.fine.iter().map(|f| f.as_slice()))
            .collect();
        let sub = Subspace::fit(&others, SUBSPACE_K)?;
        out.push(
            s.fine
                .iter()
                .map(|f| {
                    let r = sub.reconstruct(&sub.project(f, SUBSPACE_K));
                    (
                        geometry::vertex_normals(topo, &r),
                        geometry::vertex_normals(topo, f),
                    )
                })
                .collect(),
        );
    }
    let sub = &model.subspace;
    let held = held
        .fine
        .iter()
        .map(|f| geometry::vertex_normals(topo, &sub.reconstruct(&sub.project(f, sub.k()))))
        .collect();
    Ok(Inputs { train: out, held })
}

/// Eq. 4's data and temporal terms of the cGAN on the held-out frames (whole maps, covered texels).
fn terms(
    gan: &crate::cgan::Cgan,
    texels: &TexelMap,
    model: &Model,
    inputs: &[Vec<V3>],
    truth: &[Frame],
) -> Result<(f64, f64)> {
    let topo = &model.topology;
    let targets: Vec<_> = truth
        .iter()
        .map(|f| world_from_vertex_normals(texels, topo, &geometry::vertex_normals(topo, f)))
        .collect();
    let (mut data, mut temporal) = (0.0, 0.0);
    for (t, n) in inputs.iter().enumerate() {
        let out = gan.enhance(&world_from_vertex_normals(texels, topo, n))?;
        let (y, prev) = (&targets[t], &targets[t.saturating_sub(1)]);
        let (mut l1, mut diff, mut count) = (0.0, [0.0; 3], 0.0);
        for k in 0..y.n.len() {
            if y.covered[k] {
                for (c, d) in diff.iter_mut().enumerate() {
                    l1 += (out.n[k][c] - y.n[k][c]).abs() as f64;
                    *d += (out.n[k][c] - prev.n[k][c]) as f64;
                }
                count += 3.0;
            }
        }
        data += l1 / count;
        temporal += (diff.iter().sum::<f64>() / count).abs();
    }
    let n = inputs.len().max(1) as f64;
    Ok((data / n, temporal / n))
}

/// The four rows: {capture, subspace} × {with, without the temporal term}, each a generator of `cfg` trained
/// on `train` and scored on every `step`-th frame of `held` (`held_capture`: the held-out sequence's capture).
#[allow(clippy::too_many_arguments)]
pub fn table1(
    model: &Model,
    train: &[TrainingSequence],
    held: &TrainingSequence,
    held_capture: &[Frame],
    cfg: &CganConfig,
    step: usize,
    progress: &dyn Progress,
) -> Result<Vec<Table1Row>> {
    let topo = &model.topology;
    let res = model.manifest.resolution;
    cfg.check_resolution(res)?;
    let texels = TexelMap::new(&model.layout, res, res);
    let frames: Vec<usize> = (0..held.fine.len()).step_by(step.max(1)).collect();
    let kinds = [
        (
            "capture (detail model)",
            capture_inputs(model, train, held_capture, cfg.seed),
        ),
        (
            "subspace reconstruction (k = 200)",
            subspace_inputs(model, train, held)?,
        ),
    ];
    let mut rows = Vec::new();
    for (name, inputs) in &kinds {
        for temporal in [true, false] {
            let c = CganConfig {
                w_temporal: if temporal { cfg.w_temporal } else { 0.0 },
                ..cfg.clone()
            };
            progress.note(&format!("table 1: {name}, temporal term {temporal}"));
            let set = TrainingSet::new(topo, &texels, inputs.train.clone(), c.crop);
            let (gan, _, training_s) = train_generator(&set, &c, None, progress)?;
            let held_inputs: Vec<Vec<V3>> =
                frames.iter().map(|&t| inputs.held[t].clone()).collect();
            let truth: Vec<&Frame> = frames.iter().map(|&t| &held.fine[t]).collect();
            let [input_deg, cgan_deg] =
                with_and_without(&gan, topo, &model.layout, &texels, &held_inputs, &truth)?;
            // The temporal term needs consecutive frames: all of them.
            let (data, temporal_term) = terms(&gan, &texels, model, &inputs.held, &held.fine)?;
            rows.push(Table1Row {
                input: name.to_string(),
                temporal,
                input_deg,
                cgan_deg,
                data,
                temporal_term,
                training_s,
            });
        }
    }
    Ok(rows)
}
