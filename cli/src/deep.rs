//! `crease deep register|train|apply` and `crease bake`: DeepWrinkles (Lähner et al. 2018) from the command
//! line. The work is in crease-deep; this module parses arguments, shows progress and prints summaries.

use crate::progress::CliProgress;
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use crease_core::mesh::io::{open_sequence, sort_numbered, write_obj};
use crease_core::mesh::FrameSource;
use crease_deep::apply::{apply, ApplyInput, ApplyParams, CoarseDetail};
use crease_deep::cgan::CganConfig;
use crease_deep::detail::DetailParams;
use crease_deep::evaluation::loso::{evaluate, markdown, EvalParams, ExtraCase};
use crease_deep::model::{Model, RegressorKind};
use crease_deep::normal_maps::bake::{bake_sequence, BakeParams};
use crease_deep::normal_maps::uv::{auto_atlas, read_obj_mesh, read_obj_uv, UvLayout};
use crease_deep::normal_maps::Space;
use crease_deep::registration::{read_scan, RegisterParams, Registration};
use crease_deep::regression::lstm::LstmConfig;
use crease_deep::regression::pose_lowpass::PoseLowpass;
use crease_deep::train::{load_training_dir, train, TrainParams};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct DeepArgs {
    #[command(subcommand)]
    pub command: DeepCommand,
}

#[derive(Subcommand, Debug)]
pub enum DeepCommand {
    /// Register a template to a directory of scans (non-rigid ICP, §3.1); writes OUT/frame_NNNN.obj.
    Register(RegisterArgs),
    /// Train a model (subspace, regression, detail model, optional LSTM and cGAN) from training directories
    /// (gt/, pose.json).
    Train(TrainArgs),
    /// Run a model on a pose file or on coarse meshes; writes OUT/mesh/*.obj and OUT/normals/*.png.
    Apply(ApplyArgs),
    /// Held-out evaluation: each --data directory scored by a model trained on the others (or --split),
    /// with the training flags of `train`; writes OUT/eval.json and OUT/eval.md.
    Eval(EvalArgs),
}

