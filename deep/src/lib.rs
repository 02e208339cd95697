//! crease-deep: DeepWrinkles (Lähner et al. 2018, DESIGN §7) — learned folds from pose and from captured meshes.
//!
//! Maps to the paper as follows: [`register`] is §3.1 (non-rigid ICP over a deformation graph), [`subspace`] is §3.2 (PCA of registered shapes), [`pose`], [`regress`] and
//! [`lstm`] §3.3 (pose-to-shape regression), [`uv`], [`raster`] and [`normal_map`] §4.1 (normal maps in UV
//! space), [`cgan`] §4.2 (U-Net + 70×70 PatchGAN with the temporal term of Eq. 4). [`model`] stores a trained model, [`train`] fits one, [`apply`] runs it and writes the DESIGN §7
//! output contract ([`contract`]), [`bake`] turns any detailed sequence into normal maps on its coarse input;
//! [`detail_filter`] predicts the fine surface from a captured mesh (the detail `apply --coarse` draws);
//! [`pose_smoothing`] makes the pose-only shape smooth before `apply --pose` draws it.
//! No async and no networking: the CLI and the cluster worker call in here.

pub mod adam;
pub mod apply;
pub mod autoregress;
pub mod bake;
pub mod blend;
pub mod cgan;
pub mod cgan_data;
pub mod contract;
pub mod detail_filter;
pub mod enhance;
pub mod gemm_conv;
pub mod kdtree;
pub mod lstm;
pub mod mirror;
pub mod model;
pub mod normal_map;
pub mod obj_text;
pub mod point_normals;
pub mod pose;
pub mod pose_features;
pub mod pose_history;
pub mod pose_smoothing;
pub mod raster;
pub mod register;
mod register_system;
pub mod regress;
pub mod rollout_fit;
pub mod seed;
pub mod stable_state;
pub mod subspace;
pub mod train;
pub mod uv;
