//! ν-gaps between the plant each controller structure *assumes* (nominal)
//! and the plant it *meets* on a road of the catalogue (uncertain), with and
//! without ARTE (paper §IV: MFC 0.0332 → 0.0127,
//! SRC 0.91 → 0.28, MTTE 0.85 → 0.096). Definitions (also in the README,
//! "Analysis"):
//!
//! - **Roads.** The paper's four classes (asphalt, snow, stone, gravel).
//!   Each class has a *table road* (the catalogue road of that name, whose
//!   curve ARTE hands to the controller) and *members*: every catalogue road
//!   ARTE would report as that class (by default the table road plus the
//!   roads whose name contains the class name, e.g. `wet_asphalt`, and
//!   `*cobble*` for stone). Roads in no class (e.g. ice) are left out.
//! - **Operating point.** A TCS acts near the friction peak: on road r the
//!   wheel runs at λ_opt(r) (MFC, MTTE); the SRC holds the slip at its
//!   reference λ*. Speed V = 20 km/h (the middle of the paper's 10-30 km/h).
//! - **MFC** plant ω/I = K / (J s (τ_m s + 1)), J = J_w + m r² (1 − λ).
//!   Nominal λ̂ = 0 without ARTE (paper eq. 2), λ_opt(class table) with ARTE.
//!   Uncertain λ = λ_opt(true road).
//! - **MTTE** plant r F̂_d / T* = (1 − J_w/J(λ)) / ((τ_m s+1)(τ_o s+1)), the
//!   loop element its gain multiplies. The rule T_max = (J_w/(α m r) + r) F̂_d
//!   is exact for a wheel of inertia J_w + m r² α, i.e. it assumes
//!   λ̂ = 1 − α: α from `controllers.toml` without ARTE, 1 − λ_opt(class
//!   table) with ARTE. Uncertain λ = λ_opt(true road).
//! - **SRC** plant λ / μ_T (eq. 6 corrected, input as friction demand
//!   μ_T = T/(r N)) linearised at the reference λ* with the slope of the
//!   curve there. Without ARTE the controller's model is a nominal road
//!   (dry asphalt) with λ* = its λ_opt; with ARTE the class table with
//!   λ* = λ_opt(table). The uncertain plant is the true road's curve at the
//!   same λ* (the slip the controller actually holds).
//! - **Figures.** Without ARTE: the worst case over all class members, and
//!   the mean over the four classes of the within-class worst case. With
//!   ARTE: (a) correct classification, worst case over members (the
//!   within-class spread only); (b) the mean over the four classes of
//!   Σ_ĉ P(ĉ | c) · (worst member of c against table ĉ), P from the
//!   paper's Table II; (c) the worst case over every (true, reported) pair
//!   that Table II ever confuses.

use grip_physics::{RoadCatalogue, VehicleParams};

use super::AnalysisError;
use super::nugap::{NuGap, nu_gap};
use super::tf::Tf;
use super::vehicle_tf::{K_MOTOR, mfc_plant, mtte_observer_plant, src_slip, src_slip_tf};

/// Slopes dμ/dλ smaller than this are rounding noise at a smooth friction
/// peak and are taken as exactly 0 (the SRC model is then an integrator).
pub const SLOPE_ZERO: f64 = 1e-9;

/// The paper's road classes, in the order of Table II.
pub const PAPER_CLASSES: [&str; 4] = ["asphalt", "snow", "stone", "gravel"];

/// Table II (ANN confusion matrix): `TABLE_II[predicted][actual]`, classes
/// in [`PAPER_CLASSES`] order, 30 test samples per actual class.
pub const TABLE_II: [[u32; 4]; 4] = [[28, 0, 1, 1], [0, 26, 3, 4], [1, 3, 26, 2], [1, 1, 0, 23]];

/// The paper's ν-gaps (§IV), (without ARTE, with ARTE).
pub const PAPER_GAPS: [(Structure, f64, f64); 3] = [
    (Structure::Mfc, 0.0332, 0.0127),
    (Structure::Src, 0.91, 0.28),
    (Structure::Mtte, 0.85, 0.096),
];

/// One ARTE road class.
#[derive(Debug, Clone, PartialEq)]
pub struct RoadClass {
    /// Class name (as in [`PAPER_CLASSES`]).
    pub name: String,
    /// Catalogue index of the road whose table ARTE reports for this class.
    pub table: usize,
    /// Catalogue indices of every road ARTE reports as this class (includes `table`).
    pub members: Vec<usize>,
}