#[derive(Args, Debug)]
pub struct RegisterArgs {
    /// Template mesh (OBJ) in its starting pose.
    #[arg(long)]
    pub template: PathBuf,
    /// Directory of numbered scans: OBJ `v x y z [r g b]` points, boundary points coloured red.
    #[arg(long)]
    pub scans: PathBuf,
    /// Directory for the registered meshes, OUT/frame_NNNN.obj in the scans' order.
    #[arg(long)]
    pub out: PathBuf,
    /// Rigidity weight ω_r (paper: 500).
    #[arg(long, default_value_t = 500.0)]
    pub w_rigid: f64,
    /// Smoothness weight ω_s (paper: 500).
    #[arg(long, default_value_t = 500.0)]
    pub w_smooth: f64,
    /// Boundary weight ω_b (paper: 10).
    #[arg(long, default_value_t = 10.0)]
    pub w_bound: f64,
    /// Graph node spacing in template edge lengths.
    #[arg(long, default_value_t = 2.5)]
    pub node_spacing: f64,
    /// ICP iterations per scan.
    #[arg(long, default_value_t = 30)]
    pub iterations: usize,
    /// Scan points averaged into each vertex's data target (1: the nearest point alone).
    #[arg(long, default_value_t = RegisterParams::default().target_points)]
    pub target_points: usize,
    /// Floor of ω_r and ω_s, which are halved whenever the energy stalls.
    #[arg(long, default_value_t = RegisterParams::default().min_weight)]
    pub min_weight: f64,
    /// Floor of ω_r and ω_s tied to each scan's noise: at least this times the scan's noise variance along its
    /// normal in squared template edge lengths (0: only --min-weight).
    #[arg(long, default_value_t = RegisterParams::default().noise_floor)]
    pub noise_floor: f64,
    /// Weight of the point-to-plane data term (distance along the scan's normal).
    #[arg(long, default_value_t = RegisterParams::default().w_plane)]
    pub w_plane: f64,
    /// Weight of the point-to-point data term.
    #[arg(long, default_value_t = RegisterParams::default().w_point)]
    pub w_point: f64,
    /// Weight of a pull of every graph node toward its previous frame's transform (0: off).
    #[arg(long, default_value_t = RegisterParams::default().w_temporal)]
    pub w_temporal: f64,
    /// Also fit each scan from the unregistered template and keep, of the two fits, the previous result and
    /// the template, the state of lowest Eq. 1 energy (twice the time per scan).
    #[arg(long, default_value_t = RegisterParams::default().multi_start, action = clap::ArgAction::Set)]
    pub multi_start: bool,
    /// No progress bar or summary lines (errors are still printed).
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Training directories, each with gt/, captured/ and pose.json.
    #[arg(long, num_args = 1.., required = true)]
    pub data: Vec<PathBuf>,
    /// Model directory to write (replaced only when the new model is complete).
    #[arg(long)]
    pub out: PathBuf,
    /// Subspace size (capped by the number of training frames).
    #[arg(long, default_value_t = 200)]
    pub k: usize,
    /// Regressor `apply --pose` uses: autoregressive (pose and its own previous shapes, rolled out from the
    /// first frame), linear (pose only), blend (a weighted mean of those two), kernel (a Gaussian kernel over
    /// the last few poses) or lstm. All but the LSTM are always trained.
    #[arg(long, default_value = "kernel")]
    pub regressor: RegressorKind,
    /// Earlier frames whose poses the kernel regression compares besides the frame itself (0 is the frame).
    #[arg(long, value_delimiter = ',', default_value = "0,2,4,6")]
    pub kernel_window: Vec<usize>,
    /// Weigh every number of the kernel's pose window alike instead of searching a decay over the lags and a
    /// factor per pose number (one inner leave-one-out instead of about ten).
    #[arg(long)]
    pub kernel_uniform: bool,
    /// Leading shape coefficients the autoregressive regressor feeds back (capped at --k).
    #[arg(long, default_value_t = 10)]
    pub ar_state: usize,
    /// Steps of the autoregressive regressor's fit on its own rollout after the ridge fit (0: ridge only).
    #[arg(long, default_value_t = 20)]
    pub ar_rollout_iters: usize,
    /// Weight of the autoregressive rollout in the blend regressor (0..=1; the linear map gets the rest).
    #[arg(long, default_value_t = 0.5)]
    pub blend_weight: f64,
    /// Fit the blend weight by an inner leave-one-out over the training directories instead.
    #[arg(long)]
    pub blend_fit: bool,
    /// Pose lags (frames) in the control vector, e.g. 1,2,4,8,16,32 (default: none; the pose, its velocity
    /// and acceleration).
    #[arg(long, value_delimiter = ',')]
    pub lags: Vec<usize>,
    /// Time constants (frames) of decayed pose history features in the control vector, e.g. 3,10,30
    /// (leaky averages of the pose: the cloth's memory of how it got to its pose, without feedback).
    #[arg(long, value_delimiter = ',')]
    pub pose_history: Vec<f64>,
    /// Ridge weight of the linear regression (relative).
    #[arg(long, default_value_t = 1e-3)]
    pub ridge: f64,
    /// Pose features of the regression: rigid (per object: location, sine and cosine of its angles and their
    /// products), raw (the pose numbers), or auto (rigid when pose.json names its numbers OBJ.location.x …
    /// OBJ.rotation_euler.z, raw otherwise).
    #[arg(long, default_value = "auto")]
    pub pose_features: crease_deep::regression::pose_features::PoseFeatureMode,
    /// Also train the subspace and regressions on the training data reflected in a coordinate plane (x, y or
    /// z = 0), poses reflected to match; auto: in the plane where the first training frame is symmetric, if
    /// any and the poses have rigid names; none: no reflection.
    #[arg(long, default_value = "auto")]
    pub mirror: crease_deep::subspace::mirror::MirrorMode,
    /// LSTM layers of the encoder and of the decoder (paper: 4).
    #[arg(long, default_value_t = 4)]
    pub lstm_layers: usize,
    /// LSTM hidden units per layer (paper: 256).
    #[arg(long, default_value_t = 256)]
    pub lstm_hidden: usize,
    /// Frames per LSTM input sequence (paper: 3).
    #[arg(long, default_value_t = 3)]
    pub lstm_seq: usize,
    /// LSTM training epochs (with --regressor lstm).
    #[arg(long, default_value_t = 300)]
    pub lstm_epochs: usize,
    /// LSTM learning rate (Adam).
    #[arg(long, default_value_t = 1e-3)]
    pub lstm_lr: f64,
    /// The regressor whose coefficients the LSTM corrects (linear, autoregressive or blend: it learns their
    /// residual and starts as that regressor), or `none`: it predicts the coefficients itself (before).
    #[arg(long, default_value = "blend", value_parser = parse_residual_of)]
    pub lstm_residual: ResidualOf,
    /// LSTM residual targets from the base regressor fitted on the other training sequences (cross-fitted).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub lstm_cross_fit: bool,
    /// Hold the last training sequence out of the LSTM's training and keep the epoch that does best on it.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub lstm_early_stopping: bool,
    /// Leading subspace coefficients of the shape `apply --pose` draws (0: all).
    #[arg(long, default_value_t = TrainParams::default().pose_lowpass.components)]
    pub pose_components: usize,
    /// Low-pass of the shape `apply --pose` draws: the wavelength, in mean edge lengths, that a cotangent
    /// diffusion halves (0: none).
    #[arg(long, default_value_t = TrainParams::default().pose_lowpass.half_wavelength)]
    pub pose_lowpass: f64,
    /// Chebyshev degree of the detail model `apply --coarse` runs.
    #[arg(long, default_value_t = crease_deep::detail::DEFAULT_DEGREE)]
    pub detail_degree: usize,
    /// Random captures of each training frame the detail model learns from.
    #[arg(long, default_value_t = crease_deep::detail::DEFAULT_CAPTURES_PER_FRAME)]
    pub detail_captures: usize,
    /// Seed of every random choice (weights, batches): the same seed gives the same model.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Normal map resolution (square, texels per side).
    #[arg(long, default_value_t = crease_deep::normal_maps::DEFAULT_RESOLUTION)]
    pub resolution: usize,
    /// A template OBJ whose `vt` gives the UV layout (required to have `vt`); default: computed (LSCM charts).
    #[arg(long)]
    pub uv: Option<PathBuf>,
    /// cGAN training steps (batches of random crops of the maps; 0: no cGAN). The cGAN is used by apply only
    /// where it beat the maps without it on the held-out training sequence.
    #[arg(long, default_value_t = CganConfig::default().steps)]
    pub cgan_steps: usize,
    /// Filters of the generator's first layer (paper: 64).
    #[arg(long, default_value_t = CganConfig::default().filters)]
    pub cgan_filters: usize,
    /// Filters of the discriminator's first layer (paper: 64).
    #[arg(long, default_value_t = CganConfig::default().disc_filters)]
    pub cgan_disc_filters: usize,
    /// Weight of the temporal term (paper: 50; 0 trains without it).
    #[arg(long, default_value_t = CganConfig::default().w_temporal)]
    pub cgan_w_temporal: f64,
    /// Weight of the data (L1) term (paper: 100).
    #[arg(long, default_value_t = CganConfig::default().w_l1)]
    pub cgan_w_l1: f64,
    /// Weight of the adversarial term (paper: 1; 0 trains the generator on the data and temporal terms alone).
    #[arg(long, default_value_t = CganConfig::default().w_gan)]
    pub cgan_w_gan: f64,
    /// Adam's learning rate for both networks (paper: 0.0002).
    #[arg(long, default_value_t = CganConfig::default().lr)]
    pub cgan_lr: f64,
    /// U-Net levels per side (the map resolution must be a multiple of 2^depth).
    #[arg(long, default_value_t = CganConfig::default().depth)]
    pub cgan_depth: usize,
    /// Side of the square map crops the cGAN trains on (a multiple of 2^depth, at most the resolution).
    #[arg(long, default_value_t = CganConfig::default().crop)]
    pub cgan_crop: usize,
    /// cGAN checkpoint directory, written after every epoch and resumed when present.
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
    /// No progress bar or summary lines (errors are still printed).
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Training flags (--data: the sequences; --out: where the models, eval.json and eval.md go).
    #[command(flatten)]
    pub train: TrainArgs,
    /// Score every N-th frame.
    #[arg(long, default_value_t = 1)]
    pub step: usize,
    /// Capture folders of each sequence the coarse path is scored on (those present).
    #[arg(long, value_delimiter = ',', default_value = "captured")]
    pub captures: Vec<String>,
    /// Training-motions curve of the pose path: numbers of training sequences, e.g. 1,2,4,6.
    #[arg(long, value_delimiter = ',')]
    pub motions: Vec<usize>,
    /// A further case scored by the model trained on every --data directory: NAME=DIR:CAPTURE,CAPTURE
    /// (DIR holds gt/ and the capture folders).
    #[arg(long, value_parser = parse_extra)]
    pub extra: Vec<ExtraCase>,
    /// Train on each directory's first half and score its second half instead of leaving one out.
    #[arg(long)]
    pub split: bool,
    /// Hold out only these directories (by folder name, e.g. seed_7); default: each in turn.
    #[arg(long, value_delimiter = ',')]
    pub held_out: Vec<String>,
    /// Also Table 1 in spirit on the last directory held out: the cGAN (with the --cgan-* flags) from a capture
    /// and from a subspace reconstruction, with and without the temporal term.
    #[arg(long)]
    pub table1: bool,
    /// Write the Fig. 11 strip (capture | ours | gt maps) of this frame (1-based) of every held-out directory
    /// into OUT/strips.
    #[arg(long)]
    pub strip: Option<usize>,
}

