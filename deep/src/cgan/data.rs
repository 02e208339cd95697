//! Training data of the cGAN (§4.1): per frame, the vertex normals of an input shape (what `apply` would draw
//! from it) and of the detailed frame itself, drawn into crops of the model's UV layout as batches are made.
//!
//! Keeping per-vertex normals instead of whole maps holds a training sequence in a few megabytes (a 256² map
//! pair per frame would be about 2 MB), and a crop is rasterised only when a batch needs it.

use crate::cgan::{Batch, IN_CHANNELS};
use crate::detail::{training_capture, DetailModel};
use crate::nn::seed::Rng;
use crate::normal_maps::raster::TexelMap;
use candle_core::{Device, Tensor};
use crease_core::mesh::{geometry, Frame, Topology, NONE};
use crease_core::shape::mean_edge_length;
use crease_core::vec3::V3;
use rayon::prelude::*;

/// Offset of the cGAN's capture draws from the detail model's own (so the generator sees captures the
/// detail model was not fitted on).
const DRAW_OFFSET: usize = 1000;
/// Share of a crop the surface must cover for the crop to be drawn.
const MIN_CROP_COVERAGE: f64 = 0.25;

/// One frame: input and target vertex normals, and the index of the previous frame's sample (itself for a
/// sequence's first frame), whose target is the temporal term's.
pub struct Sample {
    pub input: Vec<[f32; 3]>,
    pub target: Vec<[f32; 3]>,
    pub prev: usize,
}

fn f32s(n: &[V3]) -> Vec<[f32; 3]> {
    n.iter()
        .map(|v| [v[0] as f32, v[1] as f32, v[2] as f32])
        .collect()
}

/// Samples of every training frame of a set of sequences, and the crops they may be drawn in.
pub struct TrainingSet<'a> {
    pub topo: &'a Topology,
    pub texels: &'a TexelMap,
    pub samples: Vec<Sample>,
    /// Top-left corners of the crops that are covered enough, for the crop size the set was made for.
    origins: Vec<(usize, usize)>,
    crop: usize,
}