/// The paper's four classes over `cat`: the table road is the road named
/// like the class; members are the table road and every other road whose
/// name contains the class name (plus `cobble` for stone), each road in at
/// most one class. Fails naming a class whose road is missing.
pub fn paper_classes(cat: &RoadCatalogue) -> Result<Vec<RoadClass>, AnalysisError> {
    let mut taken = vec![false; cat.len()];
    let mut out = Vec::new();
    for name in PAPER_CLASSES {
        let table = cat
            .index_of(name)
            .ok_or_else(|| AnalysisError::MissingRoad {
                name: name.to_string(),
                available: cat.names(),
            })?;
        taken[table] = true;
        out.push(RoadClass {
            name: name.to_string(),
            table,
            members: vec![table],
        });
    }
    for (i, road) in cat.iter().enumerate() {
        if taken[i] {
            continue;
        }
        let n = road.name().to_ascii_lowercase();
        if let Some(c) = out
            .iter_mut()
            .find(|c| n.contains(c.name.as_str()) || (c.name == "stone" && n.contains("cobble")))
        {
            c.members.push(i);
            taken[i] = true;
        }
    }
    Ok(out)
}

/// The three controller structures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Structure {
    /// Model following control.
    Mfc,
    /// Slip ratio control.
    Src,
    /// Maximum transmissible torque estimation.
    Mtte,
}

impl Structure {
    /// Upper-case name.
    pub fn name(self) -> &'static str {
        match self {
            Structure::Mfc => "MFC",
            Structure::Src => "SRC",
            Structure::Mtte => "MTTE",
        }
    }
}

/// Settings of the structure ν-gaps.
#[derive(Debug, Clone, PartialEq)]
pub struct GapSetup {
    /// The vehicle.
    pub vehicle: VehicleParams,
    /// Motor torque constant K, N m/A.
    pub k_motor: f64,
    /// Chassis speed at the operating point, m/s.
    pub speed: f64,
    /// MTTE relaxation factor without ARTE (`[mtte] alpha`).
    pub mtte_alpha: f64,
    /// MTTE driving-force observer time constant, s (`[mtte] tau_obs`).
    pub mtte_tau_obs: f64,
    /// The road the SRC's model assumes without ARTE.
    pub src_nominal_road: String,
}

impl Default for GapSetup {
    fn default() -> Self {
        Self {
            vehicle: VehicleParams::default(),
            k_motor: K_MOTOR,
            speed: 20.0 / 3.6,
            mtte_alpha: 0.9,
            mtte_tau_obs: 0.01,
            src_nominal_road: "asphalt".into(),
        }
    }
}

/// What a controller believes about the road.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Belief {
    NoArte,
    Table(usize),
}

/// (nominal plant, true plant on `road`) for a structure and a belief.
fn plants(
    s: Structure,
    g: &GapSetup,
    cat: &RoadCatalogue,
    belief: Belief,
    road: usize,
) -> Result<(Tf, Tf), AnalysisError> {
    let v = &g.vehicle;
    let lam_true = cat[road].lambda_opt();
    match s {
        Structure::Mfc => {
            let lam_hat = match belief {
                Belief::NoArte => 0.0,
                Belief::Table(t) => cat[t].lambda_opt(),
            };
            Ok((
                mfc_plant(v, g.k_motor, lam_hat)?,
                mfc_plant(v, g.k_motor, lam_true)?,
            ))
        }
        Structure::Mtte => {
            let lam_hat = match belief {
                Belief::NoArte => 1.0 - g.mtte_alpha,
                Belief::Table(t) => cat[t].lambda_opt(),
            };
            Ok((
                mtte_observer_plant(v, lam_hat, g.mtte_tau_obs)?,
                mtte_observer_plant(v, lam_true, g.mtte_tau_obs)?,
            ))
        }
        Structure::Src => {
            let model_road = match belief {
                Belief::NoArte => {
                    cat.index_of(&g.src_nominal_road)
                        .ok_or_else(|| AnalysisError::MissingRoad {
                            name: g.src_nominal_road.clone(),
                            available: cat.names(),
                        })?
                }
                Belief::Table(t) => t,
            };
            let lam_ref = cat[model_road].lambda_opt();
            let v_w = g.speed / (1.0 - lam_ref);
            let at = |r: usize| -> Result<Tf, AnalysisError> {
                // at a smooth peak the slope is 0 up to rounding (~1e-13):
                // take it as exactly 0 so that the model is an integrator
                let a = cat[r].dmu_dlambda(lam_ref);
                let a = if a.abs() < SLOPE_ZERO { 0.0 } else { a };
                let sl = src_slip(v, lam_ref, a, v_w)?;
                src_slip_tf(&sl, v, true)
            };
            Ok((at(model_road)?, at(road)?))
        }
    }
}

