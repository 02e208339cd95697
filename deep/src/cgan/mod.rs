//! The conditional GAN of Lähner et al. §4.2 (pix2pix-style): a U-Net generator with skip connections and a
//! PatchGAN discriminator, trained with L1·100 + temporal·50 + GAN·1 (Eq. 4), batch norm and Adam.
//!
//! Input: a world-space normal map plus its coverage (4 channels); output: the detailed map (3 channels,
//! normalised per texel afterwards). The data and temporal terms are taken over covered texels only, and the
//! temporal term |Σ (G(x_t) − y_{t−1})| is divided by the texel count so that its weight 50 means the same at
//! every size. Dropout (pix2pix's noise) is left out: inference must be deterministic, since the cluster's
//! output has to match a single-node run byte for byte.
//!
//! Sized for a CPU (the paper's 256² maps through 2 × 8 layers of 64 filters are about 6 GMAC per frame):
//! the U-Net has a fixed number of levels ([`CganConfig::depth`], 5 by default) and few filters (8, doubling
//! to 64), so it is fully convolutional: it trains on random crops of the maps ([`CganConfig::crop`], 64²
//! texels, batches of 8) and runs on the whole map at inference. The discriminator sees the same crops; with
//! two stride-2 layers its patches are 34 texels wide, about the width of a few folds at 256².
//!
//! The generator is residual: it predicts a correction added to the input normals, and its last layer starts
//! at zero, so an untrained model returns the input map and training can only add detail. The input already
//! carries the garment's shape; the cGAN's job in the paper is to add the wrinkles.

pub mod data;
pub mod enhance;
pub mod gemm_conv;
pub mod training;

use crate::nn::adam::Adam;
use crate::nn::seed::{init_vars, Rng};
use crate::nn::vars::SortedVars;
use crate::normal_maps::NormalMap;
use candle_core::{DType, Device, ModuleT, Tensor};
use candle_nn::{
    batch_norm, conv2d, conv_transpose2d, BatchNorm, BatchNormConfig, Conv2d, Conv2dConfig,
    ConvTranspose2d, ConvTranspose2dConfig, Module, VarBuilder, VarMap,
};
use crease_core::{Error, Result};
use data::TrainingSet;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const IN_CHANNELS: usize = 4;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CganConfig {
    /// Filters of the first generator layer (paper: 64); doubled per level up to 8×.
    pub filters: usize,
    /// Filters of the first discriminator layer.
    pub disc_filters: usize,
    /// U-Net levels per side (paper: 8 at 256²); maps must be a multiple of 2^depth texels wide.
    pub depth: usize,
    /// Side of the square training crops, in texels (a multiple of 2^depth).
    pub crop: usize,
    pub batch: usize,
    /// Optimisation steps (one batch each).
    pub steps: usize,
    pub w_l1: f64,
    pub w_temporal: f64,
    pub w_gan: f64,
    pub lr: f64,
    pub beta1: f64,
    pub seed: u64,
}

impl Default for CganConfig {
    fn default() -> Self {
        CganConfig {
            filters: 8,
            disc_filters: 8,
            depth: 5,
            crop: 64,
            batch: 8,
            steps: 1500,
            w_l1: 100.0,
            w_temporal: 50.0,
            w_gan: 1.0,
            lr: 2e-4,
            beta1: 0.5,
            seed: 1,
        }
    }
}

impl CganConfig {
    pub fn validate(&self) -> Result<()> {
        if self.filters == 0 || self.disc_filters == 0 || self.batch == 0 {
            return Err(Error::param("cgan", "filters and batch must be at least 1"));
        }
        if !(1..=8).contains(&self.depth) {
            return Err(Error::param(
                "cgan.depth",
                format!("{} is outside 1..=8", self.depth),
            ));
        }
        if self.crop < 16 || !self.crop.is_multiple_of(1 << self.depth) {
            return Err(Error::param(
                "cgan.crop",
                format!(
                    "{} is not a multiple of 2^depth = {} of at least 16",
                    self.crop,
                    1 << self.depth
                ),
            ));
        }
        for (n, v) in [
            ("cgan.w_l1", self.w_l1),
            ("cgan.w_temporal", self.w_temporal),
            ("cgan.w_gan", self.w_gan),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::param(n, "must be a non-negative number"));
            }
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error::param("cgan.lr", "must be positive"));
        }
        Ok(())
    }

    /// Whether maps of `resolution`² texels fit the U-Net (and the crops fit in them).
    pub fn check_resolution(&self, resolution: usize) -> Result<()> {
        if !resolution.is_multiple_of(1 << self.depth) || resolution < self.crop {
            return Err(Error::param(
                "resolution",
                format!(
                    "{resolution} is not a multiple of 2^depth = {} at least as large as the cGAN's crop {}",
                    1 << self.depth,
                    self.crop
                ),
            ));
        }
        Ok(())
    }
}

