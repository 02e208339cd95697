//! LSTM encoder–decoder pose-to-shape regression (Lähner et al. §3.3; paper: 4 layers × 256, sequences of 3).
//!
//! The encoder reads the control vectors of frames t−L+1..t; its last hidden state, repeated L times, drives
//! the decoder, whose outputs map (one linear layer) to the subspace coefficients of the same frames. Frame t's
//! prediction is the last one. Coefficients are learned in one shared unit ([`output_scale`]), so the training
//! MSE is the vertex MSE up to a constant and the large components count as much as they move the surface.
//! candle (CPU, f32); weights are seeded (see [`crate::nn::seed`]).

use crate::nn::seed::{init_vars, Rng};
use crate::nn::vars::SortedVars;
use crate::regression::kind::RegressorKind;
use candle_core::{DType, Device, Module, Tensor};
use candle_nn::rnn::{LSTMConfig, LSTM, RNN};
use candle_nn::{linear, Linear, Optimizer, VarBuilder, VarMap};
use crease_core::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LstmConfig {
    pub layers: usize,
    pub hidden: usize,
    pub seq_len: usize,
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
    pub seed: u64,
    /// The stored regressor whose prediction the network corrects: the network learns the residual
    /// (truth − that regressor's coefficients) from the pose sequence, its output layer starts at zero, so an
    /// untrained network is exactly that regressor and training only adds what the linear maps cannot
    /// express. `None`: the network predicts the coefficients themselves, as every model before format 7
    /// did (their manifests have no such field).
    #[serde(default)]
    pub residual_of: Option<RegressorKind>,
    /// The residual targets of each training sequence come from the base regressor fitted on the *other*
    /// sequences (cross-fitted, as in stacking), so the network learns the error the base makes on motion it
    /// has not seen, not its smaller in-sample error. Training-only: it does not change how a model runs.
    #[serde(default)]
    pub cross_fit: bool,
    /// Early stopping: the last training sequence (and its reflection) is held out of the network's training,
    /// the held-out loss is measured before the first epoch and after each one, and the weights of the best
    /// epoch are kept (before the first epoch, i.e. the base regressor alone, if no epoch improves on it).
    #[serde(default)]
    pub early_stopping: bool,
}

impl Default for LstmConfig {
    fn default() -> Self {
        LstmConfig {
            layers: 4,
            hidden: 256,
            seq_len: 3,
            epochs: 300,
            batch: 32,
            lr: 1e-3,
            seed: 1,
            // The residual of the blend, cross-fitted, with early stopping: over the three
            // leave-one-sequence-out splits of sleeve-train (bench/results/2026-12-05-deep-regression.md).
            residual_of: Some(RegressorKind::Blend),
            cross_fit: true,
            early_stopping: true,
        }
    }
}

impl LstmConfig {
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("lstm.layers", self.layers),
            ("lstm.hidden", self.hidden),
            ("lstm.seq_len", self.seq_len),
            ("lstm.batch", self.batch),
        ] {
            if v == 0 {
                return Err(Error::param(name, "must be at least 1"));
            }
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error::param("lstm.lr", "must be a positive number"));
        }
        if let Some(r @ (RegressorKind::Lstm | RegressorKind::Kernel)) = self.residual_of {
            return Err(Error::param(
                "lstm.residual_of",
                format!(
                    "the LSTM corrects the linear, autoregressive or blend regressor, not the {}",
                    r.name()
                ),
            ));
        }
        Ok(())
    }
}

fn ce(e: candle_core::Error) -> Error {
    Error::Numeric {
        stage: "lstm".into(),
        msg: e.to_string(),
    }
}

pub struct LstmRegressor {
    pub config: LstmConfig,
    pub in_dim: usize,
    pub out_dim: usize,
    /// Per-coefficient standard deviation the network's outputs are multiplied by.
    pub out_scale: Vec<f64>,
    varmap: VarMap,
    encoder: Vec<LSTM>,
    decoder: Vec<LSTM>,
    head: Linear,
}

/// One training example: the control vectors of L consecutive frames and their coefficients.
pub struct Window {
    pub controls: Vec<Vec<f64>>,
    pub targets: Vec<Vec<f64>>,
}

