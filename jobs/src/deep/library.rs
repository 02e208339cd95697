//! The bridge to the learning library (`deep` feature): a spec's types and parameters as crease-deep's,
//! and the checks of the training parameters only the library knows.

use super::spec::{
    CoarseDetail, DeepSpec, DeepTrainParams, MapSpace, Mirror, PoseFeatures, Regressor,
};
use crate::error::JobError;
use crease_deep::cgan::CganConfig;
use crease_deep::detail::DetailParams;
use crease_deep::model::RegressorKind;
use crease_deep::normal_maps::Space;
use crease_deep::regression::lstm::LstmConfig;
use crease_deep::regression::pose_features::PoseFeatureMode;
use crease_deep::regression::pose_lowpass::PoseLowpass;
use crease_deep::subspace::mirror::MirrorMode;
use crease_deep::train::TrainParams;
use std::path::PathBuf;

impl From<Regressor> for RegressorKind {
    fn from(r: Regressor) -> Self {
        match r {
            Regressor::Linear => RegressorKind::Linear,
            Regressor::Autoregressive => RegressorKind::Autoregressive,
            Regressor::Lstm => RegressorKind::Lstm,
            Regressor::Blend => RegressorKind::Blend,
            Regressor::Kernel => RegressorKind::Kernel,
        }
    }
}

impl From<PoseFeatures> for PoseFeatureMode {
    fn from(p: PoseFeatures) -> Self {
        match p {
            PoseFeatures::Auto => PoseFeatureMode::Auto,
            PoseFeatures::Raw => PoseFeatureMode::Raw,
            PoseFeatures::Rigid => PoseFeatureMode::Rigid,
        }
    }
}

impl From<Mirror> for MirrorMode {
    fn from(m: Mirror) -> Self {
        match m {
            Mirror::Auto => MirrorMode::Auto,
            Mirror::None => MirrorMode::None,
            Mirror::X => MirrorMode::X,
            Mirror::Y => MirrorMode::Y,
            Mirror::Z => MirrorMode::Z,
        }
    }
}

impl From<CoarseDetail> for crease_deep::apply::CoarseDetail {
    fn from(c: CoarseDetail) -> Self {
        match c {
            CoarseDetail::Relief => crease_deep::apply::CoarseDetail::Relief,
            CoarseDetail::Model => crease_deep::apply::CoarseDetail::Model,
            CoarseDetail::Blend => crease_deep::apply::CoarseDetail::Blend,
        }
    }
}

impl From<MapSpace> for Space {
    fn from(s: MapSpace) -> Self {
        match s {
            MapSpace::World => Space::World,
            MapSpace::Tangent => Space::Tangent,
        }
    }
}

/// The library's training parameters, with the UV template at `uv` (already fetched) when the spec names one.
pub fn train_params(p: &DeepTrainParams, uv: Option<PathBuf>) -> TrainParams {
    TrainParams {
        k: p.k,
        lags: p.lags.clone(),
        pose_history: p.pose_history.clone(),
        ridge: p.ridge,
        pose_features: p.pose_features.into(),
        mirror: p.mirror.into(),
        regressor: p.regressor.into(),
        kernel_window: p.kernel_window.clone(),
        kernel_uniform: p.kernel_uniform,
        ar_state: p.ar_state,
        ar_rollout_iters: p.ar_rollout_iters,
        blend_weight: p.blend_weight,
        blend_fit: p.blend_fit,
        lstm: LstmConfig {
            layers: p.lstm_layers,
            hidden: p.lstm_hidden,
            seq_len: p.lstm_seq,
            epochs: p.lstm_epochs,
            batch: 32,
            lr: p.lstm_lr,
            seed: p.seed,
            // Residual of the blend, cross-fitted, early stopping: as `crease deep train`.
            ..LstmConfig::default()
        },
        pose_lowpass: PoseLowpass {
            components: p.pose_components,
            half_wavelength: p.pose_lowpass,
        },
        detail: DetailParams {
            degree: p.detail_degree,
            captures_per_frame: p.detail_captures,
            seed: p.seed,
        },
        resolution: p.resolution,
        uv,
        cgan: (p.cgan_steps > 0).then(|| CganConfig {
            filters: p.cgan_filters,
            disc_filters: p.cgan_disc_filters,
            w_temporal: p.cgan_w_temporal,
            depth: p.cgan_depth,
            crop: p.cgan_crop,
            steps: p.cgan_steps,
            seed: p.seed,
            ..Default::default()
        }),
        checkpoint: None,
    }
}