pub(crate) fn ce(e: candle_core::Error) -> Error {
    Error::Numeric {
        stage: "cgan".into(),
        msg: e.to_string(),
    }
}

fn down_cfg() -> Conv2dConfig {
    Conv2dConfig {
        padding: 1,
        stride: 2,
        ..Default::default()
    }
}

fn up_cfg() -> ConvTranspose2dConfig {
    ConvTranspose2dConfig {
        padding: 1,
        stride: 2,
        ..Default::default()
    }
}

fn bn_cfg() -> BatchNormConfig {
    BatchNormConfig {
        eps: 1e-5,
        remove_mean: true,
        affine: true,
        momentum: 0.1,
    }
}

pub struct Generator {
    enc: Vec<(Conv2d, Option<BatchNorm>)>,
    dec: Vec<(ConvTranspose2d, Option<BatchNorm>)>,
}

impl Generator {
    pub fn new(cfg: &CganConfig, vb: VarBuilder) -> candle_core::Result<Self> {
        let depth = cfg.depth;
        let f = cfg.filters;
        let ch: Vec<usize> = (0..depth).map(|i| (f << i.min(3)).min(8 * f)).collect();
        let mut enc = Vec::new();
        for i in 0..depth {
            let cin = if i == 0 { IN_CHANNELS } else { ch[i - 1] };
            let conv = conv2d(cin, ch[i], 4, down_cfg(), vb.pp(format!("g.enc{i}")))?;
            // No norm on the first layer (pix2pix) nor on the innermost one.
            let bn = if i == 0 || i == depth - 1 {
                None
            } else {
                Some(batch_norm(ch[i], bn_cfg(), vb.pp(format!("g.bn_enc{i}")))?)
            };
            enc.push((conv, bn));
        }
        let mut dec = Vec::new();
        for j in 0..depth {
            let cin = if j == 0 {
                ch[depth - 1]
            } else {
                2 * ch[depth - 1 - j]
            };
            let cout = if j == depth - 1 { 3 } else { ch[depth - 2 - j] };
            let conv = conv_transpose2d(cin, cout, 4, up_cfg(), vb.pp(format!("g.dec{j}")))?;
            let bn = if j == depth - 1 {
                None
            } else {
                Some(batch_norm(cout, bn_cfg(), vb.pp(format!("g.bn_dec{j}")))?)
            };
            dec.push((conv, bn));
        }
        Ok(Generator { enc, dec })
    }

    /// The variable names of the last decoder layer, which starts at zero (the generator starts as the
    /// identity).
    fn last_layer_names(cfg: &CganConfig) -> [String; 2] {
        let j = cfg.depth - 1;
        [format!("g.dec{j}.weight"), format!("g.dec{j}.bias")]
    }

    /// [b, 4, H, W] → [b, 3, H, W]: the input normals plus a correction in (−1, 1), zero where the input is not
    /// covered (the target is zero there too, so the discriminator cannot tell real from fake by the gutter).
    pub fn forward(&self, x: &Tensor, train: bool) -> candle_core::Result<Tensor> {
        let mut skips = Vec::with_capacity(self.enc.len());
        let mut h = x.clone();
        for (i, (conv, bn)) in self.enc.iter().enumerate() {
            let inp = if i == 0 { h.clone() } else { leaky(&h)? };
            h = crate::cgan::gemm_conv::conv_k4s2p1(&inp, conv.weight(), conv.bias())?;
            if let Some(bn) = bn {
                h = bn.forward_t(&h, train)?;
            }
            skips.push(h.clone());
        }
        let depth = self.dec.len();
        for (j, (conv, bn)) in self.dec.iter().enumerate() {
            let inp = if j == 0 {
                h.clone()
            } else {
                Tensor::cat(&[&h, &skips[depth - 1 - j]], 1)?
            };
            // candle's own transposed convolution is a per-texel loop; this is the same sum as one GEMM.
            h = crate::cgan::gemm_conv::conv_transpose_k4s2p1(
                &inp.relu()?,
                conv.weight(),
                conv.bias(),
            )?;
            if let Some(bn) = bn {
                h = bn.forward_t(&h, train)?;
            }
        }
        let out = h.tanh()?;
        let normals = x.narrow(1, 0, 3)?;
        let coverage = x.narrow(1, 3, 1)?;
        (normals + out)?.broadcast_mul(&coverage)
    }
}

