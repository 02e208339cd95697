//! The cGAN generator as an inference step of `apply`: coarse world-space map in, detailed map out.

use crate::cgan::{CganConfig, GeneratorModel};
use crate::model::Model;
use crate::normal_maps::NormalMap;
use crease_core::{Error, Result};

pub struct Enhancer {
    generator: GeneratorModel,
}

impl Enhancer {
    /// `None` when the model has no cGAN (apply then writes the coarse maps).
    pub fn for_model(model: &Model) -> Result<Option<Enhancer>> {
        let Some(value) = &model.manifest.cgan else {
            return Ok(None);
        };
        let mpath = model.dir.join("manifest.json");
        // From format 3 on the field is always written; only older models may lack it (and are plain).
        if model.manifest.version >= 3 && value.get("residual").is_none() {
            return Err(Error::format(
                &mpath,
                None,
                "the `cgan` section has no `residual` field (format 3 models always have one)",
            ));
        }
        let config: CganConfig = serde_json::from_value(value.clone())
            .map_err(|e| Error::format(&mpath, None, format!("malformed `cgan` section: {e}")))?;
        if config.resolution != model.manifest.resolution {
            return Err(Error::format(
                &mpath,
                None,
                format!(
                    "cGAN resolution {} differs from the model's map resolution {}",
                    config.resolution, model.manifest.resolution
                ),
            ));
        }
        let generator = GeneratorModel::load(config, &model.dir.join("cgan.safetensors"))?;
        Ok(Some(Enhancer { generator }))
    }

    pub fn enhance(&self, map: &NormalMap) -> Result<NormalMap> {
        self.generator.enhance(map)
    }
}
