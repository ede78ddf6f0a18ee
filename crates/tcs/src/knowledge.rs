//! The one road-knowledge rule: how an estimated road becomes the
//! controller's [`RoadKnowledge`].
//!
//! For every road of the catalogue (`config/roads.toml`) the table holds
//! λ_opt and μ_peak of the road's μ-λ curve and the MTTE relaxation factor
//! α = 1 − λ_opt, unless the ARTE configuration's `[knowledge] alpha` names
//! the road (a value in (0, 1]). `grip sim`, the arte service (which
//! publishes these values with every road estimate) and tcs-loop build the
//! table with this code from the same files, so a drive and a simulation
//! hand the controller the same knowledge for the same road.

use std::collections::BTreeMap;

use grip_physics::{InvalidField, RoadCatalogue};
use serde::{Deserialize, Serialize};

use crate::types::RoadKnowledge;

/// `[knowledge]` of the ARTE configuration: per-road overrides.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KnowledgeConfig {
    /// MTTE relaxation factor α per road name, in (0, 1]; a road not listed
    /// gets α = 1 − λ_opt(road).
    #[serde(default)]
    pub alpha: BTreeMap<String, f64>,
}

impl KnowledgeConfig {
    /// Every named road exists in `roads` and every α is in (0, 1] (NaN
    /// fails). The field is `alpha.<road>`.
    pub fn validate(&self, roads: &RoadCatalogue) -> Result<(), InvalidField> {
        for (name, &a) in &self.alpha {
            let field = format!("alpha.{name}");
            if roads.get(name).is_none() {
                return Err(InvalidField::new(
                    field,
                    format!(
                        "`{name}` is not a road of the catalogue (roads: {})",
                        roads.names()
                    ),
                ));
            }
            if !(a > 0.0 && a <= 1.0) {
                return Err(InvalidField::new(
                    field,
                    format!("must be in (0, 1] (got {a})"),
                ));
            }
        }
        Ok(())
    }
}

/// What the table says about one road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadInfo {
    /// Optimal slip of the road's μ-λ curve.
    pub lambda_opt: f64,
    /// Peak friction coefficient.
    pub mu_peak: f64,
    /// MTTE relaxation factor: configured, or 1 − λ_opt.
    pub alpha: f64,
}

impl RoadInfo {
    /// All NaN: what an unknown road gives; the controllers' fallback rule
    /// ([`crate::ArteUse::usable`]) rejects it.
    pub const UNKNOWN: RoadInfo = RoadInfo {
        lambda_opt: f64::NAN,
        mu_peak: f64::NAN,
        alpha: f64::NAN,
    };

    /// The controller's knowledge of this road with a decision's
    /// `confidence` and `age` (s).
    pub fn knowledge(&self, confidence: f64, age: f64) -> RoadKnowledge {
        RoadKnowledge {
            lambda_opt: self.lambda_opt,
            mu_peak: self.mu_peak,
            alpha: self.alpha,
            confidence,
            age,
        }
    }
}

/// λ_opt, μ_peak and α of every catalogue road, in catalogue order.
#[derive(Debug, Clone, PartialEq)]
pub struct RoadTable {
    info: Vec<RoadInfo>,
}

impl RoadTable {
    /// Build the table (validates `cfg` against `roads`).
    pub fn new(roads: &RoadCatalogue, cfg: &KnowledgeConfig) -> Result<Self, InvalidField> {
        cfg.validate(roads)?;
        let info = roads
            .iter()
            .map(|r| {
                let lambda_opt = r.lambda_opt();
                RoadInfo {
                    lambda_opt,
                    mu_peak: r.mu_peak(),
                    alpha: cfg.alpha.get(r.name()).copied().unwrap_or(1.0 - lambda_opt),
                }
            })
            .collect();
        Ok(Self { info })
    }

    /// The road at catalogue `index`, or [`RoadInfo::UNKNOWN`].
    pub fn info(&self, index: usize) -> RoadInfo {
        self.info.get(index).copied().unwrap_or(RoadInfo::UNKNOWN)
    }

    /// Every road, in catalogue order.
    pub fn all(&self) -> &[RoadInfo] {
        &self.info
    }

    /// The knowledge a decision for catalogue road `index` gives (NaN
    /// values for an index outside the catalogue, which the fallback rule
    /// rejects).
    pub fn knowledge(&self, index: usize, confidence: f64, age: f64) -> RoadKnowledge {
        self.info(index).knowledge(confidence, age)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roads() -> RoadCatalogue {
        RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap()
    }

    #[test]
    fn default_alpha_is_one_minus_lambda_opt_and_override_wins() {
        let t = RoadTable::new(&roads(), &KnowledgeConfig::default()).unwrap();
        let a = t.info(0);
        assert!((a.lambda_opt - 0.170).abs() < 1e-3, "{a:?}");
        assert!((a.mu_peak - 1.17).abs() < 1e-2, "{a:?}");
        assert_eq!(a.alpha, 1.0 - a.lambda_opt);
        let mut cfg = KnowledgeConfig::default();
        cfg.alpha.insert("snow".into(), 0.8);
        let t = RoadTable::new(&roads(), &cfg).unwrap();
        assert_eq!(t.info(1).alpha, 0.8);
        assert_eq!(t.info(0).alpha, 1.0 - t.info(0).lambda_opt);
        let k = t.knowledge(1, 0.7, 0.05);
        assert_eq!((k.alpha, k.confidence, k.age), (0.8, 0.7, 0.05));
        assert!(t.knowledge(9, 1.0, 0.0).lambda_opt.is_nan());
    }

    #[test]
    fn bad_overrides_name_the_road() {
        for (name, a, want) in [
            ("tarmac", 0.5, "not a road"),
            ("snow", 0.0, "(0, 1]"),
            ("snow", f64::NAN, "(0, 1]"),
            ("snow", 1.5, "(0, 1]"),
        ] {
            let mut cfg = KnowledgeConfig::default();
            cfg.alpha.insert(name.into(), a);
            let e = RoadTable::new(&roads(), &cfg).unwrap_err();
            assert_eq!(e.field, format!("alpha.{name}"));
            assert!(e.reason.contains(want), "{e:?}");
        }
    }
}
