//! The cGAN generator as an inference step of `apply`: a world-space map in, the detailed map out, for the
//! inputs on which it beat the maps without it when the model was trained.

use crate::cgan::{CganSpec, GeneratorModel};
use crate::model::Model;
use crate::normal_maps::NormalMap;
use crease_core::Result;

pub struct Enhancer {
    generator: GeneratorModel,
    pub spec: CganSpec,
}

impl Enhancer {
    /// `None` when the model has no cGAN.
    pub fn for_model(model: &Model) -> Result<Option<Enhancer>> {
        let Some(spec) = &model.manifest.cgan else {
            return Ok(None);
        };
        let generator =
            GeneratorModel::load(spec.config.clone(), &model.dir.join("cgan.safetensors"))?;
        Ok(Some(Enhancer {
            generator,
            spec: spec.clone(),
        }))
    }

    pub fn enhance(&self, map: &NormalMap) -> Result<NormalMap> {
        self.generator.enhance(map)
    }
}
