//! Pose-to-shape regression (Lähner et al. §3.3): control vectors from pose files, and the regressors that map
//! them to subspace coefficients (linear, autoregressive with its rollout fit, their blend, the kernel regression over a window of poses,
//! the LSTM).

pub mod autoregress;
pub mod blend;
pub mod kernel;
pub mod kind;
pub mod linear;
pub mod lstm;
pub mod pose;
pub mod pose_features;
pub mod pose_history;
pub mod pose_lowpass;
pub mod rollout_fit;
pub mod stable_state;
