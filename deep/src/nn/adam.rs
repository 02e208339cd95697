//! Adam with its moments in the open, so a checkpoint can store them and a resumed run continues exactly where
//! it stopped (candle's own optimizers keep their state private).

use candle_core::backprop::GradStore;
use candle_core::{Device, Tensor, Var};
use std::collections::HashMap;
use std::path::Path;

pub struct Adam {
    names: Vec<String>,
    vars: Vec<Var>,
    m: Vec<Tensor>,
    v: Vec<Tensor>,
    pub step_t: usize,
    pub lr: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub eps: f64,
}

impl Adam {
    /// `named` in a fixed (sorted) order.
    pub fn new(named: Vec<(String, Var)>, lr: f64, beta1: f64) -> candle_core::Result<Self> {
        let mut m = Vec::new();
        let mut v = Vec::new();
        for (_, var) in &named {
            m.push(var.zeros_like()?);
            v.push(var.zeros_like()?);
        }
        let (names, vars) = named.into_iter().unzip();
        Ok(Adam {
            names,
            vars,
            m,
            v,
            step_t: 0,
            lr,
            beta1,
            beta2: 0.999,
            eps: 1e-8,
        })
    }

    pub fn step(&mut self, grads: &GradStore) -> candle_core::Result<()> {
        self.step_t += 1;
        let (b1, b2) = (self.beta1, self.beta2);
        let c1 = 1.0 / (1.0 - b1.powi(self.step_t as i32));
        let c2 = 1.0 / (1.0 - b2.powi(self.step_t as i32));
        for i in 0..self.vars.len() {
            if let Some(g) = grads.get(&self.vars[i]) {
                // Gradients are computed from the step's graph and would keep it (every activation of the
                // forward pass) alive through the moments, step after step: the moments hold values only.
                let g = g.detach();
                self.m[i] = ((&self.m[i] * b1)? + (&g * (1.0 - b1))?)?.detach();
                self.v[i] = ((&self.v[i] * b2)? + (g.sqr()? * (1.0 - b2))?)?.detach();
                let upd = ((&self.m[i] * c1)? / (((&self.v[i] * c2)?.sqrt()? + self.eps)?))?;
                let next = (self.vars[i].as_tensor() - (upd * self.lr)?)?;
                self.vars[i].set(&next)?;
            }
        }
        Ok(())
    }

    pub fn save(&self, path: &Path) -> candle_core::Result<()> {
        let mut map: HashMap<String, Tensor> = HashMap::new();
        for (i, n) in self.names.iter().enumerate() {
            map.insert(format!("m.{n}"), self.m[i].clone());
            map.insert(format!("v.{n}"), self.v[i].clone());
        }
        map.insert(
            "step".into(),
            Tensor::new(&[self.step_t as f32], &Device::Cpu)?,
        );
        candle_core::safetensors::save(&map, path)
    }

    pub fn load(&mut self, path: &Path) -> candle_core::Result<()> {
        let map = candle_core::safetensors::load(path, &Device::Cpu)?;
        for (i, n) in self.names.iter().enumerate() {
            let get = |k: String| {
                map.get(&k)
                    .cloned()
                    .ok_or_else(|| candle_core::Error::Msg(format!("checkpoint lacks `{k}`")))
            };
            self.m[i] = get(format!("m.{n}"))?;
            self.v[i] = get(format!("v.{n}"))?;
        }
        let s = map
            .get("step")
            .ok_or_else(|| candle_core::Error::Msg("checkpoint lacks `step`".into()))?;
        self.step_t = s.to_vec1::<f32>()?[0] as usize;
        Ok(())
    }
}
