//! Controller parameters: serde structs read from `config/controllers.toml`
//! (sections `[mfc]`, `[src]`, `[mtte]`, `[arte]`, `[loop]`), each with a
//! `validate()` that names the field and the reason. The values and their
//! sources are listed in `crates/tcs/README.md` ("Controllers").
//!
//! Every field is required in the TOML file (no silent defaults for a
//! baseline parameter); `Default` gives the documented values for tests and
//! tools.

use crate::types::RoadKnowledge;
use grip_physics::InvalidField;
use serde::Deserialize;

pub(crate) fn positive(field: &str, v: f64) -> Result<(), InvalidField> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(InvalidField::new(
            field,
            format!("must be a finite number > 0 (got {v})"),
        ))
    }
}

pub(crate) fn non_negative(field: &str, v: f64) -> Result<(), InvalidField> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(InvalidField::new(
            field,
            format!("must be a finite number >= 0 (got {v})"),
        ))
    }
}

/// The range rule of every configuration file (one home: the physics
/// crate's, which the vehicle and road files use).
pub(crate) use grip_physics::validate::in_range;

/// MFC (Hori's model following control).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MfcParams {
    /// Feedback gain K_MFC on the high-passed speed error, N m s/rad.
    pub k_mfc: f64,
    /// High-pass time constant τ₂ (`tau_hpf`), s.
    pub tau_hpf: f64,
    /// Time constant τ_f of the first-order low-pass on the high-passed
    /// speed error before the gain (`tau_noise`), s; 0: none (the paper's
    /// MFC). Not in the paper: it keeps K_MFC from turning wheel-speed noise
    /// into a chattering command (README.md, "MFC: the noise filter").
    pub tau_noise: f64,
}

impl Default for MfcParams {
    fn default() -> Self {
        Self {
            k_mfc: 177.0,
            tau_hpf: 1.0,
            tau_noise: 0.004,
        }
    }
}

/// The largest `[mfc] k_mfc` accepted, N m s/rad. The paper's analysis
/// gives no stability limit (its eq. (3) is Hurwitz for every K_MFC >= 0,
/// README.md, "Analysis", item 3), but the loop as it runs is sampled, sees
/// the wheel a sample late and passes the noise filter, and it loses
/// stability at a finite gain. 500 keeps a gain margin of 2 (twice it still
/// settles) with the shipped cars' wheel gripping at the catalogue's λ_opt
/// from snow's 0.06 to stone's 0.40 (ice's 0.015 mismatches less), with
/// every `tau_noise` accepted and the configured τ₂ = 1 s
/// (`tests/mfc_gain_bound.rs`); it is above the
/// real-pole rule (4) that gave the shipped 177 (0.9 × 196.7 at stone),
/// which for the front-mic car's heavier wheel share gives 382 at stone.
const K_MFC_MAX: f64 = 500.0;

/// The largest `[mtte] mu_floor` accepted. The floor T_floor = mu_floor · N
/// · r is a lower bound on MTTE's limit T_max: on a road whose μ_peak is
/// below mu_floor the floor alone spins the wheel and MTTE cannot limit
/// there, so it must stay under the lowest μ_peak of the roads driven on
/// (shipped 0.05, ice's). The validation does not see the catalogue: 0.5
/// (above snow's 0.19 and wet stone's 0.38, below gravel's 0.60) bounds
/// what a floor can mean at all; keeping it under the lowest road's peak
/// is the configuration's part.
const MU_FLOOR_MAX: f64 = 0.5;

impl MfcParams {
    /// 0 <= k_mfc <= 500 N m s/rad (`K_MFC_MAX`: a gain margin of 2 for
    /// the sampled loop on a gripping wheel), tau_hpf > 0,
    /// 0 <= tau_noise <= 0.1 s (a longer filter would be slower than the
    /// motor lag it must stay well inside).
    pub fn validate(&self) -> Result<(), InvalidField> {
        if !(self.k_mfc >= 0.0 && self.k_mfc <= K_MFC_MAX) {
            return Err(InvalidField::new(
                "k_mfc",
                format!(
                    "must be in [0, {K_MFC_MAX}] N m s/rad, where the sampled MFC loop keeps a \
                     gain margin of 2 on a gripping wheel (got {})",
                    self.k_mfc
                ),
            ));
        }
        positive("tau_hpf", self.tau_hpf)?;
        in_range("tau_noise", self.tau_noise, 0.0, 0.1)?;
        Ok(())
    }
}

