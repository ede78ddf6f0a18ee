//! The model file and the road catalogue entry (λ_opt, μ_peak,
//! α from the one road-knowledge rule, `grip_tcs::knowledge`) of each of its
//! classes, checked at start-up.

use std::path::Path;

use grip_arte::model::Model;
use grip_msgs::{MAX_ROAD_CLASSES, NAME_LEN};
use grip_physics::RoadCatalogue;

use crate::ArteError;
use crate::error::ModelSource;

/// Reads and validates a model file; errors carry the path
/// ([`ArteError::ModelIo`], [`ArteError::Model`]). [`load_model_from`]
/// also names what named the file.
pub fn load_model(path: &Path) -> Result<Model, ArteError> {
    load_model_from(path, ModelSource::Direct)
}

/// [`load_model`] of a path that `from` named (`arte-svc.toml`'s `model`,
/// `--model`): an error begins with it, e.g. ``config/arte-svc.toml: field
/// `model`: model file config/models/x.model: cannot read: No such file or
/// directory (os error 2)``.
pub fn load_model_from(path: &Path, from: ModelSource) -> Result<Model, ArteError> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) => {
            return Err(ArteError::ModelIo {
                path: path.to_owned(),
                from,
                reason: e.to_string(),
            });
        }
    };
    Model::from_bytes(&bytes).map_err(|error| ArteError::Model {
        path: path.to_owned(),
        from,
        error,
    })
}

/// What a road estimate says about one class's road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClassKnowledge {
    /// Class (= road) name, zero padded.
    pub name: [u8; NAME_LEN],
    /// Optimal slip of the road's μ-λ curve.
    pub lambda_opt: f64,
    /// Peak friction.
    pub mu_peak: f64,
    /// MTTE relaxation factor: `[knowledge] alpha` of the road, else 1 − λ_opt.
    pub alpha: f64,
}

/// The catalogue entry of every model class, in class order, with λ_opt,
/// μ_peak and α from the one road-knowledge rule `rule` (built from the same
/// catalogue). Errors: more
/// classes than `RoadEstimate` carries, a class name longer than
/// `NAME_LEN` bytes, or a class not in the catalogue (named, with the
/// catalogue's names and `roads_file`).
pub fn road_table(
    classes: &[String],
    roads: &RoadCatalogue,
    rule: &grip_tcs::RoadTable,
    model_path: &Path,
    roads_file: &Path,
) -> Result<Vec<ClassKnowledge>, ArteError> {
    let err = |reason: String| ArteError::Classes {
        path: model_path.to_owned(),
        reason,
    };
    if classes.is_empty() || classes.len() > MAX_ROAD_CLASSES {
        return Err(err(format!(
            "has {} classes; a road estimate carries 1..={MAX_ROAD_CLASSES}",
            classes.len()
        )));
    }
    classes
        .iter()
        .map(|c| {
            if c.len() > NAME_LEN {
                return Err(err(format!(
                    "class name `{c}` is longer than {NAME_LEN} bytes"
                )));
            }
            let i = roads.index_of(c).ok_or_else(|| {
                err(format!(
                    "class `{c}` is not a road in the catalogue {} (roads: {})",
                    roads_file.display(),
                    roads.names()
                ))
            })?;
            let k = rule.info(i);
            Ok(ClassKnowledge {
                name: grip_msgs::name_to_bytes(c),
                lambda_opt: k.lambda_opt,
                mu_peak: k.mu_peak,
                alpha: k.alpha,
            })
        })
        .collect()
}
