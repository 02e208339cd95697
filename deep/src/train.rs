//! `crease deep train`: from training sequences (registered fine meshes and poses) to a model.
//!
//! Each training directory holds `gt/` (the registered fine shapes: the subspace, the detail model and the
//! cGAN learn from them) and `pose.json`. A `captured/` beside them is not read: the detail model and the
//! cGAN learn from captures of `gt/` they make themselves ([`crate::detail::captures`]), so that no one
//! capture's way of losing detail is learned. The meshes already share the template's topology; raw scans
//! go through `crease deep register` first.

use crate::detail::{DetailData, DetailFit, DetailParams};
use crate::model::{
    write_autoregressive, write_core_parts, write_detail, write_kernel, ArSpec, Manifest,
    ModelWriter, RegressorKind, MODEL_FORMAT, MODEL_VERSION,
};
use crate::normal_maps::uv::{auto_atlas, read_obj_uv, UvLayout};
use crate::regression::autoregress::{AutoregressiveLinear, ControlsAndCoefficients, ShapeHistory};
use crate::regression::blend::{BlendSpec, WeightFit};
use crate::regression::kernel::{self, KernelData, KernelRegression};
use crate::regression::linear::LinearRegression;
use crate::regression::lstm::{windows, LstmConfig, LstmRegressor};
use crate::regression::pose::{read_pose_file, read_pose_names, ControlSpec};
use crate::regression::pose_features::{PoseFeatureMode, PoseFeatures};
use crate::regression::pose_lowpass::PoseLowpass;
use crate::subspace::mirror::{reflect_pose, MirrorMode, Reflection};
use crate::subspace::Subspace;
use crease_core::mesh::io::open_sequence;
use crease_core::mesh::{Frame, Sequence, Topology};
use crease_core::progress::Progress;
use crease_core::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

#[derive(Debug, Clone)]
pub struct TrainingSequence {
    pub dir: PathBuf,
    pub topology: Arc<Topology>,
    pub fine: Vec<Frame>,
    pub poses: Vec<Vec<f64>>,
    /// `pose_vector_names` of the pose file, when it has them ([`crate::regression::pose_features`]).
    pub pose_names: Option<Vec<String>>,
}

/// Loads `dir/gt` and `dir/pose.json`, checking they agree on the frame count.
pub fn load_training_dir(dir: &Path) -> Result<TrainingSequence> {
    let gt = Sequence::load(open_sequence(&dir.join("gt"))?.source.as_ref())?;
    let poses = read_pose_file(&dir.join("pose.json"), Some(gt.frames.len()))?;
    let pose_names = read_pose_names(&dir.join("pose.json"))?;
    Ok(TrainingSequence {
        dir: dir.to_path_buf(),
        topology: gt.topology,
        fine: gt.frames,
        poses,
        pose_names,
    })
}

#[derive(Debug, Clone)]
pub struct TrainParams {
    /// Subspace size (capped by the number of training frames).
    pub k: usize,
    pub lags: Vec<usize>,
    /// Time constants (frames) of the decayed pose history features ([`crate::regression::pose_history`]); none: no
    /// history features.
    pub pose_history: Vec<f64>,
    /// Ridge weight of the linear regression, relative to the mean diagonal of ΘᵀΘ.
    pub ridge: f64,
    /// What the pose numbers become before the regression ([`crate::regression::pose_features`]).
    pub pose_features: PoseFeatureMode,
    /// Reflection that augments the subspace and regression data ([`crate::subspace::mirror`]).
    pub mirror: MirrorMode,
    /// Regressor used by `apply --pose`. The linear and autoregressive ones are always trained (seconds);
    /// `Lstm` adds the network.
    pub regressor: RegressorKind,
    /// Earlier frames whose poses the kernel regression compares besides the frame itself
    /// ([`crate::regression::kernel`]; 0 is the frame).
    pub kernel_window: Vec<usize>,
    /// Every input number of the kernel weighed alike, instead of the searched weights
    /// ([`crate::regression::kernel::InputWeights`]).
    pub kernel_uniform: bool,
    /// Leading shape coefficients the autoregressive regressor feeds back (capped at the subspace size).
    pub ar_state: usize,
    /// Steps of the autoregressive regressor's fit on its own rollout ([`crate::regression::rollout_fit`]) after the
    /// ridge fit; 0 keeps the ridge fit.
    pub ar_rollout_iters: usize,
    /// Weight of the autoregressive rollout in the blend regressor (the linear map gets 1 − weight), unless
    /// `blend_fit`.
    pub blend_weight: f64,
    /// Fit the blend weight by an inner leave-one-out over the training sequences ([`inner_blend_weight`])
    /// instead of taking `blend_weight`.
    pub blend_fit: bool,
    pub lstm: LstmConfig,
    /// How the shape `apply --pose` draws is made smooth ([`crate::regression::pose_lowpass`]).
    pub pose_lowpass: PoseLowpass,
    /// The detail model `apply --coarse` runs ([`crate::detail`]).
    pub detail: DetailParams,
    pub resolution: usize,
    /// A template OBJ whose `vt` must give the layout; without it one is computed from the first mean shape.
    pub uv: Option<PathBuf>,
    /// The cGAN ([`crate::cgan`]), trained on random captures of the training frames and used where it beats
    /// the maps without it on the held-out training sequence; `None`: no cGAN. `crease deep train` and job
    /// specs train one ([`crate::cgan::CganConfig::default`]) unless told `--cgan-steps 0`; the library's
    /// default here is none, so that a caller pays for the network only when it asks.
    pub cgan: Option<crate::cgan::CganConfig>,
    /// Where cGAN checkpoints go as it trains; an existing checkpoint there is resumed.
    pub checkpoint: Option<PathBuf>,
}