/// SRC (slip ratio control with the fuzzy optimal-slip estimator).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SrcParams {
    /// Driving-force observer filter time constant τ_o, s.
    pub tau_obs: f64,
    /// PI proportional gain per unit of wheel speed, N m s (per unit slip):
    /// K_p = kp · max(ω, v_eps / r).
    pub kp: f64,
    /// PI integral time T_i, s (K_i = K_p / T_i).
    pub ti: f64,
    /// Gain per unit of wheel speed used for the *integral* action while the
    /// slip is below the reference (torque recovery), N m s:
    /// K_i,up = kp_recover · max(ω, v_eps / r) / T_i.
    pub kp_recover: f64,
    /// Time constant of the slope estimator's exponential window, s.
    pub tau_slope: f64,
    /// Excitation (Σ Δλ² over the window) below which the slope estimate
    /// falls back to the linear-region prior (slope = μ̂/λ).
    pub slope_excitation: f64,
    /// Low-pass time constant on the fuzzy λ*, s.
    pub tau_ref: f64,
    /// Lower bound on λ*.
    pub lambda_min: f64,
    /// Upper bound on λ*.
    pub lambda_max: f64,
    /// Launch speed, m/s: below it (pulling away, crawling) the slip SRC
    /// controls is the speed difference over `v_launch`,
    /// (r ω − V) / max(r ω, V, v_launch), and the gain schedule's wheel
    /// speed is at least `v_launch / r`. The paper's controllers are for
    /// 10-30 km/h; at a few cm/s the slip over the `v_eps` floor is mostly
    /// sensor noise, far above λ*, and SRC cut the torque of a car pulling
    /// away to next to nothing. 2 m/s as shipped; absent from a file: 0,
    /// `v_eps`, the paper's law at every speed (older drive logs replay as
    /// recorded). Above `v_launch` nothing changes.
    #[serde(default)]
    pub v_launch: f64,
}

impl Default for SrcParams {
    fn default() -> Self {
        Self {
            tau_obs: 0.01,
            kp: 6.0,
            ti: 0.2,
            kp_recover: 20.0,
            tau_slope: 0.1,
            slope_excitation: 1e-7,
            tau_ref: 0.05,
            lambda_min: 0.02,
            lambda_max: 0.45,
            v_launch: 2.0,
        }
    }
}

impl SrcParams {
    /// Ranges: time constants > 0 (tau_obs, tau_ref >= 0), kp and
    /// kp_recover > 0 (with kp = 0 the PI never cuts: SRC passes the demand
    /// through; with kp_recover = 0 its integrator never rises again after
    /// a cut), other
    /// gains >= 0, 0 < lambda_min < lambda_max < 1, 0 <= v_launch <= 10 m/s.
    pub fn validate(&self) -> Result<(), InvalidField> {
        non_negative("tau_obs", self.tau_obs)?;
        positive("kp", self.kp)?;
        positive("ti", self.ti)?;
        positive("kp_recover", self.kp_recover)?;
        positive("tau_slope", self.tau_slope)?;
        positive("slope_excitation", self.slope_excitation)?;
        non_negative("tau_ref", self.tau_ref)?;
        in_range("lambda_min", self.lambda_min, 1e-4, 0.99)?;
        in_range("lambda_max", self.lambda_max, 1e-4, 0.99)?;
        in_range("v_launch", self.v_launch, 0.0, 10.0)?;
        if self.lambda_max <= self.lambda_min {
            return Err(InvalidField::new(
                "lambda_max",
                format!(
                    "must be > lambda_min = {} (got {})",
                    self.lambda_min, self.lambda_max
                ),
            ));
        }
        Ok(())
    }
}