/// The spec field a library parameter error is about (`lstm.layers` → `deep.params.lstm_layers`).
fn param_field(name: &str) -> String {
    let field = match name {
        "cgan" => "cgan_filters".to_string(),
        "cgan.depth" => "cgan_depth".to_string(),
        "cgan.crop" => "cgan_crop".to_string(),
        n => n.replace('.', "_"),
    };
    format!("deep.params.{field}")
}

/// Checks a training job's parameters as the library will (ranges, sizes), naming the spec field.
pub fn check_params(deep: &DeepSpec) -> Result<(), JobError> {
    let DeepSpec::Train { params, .. } = deep else {
        return Ok(());
    };
    let p = train_params(params, None);
    let lib = |e: crease_core::Error| match e {
        crease_core::Error::Param { name, msg } => JobError::spec(param_field(&name), msg),
        e => JobError::spec("deep.params", e.to_string()),
    };
    p.validate().map_err(lib)?;
    if let Some(c) = &p.cgan {
        c.validate().map_err(lib)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::de::DeserializeOwned;
    use serde::Serialize;

    /// The spec's defaults are `crease deep train`'s: the library's defaults, seed 1.
    #[test]
    fn spec_defaults_are_the_librarys() {
        let t = TrainParams::default();
        let c = CganConfig::default();
        let d = DeepTrainParams::default();
        let want = (
            (
                t.k,
                t.regressor,
                t.ar_state,
                t.ar_rollout_iters,
                t.kernel_window,
                t.kernel_uniform,
            ),
            (t.blend_weight, t.blend_fit, t.lags, t.pose_history, t.ridge),
            (t.pose_features, t.mirror),
            (
                t.lstm.layers,
                t.lstm.hidden,
                t.lstm.seq_len,
                t.lstm.epochs,
                t.lstm.lr,
            ),
            (t.pose_lowpass.components, t.pose_lowpass.half_wavelength),
            (t.detail.degree, t.detail.captures_per_frame),
            (t.resolution, t.uv),
            (
                c.filters,
                c.disc_filters,
                c.w_temporal,
                c.depth,
                c.crop,
                c.steps,
            ),
        );
        let got = (
            (
                d.k,
                RegressorKind::from(d.regressor),
                d.ar_state,
                d.ar_rollout_iters,
                d.kernel_window.clone(),
                d.kernel_uniform,
            ),
            (
                d.blend_weight,
                d.blend_fit,
                d.lags.clone(),
                d.pose_history.clone(),
                d.ridge,
            ),
            (
                PoseFeatureMode::from(d.pose_features),
                MirrorMode::from(d.mirror),
            ),
            (
                d.lstm_layers,
                d.lstm_hidden,
                d.lstm_seq,
                d.lstm_epochs,
                d.lstm_lr,
            ),
            (d.pose_components, d.pose_lowpass),
            (d.detail_degree, d.detail_captures),
            (d.resolution, None::<PathBuf>),
            (
                d.cgan_filters,
                d.cgan_disc_filters,
                d.cgan_w_temporal,
                d.cgan_depth,
                d.cgan_crop,
                d.cgan_steps,
            ),
        );
        assert_eq!(got, want);
        assert_eq!((d.seed, &d.uv), (1, &None));
    }

    /// Every variant is spelled in a spec as the library spells it, and converts to that variant.
    fn same_names<
        A: Serialize + Copy,
        B: DeserializeOwned + PartialEq + std::fmt::Debug + From<A>,
    >(
        all: &[A],
    ) {
        for &a in all {
            let text = serde_json::to_string(&a).unwrap();
            let b: B = serde_json::from_str(&text).unwrap();
            assert_eq!(b, B::from(a), "{text}");
        }
    }

    #[test]
    fn spec_enums_are_the_librarys() {
        use Regressor as R;
        same_names::<_, RegressorKind>(&[R::Linear, R::Autoregressive, R::Lstm, R::Blend]);
        use PoseFeatures as P;
        same_names::<_, PoseFeatureMode>(&[P::Auto, P::Raw, P::Rigid]);
        use Mirror as M;
        same_names::<_, MirrorMode>(&[M::Auto, M::None, M::X, M::Y, M::Z]);
        same_names::<_, Space>(&[MapSpace::World, MapSpace::Tangent]);
        use CoarseDetail as C;
        for (a, b) in [
            (C::Relief, crease_deep::apply::CoarseDetail::Relief),
            (C::Model, crease_deep::apply::CoarseDetail::Model),
            (C::Blend, crease_deep::apply::CoarseDetail::Blend),
        ] {
            let text = serde_json::to_string(&a).unwrap();
            assert_eq!(text.trim_matches('"'), b.as_str());
            assert_eq!(crease_deep::apply::CoarseDetail::from(a), b);
        }
    }
}