/// Windows of `len` frames ending at every frame of a sequence (the first frames repeat frame 0, as the
/// control vectors do).
pub fn windows(controls: &[Vec<f64>], targets: &[Vec<f64>], len: usize) -> Vec<Window> {
    (0..controls.len())
        .map(|t| {
            let idx: Vec<usize> = (0..len).map(|i| (t + i + 1).saturating_sub(len)).collect();
            Window {
                controls: idx.iter().map(|&i| controls[i].clone()).collect(),
                targets: idx.iter().map(|&i| targets[i].clone()).collect(),
            }
        })
        .collect()
}

/// The network's output unit, the same for every coefficient: the RMS of all training coefficients.
///
/// The coefficients are orthonormal PCA coordinates, so a squared error summed over them is the squared vertex
/// error; one shared unit keeps the training loss proportional to it. Dividing each coefficient by its own
/// standard deviation (what models before this did) weighs the 200th component, a fold detail no pose
/// predicts, as much as the first: on sleeve-train the loss was then dominated by those components (the
/// linear map itself scores 0.92 of their variance there), the shared hidden state was spent on them, and the
/// network ended at 11.6 mm on held-out motion against 6.0 mm with the shared unit (bench/results/2026-12-05-deep-regression.md).
pub fn output_scale(targets: &[Vec<f64>]) -> Vec<f64> {
    let k = targets.first().map_or(0, Vec::len);
    let n = (targets.len() * k).max(1) as f64;
    let ms = targets.iter().flatten().map(|v| v * v).sum::<f64>() / n;
    vec![ms.sqrt().max(1e-9); k]
}

/// Cosine decay of the learning rate from `top` to `top` / 100 over `epochs`: a rate large enough to make
/// progress early keeps the loss bouncing late.
pub fn cosine_lr(top: f64, epochs: usize) -> impl Fn(usize) -> f64 {
    move |e: usize| {
        let x = e as f64 / epochs.max(1) as f64;
        let low = top / 100.0;
        low + 0.5 * (top - low) * (1.0 + (std::f64::consts::PI * x).cos())
    }
}

impl LstmRegressor {
    pub fn new(
        config: LstmConfig,
        in_dim: usize,
        out_dim: usize,
        out_scale: Vec<f64>,
    ) -> Result<Self> {
        config.validate()?;
        let varmap = VarMap::new();
        let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
        let mut encoder = Vec::new();
        let mut decoder = Vec::new();
        for l in 0..config.layers {
            let d_in = if l == 0 { in_dim } else { config.hidden };
            let cfg = LSTMConfig {
                layer_idx: l,
                ..Default::default()
            };
            encoder.push(LSTM::new(d_in, config.hidden, cfg, vb.pp("encoder")).map_err(ce)?);
            decoder
                .push(LSTM::new(config.hidden, config.hidden, cfg, vb.pp("decoder")).map_err(ce)?);
        }
        let head = linear(config.hidden, out_dim, vb.pp("head")).map_err(ce)?;
        init_vars(&varmap, config.seed, &[]).map_err(ce)?;
        if config.residual_of.is_some() {
            // A residual network starts as the base regressor itself: zero output layer.
            let data = varmap.data().lock().map_err(|_| Error::Numeric {
                stage: "lstm".into(),
                msg: "var map lock poisoned".into(),
            })?;
            for (name, var) in data.iter() {
                if name.starts_with("head.") {
                    var.set(&var.zeros_like().map_err(ce)?).map_err(ce)?;
                }
            }
        }
        Ok(LstmRegressor {
            config,
            in_dim,
            out_dim,
            out_scale,
            varmap,
            encoder,
            decoder,
            head,
        })
    }

    /// [batch, L, in] → [batch, L, out] (normalised coefficients).
    fn forward(&self, x: &Tensor) -> candle_core::Result<Tensor> {
        let mut h = x.clone();
        for layer in &self.encoder {
            let states = layer.seq(&h)?;
            h = layer.states_to_tensor(&states)?;
        }
        let l = self.config.seq_len;
        let last = h.narrow(1, l - 1, 1)?; // [b, 1, hidden]
        let mut d = last.repeat((1, l, 1))?;
        for layer in &self.decoder {
            let states = layer.seq(&d)?;
            d = layer.states_to_tensor(&states)?;
        }
        let (b, _, hd) = d.dims3()?;
        let y = self.head.forward(&d.reshape((b * l, hd))?)?;
        y.reshape((b, l, self.out_dim))
    }

