//! crease-deep: DeepWrinkles (Lähner et al. 2018) — learned folds from pose and from captured meshes.
//!
//! One folder per section of the paper: [`registration`] is §3.1 (non-rigid ICP over a deformation graph),
//! [`subspace`] §3.2 (PCA of registered shapes), [`regression`] §3.3 (pose-to-shape regression), [`normal_maps`]
//! §4.1 (normal maps in UV space), [`cgan`] §4.2 (U-Net + PatchGAN with the temporal term of Eq. 4); [`nn`] holds
//! what the two networks share. [`detail`] predicts the fine surface from a captured mesh (the detail
//! `apply --coarse` draws). [`model`] stores a trained model, [`train`] fits one, [`apply`] runs it and writes the
//! output contract ([`contract`]).
//! No async and no networking: the CLI and the cluster worker call in here.

pub mod apply;
pub mod cgan;
pub mod contract;
pub mod detail;
pub mod evaluation;
pub mod model;
pub mod nn;
pub mod normal_maps;
pub mod registration;
pub mod regression;
pub mod subspace;
pub mod train;