impl<'a> TrainingSet<'a> {
    /// A set from (input shape's normals, target normals) per frame, sequence by sequence.
    pub fn new(
        topo: &'a Topology,
        texels: &'a TexelMap,
        sequences: Vec<Vec<(Vec<V3>, Vec<V3>)>>,
        crop: usize,
    ) -> Self {
        let mut samples = Vec::new();
        for seq in sequences {
            let first = samples.len();
            for (t, (input, target)) in seq.into_iter().enumerate() {
                samples.push(Sample {
                    input: f32s(&input),
                    target: f32s(&target),
                    prev: if t == 0 { first } else { first + t - 1 },
                });
            }
        }
        let (w, h) = (texels.width, texels.height);
        let mut origins = Vec::new();
        let stride = (crop / 8).max(1);
        for y in (0..=h.saturating_sub(crop)).step_by(stride) {
            for x in (0..=w.saturating_sub(crop)).step_by(stride) {
                let covered = (y..y + crop)
                    .map(|r| {
                        (x..x + crop)
                            .filter(|&c| texels.tri[r * w + c] != NONE)
                            .count()
                    })
                    .sum::<usize>();
                if covered as f64 >= MIN_CROP_COVERAGE * (crop * crop) as f64 {
                    origins.push((x, y));
                }
            }
        }
        TrainingSet {
            topo,
            texels,
            samples,
            origins,
            crop,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty() || self.origins.is_empty()
    }

    /// A batch of `b` random crops of random samples.
    pub fn batch(&self, rng: &mut Rng, b: usize, crop: usize) -> candle_core::Result<Batch> {
        if crop != self.crop || self.is_empty() {
            return Err(candle_core::Error::Msg(format!(
                "no {crop}² crop of the maps is covered enough to train on"
            )));
        }
        let area = crop * crop;
        let mut x = Vec::with_capacity(b * IN_CHANNELS * area);
        let mut y = Vec::with_capacity(b * 3 * area);
        let mut yp = Vec::with_capacity(b * 3 * area);
        let mut m = Vec::with_capacity(b * area);
        for _ in 0..b {
            let s = &self.samples[(rng.next_u64() % self.samples.len() as u64) as usize];
            let (ox, oy) = self.origins[(rng.next_u64() % self.origins.len() as u64) as usize];
            let prev = &self.samples[s.prev].target;
            let (ci, ct, cp, cm) = (
                self.crop_of(&s.input, ox, oy),
                self.crop_of(&s.target, ox, oy),
                self.crop_of(prev, ox, oy),
                self.coverage(ox, oy),
            );
            x.extend_from_slice(&ci);
            x.extend_from_slice(&cm);
            y.extend_from_slice(&ct);
            yp.extend_from_slice(&cp);
            m.extend_from_slice(&cm);
        }
        let d = &Device::Cpu;
        Ok(Batch {
            input: Tensor::from_vec(x, (b, IN_CHANNELS, crop, crop), d)?,
            target: Tensor::from_vec(y, (b, 3, crop, crop), d)?,
            prev_target: Tensor::from_vec(yp, (b, 3, crop, crop), d)?,
            mask: Tensor::from_vec(m, (b, 1, crop, crop), d)?,
        })
    }

    /// Channel-major [3, crop, crop] of the normals interpolated over the crop (unit length, 0 off the surface).
    fn crop_of(&self, normals: &[[f32; 3]], ox: usize, oy: usize) -> Vec<f32> {
        let (c, w) = (self.crop, self.texels.width);
        let mut out = vec![0.0f32; 3 * c * c];
        for r in 0..c {
            for q in 0..c {
                let k = (oy + r) * w + ox + q;
                let t = self.texels.tri[k];
                if t == NONE {
                    continue;
                }
                let tri = self.topo.triangles()[t as usize];
                let b = self.texels.bary[k];
                let mut n = [0.0f32; 3];
                for (i, &v) in tri.iter().enumerate() {
                    for (a, x) in n.iter_mut().zip(normals[v as usize]) {
                        *a += b[i] * x;
                    }
                }
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-12);
                for (ch, a) in n.iter().enumerate() {
                    out[ch * c * c + r * c + q] = a / l;
                }
            }
        }
        out
    }

    fn coverage(&self, ox: usize, oy: usize) -> Vec<f32> {
        let (c, w) = (self.crop, self.texels.width);
        let mut out = vec![0.0f32; c * c];
        for r in 0..c {
            for q in 0..c {
                if self.texels.tri[(oy + r) * w + ox + q] != NONE {
                    out[r * c + q] = 1.0;
                }
            }
        }
        out
    }
}

/// (input normals, target normals) of every frame of one sequence: the input is the detail model's normals on
/// a random capture of the frame (`seq` and `seed` seed the draws; a guarded fallback gives the capture's own
/// normals, as `apply` would), the target the frame's own.
pub fn capture_normals(
    topo: &Topology,
    fine: &[Frame],
    detail: &DetailModel,
    seed: u64,
    seq: usize,
) -> Vec<(Vec<V3>, Vec<V3>)> {
    fine.par_iter()
        .enumerate()
        .map(|(t, f)| {
            let h = mean_edge_length(topo, f);
            let (c, _) = training_capture(topo, f, h, seed, seq, t, DRAW_OFFSET);
            let (n, _) = detail.normals(topo, &c, h, detail.surface_gate(topo, [c.as_slice()]));
            (n, geometry::vertex_normals(topo, f))
        })
        .collect()
}

/// (input normals, target normals) of frames whose input shapes are given (a reconstruction, a regression).
pub fn shape_normals(topo: &Topology, inputs: &[Frame], fine: &[Frame]) -> Vec<(Vec<V3>, Vec<V3>)> {
    inputs
        .par_iter()
        .zip(fine.par_iter())
        .map(|(c, f)| {
            (
                geometry::vertex_normals(topo, c),
                geometry::vertex_normals(topo, f),
            )
        })
        .collect()
}