/// One ν-gap between a belief and a true road.
#[derive(Debug, Clone, PartialEq)]
pub struct GapCase {
    /// The true road (catalogue name).
    pub road: String,
    /// What the controller assumed: `nominal` (no ARTE) or the class table road.
    pub believed: String,
    /// The ν-gap and its details.
    pub gap: NuGap,
}

/// The ν-gap figures of one structure (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct StructureGaps {
    /// Which structure.
    pub structure: Structure,
    /// Without ARTE, every class member (the worst is the maximum).
    pub no_arte: Vec<GapCase>,
    /// Without ARTE, mean over classes of the within-class worst case.
    pub no_arte_class_mean: f64,
    /// With ARTE and correct classification, every class member.
    pub arte_correct: Vec<GapCase>,
    /// With ARTE, Table II-weighted mean over classes.
    pub arte_table2_mean: f64,
    /// With ARTE, the worst pair that Table II confuses.
    pub arte_confused_worst: GapCase,
    /// The paper's (without, with) ARTE.
    pub paper: (f64, f64),
}

/// The largest ν-gap of a list.
pub fn worst(cases: &[GapCase]) -> Option<&GapCase> {
    cases
        .iter()
        .max_by(|a, b| a.gap.delta.total_cmp(&b.gap.delta))
}

/// ν-gap figures of the three structures over the classes `classes` of
/// `cat`, with the confusion counts `confusion[predicted][actual]` (same
/// class order as `classes`).
pub fn structure_gaps(
    setup: &GapSetup,
    cat: &RoadCatalogue,
    classes: &[RoadClass],
    confusion: &[[u32; 4]; 4],
) -> Result<Vec<StructureGaps>, AnalysisError> {
    if classes.len() != 4 {
        return Err(AnalysisError::InvalidParameter {
            name: "classes",
            value: classes.len() as f64,
            reason: "the confusion matrix has 4 classes",
        });
    }
    let mut out = Vec::new();
    for (s, paper_no, paper_arte) in PAPER_GAPS {
        let case = |belief: Belief, road: usize| -> Result<GapCase, AnalysisError> {
            let (nom, tru) = plants(s, setup, cat, belief, road)?;
            Ok(GapCase {
                road: cat[road].name().to_string(),
                believed: match belief {
                    Belief::NoArte => "nominal".into(),
                    Belief::Table(t) => cat[t].name().to_string(),
                },
                gap: nu_gap(&nom, &tru)?,
            })
        };
        let mut no_arte = Vec::new();
        let mut arte_correct = Vec::new();
        let mut no_arte_class_mean = 0.0;
        for c in classes {
            let mut w: f64 = 0.0;
            for &m in &c.members {
                let g = case(Belief::NoArte, m)?;
                w = w.max(g.gap.delta);
                no_arte.push(g);
                arte_correct.push(case(Belief::Table(c.table), m)?);
            }
            no_arte_class_mean += w / classes.len() as f64;
        }
        let mut mean = 0.0;
        let mut confused: Option<GapCase> = None;
        for (a, actual) in classes.iter().enumerate() {
            let total: u32 = (0..4).map(|p| confusion[p][a]).sum();
            if total == 0 {
                continue;
            }
            for (p, predicted) in classes.iter().enumerate() {
                let n = confusion[p][a];
                if n == 0 {
                    continue;
                }
                let mut w: Option<GapCase> = None;
                for &m in &actual.members {
                    let g = case(Belief::Table(predicted.table), m)?;
                    if w.as_ref().is_none_or(|x| g.gap.delta > x.gap.delta) {
                        w = Some(g);
                    }
                }
                if let Some(w) = w {
                    mean += f64::from(n) / f64::from(total) * w.gap.delta / classes.len() as f64;
                    if confused.as_ref().is_none_or(|x| w.gap.delta > x.gap.delta) {
                        confused = Some(w);
                    }
                }
            }
        }
        let arte_confused_worst = confused.ok_or(AnalysisError::InvalidParameter {
            name: "confusion",
            value: 0.0,
            reason: "the confusion matrix is empty",
        })?;
        out.push(StructureGaps {
            structure: s,
            no_arte,
            no_arte_class_mean,
            arte_correct,
            arte_table2_mean: mean,
            arte_confused_worst,
            paper: (paper_no, paper_arte),
        });
    }
    Ok(out)
}