impl Default for TrainParams {
    fn default() -> Self {
        TrainParams {
            k: 200,
            // Defaults chosen by the mean vertex error over the three leave-one-sequence-out splits of
            // sleeve-train (bench/results/2026-12-05-deep-regression.md): no pose lags (the pose-only map: 7.57 mm without, 8.33 mm
            // with lags 1..32), and the autoregressive regressor feeding back 10 coefficients, fitted for 20
            // steps on its own rollout (7.20 mm).
            lags: vec![],
            pose_history: vec![],
            ridge: 1e-3,
            // Rigid pose features and the mirror: over the three splits the default blend went from 6.85 mm
            // (raw pose, no mirror) to 5.27 mm with the features and 4.45 mm with both; on data without
            // rigid pose names or without a symmetric first frame both fall back to what they were.
            pose_features: PoseFeatureMode::Auto,
            mirror: MirrorMode::Auto,
            // The kernel regression over the poses of frames t, t − 2, t − 4, t − 6: leaving each of
            // sleeve-train's seven sequences out in turn (trained on the other six, mirrored), 3.55 mm of
            // vertex error against the even blend's 4.31 mm, lower on every split
            // (bench/results/2026-12-07-deep-kernel-regression.md). The blend stays available: its even
            // weight measured 6.85 mm over two-sequence splits against the rollout's 7.20 mm.
            regressor: RegressorKind::Kernel,
            kernel_window: vec![0, 2, 4, 6],
            kernel_uniform: false,
            ar_state: 10,
            ar_rollout_iters: 20,
            blend_weight: 0.5,
            blend_fit: false,
            lstm: LstmConfig::default(),
            // A light low-pass (half of a 6-edge wave kept) of the drawn shape: with the kernel regressor it
            // lowered the held-out map error on all seven splits (17.46° → 17.05° mean) for 0.02 mm of shape;
            // 12 and 24 edges lost shape and normals on seed_7.
            pose_lowpass: PoseLowpass {
                components: 0,
                half_wavelength: 6.0,
            },
            detail: DetailParams::default(),
            resolution: crate::normal_maps::DEFAULT_RESOLUTION,
            uv: None,
            cgan: None,
            checkpoint: None,
        }
    }
}

impl TrainParams {
    pub fn validate(&self) -> Result<()> {
        if self.k == 0 {
            return Err(Error::param("k", "must be at least 1"));
        }
        if self.kernel_window.is_empty() || self.kernel_window.iter().any(|&l| l > 240) {
            return Err(Error::param(
                "kernel_window",
                format!(
                    "{:?}: give one to eight frame lags of 0 to 240",
                    self.kernel_window
                ),
            ));
        }
        if self.kernel_window.len() > 8 {
            return Err(Error::param(
                "kernel_window",
                format!("{} lags; at most 8", self.kernel_window.len()),
            ));
        }
        if self.ar_state == 0 {
            return Err(Error::param("ar_state", "must be at least 1"));
        }
        if !(self.ridge.is_finite() && self.ridge >= 0.0) {
            return Err(Error::param("ridge", "must be a non-negative number"));
        }
        crate::regression::blend::check_weight(self.blend_weight)?;
        self.pose_lowpass
            .check()
            .map_err(|e| Error::param("pose_lowpass", e))?;
        if !(1..=64).contains(&self.detail.degree)
            || !(1..=16).contains(&self.detail.captures_per_frame)
        {
            return Err(Error::param(
                "detail",
                format!(
                    "degree {} (1..=64) or captures per frame {} (1..=16) out of range",
                    self.detail.degree, self.detail.captures_per_frame
                ),
            ));
        }
        if let Some(c) = &self.cgan {
            c.validate()?;
            c.check_resolution(self.resolution)?;
        }
        if !(16..=4096).contains(&self.resolution) {
            return Err(Error::param(
                "resolution",
                format!("{} is outside 16..=4096", self.resolution),
            ));
        }
        self.lstm.validate()
    }
}

