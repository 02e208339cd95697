//! A trained DeepWrinkles model on disk: a directory of `.npy` arrays, network weights (safetensors) and a
//! `manifest.json` that names the format version and every file with its size and FNV-1a hash.
//!
//! A model is written into a temporary sibling directory and renamed into place only after the manifest (the
//! last file) is written, so a crash or full disk never leaves a half-written model under the final name; a
//! loader checks the version first and each file against the manifest, so a model from another version or a
//! damaged file is a clear error, never a silently different model.

use crate::detail::{DetailModel, DetailSpec};
use crate::normal_maps::uv::{write_obj_with_uv, UvLayout};
use crate::regression::autoregress::{AutoregressiveLinear, ShapeHistory};
use crate::regression::kernel::{KernelRegression, KernelSpec};
use crate::regression::linear::LinearRegression;
use crate::regression::lstm::{LstmConfig, LstmRegressor};
use crate::regression::pose::ControlSpec;
use crate::subspace::Subspace;
use crease_core::mesh::Topology;
use crease_core::{npy, Error, Result};
use faer::Mat;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Format written by this build. Bump when the layout or meaning of any file changes.
/// Version 9 replaced the detail filter by the detail model learned from the model's own random captures
/// (`detail` in the manifest, `detail.npy`: conditioned weights and a guard) and the pose-only shape's
/// smoothing by a cotangent diffusion (`pose_lowpass`). Older models held a filter and a smoothing tied to one
/// data set's capture; they are refused by version, to be retrained. Version 11 weighs the kernel regression's
/// input numbers (`kernel.weights`; `kernel_inputs.npy` holds the weighted centres): a version 10 model reads as
/// uniform weights, and an older build must not read a version 11 one as if its centres were unweighted.
pub const MODEL_VERSION: u32 = 11;
/// Oldest format this build reads.
pub const MODEL_VERSION_MIN: u32 = 9;
pub const MODEL_FORMAT: &str = "crease-deep-model";

pub use crate::regression::kind::RegressorKind;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileEntry {
    pub bytes: u64,
    pub fnv1a64: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub version: u32,
    pub vertices: usize,
    pub triangles: usize,
    pub k: usize,
    pub control: ControlSpec,
    /// Which regressor `apply --pose` uses; the linear one is always present.
    pub regressor: RegressorKind,
    pub lstm: Option<LstmConfig>,
    /// The autoregressive regressor's shape history (its arrays are `ar_scale.npy` and `ar_start.npy`, its
    /// weights `autoregressive.npy`); absent in version 1 models.
    #[serde(default)]
    pub autoregressive: Option<ArSpec>,
    /// The blend regressor's weight and how it was chosen; absent before version 4.
    #[serde(default)]
    pub blend: Option<crate::regression::blend::BlendSpec>,
    /// The kernel regression's width, ridge and standardisation (centres in `kernel_inputs.npy`, dual weights
    /// in `kernel_dual.npy`, mean coefficients in `kernel_offset.npy`); absent before version 10.
    #[serde(default)]
    pub kernel: Option<KernelSpec>,
    /// The detail model `apply --coarse` runs ([`crate::detail`], weights in `detail.npy`).
    pub detail: DetailSpec,
    /// How `apply --pose` low-passes the regression's shape ([`crate::regression::pose_lowpass`]).
    pub pose_lowpass: crate::regression::pose_lowpass::PoseLowpass,
    /// The LSTM's output unit per coefficient: one shared value (the RMS of all training coefficients,
    /// [`crate::regression::lstm::output_scale`]) since this session; each coefficient's own standard deviation in models
    /// trained before, which load and run with their stored units unchanged.
    pub coeff_scale: Vec<f64>,
    /// Normal map resolution the model (and its cGAN) works at.
    pub resolution: usize,
    /// The cGAN, when the model has one (`cgan.safetensors`): its configuration and where `apply` uses it.
    pub cgan: Option<crate::cgan::CganSpec>,
    /// Free-form training summary (data, losses, timings) for people.
    pub training: serde_json::Value,
    pub files: BTreeMap<String, FileEntry>,
}

/// The scalar part of the autoregressive regressor's [`ShapeHistory`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArSpec {
    /// Leading coefficients fed back.
    pub k_state: usize,
    /// Earlier frames fed back (α_{t−1} … α_{t−order}).
    pub order: usize,
    /// Bound of a fed-back coefficient, in training standard deviations.
    pub clip: f64,
}

impl ArSpec {
    pub fn of(h: &ShapeHistory) -> Self {
        ArSpec {
            k_state: h.k_state,
            order: h.order,
            clip: h.clip,
        }
    }
}