pub struct Discriminator {
    /// (convolution, its stride, batch norm).
    layers: Vec<(Conv2d, usize, Option<BatchNorm>)>,
}

impl Discriminator {
    /// PatchGAN: stride-2 4×4 convolutions down to a quarter of the crop or less (at most three), then two
    /// stride-1 ones, one logit per patch.
    pub fn new(cfg: &CganConfig, vb: VarBuilder) -> candle_core::Result<Self> {
        let f = cfg.disc_filters;
        let downs = (cfg.crop.trailing_zeros() as usize)
            .saturating_sub(4)
            .clamp(1, 3);
        let mut spec = vec![(IN_CHANNELS + 3, f, 2, false)];
        let mut c = f;
        for _ in 1..downs {
            spec.push((c, 2 * c, 2, true));
            c *= 2;
        }
        spec.push((c, 2 * c, 1, true));
        spec.push((2 * c, 1, 1, false));
        let mut layers = Vec::new();
        for (i, &(cin, cout, stride, norm)) in spec.iter().enumerate() {
            let conv = conv2d(
                cin,
                cout,
                4,
                Conv2dConfig {
                    padding: 1,
                    stride,
                    ..Default::default()
                },
                vb.pp(format!("d.conv{i}")),
            )?;
            let bn = if norm {
                Some(batch_norm(cout, bn_cfg(), vb.pp(format!("d.bn{i}")))?)
            } else {
                None
            };
            layers.push((conv, stride, bn));
        }
        Ok(Discriminator { layers })
    }

    pub fn forward(&self, x: &Tensor, y: &Tensor, train: bool) -> candle_core::Result<Tensor> {
        let mut h = Tensor::cat(&[x, y], 1)?;
        let last = self.layers.len() - 1;
        for (i, (conv, stride, bn)) in self.layers.iter().enumerate() {
            // The generator's gradient passes back through every discriminator layer; candle differentiates its
            // own convolution with its per-texel transposed convolution, the GEMM form with matrix products.
            h = if *stride == 2 {
                crate::cgan::gemm_conv::conv_k4s2p1(&h, conv.weight(), conv.bias())?
            } else {
                conv.forward(&h)?
            };
            if let Some(bn) = bn {
                h = bn.forward_t(&h, train)?;
            }
            if i != last {
                h = leaky(&h)?;
            }
        }
        Ok(h)
    }
}

/// Sets the named variables to zero (the generator's last layer: it starts as the identity).
fn zero_vars(vm: &VarMap, names: &[String]) -> candle_core::Result<()> {
    let data = vm
        .data()
        .lock()
        .map_err(|_| candle_core::Error::Msg("var map lock poisoned".into()))?;
    for name in names {
        let var = data
            .get(name)
            .ok_or_else(|| candle_core::Error::Msg(format!("no variable {name}")))?;
        var.set(&var.as_tensor().zeros_like()?)?;
    }
    Ok(())
}

fn leaky(x: &Tensor) -> candle_core::Result<Tensor> {
    // LeakyReLU(0.2) = max(x, 0.2 x).
    x.maximum(&(x * 0.2)?)
}

/// Numerically stable binary cross-entropy on logits: mean(max(z, 0) − z·t + log(1 + e^(−|z|))).
fn bce_logits(z: &Tensor, target: f64) -> candle_core::Result<Tensor> {
    let pos = z.relu()?;
    let log_term = ((z.abs()?.neg()?.exp()? + 1.0)?).log()?;
    ((pos - (z * target)?)? + log_term)?.mean_all()
}

/// [1, 4, H, W] of a whole map: normals then coverage.
pub fn input_tensor(map: &NormalMap) -> candle_core::Result<Tensor> {
    let (w, h) = (map.width, map.height);
    let mut v = Vec::with_capacity(IN_CHANNELS * w * h);
    for c in 0..3 {
        v.extend(
            map.n
                .iter()
                .zip(&map.covered)
                .map(|(n, &cov)| if cov { n[c] } else { 0.0 }),
        );
    }
    v.extend(map.covered.iter().map(|&c| if c { 1.0f32 } else { 0.0 }));
    Tensor::from_vec(v, (1, IN_CHANNELS, h, w), &Device::Cpu)
}