/// The layout: from `--uv` (required to have `vt`), else computed on `shape`.
pub fn layout_for(uv: Option<&Path>, topo: &Topology, shape: &[[f64; 3]]) -> Result<UvLayout> {
    match uv {
        Some(path) => read_obj_uv(path, topo)?.ok_or_else(|| {
            Error::format(
                path,
                None,
                "has no texture coordinates (`vt` lines and `f v/vt` faces), which --uv requires",
            )
        }),
        None => auto_atlas(topo, shape, 0.01),
    }
}

/// Checks that all sequences share one topology.
pub fn common_topology(seqs: &[TrainingSequence]) -> Result<Arc<Topology>> {
    let first = seqs
        .first()
        .ok_or_else(|| Error::param("data", "no training directories"))?;
    for s in &seqs[1..] {
        if s.topology.n_vertices() != first.topology.n_vertices()
            || s.topology.triangles() != first.topology.triangles()
        {
            return Err(Error::mesh(format!(
                "{} does not have the topology of {} ({} vs {} vertices)",
                s.dir.display(),
                first.dir.display(),
                s.topology.n_vertices(),
                first.topology.n_vertices()
            )));
        }
    }
    Ok(first.topology.clone())
}

/// Subspace + regressors fitted to `seqs`, without writing anything (also used by the experiments).
pub struct Fitted {
    pub subspace: Subspace,
    pub control: ControlSpec,
    pub linear: LinearRegression,
    pub autoregressive: AutoregressiveLinear,
    /// The blend regressor's weight (its parts are `linear` and `autoregressive`).
    pub blend: BlendSpec,
    pub lstm: Option<LstmRegressor>,
    pub kernel: KernelRegression,
    pub coeff_scale: Vec<f64>,
    /// The autoregressive regressor's training rollout loss (coefficient MSE) before and after each step of
    /// its rollout fit.
    pub ar_rollout_losses: Vec<f64>,
    pub lstm_losses: Vec<f64>,
    /// With early stopping: the LSTM's held-out coefficient MSE (m²) before training and after each epoch,
    /// and the epoch whose weights were kept (0: none beat the base regressor).
    pub lstm_held_out: Vec<f64>,
    pub lstm_best_epoch: Option<usize>,
    pub seconds: BTreeSummary,
    /// The reflection that augmented the training data, if any.
    pub mirror: Option<Reflection>,
}

#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct BTreeSummary {
    pub subspace_s: f64,
    pub linear_s: f64,
    pub autoregressive_s: f64,
    pub lstm_s: f64,
    pub lstm_s_per_epoch: f64,
    pub kernel_s: f64,
}