    fn batch_tensors(&self, ws: &[&Window]) -> candle_core::Result<(Tensor, Tensor)> {
        let l = self.config.seq_len;
        let mut xs = Vec::with_capacity(ws.len() * l * self.in_dim);
        let mut ys = Vec::with_capacity(ws.len() * l * self.out_dim);
        for w in ws {
            for i in 0..l {
                xs.extend(w.controls[i].iter().map(|&v| v as f32));
                ys.extend(
                    w.targets[i]
                        .iter()
                        .zip(&self.out_scale)
                        .map(|(&v, s)| (v / s) as f32),
                );
            }
        }
        Ok((
            Tensor::from_vec(xs, (ws.len(), l, self.in_dim), &Device::Cpu)?,
            Tensor::from_vec(ys, (ws.len(), l, self.out_dim), &Device::Cpu)?,
        ))
    }

    /// Trains with AdamW on shuffled mini-batches; `on_epoch(epoch, mean loss)` after each epoch. Returns the
    /// per-epoch losses.
    pub fn train(&mut self, data: &[Window], on_epoch: impl FnMut(usize, f64)) -> Result<Vec<f64>> {
        let lr = self.config.lr;
        self.train_scheduled(data, |_| lr, on_epoch)
    }

    /// [`LstmRegressor::train`] with the learning rate of each epoch from `lr(epoch)`: a constant rate that
    /// is large enough to make progress early keeps the loss bouncing late, so long runs decay it.
    pub fn train_scheduled(
        &mut self,
        data: &[Window],
        lr: impl Fn(usize) -> f64,
        mut on_epoch: impl FnMut(usize, f64),
    ) -> Result<Vec<f64>> {
        self.train_scheduled_with(data, lr, |_, epoch, loss| on_epoch(epoch, loss))
    }

    fn train_scheduled_with(
        &mut self,
        data: &[Window],
        lr: impl Fn(usize) -> f64,
        mut on_epoch: impl FnMut(&Self, usize, f64),
    ) -> Result<Vec<f64>> {
        if data.is_empty() {
            return Err(Error::param("lstm", "no training windows"));
        }
        let mut opt = candle_nn::AdamW::new(
            self.varmap.all_vars_sorted(),
            candle_nn::ParamsAdamW {
                lr: self.config.lr,
                weight_decay: 0.0,
                ..Default::default()
            },
        )
        .map_err(ce)?;
        let mut rng = Rng::new(self.config.seed.wrapping_add(1));
        let mut order: Vec<usize> = (0..data.len()).collect();
        let mut losses = Vec::with_capacity(self.config.epochs);
        for epoch in 0..self.config.epochs {
            opt.set_learning_rate(lr(epoch));
            rng.shuffle(&mut order);
            let (mut sum, mut count) = (0.0, 0usize);
            for chunk in order.chunks(self.config.batch) {
                let ws: Vec<&Window> = chunk.iter().map(|&i| &data[i]).collect();
                let (x, y) = self.batch_tensors(&ws).map_err(ce)?;
                let pred = self.forward(&x).map_err(ce)?;
                let loss = (pred - y)
                    .map_err(ce)?
                    .sqr()
                    .map_err(ce)?
                    .mean_all()
                    .map_err(ce)?;
                opt.backward_step(&loss).map_err(ce)?;
                sum += loss.to_scalar::<f32>().map_err(ce)? as f64 * ws.len() as f64;
                count += ws.len();
            }
            let mean = sum / count as f64;
            if !mean.is_finite() {
                return Err(Error::Numeric {
                    stage: "lstm".into(),
                    msg: format!("training loss became {mean} at epoch {}", epoch + 1),
                });
            }
            losses.push(mean);
            on_epoch(self, epoch, mean);
        }
        Ok(losses)
    }

    /// [`LstmRegressor::train_scheduled`] with early stopping on `validation`: its mean squared error of the
    /// last frame's coefficients (m²) is measured before the first epoch and after every epoch, and the
    /// weights of the best of those are restored at the end. Returns (training losses, held-out errors, best
    /// epoch count: 0 when no epoch beat the untrained network).
    pub fn train_early_stopping(
        &mut self,
        data: &[Window],
        validation: &[Window],
        lr: impl Fn(usize) -> f64,
        mut on_epoch: impl FnMut(usize, f64, f64),
    ) -> Result<(Vec<f64>, Vec<f64>, usize)> {
        if validation.is_empty() {
            return Err(Error::param("lstm", "no validation windows"));
        }
        let mut held = vec![self.held_out_mse(validation)?];
        let mut best = (held[0], 0usize, self.snapshot()?);
        let mut err = None;
        let losses = self.train_scheduled_with(data, lr, |net, epoch, loss| {
            let e = match net.held_out_mse(validation) {
                Ok(e) => e,
                Err(e) => {
                    err.get_or_insert(e);
                    f64::INFINITY
                }
            };
            held.push(e);
            if e < best.0 {
                match net.snapshot() {
                    Ok(s) => best = (e, epoch + 1, s),
                    Err(e) => {
                        err.get_or_insert(e);
                    }
                }
            }
            on_epoch(epoch, loss, e);
        })?;
        if let Some(e) = err {
            return Err(e);
        }
        self.restore(&best.2)?;
        Ok((losses, held, best.1))
    }