fn parse_extra(s: &str) -> std::result::Result<ExtraCase, String> {
    let (name, rest) = s
        .split_once('=')
        .ok_or_else(|| format!("`{s}`: expected NAME=DIR:CAPTURE,…"))?;
    let (dir, caps) = rest
        .rsplit_once(':')
        .ok_or_else(|| format!("`{s}`: expected NAME=DIR:CAPTURE,…"))?;
    Ok(ExtraCase {
        name: name.to_string(),
        dir: PathBuf::from(dir),
        captures: caps.split(',').map(str::to_string).collect(),
    })
}

#[derive(Args, Debug)]
pub struct ApplyArgs {
    /// Model directory written by `crease deep train` (checked against its manifest).
    #[arg(long)]
    pub model: PathBuf,
    /// Pose file (pose.json): shapes come from the model's regression.
    #[arg(long, conflicts_with = "coarse", required_unless_present = "coarse")]
    pub pose: Option<PathBuf>,
    /// Coarse mesh sequence in the model's topology (e.g. a capture).
    #[arg(long)]
    pub coarse: Option<PathBuf>,
    /// Output directory: mesh/frame_NNNN.obj (with vt) and normals/frame_NNNN.png per frame, done.json last.
    #[arg(long)]
    pub out: PathBuf,
    /// Normal map space: world (default) or tangent.
    #[arg(long, default_value = "world")]
    pub space: Space,
    /// Override the model's regressor for --pose: linear, autoregressive, blend, kernel or lstm.
    #[arg(long)]
    pub regressor: Option<RegressorKind>,
    /// Write the coarse maps without the cGAN.
    #[arg(long)]
    pub no_cgan: bool,
    /// --coarse: where the capture's detail comes from: `relief` (crease's fold relief over the whole sequence),
    /// `model` (the model's learned detail filter, frame by frame) or `blend` (the midpoint of the two)
    /// [default: whichever won on the model's held-out training sequence, see its manifest's detail.coarse]
    #[arg(long)]
    pub coarse_detail: Option<CoarseDetail>,
    /// No progress bar or summary lines (errors are still printed).
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Coarse sequence the maps belong to.
    #[arg(long)]
    pub coarse: PathBuf,
    /// Detailed sequence (any mode's output, or gt), same frame count; may have another topology.
    #[arg(long)]
    pub detailed: PathBuf,
    /// Output directory, laid out as `crease deep apply` writes it (mesh/, normals/, done.json).
    #[arg(long)]
    pub out: PathBuf,
    /// Normal map space: world (default) or tangent.
    #[arg(long, default_value = "world")]
    pub space: Space,
    /// Normal map resolution (square, texels per side).
    #[arg(long, default_value_t = crease_deep::normal_maps::DEFAULT_RESOLUTION)]
    pub resolution: usize,
    /// OBJ with the UV layout to use (required to have `vt`); default: the coarse input's own `vt`, else
    /// computed (LSCM charts).
    #[arg(long)]
    pub uv: Option<PathBuf>,
    /// How far a texel's ray may reach for the detailed surface, in coarse edge lengths.
    #[arg(long, default_value_t = 8.0)]
    pub max_dist: f64,
    /// No progress bar or summary lines (errors are still printed).
    #[arg(long)]
    pub quiet: bool,
}