pub fn fit(
    seqs: &[TrainingSequence],
    params: &TrainParams,
    progress: &dyn Progress,
) -> Result<Fitted> {
    params.validate()?;
    let topo = common_topology(seqs)?;
    let first = seqs
        .first()
        .ok_or_else(|| Error::param("data", "no training directories"))?;
    let pose_source = first.dir.join("pose.json").display().to_string();
    let features = PoseFeatures::choose(
        params.pose_features,
        first.pose_names.as_deref(),
        &pose_source,
    )?;
    if features != PoseFeatures::Raw {
        if let Some(s) = seqs.iter().find(|s| s.pose_names != first.pose_names) {
            return Err(Error::param(
                "pose_features",
                format!(
                    "{} names its pose numbers differently from {pose_source} (`pose_vector_names`)",
                    s.dir.join("pose.json").display()
                ),
            ));
        }
    }
    let mirror = Reflection::choose(
        params.mirror,
        &topo,
        &first.fine[0],
        features != PoseFeatures::Raw,
        &first.dir.display().to_string(),
    )?;
    // Every training sequence, then (with a reflection) every one reflected: (fine frames, poses).
    let reflected: Vec<(Vec<Frame>, Vec<Vec<f64>>)> = match &mirror {
        Some(r) => seqs
            .iter()
            .map(|s| {
                (
                    s.fine.iter().map(|f| r.reflect_frame(f)).collect(),
                    s.poses.iter().map(|p| reflect_pose(p, r.axis)).collect(),
                )
            })
            .collect(),
        None => Vec::new(),
    };
    let data: Vec<(&[Frame], &[Vec<f64>])> = seqs
        .iter()
        .map(|s| (s.fine.as_slice(), s.poses.as_slice()))
        .chain(reflected.iter().map(|(f, p)| (f.as_slice(), p.as_slice())))
        .collect();
    if let Some(r) = &mirror {
        progress.note(&format!(
            "mirror: training data reflected in {} = 0 too (first frame asymmetry {:.2} edge lengths)",
            r.axis_name(),
            r.asymmetry
        ));
    }
    let t0 = Instant::now();
    let frames: Vec<&[[f64; 3]]> = data
        .iter()
        .flat_map(|(fine, _)| fine.iter().map(|f| f.as_slice()))
        .collect();
    let subspace = Subspace::fit(&frames, params.k)?;
    let k = subspace.k();
    let subspace_s = t0.elapsed().as_secs_f64();
    progress.note(&format!(
        "subspace: {k} components from {} frames in {subspace_s:.1} s",
        frames.len()
    ));
    let pose_refs: Vec<&[Vec<f64>]> = data.iter().map(|(_, p)| *p).collect();
    let control = ControlSpec::fit_features(&pose_refs, params.lags.clone(), features)?
        .with_history(&pose_refs, &params.pose_history)?;
    let mut controls = Vec::new();
    let mut targets = Vec::new();
    let mut per_seq = Vec::new();
    for (fine, poses) in &data {
        let c = control.controls(poses)?;
        let t: Vec<Vec<f64>> = fine.iter().map(|f| subspace.project(f, k)).collect();
        controls.extend(c.iter().cloned());
        targets.extend(t.iter().cloned());
        per_seq.push((c, t));
    }
    let t1 = Instant::now();
    let linear = LinearRegression::fit(&controls, &targets, params.ridge)?;
    let linear_s = t1.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let seqs: Vec<ControlsAndCoefficients> = per_seq
        .iter()
        .map(|(c, a)| (c.as_slice(), a.as_slice()))
        .collect();
    let (autoregressive, ar_rollout_losses) = fit_autoregressive(&seqs, params, k)?;
    let blend = if params.blend_fit {
        inner_blend_weight(&seqs, params, k)?
    } else {
        BlendSpec::fixed(params.blend_weight)?
    };
    progress.note(&format!(
        "blend: weight {:.3} of the autoregressive rollout ({})",
        blend.weight, blend.method
    ));
    let autoregressive_s = t1.elapsed().as_secs_f64();
    let n_orig = data.len() / if mirror.is_some() { 2 } else { 1 };
    let t_kernel = Instant::now();
    let kernel_targets: Vec<&[Vec<f64>]> = per_seq.iter().map(|(_, t)| t.as_slice()).collect();
    let kernel = fit_kernel(&pose_refs, &kernel_targets, n_orig, params)?;
    let kernel_s = t_kernel.elapsed().as_secs_f64();
    let weights = kernel
        .spec
        .weights
        .as_ref()
        .map(|w| {
            format!(
                ", lag decay {} per frame, pose number factors {:?}",
                w.decay, w.numbers
            )
        })
        .unwrap_or_default();
    progress.note(&format!(
        "kernel: width {} ridge {:.0e}{weights} over {} frames ({}) in {kernel_s:.1} s",
        kernel.spec.width, kernel.spec.ridge, kernel.spec.centres, kernel.spec.method
    ));
    let (mut lstm, mut lstm_losses, mut lstm_s) = (None, Vec::new(), 0.0);
    let (mut lstm_held_out, mut lstm_best_epoch) = (Vec::new(), None);
    // One shared output unit (not one per coefficient): the network's loss is then the vertex MSE.
    let mut coeff_scale = crate::regression::lstm::output_scale(&targets);
    if params.regressor == RegressorKind::Lstm {
        let t2 = Instant::now();
        let cfg = &params.lstm;
        // What the network learns per training sequence: the coefficients, or what the base regressor
        // leaves of them (fitted on all sequences, or on the others: cross-fitted).
        let lstm_targets: Vec<Vec<Vec<f64>>> = match cfg.residual_of {
            None => per_seq.iter().map(|(_, t)| t.clone()).collect(),
            Some(base) => {
                let preds: Vec<Vec<Vec<f64>>> = if cfg.cross_fit && n_orig >= 2 {
                    cross_fitted_predictions(&seqs, n_orig, base, &blend, params, k)?
                } else {
                    seqs.iter()
                        .map(|(c, _)| {
                            base_coefficients(base, &linear, &autoregressive, blend.weight, c)
                        })
                        .collect::<Result<_>>()?
                };
                per_seq
                    .iter()
                    .zip(&preds)
                    .map(|((_, t), p)| {
                        t.iter()
                            .zip(p)
                            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x - y).collect())
                            .collect()
                    })
                    .collect()
            }
        };
        // The held-out group of early stopping: the last training sequence and its reflection.
        let held = |i: usize| cfg.early_stopping && n_orig >= 2 && i % n_orig == n_orig - 1;
        let (mut train_w, mut val_w) = (Vec::new(), Vec::new());
        for (i, ((c, _), t)) in per_seq.iter().zip(&lstm_targets).enumerate() {
            let w = windows(c, t, cfg.seq_len);
            if held(i) {
                val_w.extend(w);
            } else {
                train_w.extend(w);
            }
        }
        let train_targets: Vec<Vec<f64>> = lstm_targets
            .iter()
            .enumerate()
            .filter(|(i, _)| !held(*i))
            .flat_map(|(_, t)| t.iter().cloned())
            .collect();
        coeff_scale = crate::regression::lstm::output_scale(&train_targets);
        let mut net = LstmRegressor::new(cfg.clone(), control.len(), k, coeff_scale.clone())?;
        progress.begin("lstm", cfg.epochs as u64);
        let lr = crate::regression::lstm::cosine_lr(cfg.lr, cfg.epochs);
        let note = |epoch: usize, loss: f64, held: Option<f64>| {
            progress.advance("lstm", 1);
            if (epoch + 1).is_multiple_of(25) || epoch == 0 {
                let h = held.map_or(String::new(), |h| format!(", held-out {h:.4e} m²"));
                progress.note(&format!("lstm epoch {}: loss {loss:.5}{h}", epoch + 1));
            }
        };
        if val_w.is_empty() {
            lstm_losses = net.train_scheduled(&train_w, lr, |e, l| note(e, l, None))?;
        } else {
            let (losses, held_out, best) =
                net.train_early_stopping(&train_w, &val_w, lr, |e, l, h| note(e, l, Some(h)))?;
            progress.note(&format!(
                "lstm: kept epoch {best} of {} (held-out {:.4e} m², {:.4e} before training)",
                cfg.epochs, held_out[best], held_out[0]
            ));
            lstm_losses = losses;
            lstm_held_out = held_out;
            lstm_best_epoch = Some(best);
        }
        progress.end("lstm");
        lstm_s = t2.elapsed().as_secs_f64();
        lstm = Some(net);
    }
    Ok(Fitted {
        subspace,
        control,
        linear,
        autoregressive,
        blend,
        lstm,
        kernel,
        coeff_scale,
        ar_rollout_losses,
        lstm_losses,
        lstm_held_out,
        lstm_best_epoch,
        seconds: BTreeSummary {
            subspace_s,
            linear_s,
            autoregressive_s,
            lstm_s,
            lstm_s_per_epoch: lstm_s / params.lstm.epochs.max(1) as f64,
            kernel_s,
        },
        mirror,
    })
}