/// MTTE (maximum transmissible torque estimation).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MtteParams {
    /// Driving-force observer filter time constant τ_o, s.
    pub tau_obs: f64,
    /// Relaxation factor α without ARTE (chassis over wheel acceleration), (0, 1].
    pub alpha: f64,
    /// Low-pass time constant τ₁ on T_max, s.
    pub tau_lpf: f64,
    /// Start-up floor for T_max as a friction coefficient: T_max >= mu_floor · N · r.
    pub mu_floor: f64,
    /// A rise of the driver's demand passes into T_max while the wheel takes
    /// no more than this share of the torque to spin itself up
    /// (J_w dω/dt <= spin_share · LPF(T), from the observer; 1-2 % while it
    /// grips). Not in the paper, whose demands are constant: without it
    /// T_max grows only by the (1/α − 1) J_w share per τ₁ and a ramped
    /// pedal from rest stays at T_floor. 0.1 as shipped; absent from a
    /// file: 0, no rise passes (older drive logs replay as recorded).
    #[serde(default)]
    pub spin_share: f64,
}

impl Default for MtteParams {
    fn default() -> Self {
        Self {
            tau_obs: 0.01,
            alpha: 0.9,
            tau_lpf: 0.05,
            mu_floor: 0.05,
            spin_share: 0.1,
        }
    }
}

impl MtteParams {
    /// tau_obs, tau_lpf >= 0; 0 < alpha <= 1; 0 < mu_floor <= 0.5
    /// (`MU_FLOOR_MAX`; with 0, T_max can fall to 0, from where only a rise
    /// of the demand lifts it); 0 <= spin_share <= 1.
    pub fn validate(&self) -> Result<(), InvalidField> {
        non_negative("tau_obs", self.tau_obs)?;
        if !(self.alpha.is_finite() && self.alpha > 0.0 && self.alpha <= 1.0) {
            return Err(InvalidField::new(
                "alpha",
                format!("must be in (0, 1] (got {})", self.alpha),
            ));
        }
        non_negative("tau_lpf", self.tau_lpf)?;
        if !(self.mu_floor > 0.0 && self.mu_floor <= MU_FLOOR_MAX) {
            return Err(InvalidField::new(
                "mu_floor",
                format!(
                    "must be in (0, {MU_FLOOR_MAX}]: T_max never drops below mu_floor · N · r, \
                     so MTTE cannot limit on a road whose mu_peak is below it (got {})",
                    self.mu_floor
                ),
            ));
        }
        in_range("spin_share", self.spin_share, 0.0, 1.0)?;
        Ok(())
    }
}

/// When a controller may use ARTE's road knowledge (the fallback rule).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArteUse {
    /// Road knowledge older than this (s) is ignored.
    pub max_age_s: f64,
    /// Road knowledge less confident than this is ignored, [0, 1].
    pub min_confidence: f64,
}

impl Default for ArteUse {
    fn default() -> Self {
        Self {
            max_age_s: 0.3,
            min_confidence: 0.6,
        }
    }
}

impl ArteUse {
    /// The longest `max_age_s`, s: tcs-loop declares the road-estimate
    /// stream dead after 1 s without an estimate (its monitor's warning),
    /// and a dead stream's knowledge must not act on the torque. A
    /// fail-safe trial (2026-12-07) set 1e6: knowledge of a stopped arte
    /// stayed "used" while that warning said the controller had fallen back.
    pub const MAX_AGE_LIMIT_S: f64 = 1.0;

    /// max_age_s in [0, [`Self::MAX_AGE_LIMIT_S`]], min_confidence in [0, 1].
    pub fn validate(&self) -> Result<(), InvalidField> {
        non_negative("max_age_s", self.max_age_s)?;
        if self.max_age_s > Self::MAX_AGE_LIMIT_S {
            return Err(InvalidField::new(
                "max_age_s",
                format!(
                    "{} s is longer than {} s: tcs-loop declares the road-estimate stream dead after {} s without an estimate, and the knowledge of a dead stream must not act on the torque",
                    self.max_age_s,
                    Self::MAX_AGE_LIMIT_S,
                    Self::MAX_AGE_LIMIT_S
                ),
            ));
        }
        in_range("min_confidence", self.min_confidence, 0.0, 1.0)?;
        Ok(())
    }

