//! The conditional GAN of Lähner et al. §4.2 (pix2pix-style): a U-Net generator with skip connections and a
//! 70×70 PatchGAN discriminator, trained with L1·100 + temporal·50 + GAN·1 (Eq. 4), batch norm and Adam.
//!
//! Input: the coarse world-space normal map plus its coverage (4 channels); output: the detailed map (3
//! channels, tanh, normalised per texel afterwards). The data and temporal terms are taken over covered texels
//! only (the grey "no information" areas of the paper's maps carry no signal), and the temporal term
//! |Σ (G(x_t) − y_{t−1})| is divided by the texel count so that its weight 50 means the same at every
//! resolution. Dropout (pix2pix's noise) is left out: inference must be deterministic, since the cluster's
//! output has to match a single-node run byte for byte.
//!
//! At 256² with 64 filters the generator is 8 + 8 layers as in the paper; smaller resolutions use
//! log2(resolution) layers per side, so the innermost feature map is always 1×1.
//!
//! The generator is residual by default ([`CganConfig::residual`]): it predicts a correction that is added to
//! the input normals, and its last layer starts at zero, so an untrained model returns the input map and
//! training can only add detail. The coarse map already carries the garment's large shape, and the cGAN's job
//! in the paper is to add the wrinkles; a generator that has to rebuild the whole map from noise started (and,
//! after one epoch, stayed) far worse than its own input.

pub mod data;
pub mod enhance;
pub mod gemm_conv;

use crate::nn::adam::Adam;
use crate::nn::seed::{init_vars, Rng};
use crate::normal_maps::NormalMap;
use crate::regression::lstm::SortedVars;
use candle_core::{DType, Device, ModuleT, Tensor};
use candle_nn::{
    batch_norm, conv2d, conv_transpose2d, BatchNorm, BatchNormConfig, Conv2d, Conv2dConfig,
    ConvTranspose2d, ConvTranspose2dConfig, Module, VarBuilder, VarMap,
};
use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const IN_CHANNELS: usize = 4;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CganConfig {
    pub resolution: usize,
    /// Filters of the first generator layer (paper: 64); doubled per layer up to 8×.
    pub filters: usize,
    /// Filters of the first discriminator layer.
    pub disc_filters: usize,
    pub w_l1: f64,
    pub w_temporal: f64,
    pub w_gan: f64,
    pub lr: f64,
    pub beta1: f64,
    pub epochs: usize,
    pub batch: usize,
    pub seed: u64,
    /// Output = input normals + G(input) (last layer initialised to zero) instead of G(input) alone. Absent in
    /// the manifests of model format 2 and older, whose generators are not residual: it then reads as false.
    #[serde(default)]
    pub residual: bool,
}

impl Default for CganConfig {
    fn default() -> Self {
        CganConfig {
            resolution: 256,
            filters: 64,
            disc_filters: 64,
            w_l1: 100.0,
            w_temporal: 50.0,
            w_gan: 1.0,
            lr: 2e-4,
            beta1: 0.5,
            epochs: 20,
            batch: 1,
            seed: 1,
            residual: true,
        }
    }
}