impl Fitted {
    /// Subspace coefficients of every frame of `poses` (a whole sequence from its first frame) by the
    /// regressor `kind`, as `apply --pose` computes them from the stored model.
    pub fn coefficients(&self, kind: RegressorKind, poses: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
        let controls = self.control.controls(poses)?;
        let linear = || controls.iter().map(|c| self.linear.predict(c)).collect();
        Ok(match kind {
            RegressorKind::Linear => linear(),
            RegressorKind::Autoregressive => self.autoregressive.rollout(&controls),
            RegressorKind::Blend => crate::regression::blend::mix(
                &linear(),
                &self.autoregressive.rollout(&controls),
                self.blend.weight,
            ),
            RegressorKind::Kernel => self.kernel.predict_sequence(poses),
            RegressorKind::Lstm => {
                let net = self.lstm.as_ref().ok_or_else(|| {
                    Error::param("regressor", "no LSTM was trained (--regressor lstm)")
                })?;
                let base = match net.config.residual_of {
                    Some(b) => Some(base_coefficients(
                        b,
                        &self.linear,
                        &self.autoregressive,
                        self.blend.weight,
                        &controls,
                    )?),
                    None => None,
                };
                net.predict_sequence(&controls, base.as_deref())?
            }
        })
    }
}

/// The kernel regression on every training sequence (and its reflection, same group: held out together in
/// the inner leave-one-out that picks its width and ridge).
fn fit_kernel(
    poses: &[&[Vec<f64>]],
    targets: &[&[Vec<f64>]],
    n_orig: usize,
    params: &TrainParams,
) -> Result<KernelRegression> {
    // The raw pose numbers standardised as the control vector's are (a constant or repeated number gets scale
    // 0: a copy would count twice in a distance).
    let ControlSpec { mean, scale, .. } = ControlSpec::fit(poses, vec![])?;
    let inputs: Vec<Vec<Vec<f64>>> = poses
        .iter()
        .map(|p| kernel::window_inputs(p, &mean, &scale, &params.kernel_window))
        .collect();
    let kd: Vec<KernelData> = inputs
        .iter()
        .zip(targets)
        .enumerate()
        .map(|(i, (x, t))| KernelData {
            inputs: x,
            targets: t,
            group: i % n_orig.max(1),
        })
        .collect();
    KernelRegression::fit(
        &kd,
        params.kernel_window.clone(),
        mean,
        scale,
        !params.kernel_uniform,
    )
}