pub struct Model {
    pub manifest: Manifest,
    pub topology: Arc<Topology>,
    pub layout: UvLayout,
    pub subspace: Subspace,
    pub linear: LinearRegression,
    pub autoregressive: Option<AutoregressiveLinear>,
    pub lstm: Option<LstmRegressor>,
    pub kernel: Option<KernelRegression>,
    /// The detail model `apply --coarse` runs.
    pub detail: DetailModel,
    /// Directory the model was loaded from (for components that load lazily, like the cGAN).
    pub dir: PathBuf,
}

pub fn fnv1a64(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Collects a model's files in a staging directory, then publishes them atomically.
pub struct ModelWriter {
    final_dir: PathBuf,
    staging: PathBuf,
    files: BTreeMap<String, FileEntry>,
}

impl ModelWriter {
    pub fn new(final_dir: &Path) -> Result<Self> {
        let parent = final_dir
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        crease_core::fsutil::create_dir_all(parent)?;
        let name = final_dir.file_name().ok_or_else(|| {
            Error::param(
                "out",
                format!("{} is not a directory name", final_dir.display()),
            )
        })?;
        let staging = parent.join(format!(
            ".{}.partial-{}",
            name.to_string_lossy(),
            std::process::id()
        ));
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        }
        crease_core::fsutil::create_dir_all(&staging)?;
        Ok(ModelWriter {
            final_dir: final_dir.to_path_buf(),
            staging,
            files: BTreeMap::new(),
        })
    }

    /// Path inside the staging directory for a file a library writes itself (then [`ModelWriter::record`]).
    pub fn staging_path(&self, name: &str) -> PathBuf {
        self.staging.join(name)
    }

    pub fn record(&mut self, name: &str) -> Result<()> {
        let path = self.staging.join(name);
        let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
        self.files.insert(
            name.to_string(),
            FileEntry {
                bytes: bytes.len() as u64,
                fnv1a64: fnv1a64(&bytes),
            },
        );
        Ok(())
    }

    pub fn put(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        crease_core::fsutil::write_atomic(&self.staging.join(name), bytes)?;
        self.record(name)
    }

    /// Writes the manifest last and renames the staging directory to the final name (replacing an older model
    /// there only now, when the new one is whole).
    pub fn publish(mut self, mut manifest: Manifest) -> Result<PathBuf> {
        manifest.files = std::mem::take(&mut self.files);
        let text = serde_json::to_string_pretty(&manifest)
            .map_err(|e| Error::param("manifest", e.to_string()))?;
        crease_core::fsutil::write_atomic(&self.staging.join("manifest.json"), text.as_bytes())?;
        if self.final_dir.exists() {
            let old = self.staging.with_extension("old");
            std::fs::rename(&self.final_dir, &old).map_err(|e| Error::io(&self.final_dir, e))?;
            std::fs::rename(&self.staging, &self.final_dir)
                .map_err(|e| Error::io(&self.final_dir, e))?;
            let _ = std::fs::remove_dir_all(&old);
        } else {
            std::fs::rename(&self.staging, &self.final_dir)
                .map_err(|e| Error::io(&self.final_dir, e))?;
        }
        Ok(self.final_dir.clone())
    }
}