pub fn deep(a: DeepArgs) -> Result<()> {
    match a.command {
        DeepCommand::Register(a) => register(a),
        DeepCommand::Train(a) => train_cmd(a),
        DeepCommand::Apply(a) => apply_cmd(a),
        DeepCommand::Eval(a) => eval_cmd(a),
    }
}

fn register(a: RegisterArgs) -> Result<()> {
    let (topo, template, _) = read_obj_mesh(&a.template)?;
    let mut files = Vec::new();
    for e in std::fs::read_dir(&a.scans).with_context(|| format!("{}", a.scans.display()))? {
        let p = e?.path();
        if p.extension().is_some_and(|x| x.eq_ignore_ascii_case("obj")) {
            files.push(p);
        }
    }
    if files.is_empty() {
        bail!("{}: no scans (.obj point files)", a.scans.display());
    }
    let files = sort_numbered(files)?;
    let params = RegisterParams {
        w_rigid: a.w_rigid,
        w_smooth: a.w_smooth,
        w_bound: a.w_bound,
        node_spacing: a.node_spacing,
        iterations: a.iterations,
        target_points: a.target_points,
        min_weight: a.min_weight,
        noise_floor: a.noise_floor,
        w_plane: a.w_plane,
        w_point: a.w_point,
        w_temporal: a.w_temporal,
        multi_start: a.multi_start,
        ..Default::default()
    };
    let progress = CliProgress::new(a.quiet);
    let mut reg = Registration::new(topo.clone(), &template, params)?;
    progress.println(&format!(
        "deformation graph: {} nodes for {} vertices",
        reg.n_nodes(),
        topo.n_vertices()
    ));
    crease_core::fsutil::create_dir_all(&a.out)?;
    use crease_core::progress::Progress;
    progress.begin("register", files.len() as u64);
    let t0 = Instant::now();
    for (i, f) in files.iter().enumerate() {
        let scan = read_scan(&f.path)?;
        let out = reg
            .register(&scan)
            .with_context(|| format!("registering {}", f.path.display()))?;
        write_obj(&a.out.join(format!("frame_{:04}.obj", i + 1)), &topo, &out)?;
        progress.advance("register", 1);
    }
    progress.end("register");
    progress.println(&format!(
        "registered {} scans, {:.1} s per scan",
        files.len(),
        t0.elapsed().as_secs_f64() / files.len() as f64
    ));
    Ok(())
}