/// One training batch: input [b, 4, c, c], target and previous target [b, 3, c, c], coverage [b, 1, c, c].
pub struct Batch {
    pub input: Tensor,
    pub target: Tensor,
    pub prev_target: Tensor,
    pub mask: Tensor,
}

/// Losses of one step (generator terms before weighting).
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize, PartialEq)]
pub struct StepLosses {
    pub l1: f64,
    pub temporal: f64,
    pub gan: f64,
    pub disc: f64,
}

pub struct Cgan {
    pub config: CganConfig,
    gen_vars: VarMap,
    disc_vars: VarMap,
    pub gen: Generator,
    disc: Discriminator,
    opt_g: Adam,
    opt_d: Adam,
    /// Steps completed (for resuming).
    pub step: usize,
}

fn named_sorted(vm: &VarMap) -> Vec<(String, candle_core::Var)> {
    let data = match vm.data().lock() {
        Ok(d) => d,
        Err(p) => p.into_inner(),
    };
    let mut v: Vec<(String, candle_core::Var)> =
        data.iter().map(|(k, v)| (k.clone(), v.clone())).collect();
    v.sort_by(|a, b| a.0.cmp(&b.0));
    v
}

impl Cgan {
    pub fn new(config: CganConfig) -> Result<Self> {
        config.validate()?;
        let gen_vars = VarMap::new();
        let disc_vars = VarMap::new();
        let gen = Generator::new(
            &config,
            VarBuilder::from_varmap(&gen_vars, DType::F32, &Device::Cpu),
        )
        .map_err(ce)?;
        let disc = Discriminator::new(
            &config,
            VarBuilder::from_varmap(&disc_vars, DType::F32, &Device::Cpu),
        )
        .map_err(ce)?;
        init_vars(&gen_vars, config.seed, &["g."]).map_err(ce)?;
        init_vars(&disc_vars, config.seed.wrapping_add(17), &["d."]).map_err(ce)?;
        zero_vars(&gen_vars, &Generator::last_layer_names(&config)).map_err(ce)?;
        // Only trainable tensors go to the optimisers; batch-norm running statistics are updated by the layers.
        let trainable = |vm: &VarMap| {
            named_sorted(vm)
                .into_iter()
                .filter(|(n, _)| !n.ends_with("running_mean") && !n.ends_with("running_var"))
                .collect::<Vec<_>>()
        };
        let opt_g = Adam::new(trainable(&gen_vars), config.lr, config.beta1).map_err(ce)?;
        let opt_d = Adam::new(trainable(&disc_vars), config.lr, config.beta1).map_err(ce)?;
        Ok(Cgan {
            config,
            gen_vars,
            disc_vars,
            gen,
            disc,
            opt_g,
            opt_d,
            step: 0,
        })
    }

