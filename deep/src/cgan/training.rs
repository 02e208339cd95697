//! Training the cGAN for a model, and deciding where `apply` uses it.
//!
//! The generator trains on every training sequence but the last, whose frames decide: `apply --coarse` uses it
//! when the maps of random captures of that sequence, enhanced, are closer to its normals than the detail
//! model's maps alone; `apply --pose` when the pose path's maps of that sequence (the regression fitted
//! without it) are. With one training sequence its last quarter of frames is held out instead.

use super::data::{capture_normals, TrainingSet};
use super::{Cgan, CganConfig, CganSpec, StepLosses};
use crate::detail::{training_capture, DetailModel};
use crate::normal_maps::bake::map_normal_error;
use crate::normal_maps::raster::TexelMap;
use crate::normal_maps::uv::UvLayout;
use crate::normal_maps::{sample_vertex_normals, world_from_vertex_normals, NormalMap};
use crease_core::mesh::{geometry, Frame, Topology};
use crease_core::progress::Progress;
use crease_core::shape::mean_edge_length;
use crease_core::vec3::V3;
use crease_core::Result;
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

/// Offset of the validation captures' draws (neither the detail model's nor the generator's training ones).
const VALIDATION_DRAW: usize = 2000;
/// Every how many held-out frames one is scored.
const VALIDATION_STEP: usize = 4;

/// Trains a generator on `set` with per-report checkpoints in `checkpoint` (resumed when one is there).
pub fn train_generator(
    set: &TrainingSet,
    cfg: &CganConfig,
    checkpoint: Option<&Path>,
    progress: &dyn Progress,
) -> Result<(Cgan, Vec<StepLosses>, f64)> {
    let mut gan = match checkpoint {
        Some(dir) if dir.join("state.json").exists() => {
            let g = Cgan::resume(cfg.clone(), dir)?;
            progress.note(&format!(
                "cgan: resuming from {} after step {}",
                dir.display(),
                g.step
            ));
            g
        }
        _ => Cgan::new(cfg.clone())?,
    };
    let report = (cfg.steps / 10).max(1);
    progress.begin("cgan", cfg.steps.saturating_sub(gan.step) as u64);
    let t0 = Instant::now();
    let history = gan.train(set, report, |g, step, l| {
        progress.advance("cgan", report as u64);
        progress.note(&format!(
            "cgan step {step}: L1 {:.4} temporal {:.4} GAN {:.3} D {:.3}",
            l.l1, l.temporal, l.gan, l.disc
        ));
        if let Some(dir) = checkpoint {
            g.save_checkpoint(dir)?;
        }
        Ok(())
    })?;
    progress.end("cgan");
    Ok((gan, history, t0.elapsed().as_secs_f64()))
}

/// Mean map normal error (°) of `maps` against the frames' own normals, sampled at the vertices.
pub fn map_error(topo: &Topology, layout: &UvLayout, maps: &[NormalMap], truth: &[&Frame]) -> f64 {
    let e: f64 = maps
        .par_iter()
        .zip(truth.par_iter())
        .map(|(m, t)| map_normal_error(&sample_vertex_normals(m, topo, layout), topo, t).0)
        .sum();
    e / maps.len().max(1) as f64
}

/// Error of maps of `normals` without and with the generator (°).
pub fn with_and_without(
    gan: &Cgan,
    topo: &Topology,
    layout: &UvLayout,
    texels: &TexelMap,
    normals: &[Vec<V3>],
    truth: &[&Frame],
) -> Result<[f64; 2]> {
    let maps: Vec<NormalMap> = normals
        .par_iter()
        .map(|n| world_from_vertex_normals(texels, topo, n))
        .collect();
    let enhanced: Vec<NormalMap> = maps.iter().map(|m| gan.enhance(m)).collect::<Result<_>>()?;
    Ok([
        map_error(topo, layout, &maps, truth),
        map_error(topo, layout, &enhanced, truth),
    ])
}

/// What [`train_cgan`] needs of the model being trained.
pub struct CganInputs<'a> {
    pub topo: &'a Topology,
    pub layout: &'a UvLayout,
    pub resolution: usize,
    /// Detailed frames per training sequence.
    pub fine: Vec<&'a [Frame]>,
    pub detail: &'a DetailModel,
    /// The pose path's shapes of the held-out frames from a regression fitted without them, when known.
    pub pose_shapes: Option<Vec<Frame>>,
}