    /// Mean squared error (m², per coefficient) of the last frame of each window against its target.
    pub fn held_out_mse(&self, ws: &[Window]) -> Result<f64> {
        let pred = self.predict(ws)?;
        let (mut sum, mut n) = (0.0, 0usize);
        for (p, w) in pred.iter().zip(ws) {
            let t = w.targets.last().map_or(&[][..], |t| t.as_slice());
            for (a, b) in p.iter().zip(t) {
                sum += (a - b).powi(2);
                n += 1;
            }
        }
        Ok(sum / n.max(1) as f64)
    }

    fn snapshot(&self) -> Result<Vec<Tensor>> {
        self.varmap
            .all_vars_sorted()
            .iter()
            .map(|v| v.as_tensor().copy().map_err(ce))
            .collect()
    }

    fn restore(&self, saved: &[Tensor]) -> Result<()> {
        for (v, t) in self.varmap.all_vars_sorted().iter().zip(saved) {
            v.set(t).map_err(ce)?;
        }
        Ok(())
    }

    /// Coefficients of the last frame of each window.
    pub fn predict(&self, ws: &[Window]) -> Result<Vec<Vec<f64>>> {
        let mut out = Vec::with_capacity(ws.len());
        for chunk in ws.chunks(256) {
            let refs: Vec<&Window> = chunk.iter().collect();
            let (x, _) = self.batch_tensors(&refs).map_err(ce)?;
            let y = self.forward(&x).map_err(ce)?;
            let l = self.config.seq_len;
            let last = y.narrow(1, l - 1, 1).map_err(ce)?.squeeze(1).map_err(ce)?;
            let rows: Vec<Vec<f32>> = last.to_vec2().map_err(ce)?;
            for r in rows {
                out.push(
                    r.iter()
                        .zip(&self.out_scale)
                        .map(|(&v, s)| v as f64 * s)
                        .collect(),
                );
            }
        }
        Ok(out)
    }

    /// The coefficients of every frame of a sequence from its control vectors: the network's prediction, plus
    /// `base` (the base regressor's coefficients, required when the network is a residual one).
    pub fn predict_sequence(
        &self,
        controls: &[Vec<f64>],
        base: Option<&[Vec<f64>]>,
    ) -> Result<Vec<Vec<f64>>> {
        let dummy = vec![vec![0.0; self.out_dim]; controls.len()];
        let mut out = self.predict(&windows(controls, &dummy, self.config.seq_len))?;
        match (self.config.residual_of, base) {
            (None, _) => {}
            (Some(_), Some(base)) if base.len() == out.len() => {
                for (o, b) in out.iter_mut().zip(base) {
                    for (x, y) in o.iter_mut().zip(b) {
                        *x += y;
                    }
                }
            }
            (Some(kind), _) => {
                return Err(Error::param(
                    "lstm",
                    format!(
                        "a residual LSTM needs the {} regressor's coefficients of every frame",
                        kind.name()
                    ),
                ))
            }
        }
        Ok(out)
    }

    /// Saves the weights (safetensors).
    pub fn save(&self, path: &Path) -> Result<()> {
        self.varmap
            .save(path)
            .map_err(|e| Error::format(path, None, format!("cannot save LSTM weights: {e}")))
    }

    /// Loads weights saved by [`LstmRegressor::save`] into a network of the same shape.
    pub fn load(
        config: LstmConfig,
        in_dim: usize,
        out_dim: usize,
        out_scale: Vec<f64>,
        path: &Path,
    ) -> Result<Self> {
        let mut net = LstmRegressor::new(config, in_dim, out_dim, out_scale)?;
        net.varmap.load(path).map_err(|e| {
            Error::format(
                path,
                None,
                format!("not LSTM weights of this model's shape: {e}"),
            )
        })?;
        Ok(net)
    }
}
