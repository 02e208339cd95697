//! Seeded randomness for training. candle's CPU generator cannot be seeded, so every parameter is
//! (re)initialised here from a SplitMix64 stream taken in name order: the same seed gives the same weights,
//! hence (with deterministic batching) the same model bytes.

use candle_core::{Device, Tensor};
use candle_nn::VarMap;

/// SplitMix64: tiny, fast and good enough to draw initial weights and shuffle batches.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Fisher–Yates shuffle.
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = (self.next_u64() % (i as u64 + 1)) as usize;
            v.swap(i, j);
        }
    }
}

/// Re-draws every variable of `varmap` from `seed`: biases and batch-norm shifts/means zero, batch-norm scales
/// and variances one, weights uniform in ±1/√fan_in (PyTorch's default bound), or N(0, 0.02) for the names
/// listed in `gaussian` (pix2pix's convolution init).
pub fn init_vars(
    varmap: &VarMap,
    seed: u64,
    gaussian_prefixes: &[&str],
) -> candle_core::Result<()> {
    let data = varmap
        .data()
        .lock()
        .map_err(|_| candle_core::Error::Msg("var map lock poisoned".into()))?;
    let mut names: Vec<&String> = data.keys().collect();
    names.sort();
    let mut rng = Rng::new(seed);
    for name in names {
        let var = &data[name];
        let dims = var.dims().to_vec();
        let count: usize = dims.iter().product();
        let leaf = name.rsplit('.').next().unwrap_or(name);
        let values: Vec<f32> = if leaf.starts_with("bias") || leaf == "running_mean" {
            vec![0.0; count]
        } else if leaf == "running_var" || (name.contains("bn") && leaf == "weight") {
            vec![1.0; count]
        } else if gaussian_prefixes.iter().any(|p| name.starts_with(p)) {
            (0..count)
                .map(|_| {
                    let (u1, u2) = (rng.uniform().max(1e-12), rng.uniform());
                    (0.02 * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
                })
                .collect()
        } else {
            let fan_in: usize = dims.iter().skip(1).product::<usize>().max(1);
            let b = 1.0 / (fan_in as f64).sqrt();
            (0..count)
                .map(|_| ((rng.uniform() * 2.0 - 1.0) * b) as f32)
                .collect()
        };
        var.set(&Tensor::from_vec(values, dims.as_slice(), &Device::Cpu)?)?;
    }
    Ok(())
}