/// The frames the generator trains on and the held-out ones, per [`CganInputs::fine`] (see the module docs).
pub fn split(fine: &[&[Frame]]) -> (Vec<Vec<Frame>>, Vec<Frame>) {
    if fine.len() >= 2 {
        (
            fine[..fine.len() - 1].iter().map(|s| s.to_vec()).collect(),
            fine[fine.len() - 1].to_vec(),
        )
    } else {
        let s = fine.first().copied().unwrap_or(&[]);
        let cut = s.len() - s.len() / 4;
        (vec![s[..cut].to_vec()], s[cut..].to_vec())
    }
}

/// Trains the generator on random captures of the training frames (input: the detail model's normals) and
/// decides where `apply` uses it; writes its weights to `weights_out`.
pub fn train_cgan(
    inputs: &CganInputs,
    cfg: &CganConfig,
    checkpoint: Option<&Path>,
    weights_out: &Path,
    progress: &dyn Progress,
) -> Result<(CganSpec, serde_json::Value)> {
    cfg.check_resolution(inputs.resolution)?;
    let topo = inputs.topo;
    let texels = TexelMap::new(inputs.layout, inputs.resolution, inputs.resolution);
    let t0 = Instant::now();
    let (train, held) = split(&inputs.fine);
    let sequences: Vec<Vec<(Vec<V3>, Vec<V3>)>> = train
        .iter()
        .enumerate()
        .map(|(i, f)| capture_normals(topo, f, inputs.detail, cfg.seed, i))
        .collect();
    let set = TrainingSet::new(topo, &texels, sequences, cfg.crop);
    let prep_s = t0.elapsed().as_secs_f64();
    let (gan, history, train_s) = train_generator(&set, cfg, checkpoint, progress)?;
    gan.save_generator(weights_out)?;
    // Validation on the held-out frames.
    let frames: Vec<usize> = (0..held.len()).step_by(VALIDATION_STEP).collect();
    let truth: Vec<&Frame> = frames.iter().map(|&t| &held[t]).collect();
    let coarse_normals: Vec<Vec<V3>> = frames
        .par_iter()
        .map(|&t| {
            let f = &held[t];
            let h = mean_edge_length(topo, f);
            let (c, _) = training_capture(topo, f, h, cfg.seed, usize::MAX, t, VALIDATION_DRAW);
            inputs
                .detail
                .normals(
                    topo,
                    &c,
                    h,
                    inputs.detail.surface_gate(topo, [c.as_slice()]),
                )
                .0
        })
        .collect();
    let coarse_deg = with_and_without(&gan, topo, inputs.layout, &texels, &coarse_normals, &truth)?;
    let pose_deg = match &inputs.pose_shapes {
        Some(shapes) => {
            let normals: Vec<Vec<V3>> = frames
                .iter()
                .map(|&t| geometry::vertex_normals(topo, &shapes[t]))
                .collect();
            with_and_without(&gan, topo, inputs.layout, &texels, &normals, &truth)?
        }
        None => [f64::NAN, f64::NAN],
    };
    let spec = CganSpec {
        config: cfg.clone(),
        coarse_deg,
        pose_deg,
        use_coarse: coarse_deg[1] < coarse_deg[0],
        use_pose: pose_deg[1] < pose_deg[0],
    };
    progress.note(&format!(
        "cgan: held-out maps {:.2}° → {:.2}° from captures ({}), {:.2}° → {:.2}° from poses ({})",
        coarse_deg[0],
        coarse_deg[1],
        if spec.use_coarse { "used" } else { "not used" },
        pose_deg[0],
        pose_deg[1],
        if spec.use_pose { "used" } else { "not used" },
    ));
    let summary = serde_json::json!({
        "samples": set.samples.len(),
        "held_out_frames": held.len(),
        "preparation_s": prep_s,
        "training_s": train_s,
        "s_per_step": train_s / cfg.steps.max(1) as f64,
        "losses": history,
    });
    Ok((spec, summary))
}