    /// The knowledge a controller may use this cycle, or `None` (run the
    /// no-ARTE behaviour). Usable means: present; `age` finite, >= 0 and
    /// <= `max_age_s`; `confidence` >= `min_confidence`; and the physical
    /// values plausible: 0 < λ_opt < 1, 0 < α <= 1, mu_peak finite and > 0.
    /// Anything else (NaN included) falls back.
    pub fn usable<'a>(&self, road: Option<&'a RoadKnowledge>) -> Option<&'a RoadKnowledge> {
        let k = road?;
        let fresh = k.age.is_finite() && k.age >= 0.0 && k.age <= self.max_age_s;
        let confident = k.confidence.is_finite() && k.confidence >= self.min_confidence;
        let plausible = k.lambda_opt.is_finite()
            && k.lambda_opt > 0.0
            && k.lambda_opt < 1.0
            && k.alpha.is_finite()
            && k.alpha > 0.0
            && k.alpha <= 1.0
            && k.mu_peak.is_finite()
            && k.mu_peak > 0.0;
        (fresh && confident && plausible).then_some(k)
    }
}

/// `[loop]`: the controller rate.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoopParams {
    /// Controller rate, Hz (dt = 1 / rate_hz).
    pub rate_hz: f64,
}

impl Default for LoopParams {
    fn default() -> Self {
        Self { rate_hz: 1000.0 }
    }
}

impl LoopParams {
    /// 1 Hz <= rate_hz <= 100 kHz.
    pub fn validate(&self) -> Result<(), InvalidField> {
        in_range("rate_hz", self.rate_hz, 1.0, 100_000.0)
    }

    /// Sample time, s.
    pub fn dt(&self) -> f64 {
        1.0 / self.rate_hz
    }
}

/// Everything in `config/controllers.toml`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllersConfig {
    /// `[mfc]`
    pub mfc: MfcParams,
    /// `[src]`
    pub src: SrcParams,
    /// `[mtte]`
    pub mtte: MtteParams,
    /// `[arte]`: the fallback rule shared by all three controllers.
    pub arte: ArteUse,
    /// `[loop]`
    #[serde(rename = "loop")]
    pub loop_: LoopParams,
    /// `[preview]`: the torque the believed and the previewed road allow
    /// (ARTE variants; `crate::road_aware`). Optional: defaults.
    #[serde(default)]
    pub preview: crate::road_aware::PreviewParams,
    /// `[fusion]`: the road belief (ARTE variants; `crate::fusion`).
    /// Optional: defaults.
    #[serde(default)]
    pub fusion: crate::fusion::FusionParams,
}