    /// One optimisation step on a batch (discriminator, then generator).
    pub fn train_step(&mut self, b: &Batch) -> Result<StepLosses> {
        let cfg = &self.config;
        let (x, y, y_prev, mask) = (&b.input, &b.target, &b.prev_target, &b.mask);
        let fake = self.gen.forward(x, true).map_err(ce)?;
        // Discriminator.
        let d_real = self.disc.forward(x, y, true).map_err(ce)?;
        let d_fake = self.disc.forward(x, &fake.detach(), true).map_err(ce)?;
        let loss_d = ((bce_logits(&d_real, 1.0).map_err(ce)?
            + bce_logits(&d_fake, 0.0).map_err(ce)?)
        .map_err(ce)?
            * 0.5)
            .map_err(ce)?;
        let gd = loss_d.backward().map_err(ce)?;
        self.opt_d.step(&gd).map_err(ce)?;
        // Generator.
        let d_gen = self.disc.forward(x, &fake, true).map_err(ce)?;
        let gan = bce_logits(&d_gen, 1.0).map_err(ce)?;
        let count =
            (mask.sum_all().map_err(ce)?.to_scalar::<f32>().map_err(ce)? as f64 * 3.0).max(1.0);
        let mask3 = mask.broadcast_as(fake.shape()).map_err(ce)?;
        let l1 = (((&fake - y).map_err(ce)?.abs().map_err(ce)? * &mask3)
            .map_err(ce)?
            .sum_all()
            .map_err(ce)?
            / count)
            .map_err(ce)?;
        let temporal = (((&fake - y_prev).map_err(ce)? * &mask3)
            .map_err(ce)?
            .sum_all()
            .map_err(ce)?
            / count)
            .map_err(ce)?
            .abs()
            .map_err(ce)?;
        let loss_g = ((((&gan * cfg.w_gan).map_err(ce)? + (&l1 * cfg.w_l1).map_err(ce)?)
            .map_err(ce)?
            + (&temporal * cfg.w_temporal).map_err(ce)?)
        .map_err(ce)?)
        .to_dtype(DType::F32)
        .map_err(ce)?;
        let gg = loss_g.backward().map_err(ce)?;
        self.opt_g.step(&gg).map_err(ce)?;
        let s = |t: &Tensor| -> Result<f64> { Ok(t.to_scalar::<f32>().map_err(ce)? as f64) };
        let out = StepLosses {
            l1: s(&l1)?,
            temporal: s(&temporal)?,
            gan: s(&gan)?,
            disc: s(&loss_d)?,
        };
        if ![out.l1, out.temporal, out.gan, out.disc]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(Error::Numeric {
                stage: "cgan".into(),
                msg: format!("a loss became non-finite: {out:?}"),
            });
        }
        Ok(out)
    }

    /// Trains until `config.steps` steps are done (continuing from `self.step`). Step i's batch is drawn from
    /// a generator seeded by the seed and i, so a resumed run sees the same batches as an uninterrupted one.
    /// Every `report` steps `on_report` gets the mean losses since the last report and may write a checkpoint.
    pub fn train(
        &mut self,
        data: &TrainingSet,
        report: usize,
        mut on_report: impl FnMut(&mut Cgan, usize, &StepLosses) -> Result<()>,
    ) -> Result<Vec<StepLosses>> {
        let mut history = Vec::new();
        let (mut sum, mut n) = (StepLosses::default(), 0.0);
        while self.step < self.config.steps {
            let mut rng = Rng::new(self.config.seed ^ (0xE90C_0000 + self.step as u64));
            let batch = data
                .batch(&mut rng, self.config.batch, self.config.crop)
                .map_err(ce)?;
            let l = self.train_step(&batch)?;
            sum.l1 += l.l1;
            sum.temporal += l.temporal;
            sum.gan += l.gan;
            sum.disc += l.disc;
            n += 1.0;
            self.step += 1;
            if self.step.is_multiple_of(report.max(1)) || self.step == self.config.steps {
                let mean = StepLosses {
                    l1: sum.l1 / n,
                    temporal: sum.temporal / n,
                    gan: sum.gan / n,
                    disc: sum.disc / n,
                };
                history.push(mean);
                let step = self.step;
                on_report(self, step, &mean)?;
                (sum, n) = (StepLosses::default(), 0.0);
            }
        }
        Ok(history)
    }

    /// The generator's output for one map (eval mode: batch-norm running statistics), normalised per texel,
    /// covered where the input is.
    pub fn enhance(&self, input: &NormalMap) -> Result<NormalMap> {
        enhance_with(&self.gen, input)
    }

    /// Generator weights only: what a model ships.
    pub fn save_generator(&self, path: &Path) -> Result<()> {
        self.gen_vars
            .save(path)
            .map_err(|e| Error::format(path, None, format!("cannot save cGAN weights: {e}")))
    }

    /// Writes a resumable checkpoint (weights, optimiser moments, step) into `dir`, atomically: the files go
    /// to a temporary directory that replaces `dir` once complete.
    pub fn save_checkpoint(&self, dir: &Path) -> Result<()> {
        let tmp = PathBuf::from(format!("{}.tmp-{}", dir.display(), std::process::id()));
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
        }
        crease_core::fsutil::create_dir_all(&tmp)?;
        let f = |e: candle_core::Error| {
            Error::format(&tmp, None, format!("cannot write checkpoint: {e}"))
        };
        self.gen_vars
            .save(tmp.join("generator.safetensors"))
            .map_err(f)?;
        self.disc_vars
            .save(tmp.join("discriminator.safetensors"))
            .map_err(f)?;
        self.opt_g
            .save(&tmp.join("adam_g.safetensors"))
            .map_err(f)?;
        self.opt_d
            .save(&tmp.join("adam_d.safetensors"))
            .map_err(f)?;
        let state = serde_json::json!({ "step": self.step, "config": self.config });
        crease_core::fsutil::write_atomic(&tmp.join("state.json"), state.to_string().as_bytes())?;
        if dir.exists() {
            std::fs::remove_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        std::fs::rename(&tmp, dir).map_err(|e| Error::io(dir, e))
    }

    /// Restores a checkpoint written by [`Cgan::save_checkpoint`] with the same configuration (steps may
    /// differ: a resumed run may train longer).
    pub fn resume(config: CganConfig, dir: &Path) -> Result<Self> {
        let state_path = dir.join("state.json");
        let text = std::fs::read_to_string(&state_path).map_err(|e| Error::io(&state_path, e))?;
        let state: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::format(&state_path, Some(e.line()), e.to_string()))?;
        let saved: CganConfig = serde_json::from_value(state["config"].clone())
            .map_err(|e| Error::format(&state_path, None, format!("config: {e}")))?;
        let same_net = CganConfig {
            steps: config.steps,
            ..saved.clone()
        } == config;
        if !same_net {
            return Err(Error::param(
                "cgan",
                format!(
                    "checkpoint {} was trained with another configuration",
                    dir.display()
                ),
            ));
        }
        let mut g = Cgan::new(config)?;
        let f = |p: PathBuf| {
            move |e: candle_core::Error| {
                Error::format(&p, None, format!("cannot read checkpoint: {e}"))
            }
        };
        g.gen_vars
            .load(dir.join("generator.safetensors"))
            .map_err(f(dir.join("generator.safetensors")))?;
        g.disc_vars
            .load(dir.join("discriminator.safetensors"))
            .map_err(f(dir.join("discriminator.safetensors")))?;
        g.opt_g
            .load(&dir.join("adam_g.safetensors"))
            .map_err(f(dir.join("adam_g.safetensors")))?;
        g.opt_d
            .load(&dir.join("adam_d.safetensors"))
            .map_err(f(dir.join("adam_d.safetensors")))?;
        g.step = state["step"].as_u64().unwrap_or(0) as usize;
        Ok(g)
    }

    /// The generator's current weights as little-endian bytes in name order (determinism checks).
    pub fn generator_bytes(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        for v in self.gen_vars.all_vars_sorted() {
            let vals: Vec<f32> = v
                .as_tensor()
                .flatten_all()
                .map_err(ce)?
                .to_vec1()
                .map_err(ce)?;
            out.extend(vals.iter().flat_map(|x| x.to_le_bytes()));
        }
        Ok(out)
    }
}