impl Drop for ModelWriter {
    fn drop(&mut self) {
        // Not published (an error on the way): leave nothing that could be mistaken for a model.
        if self.staging.exists() {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
}

/// Writes the parts every model has; the caller adds the networks it trained, then publishes.
#[allow(clippy::too_many_arguments)]
pub fn write_core_parts(
    w: &mut ModelWriter,
    topo: &Topology,
    layout: &UvLayout,
    subspace: &Subspace,
    linear: &LinearRegression,
) -> Result<()> {
    let tris: Vec<u32> = topo
        .triangles()
        .iter()
        .flat_map(|t| t.iter().copied())
        .collect();
    w.put(
        "triangles.npy",
        &npy::to_bytes(&[topo.n_triangles(), 3], &tris),
    )?;
    let uv: Vec<f64> = layout.uv.iter().flat_map(|p| p.iter().copied()).collect();
    w.put("uv.npy", &npy::to_bytes(&[layout.uv.len(), 2], &uv))?;
    let corners: Vec<u32> = layout
        .corners
        .iter()
        .flat_map(|c| c.iter().copied())
        .collect();
    w.put(
        "uv_corners.npy",
        &npy::to_bytes(&[layout.corners.len(), 3], &corners),
    )?;
    w.put(
        "mean.npy",
        &npy::to_bytes(&[subspace.dim()], &subspace.mean),
    )?;
    let (d, k) = (subspace.dim(), subspace.k());
    let mut basis = Vec::with_capacity(d * k);
    for r in 0..d {
        for c in 0..k {
            basis.push(subspace.basis[(r, c)]);
        }
    }
    w.put("basis.npy", &npy::to_bytes(&[d, k], &basis))?;
    w.put(
        "singular_values.npy",
        &npy::to_bytes(&[subspace.singular_values.len()], &subspace.singular_values),
    )?;
    w.put(
        "linear.npy",
        &npy::to_bytes(&[linear.k, linear.m], &linear.weights),
    )?;
    // For people and other tools: the mean shape with its UV layout.
    let mean_shape = crate::subspace::unflatten(&subspace.mean);
    let obj = w.staging_path("template.obj");
    write_obj_with_uv(&obj, topo, &mean_shape, layout)?;
    w.record("template.obj")
}

/// Writes the detail model's weights (`detail.npy`: interior row, boundary row); its [`DetailSpec`] goes into
/// the manifest.
pub fn write_detail(w: &mut ModelWriter, m: &DetailModel) -> Result<()> {
    let weights: Vec<f64> = m.interior.iter().chain(&m.boundary).copied().collect();
    w.put(
        "detail.npy",
        &npy::to_bytes(&[2, m.interior.len()], &weights),
    )
}

/// Writes the kernel regression's arrays; its [`KernelSpec`] goes into the manifest.
pub fn write_kernel(w: &mut ModelWriter, kr: &KernelRegression) -> Result<()> {
    let n = kr.spec.centres;
    w.put(
        "kernel_inputs.npy",
        &npy::to_bytes(&[n, kr.input_len()], &kr.inputs),
    )?;
    w.put(
        "kernel_dual.npy",
        &npy::to_bytes(&[n, kr.offset.len()], &kr.dual),
    )?;
    w.put(
        "kernel_offset.npy",
        &npy::to_bytes(&[kr.offset.len()], &kr.offset),
    )
}

/// Writes the autoregressive regressor's arrays; its [`ArSpec`] goes into the manifest.
pub fn write_autoregressive(w: &mut ModelWriter, ar: &AutoregressiveLinear) -> Result<()> {
    let r = &ar.regression;
    w.put(
        "autoregressive.npy",
        &npy::to_bytes(&[r.k, r.m], &r.weights),
    )?;
    let h = &ar.history;
    w.put("ar_scale.npy", &npy::to_bytes(&[h.scale.len()], &h.scale))?;
    w.put("ar_start.npy", &npy::to_bytes(&[h.start.len()], &h.start))
}

impl Model {
    /// Reads the manifest (version first), then every file, checking each against the manifest.
    pub fn load(dir: &Path) -> Result<Model> {
        let mpath = dir.join("manifest.json");
        if !mpath.exists() {
            let partial = dir.is_dir();
            return Err(Error::format(
                &mpath,
                None,
                if partial {
                    "missing: this is not a complete crease-deep model (training did not finish?)"
                } else {
                    "missing: no model at this path"
                },
            ));
        }
        let text = std::fs::read_to_string(&mpath).map_err(|e| Error::io(&mpath, e))?;
        let raw: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::format(&mpath, Some(e.line()), format!("invalid JSON: {e}")))?;
        if raw.get("format").and_then(|f| f.as_str()) != Some(MODEL_FORMAT) {
            return Err(Error::format(
                &mpath,
                None,
                format!("not a {MODEL_FORMAT} manifest (`format` field)"),
            ));
        }
        match raw.get("version").and_then(|v| v.as_u64()) {
            Some(v) if (MODEL_VERSION_MIN as u64..=MODEL_VERSION as u64).contains(&v) => {}
            Some(v) => {
                return Err(Error::format(
                    &mpath,
                    None,
                    format!("model format version {v}; this build of crease reads versions {MODEL_VERSION_MIN} to {MODEL_VERSION} (retrain or use the matching crease)"),
                ))
            }
            None => return Err(Error::format(&mpath, None, "no `version` field")),
        }
        let manifest: Manifest = serde_json::from_value(raw)
            .map_err(|e| Error::format(&mpath, None, format!("malformed manifest: {e}")))?;
        let read = |name: &str| -> Result<Vec<u8>> {
            let path = dir.join(name);
            let entry = manifest
                .files
                .get(name)
                .ok_or_else(|| Error::format(&mpath, None, format!("does not list `{name}`")))?;
            let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
            if bytes.len() as u64 != entry.bytes || fnv1a64(&bytes) != entry.fnv1a64 {
                return Err(Error::format(
                    &path,
                    None,
                    "does not match the model manifest (size or hash): damaged or from another model",
                ));
            }
            Ok(bytes)
        };
        let p = |name: &str| dir.join(name);
        let (shape, tris) = npy::from_bytes::<u32>(&p("triangles.npy"), &read("triangles.npy")?)?;
        if shape.len() != 2 || shape[1] != 3 || shape[0] != manifest.triangles {
            return Err(Error::format(
                p("triangles.npy"),
                None,
                format!("shape {shape:?}"),
            ));
        }
        let tris: Vec<[u32; 3]> = tris.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let topology = Arc::new(
            Topology::new(manifest.vertices, tris)
                .map_err(|e| e.at(Some(p("triangles.npy")), None))?,
        );
        let (_, uv) = npy::from_bytes::<f64>(&p("uv.npy"), &read("uv.npy")?)?;
        let (_, corners) = npy::from_bytes::<u32>(&p("uv_corners.npy"), &read("uv_corners.npy")?)?;
        let layout = UvLayout {
            uv: uv.chunks_exact(2).map(|c| [c[0], c[1]]).collect(),
            corners: corners
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
        };
        layout.check(&topology, &p("uv_corners.npy").display().to_string())?;
        let (_, mean) = npy::from_bytes::<f64>(&p("mean.npy"), &read("mean.npy")?)?;
        let (bshape, basis) = npy::from_bytes::<f64>(&p("basis.npy"), &read("basis.npy")?)?;
        if bshape != [3 * manifest.vertices, manifest.k] || mean.len() != 3 * manifest.vertices {
            return Err(Error::format(
                p("basis.npy"),
                None,
                format!("shape {bshape:?} does not fit the manifest"),
            ));
        }
        let (_, sv) =
            npy::from_bytes::<f64>(&p("singular_values.npy"), &read("singular_values.npy")?)?;
        let k = manifest.k;
        let subspace = Subspace {
            mean,
            basis: Mat::from_fn(3 * manifest.vertices, k, |r, c| basis[r * k + c]),
            singular_values: sv,
        };
        let (lshape, weights) = npy::from_bytes::<f64>(&p("linear.npy"), &read("linear.npy")?)?;
        if lshape != [k, manifest.control.len()] {
            return Err(Error::format(
                p("linear.npy"),
                None,
                format!("shape {lshape:?} does not fit the manifest"),
            ));
        }
        let linear = LinearRegression {
            k,
            m: manifest.control.len(),
            weights,
        };
        let autoregressive = match &manifest.autoregressive {
            Some(spec) => {
                let (wshape, weights) =
                    npy::from_bytes::<f64>(&p("autoregressive.npy"), &read("autoregressive.npy")?)?;
                let m = manifest.control.len() + spec.k_state * spec.order;
                if wshape != [k, m] {
                    return Err(Error::format(
                        p("autoregressive.npy"),
                        None,
                        format!("shape {wshape:?} does not fit the manifest ([{k}, {m}])"),
                    ));
                }
                let (_, scale) =
                    npy::from_bytes::<f64>(&p("ar_scale.npy"), &read("ar_scale.npy")?)?;
                let (_, start) =
                    npy::from_bytes::<f64>(&p("ar_start.npy"), &read("ar_start.npy")?)?;
                if scale.len() != spec.k_state || start.len() != k {
                    return Err(Error::format(
                        p("ar_scale.npy"),
                        None,
                        format!(
                            "{} scales and {} start coefficients; the manifest says {} and {k}",
                            scale.len(),
                            start.len(),
                            spec.k_state
                        ),
                    ));
                }
                Some(AutoregressiveLinear {
                    history: ShapeHistory {
                        k_state: spec.k_state,
                        order: spec.order,
                        scale,
                        start,
                        clip: spec.clip,
                    },
                    regression: LinearRegression { k, m, weights },
                })
            }
            None => None,
        };
        let lstm = match &manifest.lstm {
            Some(cfg) => {
                read("lstm.safetensors")?;
                Some(LstmRegressor::load(
                    cfg.clone(),
                    manifest.control.len(),
                    k,
                    manifest.coeff_scale.clone(),
                    &p("lstm.safetensors"),
                )?)
            }
            None => None,
        };
        let kernel = match &manifest.kernel {
            Some(spec) => {
                let (_, inputs) =
                    npy::from_bytes::<f64>(&p("kernel_inputs.npy"), &read("kernel_inputs.npy")?)?;
                let (_, dual) =
                    npy::from_bytes::<f64>(&p("kernel_dual.npy"), &read("kernel_dual.npy")?)?;
                let (_, offset) =
                    npy::from_bytes::<f64>(&p("kernel_offset.npy"), &read("kernel_offset.npy")?)?;
                let kr = KernelRegression {
                    spec: spec.clone(),
                    inputs,
                    dual,
                    offset,
                };
                let numbers = manifest.control.pose_dim();
                let fits = kr.check().and_then(|_| {
                    if kr.offset.len() != k {
                        Err(format!(
                            "{} coefficients; the model has {k}",
                            kr.offset.len()
                        ))
                    } else if kr.spec.mean.len() != numbers {
                        Err(format!(
                            "{} pose numbers; the control spec gives {numbers}",
                            kr.spec.mean.len()
                        ))
                    } else {
                        Ok(())
                    }
                });
                fits.map_err(|e| {
                    Error::format(
                        p("kernel_dual.npy"),
                        None,
                        format!("does not fit the manifest's `kernel`: {e}"),
                    )
                })?;
                Some(kr)
            }
            None => None,
        };
        if let Some(c) = &manifest.cgan {
            read("cgan.safetensors")?;
            c.config
                .validate()
                .and_then(|_| c.config.check_resolution(manifest.resolution))
                .map_err(|e| Error::format(&mpath, None, format!("`cgan`: {e}")))?;
        }
        let detail = {
            let (shape, weights) = npy::from_bytes::<f64>(&p("detail.npy"), &read("detail.npy")?)?;
            if shape.len() != 2 || shape[0] != 2 {
                return Err(Error::format(
                    p("detail.npy"),
                    None,
                    format!("shape {shape:?} is not [2, n]"),
                ));
            }
            let (interior, boundary) = weights.split_at(shape[1]);
            let m = DetailModel {
                spec: manifest.detail.clone(),
                interior: interior.to_vec(),
                boundary: boundary.to_vec(),
            };
            m.check().map_err(|e| {
                Error::format(
                    p("detail.npy"),
                    None,
                    format!("does not fit the manifest's `detail`: {e}"),
                )
            })?;
            m
        };
        manifest
            .pose_lowpass
            .check()
            .map_err(|e| Error::format(&mpath, None, format!("`pose_lowpass`: {e}")))?;
        match &manifest.blend {
            Some(b) => crate::regression::blend::check_weight(b.weight)
                .map_err(|e| Error::format(&mpath, None, format!("`blend.weight`: {e}")))?,
            None => {
                return Err(Error::format(
                    &mpath,
                    None,
                    "manifest without the `blend` field it requires",
                ))
            }
        }
        if manifest.blend.is_some() && manifest.autoregressive.is_none() {
            return Err(Error::format(
                &mpath,
                None,
                "has a `blend` weight but no autoregressive regressor to blend",
            ));
        }
        Ok(Model {
            manifest,
            topology,
            layout,
            subspace,
            linear,
            autoregressive,
            lstm,
            kernel,
            detail,
            dir: dir.to_path_buf(),
        })
    }

    /// Refuses a regressor the model does not hold, naming the model and why.
    /// Where `apply --coarse` takes a capture's detail from by default: what training decided on the held-out
    /// sequence, or the learned filter for a model trained before the relief was an option.
    pub fn coarse_detail(&self) -> crate::detail::relief::CoarseDetail {
        use crate::detail::relief::CoarseDetail;
        match &self.detail.spec.coarse {
            Some(c) => c.detail(),
            None => CoarseDetail::Model,
        }
    }

    pub fn check_regressor(&self, kind: RegressorKind) -> Result<()> {
        let has = match kind {
            RegressorKind::Linear => true,
            RegressorKind::Autoregressive => self.autoregressive.is_some(),
            RegressorKind::Lstm => match self.lstm.as_ref().map(|n| n.config.residual_of) {
                None => false,
                Some(None) => true,
                Some(Some(base)) => {
                    base != RegressorKind::Lstm && self.check_regressor(base).is_ok()
                }
            },
            RegressorKind::Blend => self.autoregressive.is_some() && self.manifest.blend.is_some(),
            RegressorKind::Kernel => self.kernel.is_some(),
        };
        if has {
            Ok(())
        } else {
            Err(self.missing_regressor(kind))
        }
    }

    /// The error for a regressor the model lacks.
    pub fn missing_regressor(&self, kind: RegressorKind) -> Error {
        let why = match kind {
            RegressorKind::Autoregressive | RegressorKind::Blend | RegressorKind::Kernel => {
                format!(
                    "format version {} models have none; retrain it with this crease",
                    self.manifest.version
                )
            }
            _ => "it was trained without one".to_string(),
        };
        Error::format(
            self.dir.join("manifest.json"),
            None,
            format!("the model has no {} regressor ({why})", kind.name()),
        )
    }
}