impl ControllersConfig {
    /// Validate every section; the field is prefixed with its section
    /// (e.g. `mfc.tau_hpf`).
    pub fn validate(&self) -> Result<(), InvalidField> {
        self.mfc.validate().map_err(|e| e.prefixed("mfc"))?;
        self.src.validate().map_err(|e| e.prefixed("src"))?;
        self.mtte.validate().map_err(|e| e.prefixed("mtte"))?;
        self.arte.validate().map_err(|e| e.prefixed("arte"))?;
        self.loop_.validate().map_err(|e| e.prefixed("loop"))?;
        self.preview.validate().map_err(|e| e.prefixed("preview"))?;
        self.fusion.validate().map_err(|e| e.prefixed("fusion"))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn knowledge() -> RoadKnowledge {
        RoadKnowledge {
            lambda_opt: 0.17,
            mu_peak: 1.17,
            alpha: 0.83,
            confidence: 0.9,
            age: 0.05,
        }
    }

    #[test]
    fn defaults_validate() {
        ControllersConfig::default().validate().unwrap();
    }

    #[test]
    fn bad_values_name_the_field() {
        let mut c = ControllersConfig::default();
        c.mfc.tau_hpf = f64::NAN;
        assert_eq!(c.validate().unwrap_err().field, "mfc.tau_hpf");
        for bad in [-1e-3, 0.2, f64::NAN, f64::INFINITY] {
            let mut c = ControllersConfig::default();
            c.mfc.tau_noise = bad;
            let e = c.validate().unwrap_err();
            assert_eq!(e.field, "mfc.tau_noise", "{bad}");
            assert!(e.reason.contains("[0, 0.1]"), "{}", e.reason);
        }
        let mut c = ControllersConfig::default();
        c.src.lambda_max = 0.01;
        assert_eq!(c.validate().unwrap_err().field, "src.lambda_max");
        let mut c = ControllersConfig::default();
        c.mtte.alpha = 1.5;
        assert_eq!(c.validate().unwrap_err().field, "mtte.alpha");
        let mut c = ControllersConfig::default();
        c.arte.min_confidence = -0.1;
        assert_eq!(c.validate().unwrap_err().field, "arte.min_confidence");
        c.arte.min_confidence = 0.6;
        c.arte.max_age_s = 1.5;
        let e = c.validate().unwrap_err();
        assert_eq!(e.field, "arte.max_age_s");
        assert!(e.reason.contains("1.5 s is longer than 1 s"), "{e:?}");
        c.arte.max_age_s = 1.0;
        assert!(c.validate().is_ok());
        let mut c = ControllersConfig::default();
        c.loop_.rate_hz = 0.0;
        assert_eq!(c.validate().unwrap_err().field, "loop.rate_hz");
    }

    #[test]
    fn values_that_switch_a_controller_off_are_refused() {
        let field = |c: ControllersConfig| c.validate().unwrap_err();
        // SRC: kp = 0 never cuts (a passthrough), with kp_recover = 0 the
        // integrator never rises again after a cut.
        for bad in [0.0, -1.0, f64::NAN] {
            let mut c = ControllersConfig::default();
            c.src.kp = bad;
            let e = field(c);
            assert_eq!(e.field, "src.kp", "{bad}");
            assert!(e.reason.contains("> 0"), "{}", e.reason);
            let mut c = ControllersConfig::default();
            c.src.kp_recover = bad;
            assert_eq!(field(c).field, "src.kp_recover", "{bad}");
        }
        // MTTE: a floor of 0 lets T_max collapse to 0; one above what a
        // road carries keeps MTTE from limiting there (2.0: ~1900 N m).
        for bad in [0.0, -0.01, 0.51, 2.0, f64::NAN, f64::INFINITY] {
            let mut c = ControllersConfig::default();
            c.mtte.mu_floor = bad;
            let e = field(c);
            assert_eq!(e.field, "mtte.mu_floor", "{bad}");
            assert!(e.reason.contains("(0, 0.5]"), "{}", e.reason);
            assert!(e.reason.contains(&format!("(got {bad})")), "{}", e.reason);
        }
        // MFC: no gain above the bound of the sampled loop.
        for bad in [500.5, 2000.0, f64::INFINITY, f64::NAN, -1.0] {
            let mut c = ControllersConfig::default();
            c.mfc.k_mfc = bad;
            let e = field(c);
            assert_eq!(e.field, "mfc.k_mfc", "{bad}");
            assert!(e.reason.contains("[0, 500]"), "{}", e.reason);
        }
        // The edges that stay.
        let mut c = ControllersConfig::default();
        c.src.kp = 1e-6;
        c.src.kp_recover = 1e-6;
        c.mtte.mu_floor = 0.5;
        c.mfc.k_mfc = 500.0;
        c.validate().unwrap();
        c.mtte.mu_floor = 1e-6;
        c.mfc.k_mfc = 0.0;
        c.validate().unwrap();
    }

    #[test]
    fn fallback_rule() {
        let u = ArteUse {
            max_age_s: 0.3,
            min_confidence: 0.6,
        };
        let k = knowledge();
        assert!(u.usable(Some(&k)).is_some());
        assert!(u.usable(None).is_none());
        assert!(u.usable(Some(&RoadKnowledge { age: 0.31, ..k })).is_none());
        assert!(u.usable(Some(&RoadKnowledge { age: 0.3, ..k })).is_some());
        assert!(
            u.usable(Some(&RoadKnowledge {
                confidence: 0.59,
                ..k
            }))
            .is_none()
        );
        assert!(
            u.usable(Some(&RoadKnowledge {
                confidence: f64::NAN,
                ..k
            }))
            .is_none()
        );
        assert!(
            u.usable(Some(&RoadKnowledge { age: f64::NAN, ..k }))
                .is_none()
        );
        assert!(
            u.usable(Some(&RoadKnowledge {
                lambda_opt: 1.0,
                ..k
            }))
            .is_none()
        );
        assert!(u.usable(Some(&RoadKnowledge { alpha: 0.0, ..k })).is_none());
        assert!(
            u.usable(Some(&RoadKnowledge {
                mu_peak: f64::INFINITY,
                ..k
            }))
            .is_none()
        );
    }
}