/// `--lstm-residual`: the regressor the LSTM corrects, or none.
#[derive(Debug, Clone, Copy)]
pub struct ResidualOf(pub Option<RegressorKind>);

fn parse_residual_of(s: &str) -> std::result::Result<ResidualOf, String> {
    match s {
        "none" => Ok(ResidualOf(None)),
        "lstm" => {
            Err("the LSTM cannot correct itself (linear, autoregressive, blend or none)".into())
        }
        _ => s.parse::<RegressorKind>().map(|k| ResidualOf(Some(k))),
    }
}

fn train_cmd(a: TrainArgs) -> Result<()> {
    let progress = CliProgress::new(a.quiet);
    let mut seqs = Vec::new();
    for d in &a.data {
        seqs.push(load_training_dir(d)?);
        progress.println(&format!(
            "loaded {}: {} frames",
            d.display(),
            seqs.last().map_or(0, |s| s.fine.len())
        ));
    }
    let params = train_params(&a);
    let t0 = Instant::now();
    let out = train(&seqs, &params, &a.out, &progress)?;
    progress.println(&format!(
        "model written to {} in {:.1} s",
        out.display(),
        t0.elapsed().as_secs_f64()
    ));
    Ok(())
}

fn train_params(a: &TrainArgs) -> TrainParams {
    TrainParams {
        k: a.k,
        lags: a.lags.clone(),
        pose_history: a.pose_history.clone(),
        ridge: a.ridge,
        pose_features: a.pose_features,
        mirror: a.mirror,
        regressor: a.regressor,
        kernel_window: a.kernel_window.clone(),
        kernel_uniform: a.kernel_uniform,
        ar_state: a.ar_state,
        ar_rollout_iters: a.ar_rollout_iters,
        blend_weight: a.blend_weight,
        blend_fit: a.blend_fit,
        lstm: LstmConfig {
            layers: a.lstm_layers,
            hidden: a.lstm_hidden,
            seq_len: a.lstm_seq,
            epochs: a.lstm_epochs,
            batch: 32,
            lr: a.lstm_lr,
            seed: a.seed,
            residual_of: a.lstm_residual.0,
            cross_fit: a.lstm_cross_fit,
            early_stopping: a.lstm_early_stopping,
        },
        pose_lowpass: PoseLowpass {
            components: a.pose_components,
            half_wavelength: a.pose_lowpass,
        },
        detail: DetailParams {
            degree: a.detail_degree,
            captures_per_frame: a.detail_captures,
            seed: a.seed,
        },
        resolution: a.resolution,
        uv: a.uv.clone(),
        cgan: (a.cgan_steps > 0).then(|| CganConfig {
            filters: a.cgan_filters,
            disc_filters: a.cgan_disc_filters,
            w_temporal: a.cgan_w_temporal,
            w_l1: a.cgan_w_l1,
            w_gan: a.cgan_w_gan,
            lr: a.cgan_lr,
            depth: a.cgan_depth,
            crop: a.cgan_crop,
            steps: a.cgan_steps,
            seed: a.seed,
            ..Default::default()
        }),
        checkpoint: a.checkpoint.clone(),
    }
}