/// The coefficients of every frame by one of the linear regressors (not the LSTM), from the control vectors
/// of a whole sequence: what a residual LSTM adds to.
pub fn base_coefficients(
    kind: RegressorKind,
    linear: &LinearRegression,
    autoregressive: &AutoregressiveLinear,
    blend_weight: f64,
    controls: &[Vec<f64>],
) -> Result<Vec<Vec<f64>>> {
    let lin = || controls.iter().map(|c| linear.predict(c)).collect();
    Ok(match kind {
        RegressorKind::Linear => lin(),
        RegressorKind::Autoregressive => autoregressive.rollout(controls),
        RegressorKind::Blend => {
            crate::regression::blend::mix(&lin(), &autoregressive.rollout(controls), blend_weight)
        }
        RegressorKind::Lstm | RegressorKind::Kernel => {
            return Err(Error::param(
                "lstm.residual_of",
                format!(
                    "the LSTM corrects the linear, autoregressive or blend regressor, not the {}",
                    kind.name()
                ),
            ))
        }
    })
}

/// The base regressor's predictions of every training sequence from a fit on the other original sequences
/// (an original and its reflection, `i` and `i + n_orig`, are held out together: a reflection is no unseen
/// motion), with the same parameters and blend weight.
fn cross_fitted_predictions(
    seqs: &[ControlsAndCoefficients<'_>],
    n_orig: usize,
    base: RegressorKind,
    blend: &BlendSpec,
    params: &TrainParams,
    k: usize,
) -> Result<Vec<Vec<Vec<f64>>>> {
    let mut out = vec![Vec::new(); seqs.len()];
    for g in 0..n_orig {
        let (linear, ar) = fit_without(seqs, |j| j % n_orig == g, params, k)?;
        for (j, s) in seqs.iter().enumerate().filter(|(j, _)| j % n_orig == g) {
            out[j] = base_coefficients(base, &linear, &ar, blend.weight, s.0)?;
        }
    }
    Ok(out)
}

/// The blend weight by an inner leave-one-out over the training sequences: each one is predicted by the linear
/// map and the autoregressive rollout fitted (with `params`) on the others, and the weight is the least-squares
/// one over all those predictions, clamped to [0, 1]. With fewer than two sequences there is nothing to hold
/// out and the weight is the even 0.5.
pub fn inner_blend_weight(
    seqs: &[ControlsAndCoefficients<'_>],
    params: &TrainParams,
    k: usize,
) -> Result<BlendSpec> {
    if seqs.len() < 2 {
        return Ok(BlendSpec {
            method: "fixed: one training sequence, no inner leave-one-out".into(),
            ..BlendSpec::fixed(0.5)?
        });
    }
    let mut total = WeightFit::default();
    let mut fold_weights = Vec::new();
    for (i, (c, a)) in seqs.iter().enumerate() {
        let (linear, ar) = fit_without(seqs, |j| j == i, params, k)?;
        let lin: Vec<Vec<f64>> = c.iter().map(|x| linear.predict(x)).collect();
        let rolled = ar.rollout(c);
        let mut fold = WeightFit::default();
        fold.add(&lin, &rolled, a);
        fold_weights.push(fold.raw());
        total.num += fold.num;
        total.den += fold.den;
    }
    Ok(BlendSpec {
        weight: total.weight(),
        method: "inner-leave-one-out".into(),
        fold_weights,
    })
}

/// The linear map and the autoregressive regressor fitted on the sequences `held_out` does not pick: the two
/// parts of the blend as a held-out sequence would see them (cross-fitting and the inner leave-one-out).
fn fit_without(
    seqs: &[ControlsAndCoefficients<'_>],
    held_out: impl Fn(usize) -> bool,
    params: &TrainParams,
    k: usize,
) -> Result<(LinearRegression, AutoregressiveLinear)> {
    let others: Vec<ControlsAndCoefficients> = seqs
        .iter()
        .enumerate()
        .filter(|(j, _)| !held_out(*j))
        .map(|(_, s)| *s)
        .collect();
    let controls: Vec<Vec<f64>> = others.iter().flat_map(|s| s.0.iter().cloned()).collect();
    let targets: Vec<Vec<f64>> = others.iter().flat_map(|s| s.1.iter().cloned()).collect();
    let linear = LinearRegression::fit(&controls, &targets, params.ridge)?;
    let (ar, _) = fit_autoregressive(&others, params, k)?;
    Ok((linear, ar))
}

/// The autoregressive regressor on each sequence's (control vectors, true coefficients): the ridge fit, then
/// `ar_rollout_iters` steps on its own rollout. Returns it with the rollout losses.
fn fit_autoregressive(
    seqs: &[ControlsAndCoefficients<'_>],
    params: &TrainParams,
    k: usize,
) -> Result<(AutoregressiveLinear, Vec<f64>)> {
    let a_refs: Vec<&[Vec<f64>]> = seqs.iter().map(|(_, a)| *a).collect();
    let history = ShapeHistory::fit(&a_refs, params.ar_state.min(k), 2)?;
    let mut ar = AutoregressiveLinear::fit(seqs, history, params.ridge, 0)?;
    let report = crate::regression::rollout_fit::refine(
        &mut ar,
        seqs,
        params.ridge,
        params.ar_rollout_iters,
        |_, _| {},
    )?;
    Ok((ar, report.losses))
}

/// The detailed frames held out of the detail model's fit: the last sequence, or with one sequence its last
/// quarter.
fn held_out_frames(seqs: &[TrainingSequence]) -> &[Frame] {
    match seqs {
        [only] => &only.fine[only.fine.len() - only.fine.len() / 4..],
        [.., last] => &last.fine,
        [] => &[],
    }
}

/// Trains on `seqs` and publishes the model at `out`.
pub fn train(
    seqs: &[TrainingSequence],
    params: &TrainParams,
    out: &Path,
    progress: &dyn Progress,
) -> Result<PathBuf> {
    let topo = common_topology(seqs)?;
    let fitted = fit(seqs, params, progress)?;
    let mean_shape = crate::subspace::unflatten(&fitted.subspace.mean);
    let layout = layout_for(params.uv.as_deref(), &topo, &mean_shape)?;
    let t_detail = Instant::now();
    let DetailFit {
        model: mut detail,
        held_out,
    } = fit_detail(seqs, &topo, &params.detail)?;
    progress.note(&format!(
        "detail model: degree {}, ridge {:.0e}; held-out sequence's random captures {:.2}° → {:.2}° in {:.1} s",
        detail.spec.degree,
        detail.spec.ridge,
        detail.spec.held_out_capture_deg,
        detail.spec.held_out_model_deg,
        t_detail.elapsed().as_secs_f64()
    ));
    let t_choice = Instant::now();
    let choice =
        crate::detail::relief::choose(&topo, &held_out, held_out_frames(seqs), params.detail.seed)?;
    progress.note(&format!(
        "coarse detail: {} (held-out sequence's sequence captures {:.2}°: relief {:.2}°, learned filter {:.2}°, blend {:.2}°) in {:.1} s",
        choice.detail().as_str(),
        choice.capture_deg,
        choice.relief_deg,
        choice.model_deg,
        choice.blend_deg.unwrap_or(f64::NAN),
        t_choice.elapsed().as_secs_f64()
    ));
    detail.spec.coarse = Some(choice);
    let mut w = ModelWriter::new(out)?;
    write_core_parts(&mut w, &topo, &layout, &fitted.subspace, &fitted.linear)?;
    write_autoregressive(&mut w, &fitted.autoregressive)?;
    write_kernel(&mut w, &fitted.kernel)?;
    write_detail(&mut w, &detail)?;
    if let Some(net) = &fitted.lstm {
        net.save(&w.staging_path("lstm.safetensors"))?;
        w.record("lstm.safetensors")?;
    }
    let mut cgan_spec = None;
    let mut cgan_summary = serde_json::Value::Null;
    if let Some(cfg) = &params.cgan {
        let fine: Vec<&[Frame]> = seqs.iter().map(|s| s.fine.as_slice()).collect();
        // The pose path of the sequence the cGAN holds out, from a regression fitted without it.
        let pose_shapes = match seqs.split_last() {
            Some((held, rest)) if !rest.is_empty() => {
                let f = fit(rest, params, progress)?;
                let coeffs = f.coefficients(params.regressor, &held.poses)?;
                Some(
                    coeffs
                        .iter()
                        .map(|c| params.pose_lowpass.shape(&topo, &f.subspace, c))
                        .collect(),
                )
            }
            _ => None,
        };
        let inputs = crate::cgan::training::CganInputs {
            topo: &topo,
            layout: &layout,
            resolution: params.resolution,
            fine,
            detail: &detail,
            pose_shapes,
        };
        let (spec, summary) = crate::cgan::training::train_cgan(
            &inputs,
            cfg,
            params.checkpoint.as_deref(),
            &w.staging_path("cgan.safetensors"),
            progress,
        )?;
        w.record("cgan.safetensors")?;
        cgan_spec = Some(spec);
        cgan_summary = summary;
    }
    let manifest = Manifest {
        format: MODEL_FORMAT.into(),
        version: MODEL_VERSION,
        vertices: topo.n_vertices(),
        triangles: topo.n_triangles(),
        k: fitted.subspace.k(),
        control: fitted.control.clone(),
        regressor: params.regressor,
        lstm: fitted.lstm.as_ref().map(|n| n.config.clone()),
        autoregressive: Some(ArSpec::of(&fitted.autoregressive.history)),
        blend: Some(fitted.blend.clone()),
        kernel: Some(fitted.kernel.spec.clone()),
        detail: detail.spec.clone(),
        pose_lowpass: params.pose_lowpass,
        coeff_scale: fitted.coeff_scale.clone(),
        resolution: params.resolution,
        cgan: cgan_spec,
        training: serde_json::json!({
            "data": seqs.iter().map(|s| s.dir.display().to_string()).collect::<Vec<_>>(),
            "frames": seqs.iter().map(|s| s.fine.len()).sum::<usize>(),
            "seconds": fitted.seconds,
            "lstm_final_loss": fitted.lstm_losses.last(),
            "lstm_best_epoch": fitted.lstm_best_epoch,
            "lstm_held_out_mse": [fitted.lstm_held_out.first(), fitted.lstm_best_epoch.and_then(|e| fitted.lstm_held_out.get(e))],
            "autoregressive_rollout_loss": [fitted.ar_rollout_losses.first(), fitted.ar_rollout_losses.last()],
            "mirror": fitted.mirror.as_ref().map(|r| serde_json::json!({"axis": r.axis_name(), "asymmetry_edges": r.asymmetry})),
            "cgan": cgan_summary,
            "detail_s": t_detail.elapsed().as_secs_f64(),
        }),
        files: Default::default(),
    };
    w.publish(manifest)
}

/// The detail model ([`crate::detail`]) fitted on random captures of every training frame, the last training
/// sequence held out to choose its ridge. The mirrored frames are not used: the model is the same in any
/// reflection of the mesh.
pub fn fit_detail(
    seqs: &[TrainingSequence],
    topo: &Topology,
    params: &DetailParams,
) -> Result<DetailFit> {
    let data = DetailData {
        topo,
        sequences: seqs.iter().map(|s| s.fine.as_slice()).collect(),
    };
    crate::detail::fit_with_held_out(&data, params)
}