impl CganConfig {
    pub fn validate(&self) -> Result<()> {
        if !self.resolution.is_power_of_two() || !(16..=1024).contains(&self.resolution) {
            return Err(Error::param(
                "cgan.resolution",
                format!("{} is not a power of two in 16..=1024", self.resolution),
            ));
        }
        if self.filters == 0 || self.disc_filters == 0 || self.batch == 0 {
            return Err(Error::param("cgan", "filters and batch must be at least 1"));
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

    /// Layers per U-Net side: log2(resolution), at most 8 (the paper's 2 × 8 at 256²).
    pub fn depth(&self) -> usize {
        (self.resolution.trailing_zeros() as usize).min(8)
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
    residual: bool,
}

impl Generator {
    pub fn new(cfg: &CganConfig, vb: VarBuilder) -> candle_core::Result<Self> {
        let depth = cfg.depth();
        let f = cfg.filters;
        let ch: Vec<usize> = (0..depth).map(|i| (f << i.min(3)).min(8 * f)).collect();
        let mut enc = Vec::new();
        for i in 0..depth {
            let cin = if i == 0 { IN_CHANNELS } else { ch[i - 1] };
            let conv = conv2d(cin, ch[i], 4, down_cfg(), vb.pp(format!("g.enc{i}")))?;
            // No norm on the first layer (pix2pix) nor on the 1×1 innermost one (its batch statistics are
            // degenerate at batch size 1).
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
        Ok(Generator {
            enc,
            dec,
            residual: cfg.residual,
        })
    }

    /// The variable names of the last decoder layer, which a residual generator starts at zero.
    fn last_layer_names(cfg: &CganConfig) -> [String; 2] {
        let j = cfg.depth() - 1;
        [format!("g.dec{j}.weight"), format!("g.dec{j}.bias")]
    }

    /// [b, 4, H, W] → [b, 3, H, W]: in (−1, 1), or for a residual generator the input normals plus a
    /// correction in (−1, 1), zero where the input is not covered (the target is zero there too, so the
    /// discriminator cannot tell real from fake by the gutter).
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
        if !self.residual {
            return Ok(out);
        }
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
    /// PatchGAN: three stride-2 and two stride-1 4×4 convolutions, a 70×70 receptive field per output logit.
    /// Maps smaller than 32² get fewer stride-2 layers, so at least a 2×2 grid of patches remains.
    pub fn new(cfg: &CganConfig, vb: VarBuilder) -> candle_core::Result<Self> {
        let f = cfg.disc_filters;
        let downs = (cfg.resolution.trailing_zeros() as usize)
            .saturating_sub(2)
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

/// Sets the named variables to zero (the residual generator's last layer: it starts as the identity).
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

/// One training pair: the coarse map (input), the detailed map (target) and the previous frame's detailed map.
#[derive(Clone)]
pub struct Sample {
    pub input: NormalMap,
    pub target: NormalMap,
    pub prev_target: NormalMap,
}

/// [4, H, W]: normals then coverage.
pub fn input_tensor(maps: &[&NormalMap]) -> candle_core::Result<Tensor> {
    let (w, h) = (maps[0].width, maps[0].height);
    let mut v = Vec::with_capacity(maps.len() * IN_CHANNELS * w * h);
    for m in maps {
        for c in 0..3 {
            v.extend(
                m.n.iter()
                    .zip(&m.covered)
                    .map(|(n, &cov)| if cov { n[c] } else { 0.0 }),
            );
        }
        v.extend(m.covered.iter().map(|&c| if c { 1.0f32 } else { 0.0 }));
    }
    Tensor::from_vec(v, (maps.len(), IN_CHANNELS, h, w), &Device::Cpu)
}

/// ([b, 3, H, W] normals, [b, 1, H, W] coverage).
fn target_tensor(maps: &[&NormalMap]) -> candle_core::Result<(Tensor, Tensor)> {
    let (w, h) = (maps[0].width, maps[0].height);
    let mut v = Vec::with_capacity(maps.len() * 3 * w * h);
    let mut m = Vec::with_capacity(maps.len() * w * h);
    for map in maps {
        for c in 0..3 {
            v.extend(
                map.n
                    .iter()
                    .zip(&map.covered)
                    .map(|(n, &cov)| if cov { n[c] } else { 0.0 }),
            );
        }
        m.extend(map.covered.iter().map(|&c| if c { 1.0f32 } else { 0.0 }));
    }
    Ok((
        Tensor::from_vec(v, (maps.len(), 3, h, w), &Device::Cpu)?,
        Tensor::from_vec(m, (maps.len(), 1, h, w), &Device::Cpu)?,
    ))
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
    /// Epochs completed (for resuming).
    pub epoch: usize,
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
        if config.residual {
            zero_vars(&gen_vars, &Generator::last_layer_names(&config)).map_err(ce)?;
        }
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
            epoch: 0,
        })
    }

    /// One optimisation step on a batch (discriminator, then generator).
    pub fn step(&mut self, batch: &[&Sample]) -> Result<StepLosses> {
        let cfg = &self.config;
        let inputs: Vec<&NormalMap> = batch.iter().map(|s| &s.input).collect();
        let targets: Vec<&NormalMap> = batch.iter().map(|s| &s.target).collect();
        let prevs: Vec<&NormalMap> = batch.iter().map(|s| &s.prev_target).collect();
        let x = input_tensor(&inputs).map_err(ce)?;
        let (y, mask) = target_tensor(&targets).map_err(ce)?;
        let (y_prev, _) = target_tensor(&prevs).map_err(ce)?;
        let fake = self.gen.forward(&x, true).map_err(ce)?;
        // Discriminator.
        let d_real = self.disc.forward(&x, &y, true).map_err(ce)?;
        let d_fake = self.disc.forward(&x, &fake.detach(), true).map_err(ce)?;
        let loss_d = ((bce_logits(&d_real, 1.0).map_err(ce)?
            + bce_logits(&d_fake, 0.0).map_err(ce)?)
        .map_err(ce)?
            * 0.5)
            .map_err(ce)?;
        let gd = loss_d.backward().map_err(ce)?;
        self.opt_d.step(&gd).map_err(ce)?;
        // Generator.
        let d_gen = self.disc.forward(&x, &fake, true).map_err(ce)?;
        let gan = bce_logits(&d_gen, 1.0).map_err(ce)?;
        let count =
            (mask.sum_all().map_err(ce)?.to_scalar::<f32>().map_err(ce)? as f64 * 3.0).max(1.0);
        let mask3 = mask.broadcast_as(fake.shape()).map_err(ce)?;
        let l1 = (((&fake - &y).map_err(ce)?.abs().map_err(ce)? * &mask3)
            .map_err(ce)?
            .sum_all()
            .map_err(ce)?
            / count)
            .map_err(ce)?;
        let temporal = (((&fake - &y_prev).map_err(ce)? * &mask3)
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

    /// Trains until `config.epochs` epochs are done (continuing from `self.epoch`), shuffling with a seed per
    /// epoch so a resumed run sees the same batches as an uninterrupted one. After each epoch `on_epoch`
    /// gets the epoch's mean losses and may write a checkpoint.
    pub fn train(
        &mut self,
        data: &[Sample],
        mut on_step: impl FnMut(usize, usize, &StepLosses),
        mut on_epoch: impl FnMut(&mut Cgan, usize, &StepLosses) -> Result<()>,
    ) -> Result<Vec<StepLosses>> {
        if data.is_empty() {
            return Err(Error::param("cgan", "no training samples"));
        }
        let mut history = Vec::new();
        while self.epoch < self.config.epochs {
            let mut order: Vec<usize> = (0..data.len()).collect();
            Rng::new(self.config.seed ^ (0xE90C + self.epoch as u64)).shuffle(&mut order);
            let mut sum = StepLosses::default();
            let mut n = 0.0;
            for (i, chunk) in order.chunks(self.config.batch).enumerate() {
                let batch: Vec<&Sample> = chunk.iter().map(|&k| &data[k]).collect();
                let l = self.step(&batch)?;
                on_step(self.epoch, i, &l);
                sum.l1 += l.l1;
                sum.temporal += l.temporal;
                sum.gan += l.gan;
                sum.disc += l.disc;
                n += 1.0;
            }
            let mean = StepLosses {
                l1: sum.l1 / n,
                temporal: sum.temporal / n,
                gan: sum.gan / n,
                disc: sum.disc / n,
            };
            self.epoch += 1;
            history.push(mean);
            let e = self.epoch;
            on_epoch(self, e, &mean)?;
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

    /// Writes a resumable checkpoint (weights, optimiser moments, epoch) into `dir`, atomically: the files go
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
        let state = serde_json::json!({ "epoch": self.epoch, "config": self.config });
        crease_core::fsutil::write_atomic(&tmp.join("state.json"), state.to_string().as_bytes())?;
        if dir.exists() {
            std::fs::remove_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        std::fs::rename(&tmp, dir).map_err(|e| Error::io(dir, e))
    }

    /// Restores a checkpoint written by [`Cgan::save_checkpoint`] with the same configuration (epochs may
    /// differ: a resumed run may train longer).
    pub fn resume(config: CganConfig, dir: &Path) -> Result<Self> {
        let state_path = dir.join("state.json");
        let text = std::fs::read_to_string(&state_path).map_err(|e| Error::io(&state_path, e))?;
        let state: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::format(&state_path, Some(e.line()), e.to_string()))?;
        let saved: CganConfig = serde_json::from_value(state["config"].clone())
            .map_err(|e| Error::format(&state_path, None, format!("config: {e}")))?;
        let same_net = CganConfig {
            epochs: config.epochs,
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
        g.epoch = state["epoch"].as_u64().unwrap_or(0) as usize;
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
    let x = input_tensor(&[input]).map_err(ce)?;
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