fn eval_cmd(a: EvalArgs) -> Result<()> {
    let progress = CliProgress::new(a.train.quiet);
    let params = EvalParams {
        train: train_params(&a.train),
        step: a.step,
        captures: a.captures,
        motions: a.motions,
        extra: a.extra,
        split: a.split,
        held_out: a.held_out,
        table1: a.table1.then(|| CganConfig {
            filters: a.train.cgan_filters,
            disc_filters: a.train.cgan_disc_filters,
            w_temporal: a.train.cgan_w_temporal,
            w_l1: a.train.cgan_w_l1,
            w_gan: a.train.cgan_w_gan,
            lr: a.train.cgan_lr,
            depth: a.train.cgan_depth,
            crop: a.train.cgan_crop,
            steps: a.train.cgan_steps.max(1),
            seed: a.train.seed,
            ..Default::default()
        }),
        strip: a.strip,
        strips: a.train.out.join("strips"),
        work: a.train.out.join("models"),
    };
    crease_core::fsutil::create_dir_all(&a.train.out)?;
    let report = evaluate(&a.train.data, &params, &progress)?;
    let md = markdown(&report);
    let json = serde_json::to_string_pretty(&report)?;
    crease_core::fsutil::write_atomic(&a.train.out.join("eval.json"), json.as_bytes())?;
    crease_core::fsutil::write_atomic(&a.train.out.join("eval.md"), md.as_bytes())?;
    println!("{md}");
    Ok(())
}