/// The manifest's `cgan`: the network, where `apply` uses it, and the held-out figures that decided it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CganSpec {
    pub config: CganConfig,
    /// Map normal error (°) on the held-out training sequence of `apply --coarse`'s maps of random captures,
    /// without and with the generator.
    pub coarse_deg: [f64; 2],
    /// The same of `apply --pose`'s maps (the regression fitted without that sequence).
    pub pose_deg: [f64; 2],
    /// Whether `apply --coarse` / `apply --pose` run the generator: where it beat the maps without it.
    pub use_coarse: bool,
    pub use_pose: bool,
}

/// A generator loaded for inference.
pub struct GeneratorModel {
    pub config: CganConfig,
    gen: Generator,
    _vars: VarMap,
}

impl GeneratorModel {
    pub fn load(config: CganConfig, path: &Path) -> Result<Self> {
        config.validate()?;
        let mut vars = VarMap::new();
        let gen = Generator::new(
            &config,
            VarBuilder::from_varmap(&vars, DType::F32, &Device::Cpu),
        )
        .map_err(ce)?;
        vars.load(path).map_err(|e| {
            Error::format(
                path,
                None,
                format!("not cGAN weights of this model's shape: {e}"),
            )
        })?;
        Ok(GeneratorModel {
            config,
            gen,
            _vars: vars,
        })
    }

    pub fn enhance(&self, input: &NormalMap) -> Result<NormalMap> {
        enhance_with(&self.gen, input)
    }
}

fn enhance_with(gen: &Generator, input: &NormalMap) -> Result<NormalMap> {
    let x = input_tensor(input).map_err(ce)?;
    let y = gen.forward(&x, false).map_err(ce)?;
    let y = y.squeeze(0).map_err(ce)?; // [3, H, W]
    let norm = y
        .sqr()
        .map_err(ce)?
        .sum_keepdim(0)
        .map_err(ce)?
        .sqrt()
        .map_err(ce)?;
    let y = y.broadcast_div(&(norm + 1e-8).map_err(ce)?).map_err(ce)?;
    let planes: Vec<Vec<f32>> = y.flatten_from(1).map_err(ce)?.to_vec2().map_err(ce)?;
    let mut out = input.clone();
    for (k, (n, &covered)) in out.n.iter_mut().zip(&out.covered).enumerate() {
        if covered {
            *n = [planes[0][k], planes[1][k], planes[2][k]];
        }
    }
    Ok(out)
}