fn apply_cmd(a: ApplyArgs) -> Result<()> {
    let model = Model::load(&a.model)?;
    let input = match (&a.pose, &a.coarse) {
        (Some(p), None) => ApplyInput::Pose(p.clone()),
        (None, Some(c)) => ApplyInput::Coarse(c.clone()),
        _ => bail!("give exactly one of --pose and --coarse"),
    };
    let params = ApplyParams {
        space: a.space,
        regressor: a.regressor,
        frames: None,
        no_cgan: a.no_cgan,
        coarse_detail: a.coarse_detail,
    };
    let progress = CliProgress::new(a.quiet);
    let t0 = Instant::now();
    let summary = apply(&model, &input, &params, &a.out, &progress)?;
    let n = summary.frames;
    progress.println(&format!(
        "wrote {n} frames to {} ({:.1} ms per frame)",
        a.out.display(),
        1e3 * t0.elapsed().as_secs_f64() / n.max(1) as f64
    ));
    if let Some((t, d)) = summary.outside.first() {
        // Said even with --quiet: these shapes are not a prediction the model can stand behind.
        eprintln!(
            "{} of {n} frames have poses outside what the kernel regressor learned (frame {}: {d:.2} training standard deviations from the nearest training frame's); their shapes are close to the mean shape",
            summary.outside.len(),
            t + 1
        );
    }
    if !summary.fallback.is_empty() {
        // Said even with --quiet: the maps of these frames are not what the model would make.
        eprintln!(
            "{} of {n} frames got the input's own normals (outside what the detail model learned; their OBJ says why):",
            summary.fallback.len()
        );
        for (t, why) in summary.fallback.iter().take(10) {
            eprintln!("  frame {}: {why}", t + 1);
        }
    }
    Ok(())
}

/// The layout a bake uses: `--uv` (must have `vt`), else the coarse input's own `vt`, else computed.
fn bake_layout(
    uv: Option<&Path>,
    coarse_path: &Path,
    coarse: &dyn FrameSource,
) -> Result<UvLayout> {
    let topo = coarse.topology();
    if let Some(p) = uv {
        return read_obj_uv(p, topo)?.with_context(|| {
            format!(
                "{}: has no texture coordinates (`vt`), which --uv requires",
                p.display()
            )
        });
    }
    let layout = crease_core::mesh::io::detect_layout(coarse_path)?;
    if let Some(obj) = layout
        .input_files()
        .into_iter()
        .find(|f| f.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")))
    {
        if let Some(l) = read_obj_uv(&obj, topo)? {
            return Ok(l);
        }
    }
    Ok(auto_atlas(topo, &coarse.read_frame(0)?, 0.01)?)
}

pub fn bake(a: BakeArgs) -> Result<()> {
    let coarse = open_sequence(&a.coarse)?.source;
    let detailed = open_sequence(&a.detailed)?.source;
    let layout = bake_layout(a.uv.as_deref(), &a.coarse, coarse.as_ref())?;
    let params = BakeParams {
        resolution: a.resolution,
        space: a.space,
        max_dist_edges: a.max_dist,
    };
    let progress = CliProgress::new(a.quiet);
    let t0 = Instant::now();
    bake_sequence(
        coarse.as_ref(),
        detailed.as_ref(),
        &layout,
        &params,
        &a.out,
        &progress,
    )?;
    progress.println(&format!(
        "baked {} frames into {} in {:.1} s",
        coarse.n_frames(),
        a.out.display(),
        t0.elapsed().as_secs_f64()
    ));
    Ok(())
}
