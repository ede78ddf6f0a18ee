//! The paper's transfer functions (§III, eqs. 1-11) for a configured
//! vehicle, with the corrections listed in `crates/tcs/README.md`
//! ("Analysis"). Symbols:
//!
//! - `m = M/n`: the vehicle mass carried by the driven wheel (paper: M; the
//!   paper's Table IV values are per vehicle, the one-wheel model needs the
//!   share, crates/physics/README.md "Plant").
//! - `N`: the driven wheel's normal force, the vehicle's own
//!   [`VehicleParams::normal_force`], N = share · M g / n (`share` =
//!   `driven_load_share`; M g / n = m g on the paper's quarter car, share 1).
//! - `J(λ) = J_w + m r² (1 − λ)`: the inertia felt at the wheel at a constant
//!   slip λ (paper eq. 1); `J_model = J(0)` (eq. 2).
//! - `K`: motor torque constant, N m/A ([`K_MOTOR`] = 1 N m/A, so a current
//!   and a torque command are numerically the same; the paper leaves K
//!   undefined).
//! - `τ₁ = tau_m`: motor lag. `τ₂ = tau_hpf`: MFC high-pass.
//! - `a = dμ/dλ(λ_o)`: slope of the road's μ-λ curve at the operating slip.
//! - `M_w = J_w / r²`: the wheel's inertia as an equivalent mass (the paper's
//!   "M_W wheel inertia" in eqs. 7-8; not the wheel's mass m_wheel).

use grip_physics::VehicleParams;

use super::AnalysisError;
use super::poly::{Poly, fmt_num};
use super::tf::Tf;

/// Motor torque constant K used when none is given, N m/A.
pub const K_MOTOR: f64 = 1.0;

fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    reason: &'static str,
) -> Result<(), AnalysisError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(AnalysisError::InvalidParameter {
            name,
            value,
            reason,
        })
    }
}

fn slip(lambda: f64) -> Result<(), AnalysisError> {
    check(
        "lambda",
        lambda,
        (0.0..1.0).contains(&lambda),
        "slip must be in [0, 1)",
    )
}

fn vehicle_ok(v: &VehicleParams) -> Result<(), AnalysisError> {
    v.validate().map_err(AnalysisError::Vehicle)
}

fn p(desc: &[f64]) -> Result<Poly, AnalysisError> {
    Poly::new(desc)
}

/// Inertia felt at the wheel at constant slip λ, J_w + (M/n) r² (1 − λ)
/// (paper eq. 1 with M → M/n), kg m².
pub fn j_real(v: &VehicleParams, lambda: f64) -> f64 {
    v.j_w + v.mass_share() * v.r * v.r * (1.0 - lambda)
}

/// Δ of eq. (5), J_r = J_m / (1 + Δ): Δ = J_m / J_r − 1.
pub fn delta(j_m: f64, j_r: f64) -> f64 {
    j_m / j_r - 1.0
}

/// The MFC plant seen by the controller: motor lag and wheel inertia,
/// ω / I = K / (J s (τ₁ s + 1)), J = J(λ). The model inside the MFC is the
/// same with J = J_model.
pub fn mfc_plant(v: &VehicleParams, k_motor: f64, lambda: f64) -> Result<Tf, AnalysisError> {
    vehicle_ok(v)?;
    slip(lambda)?;
    check("k_motor", k_motor, k_motor > 0.0, "must be > 0")?;
    let j = j_real(v, lambda);
    Tf::new(p(&[k_motor])?, p(&[j * v.tau_m, j, 0.0])?)
}

/// Eq. (3), corrected: ω_diff / I_ref of the MFC loop with model inertia
/// `j_m`, real inertia `j_r`, gain `k_mfc` (N m s/rad with K = 1 N m/A) and
/// high-pass time constant `tau2`:
///
/// ```text
/// K (J_m − J_r) (τ₂ s + 1)
/// ─────────────────────────────────────────────────────────────────────
/// s [τ₁τ₂ J_m J_r s² + J_m J_r (τ₁+τ₂) s + J_m J_r + K_MFC τ₂ K (J_m − J_r)]
/// ```
///
/// The paper's numerator lacks the high-pass filter's factor (τ₂ s + 1).
pub fn mfc_omega_diff(
    v: &VehicleParams,
    k_motor: f64,
    j_m: f64,
    j_r: f64,
    k_mfc: f64,
    tau2: f64,
) -> Result<Tf, AnalysisError> {
    vehicle_ok(v)?;
    check("j_m", j_m, j_m > 0.0, "must be > 0")?;
    check("j_r", j_r, j_r > 0.0, "must be > 0")?;
    check("k_mfc", k_mfc, k_mfc >= 0.0, "must be >= 0")?;
    check("tau_hpf", tau2, tau2 > 0.0, "must be > 0")?;
    let t1 = v.tau_m;
    let jj = j_m * j_r;
    let num = p(&[k_motor * (j_m - j_r) * tau2, k_motor * (j_m - j_r)])?;
    let den = p(&[
        t1 * tau2 * jj,
        jj * (t1 + tau2),
        jj + k_mfc * tau2 * k_motor * (j_m - j_r),
        0.0,
    ])?;
    Tf::new(num, den)
}

/// The K_MFC bound of eq. (4) and what it means.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MfcBound {
    /// Δ = J_m / J_r − 1 (eq. 5).
    pub delta: f64,
    /// τ₂ used, s.
    pub tau2: f64,
    /// K_MFC ≤ J_m (τ₂ − τ₁)² / (4 τ₂² τ₁ K Δ), N m s/rad (∞ for Δ <= 0).
    pub bound: f64,
    /// The gain at which the loop (the bracket of eq. 3) stops being
    /// Hurwitz: K_MFC > −J_m J_r / (τ₂ K (J_m − J_r)); −∞ (never) for Δ > 0.
    pub hurwitz_limit: f64,
}

/// Eq. (4) with Δ from eq. (5). The bracket of eq. (3) is a quadratic with
/// positive s² and s coefficients: it is Hurwitz for every K_MFC ≥ 0 when
/// J_m > J_r. Eq. (4) is its discriminant ≥ 0, i.e. the condition for two
/// real (non-oscillating) poles, not for stability; the paper calls it
/// "absolute stability".
pub fn kmfc_bound(
    j_m: f64,
    j_r: f64,
    tau1: f64,
    tau2: f64,
    k_motor: f64,
) -> Result<MfcBound, AnalysisError> {
    check("j_m", j_m, j_m > 0.0, "must be > 0")?;
    check("j_r", j_r, j_r > 0.0, "must be > 0")?;
    check("tau_m", tau1, tau1 > 0.0, "must be > 0")?;
    check("tau_hpf", tau2, tau2 > 0.0, "must be > 0")?;
    check("k_motor", k_motor, k_motor > 0.0, "must be > 0")?;
    let d = delta(j_m, j_r);
    let bound = if d > 0.0 {
        j_m * (tau2 - tau1).powi(2) / (4.0 * tau2 * tau2 * tau1 * k_motor * d)
    } else {
        f64::INFINITY
    };
    let hurwitz_limit = if d > 0.0 {
        f64::NEG_INFINITY
    } else if d < 0.0 {
        -j_m * j_r / (tau2 * k_motor * (j_m - j_r))
    } else {
        f64::INFINITY
    };
    Ok(MfcBound {
        delta: d,
        tau2,
        bound,
        hurwitz_limit,
    })
}

/// Where the configured MFC gain lies above bound (4) for this vehicle: for
/// each road of `cat`, the real inertia at the road's λ_opt (where the MFC
/// is meant to hold the wheel), the bound with the loop's full lag
/// (τ₁ = τ_m + `tau_noise`, τ₂ = `tau_hpf`, K = [`K_MOTOR`]) and, if `k_mfc`
/// exceeds it, (road name, bound). Empty when the gain is within every road's
/// bound (the shipped vehicles). Above the bound the MFC loop is still
/// Hurwitz (Δ > 0 at any slip), but its poles are complex: the wheel speed
/// overshoots and rings where the paper's tuning assumed it would not. The
/// free-spinning wheel (J_r = J_w) is left out: every configuration exceeds
/// it, which is MFC's known limit cycle on a spinning wheel.
pub fn kmfc_above_bound(
    v: &VehicleParams,
    cat: &grip_physics::RoadCatalogue,
    mfc: &crate::MfcParams,
) -> Result<Vec<(String, f64)>, AnalysisError> {
    vehicle_ok(v)?;
    let jm = v.j_model();
    let mut above = Vec::new();
    for r in cat.iter() {
        let b = kmfc_bound(
            jm,
            j_real(v, r.lambda_opt()),
            v.tau_m + mfc.tau_noise,
            mfc.tau_hpf,
            K_MOTOR,
        )?;
        if mfc.k_mfc > b.bound {
            above.push((r.name().to_owned(), b.bound));
        }
    }
    Ok(above)
}

/// The roads [`kmfc_above_bound`] found, as the warnings list them
/// (`"gravel 359, stone 181"`, bounds in N m s/rad), and the lowest of
/// their bounds, floored: the largest gain within all of them.
pub fn kmfc_above_list(above: &[(String, f64)]) -> (String, f64) {
    let lowest = above.iter().map(|(_, b)| *b).fold(f64::INFINITY, f64::min);
    let roads: Vec<String> = above.iter().map(|(n, b)| format!("{n} {b:.0}")).collect();
    (roads.join(", "), lowest.floor())
}

/// The start-up warning for [`kmfc_above_bound`]: `None` when the gain is
/// within every road's bound; else one line naming the controllers file,
/// the gain, the vehicle file, the roads with their bounds and what to do.
pub fn kmfc_warning(
    v: &VehicleParams,
    vehicle_file: &std::path::Path,
    cat: &grip_physics::RoadCatalogue,
    mfc: &crate::MfcParams,
    controllers_file: &std::path::Path,
) -> Result<Option<String>, AnalysisError> {
    let above = kmfc_above_bound(v, cat, mfc)?;
    if above.is_empty() {
        return Ok(None);
    }
    let (roads, lowest) = kmfc_above_list(&above);
    Ok(Some(format!(
        "{}: [mfc] k_mfc = {} N m s/rad is above the MFC's no-overshoot bound (4) for the vehicle of {} \
         on {} of {} roads (bound at the road's lambda_opt, N m s/rad: {}): the loop stays stable but its \
         wheel speed overshoots and rings there; the gain is the paper's car's, set k_mfc at or below {:.0} \
         for this vehicle (`grip analyze --vehicle {}` shows the bounds)",
        controllers_file.display(),
        mfc.k_mfc,
        vehicle_file.display(),
        above.len(),
        cat.len(),
        roads,
        lowest,
        vehicle_file.display(),
    )))
}

/// SRC's gains as derived for a vehicle (crates/tcs/README.md,
/// "Controllers", SRC "Gains"). At the friction peak the slip answers the
/// torque like an integrator, (1 − λ)/(J_w ω), behind the motor lag τ_m;
/// the symmetric optimum for k/(s (τ_m s + 1)) gives `kp` and `ti`. Below
/// the peak the wheel drags its share of the car, (M/n) r², which bounds
/// `kp_recover`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SrcGains {
    /// `[src] kp` = J_w / (2 τ_m), N m s (per unit slip and wheel speed).
    pub kp: f64,
    /// `[src] ti` = 4 τ_m, s.
    pub ti: f64,
    /// The lower end of `[src] kp_recover`, J_w / (2 τ_m), N m s: the
    /// peak-tuned gain, with which the torque recovers slowly after a cut.
    pub kp_recover_min: f64,
    /// The upper end of `[src] kp_recover`, (J_w + (M/n) r²) / (2 τ_m) =
    /// J_model / (2 τ_m), N m s: the symmetric optimum of the wheel coupled
    /// to its share of the car, which recovers into a limit cycle on snow.
    pub kp_recover_max: f64,
}

/// How far `[src] kp` and `[src] ti` may lie from their derivation, as a
/// ratio either way, before [`src_gains_off`] names them: within it the
/// symmetric optimum's phase margin (36.9°) stays within 30.9-41.8° and its
/// crossover within 0.82-1.21 times the design's (test
/// `the_src_gain_ratio_keeps_the_symmetric_optimums_margin`;
/// crates/tcs/README.md, "The SRC gains on another car").
pub const SRC_GAIN_RATIO: f64 = 1.25;

/// [`SrcGains`] for the vehicle. Needs a motor lag: with τ_m = 0 the
/// symmetric optimum is not defined (an error naming `tau_m`).
pub fn src_gains(v: &VehicleParams) -> Result<SrcGains, AnalysisError> {
    vehicle_ok(v)?;
    check(
        "tau_m",
        v.tau_m,
        v.tau_m > 0.0,
        "SRC's gains are derived from the motor lag, which must be > 0",
    )?;
    let two_tau = 2.0 * v.tau_m;
    Ok(SrcGains {
        kp: v.j_w / two_tau,
        ti: 4.0 * v.tau_m,
        kp_recover_min: v.j_w / two_tau,
        kp_recover_max: v.j_model() / two_tau,
    })
}

/// One `[src]` gain that does not suit the vehicle, with what was derived
/// for it ([`src_gains_off`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SrcGainOff {
    /// `kp` more than [`SRC_GAIN_RATIO`] either way from J_w / (2 τ_m).
    Kp {
        /// As configured, N m s.
        configured: f64,
        /// J_w / (2 τ_m), N m s.
        derived: f64,
    },
    /// `ti` more than [`SRC_GAIN_RATIO`] either way from 4 τ_m.
    Ti {
        /// As configured, s.
        configured: f64,
        /// 4 τ_m, s.
        derived: f64,
    },
    /// `kp_recover` outside [J_w / (2 τ_m), (J_w + (M/n) r²) / (2 τ_m)].
    KpRecover {
        /// As configured, N m s.
        configured: f64,
        /// J_w / (2 τ_m), N m s.
        min: f64,
        /// (J_w + (M/n) r²) / (2 τ_m), N m s.
        max: f64,
    },
}

impl SrcGainOff {
    /// The key in `[src]`: `kp`, `ti` or `kp_recover`.
    pub fn key(&self) -> &'static str {
        match self {
            Self::Kp { .. } => "kp",
            Self::Ti { .. } => "ti",
            Self::KpRecover { .. } => "kp_recover",
        }
    }

    /// What is off, for the warnings: `[src] kp = 6 N m s is 0.2x the
    /// symmetric optimum J_w/(2 tau_m) = 30 N m s`.
    fn describe(&self) -> String {
        let ratio = |c: f64, d: f64| fmt_num((100.0 * c / d).round() / 100.0);
        match *self {
            Self::Kp {
                configured,
                derived,
            } => format!(
                "[src] kp = {} N m s is {}x the symmetric optimum J_w/(2 tau_m) = {} N m s",
                fmt_num(configured),
                ratio(configured, derived),
                fmt_num(derived)
            ),
            Self::Ti {
                configured,
                derived,
            } => format!(
                "[src] ti = {} s is {}x the symmetric optimum's 4 tau_m = {} s",
                fmt_num(configured),
                ratio(configured, derived),
                fmt_num(derived)
            ),
            Self::KpRecover {
                configured, min, ..
            } if configured < min => format!(
                "[src] kp_recover = {} N m s is below J_w/(2 tau_m) = {} N m s (the torque recovers slowly after a cut)",
                fmt_num(configured),
                fmt_num(min)
            ),
            Self::KpRecover {
                configured, max, ..
            } => format!(
                "[src] kp_recover = {} N m s is above (J_w + (M/n) r^2)/(2 tau_m) = {} N m s (the recovery overshoots into a limit cycle on snow)",
                fmt_num(configured),
                fmt_num(max)
            ),
        }
    }

    /// What to set instead: `kp = 30`, `kp_recover within [30, 716]`.
    fn fix(&self) -> String {
        match *self {
            Self::Kp { derived, .. } => format!("kp = {} N m s", fmt_num(derived)),
            Self::Ti { derived, .. } => format!("ti = {} s", fmt_num(derived)),
            Self::KpRecover { min, max, .. } => format!(
                "kp_recover within [{}, {}] N m s",
                fmt_num(min),
                fmt_num(max)
            ),
        }
    }
}

/// The `[src]` gains that do not suit this vehicle, in the file's order
/// (kp, ti, kp_recover); empty when all do (the shipped vehicles). `kp` and
/// `ti` are off when more than [`SRC_GAIN_RATIO`] either way from their
/// derivation ([`src_gains`]); `kp_recover` when outside its interval (to
/// rounding: 1e-9 of the end). A warning, never a refusal: the shipped
/// values are a derivation and a tuning, not limits.
pub fn src_gains_off(
    v: &VehicleParams,
    src: &crate::SrcParams,
) -> Result<Vec<SrcGainOff>, AnalysisError> {
    let g = src_gains(v)?;
    let beyond = |c: f64, d: f64| !(1.0 / SRC_GAIN_RATIO..=SRC_GAIN_RATIO).contains(&(c / d));
    let mut off = Vec::new();
    if beyond(src.kp, g.kp) {
        off.push(SrcGainOff::Kp {
            configured: src.kp,
            derived: g.kp,
        });
    }
    if beyond(src.ti, g.ti) {
        off.push(SrcGainOff::Ti {
            configured: src.ti,
            derived: g.ti,
        });
    }
    let (min, max) = (g.kp_recover_min, g.kp_recover_max);
    if src.kp_recover < min * (1.0 - 1e-9) || src.kp_recover > max * (1.0 + 1e-9) {
        off.push(SrcGainOff::KpRecover {
            configured: src.kp_recover,
            min,
            max,
        });
    }
    Ok(off)
}

/// The gains [`src_gains_off`] found, as the warnings say them: what is off
/// (`[src] kp = 6 N m s is 0.2x ...`), the vehicle's values they are
/// derived from (J_w and τ_m; M/n and r too when `kp_recover` is off), and
/// what to set.
pub fn src_gains_off_list(v: &VehicleParams, off: &[SrcGainOff]) -> (String, String, String) {
    let what: Vec<String> = off.iter().map(SrcGainOff::describe).collect();
    let fix: Vec<String> = off.iter().map(SrcGainOff::fix).collect();
    let mut values = format!(
        "J_w = {} kg m^2, tau_m = {} s",
        fmt_num(v.j_w),
        fmt_num(v.tau_m)
    );
    if off
        .iter()
        .any(|o| matches!(o, SrcGainOff::KpRecover { .. }))
    {
        values.push_str(&format!(
            ", M/n = {} kg, r = {} m",
            fmt_num(v.mass_share()),
            fmt_num(v.r)
        ));
    }
    (what.join(", "), values, fix.join(", "))
}

/// The start-up warning for [`src_gains_off`]: `None` when SRC's gains
/// suit the vehicle; else one line naming the controllers file, each key
/// that is off with its value and the value derived for this vehicle, the
/// vehicle file with the values it comes from, and what to do.
pub fn src_gain_warning(
    v: &VehicleParams,
    vehicle_file: &std::path::Path,
    src: &crate::SrcParams,
    controllers_file: &std::path::Path,
) -> Result<Option<String>, AnalysisError> {
    let off = src_gains_off(v, src)?;
    if off.is_empty() {
        return Ok(None);
    }
    let (what, values, fix) = src_gains_off_list(v, &off);
    Ok(Some(format!(
        "{}: {} for the vehicle of {} ({}): SRC's gains follow from the wheel's inertia and the motor's lag, \
         and these suit another car; set {} for this vehicle (`grip analyze --vehicle {}` shows the derivation)",
        controllers_file.display(),
        what,
        vehicle_file.display(),
        values,
        fix,
        vehicle_file.display(),
    )))
}

/// The start-up check of the gains of the controller `kind` against the
/// vehicle file: [`kmfc_warning`] for MFC, [`src_gain_warning`] for SRC,
/// none for MTTE (its gain K = J_w/(α (M/n) r) + r is computed from the
/// vehicle itself). tcs-loop logs it, `grip sim` prints it for each
/// controller it runs.
pub fn gain_warning(
    kind: crate::ControllerKind,
    v: &VehicleParams,
    vehicle_file: &std::path::Path,
    cat: &grip_physics::RoadCatalogue,
    controllers: &crate::ControllersConfig,
    controllers_file: &std::path::Path,
) -> Result<Option<String>, AnalysisError> {
    match kind {
        crate::ControllerKind::Mfc => {
            kmfc_warning(v, vehicle_file, cat, &controllers.mfc, controllers_file)
        }
        crate::ControllerKind::Src => {
            src_gain_warning(v, vehicle_file, &controllers.src, controllers_file)
        }
        crate::ControllerKind::Mtte => Ok(None),
    }
}

/// Parameters of the SRC slip plant, eqs. (6)-(8).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SrcSlip {
    /// Operating slip λ_o.
    pub lambda_o: f64,
    /// Slope a = dμ/dλ at λ_o.
    pub a: f64,
    /// Wheel circumferential speed V_w = r ω, m/s.
    pub v_w: f64,
    /// M_w = J_w / r², kg.
    pub m_w: f64,
    /// N_e = (M_w + m (1 − λ_o)) / m · N, eq. (8), N.
    pub n_e: f64,
    /// τ = M_w V_w / (a N_e), eq. (7), s (infinite for a = 0, negative past the peak).
    pub tau: f64,
    /// Static gain (1 − λ_o) / (r a N_e) of λ / T, 1/(N m) (eq. 6 divided by r).
    pub gain: f64,
}

/// Eqs. (6)-(8) at operating slip `lambda_o`, slope `a` and wheel speed `v_w`.
pub fn src_slip(
    v: &VehicleParams,
    lambda_o: f64,
    a: f64,
    v_w: f64,
) -> Result<SrcSlip, AnalysisError> {
    vehicle_ok(v)?;
    slip(lambda_o)?;
    check("a", a, true, "slope must be finite")?;
    check("v_w", v_w, v_w > 0.0, "wheel speed must be > 0")?;
    let m = v.mass_share();
    let n = v.normal_force();
    let m_w = v.j_w / (v.r * v.r);
    let n_e = (m_w + m * (1.0 - lambda_o)) / m * n;
    Ok(SrcSlip {
        lambda_o,
        a,
        v_w,
        m_w,
        n_e,
        tau: m_w * v_w / (a * n_e),
        gain: (1.0 - lambda_o) / (v.r * a * n_e),
    })
}

/// Eq. (6), corrected: λ / T (T in N m) =
/// (1 − λ_o) / (r a N_e) · 1 / (1 + τ s), written without dividing by a so
/// that a = 0 (the friction peak: an integrator) and a < 0 (past the peak:
/// an unstable pole) are represented:
///
/// ```text
/// λ / T = (1 − λ_o) / (r M_w V_w s + r a N_e)
/// ```
///
/// `per_mu` scales the input to the friction coefficient the torque asks
/// of the road, μ_T = T / (r N): λ / μ_T = r N · λ / T (dimensionless both
/// sides; used for the ν-gap).
pub fn src_slip_tf(s: &SrcSlip, v: &VehicleParams, per_mu: bool) -> Result<Tf, AnalysisError> {
    let scale = if per_mu { v.r * v.normal_force() } else { 1.0 };
    Tf::new(
        p(&[scale * (1.0 - s.lambda_o)])?,
        p(&[v.r * s.m_w * s.v_w, v.r * s.a * s.n_e])?,
    )
}

/// Eq. (9), corrected: V_diff / I = K r λ / (s (τ_m s + 1) J(λ)), with
/// J(λ) = J_w + m r² (1 − λ) = J_real of eq. (1)/(10). The paper writes the
/// bracket as M r² (1 − λ) + J_r, counting the vehicle share twice, and
/// drops K.
pub fn src_vdiff_tf(v: &VehicleParams, k_motor: f64, lambda: f64) -> Result<Tf, AnalysisError> {
    vehicle_ok(v)?;
    slip(lambda)?;
    let j = j_real(v, lambda);
    Tf::new(p(&[k_motor * v.r * lambda])?, p(&[v.tau_m * j, j, 0.0])?)
}

/// MTTE gain K = J_w / (α m r) + r (m), so that T_max = K F̂_d.
pub fn mtte_gain(v: &VehicleParams, alpha: f64) -> Result<f64, AnalysisError> {
    vehicle_ok(v)?;
    check(
        "alpha",
        alpha,
        alpha > 0.0 && alpha <= 1.0,
        "must be in (0, 1]",
    )?;
    Ok(v.j_w / (alpha * v.mass_share() * v.r) + v.r)
}

/// Eq. (11) as printed, with its symbols identified (the paper does not
/// define them; the identification reproduces its denominator and numerator
/// exactly, see the README): the MTTE loop with the driving-force observer
/// fed by the torque *command* T*, observer low-pass τ (`tau_lpf`), motor
/// lag τ₁ = tau_m, gain K = J_w/(α m r) + r, and an input-multiplicative
/// uncertainty on the wheel 1/(J_n s) (z = motor torque, w = Δ z):
///
/// ```text
/// T_zw = −J_w K / (J_n r τ₁ τ s² + J_n (r τ − K τ₁ + r τ₁) s + J_n r − (J_n − J_w) K)
/// ```
///
/// with J_n = J(λ) at operating slip λ (the paper's M r² is J_n − J_w).
/// The constant term is J_w r (1 − (1 − λ)/α): negative for α < 1 − λ, so
/// T_zw has a right-half-plane pole: T_max keeps growing (until the min with
/// the demand takes over) while the wheel grips, and decays once slip
/// exceeds 1 − α.
pub fn mtte_tzw_paper(
    v: &VehicleParams,
    alpha: f64,
    tau_lpf: f64,
    lambda: f64,
) -> Result<Tf, AnalysisError> {
    let k = mtte_gain(v, alpha)?;
    slip(lambda)?;
    check("tau_lpf", tau_lpf, tau_lpf > 0.0, "must be > 0")?;
    let (jn, r, t1, t) = (j_real(v, lambda), v.r, v.tau_m, tau_lpf);
    Tf::new(
        p(&[-v.j_w * k])?,
        p(&[
            jn * r * t1 * t,
            jn * (r * t - k * t1 + r * t1),
            jn * r - (jn - v.j_w) * k,
        ])?,
    )
}

/// T_zw for grip's MTTE (`crate::mtte`): the observer is fed the *measured*
/// torque and filtered by 1/(τ_o s + 1), and T_max passes a low-pass
/// 1/(τ_l s + 1); same uncertainty channel as [`mtte_tzw_paper`]:
///
/// ```text
/// T_zw = −J_w K / (J_n r (τ_o s + 1)(τ_l s + 1)(τ_m s + 1) − (J_n − J_w) K)
/// ```
pub fn mtte_tzw_grip(
    v: &VehicleParams,
    alpha: f64,
    tau_obs: f64,
    tau_lpf: f64,
    lambda: f64,
) -> Result<Tf, AnalysisError> {
    let k = mtte_gain(v, alpha)?;
    slip(lambda)?;
    check("tau_obs", tau_obs, tau_obs > 0.0, "must be > 0")?;
    check("tau_lpf", tau_lpf, tau_lpf > 0.0, "must be > 0")?;
    let jn = j_real(v, lambda);
    let q = p(&[tau_obs, 1.0])?
        .mul(&p(&[tau_lpf, 1.0])?)
        .mul(&p(&[v.tau_m, 1.0])?)
        .scale(jn * v.r);
    let den = q.sub(&Poly::constant((jn - v.j_w) * k));
    Tf::new(p(&[-v.j_w * k])?, den)
}

/// The element of the MTTE loop that the gain K multiplies, from the torque
/// command to the observed driving force expressed as a wheel torque:
/// r F̂_d / T* = (1 − J_w / J(λ)) / ((τ_m s + 1)(τ_o s + 1)) (dimensionless).
pub fn mtte_observer_plant(
    v: &VehicleParams,
    lambda: f64,
    tau_obs: f64,
) -> Result<Tf, AnalysisError> {
    vehicle_ok(v)?;
    slip(lambda)?;
    check("tau_obs", tau_obs, tau_obs > 0.0, "must be > 0")?;
    let g = 1.0 - v.j_w / j_real(v, lambda);
    Tf::new(p(&[g])?, p(&[v.tau_m, 1.0])?.mul(&p(&[tau_obs, 1.0])?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Complex;

    fn v() -> VehicleParams {
        VehicleParams::default()
    }

    #[test]
    fn mfc_eq3_matches_block_diagram() {
        let v = v();
        let (jm, jr) = (v.j_model(), j_real(&v, 0.17));
        let (k, kmfc, t2) = (1.3, 2.5, 1.0);
        let tf = mfc_omega_diff(&v, k, jm, jr, kmfc, t2).unwrap();
        for w in [0.05, 0.7, 13.0] {
            let s = Complex::new(0.0, w);
            let g = (jm - jr) / (jm * jr * s);
            let motor = k / (v.tau_m * s + 1.0);
            let h = t2 * s / (t2 * s + 1.0);
            let want = g * motor / (1.0 + kmfc * h * g * motor);
            assert!((tf.eval_c(s) - want).norm() < 1e-12 * want.norm(), "ω={w}");
        }
    }

    #[test]
    fn the_gain_check_names_the_roads_a_light_car_overshoots_on() {
        let cat = grip_physics::RoadCatalogue::burckhardt(&["asphalt", "snow", "stone"]).unwrap();
        let mfc = crate::MfcParams {
            k_mfc: 177.0,
            tau_hpf: 1.0,
            tau_noise: 0.004,
        };
        // the paper's car: within every road's bound, no warning
        assert!(kmfc_above_bound(&v(), &cat, &mfc).unwrap().is_empty());
        let none = kmfc_warning(&v(), "v.toml".as_ref(), &cat, &mfc, "c.toml".as_ref());
        assert_eq!(none.unwrap(), None);
        // a light car with small wheels: J_r on stone ≈ 4.2 kg m², bound well under 177
        let light = VehicleParams {
            mass: 800.0,
            r: 0.25,
            j_w: 0.4,
            ..v()
        };
        let above = kmfc_above_bound(&light, &cat, &mfc).unwrap();
        let names: Vec<&str> = above.iter().map(|(n, _)| n.as_str()).collect();
        assert!(names.contains(&"stone"), "{above:?}");
        assert!(!names.contains(&"snow"), "{above:?}");
        // each bound is eq. (4) written out here: J_m (τ₂ − τ₁)² / (4 τ₂² τ₁ Δ)
        for (name, bound) in &above {
            let road = cat.iter().find(|r| r.name() == name).unwrap();
            let m = light.mass_share();
            let jm = light.j_w + m * light.r * light.r;
            let jr = light.j_w + m * light.r * light.r * (1.0 - road.lambda_opt());
            let t1 = light.tau_m + 0.004;
            let want = jm * (1.0 - t1).powi(2) / (4.0 * t1 * (jm / jr - 1.0));
            assert!(
                (bound - want).abs() < 1e-9 * want,
                "{name}: {bound} vs {want}"
            );
            assert!(*bound < 177.0);
        }
        let w = kmfc_warning(
            &light,
            "my-car.toml".as_ref(),
            &cat,
            &mfc,
            "controllers.toml".as_ref(),
        )
        .unwrap()
        .unwrap();
        for says in [
            "controllers.toml",
            "k_mfc = 177",
            "my-car.toml",
            "stone",
            "grip analyze --vehicle my-car.toml",
        ] {
            assert!(w.contains(says), "{says}: {w}");
        }
    }

    #[test]
    fn a_heavier_wheel_with_a_quicker_motor_gets_its_own_src_gains() {
        let src = crate::SrcParams::default();
        // the paper's car: the shipped gains are its derivation
        let g = src_gains(&v()).unwrap();
        assert!(
            (g.kp - 6.0).abs() < 1e-12 && (g.ti - 0.2).abs() < 1e-12,
            "{g:?}"
        );
        assert!((g.kp_recover_max - 280.4).abs() < 1e-9, "{g:?}");
        assert!(src_gains_off(&v(), &src).unwrap().is_empty());
        let none = src_gain_warning(&v(), "v.toml".as_ref(), &src, "c.toml".as_ref());
        assert_eq!(none.unwrap(), None);
        // twice the wheel, a motor 2.5 times quicker
        let car = VehicleParams {
            j_w: 1.2,
            tau_m: 0.02,
            ..v()
        };
        let off = src_gains_off(&car, &src).unwrap();
        let keys: Vec<&str> = off.iter().map(SrcGainOff::key).collect();
        assert_eq!(keys, ["kp", "ti", "kp_recover"]);
        let SrcGainOff::Kp {
            configured,
            derived,
        } = off[0]
        else {
            panic!("{off:?}")
        };
        assert_eq!(configured, 6.0);
        assert!((derived - 30.0).abs() < 1e-9, "{derived}");
        let SrcGainOff::Ti { derived, .. } = off[1] else {
            panic!("{off:?}")
        };
        assert!((derived - 0.08).abs() < 1e-12, "{derived}");
        // (1.2 + 350 · 0.28²) / 0.04 = 716
        let SrcGainOff::KpRecover { min, max, .. } = off[2] else {
            panic!("{off:?}")
        };
        assert!(
            (min - 30.0).abs() < 1e-9 && (max - 716.0).abs() < 1e-9,
            "{min} {max}"
        );
        let w = src_gain_warning(
            &car,
            "my-car.toml".as_ref(),
            &src,
            "controllers.toml".as_ref(),
        )
        .unwrap()
        .unwrap();
        assert!(
            w.starts_with("controllers.toml: [src] kp = 6 N m s is 0.2x"),
            "{w}"
        );
        for says in [
            "J_w/(2 tau_m) = 30 N m s",
            "[src] ti = 0.2 s is 2.5x the symmetric optimum's 4 tau_m = 0.08 s",
            "[src] kp_recover = 20 N m s is below J_w/(2 tau_m) = 30 N m s",
            "for the vehicle of my-car.toml (J_w = 1.2 kg m^2, tau_m = 0.02 s, M/n = 350 kg, r = 0.28 m)",
            "set kp = 30 N m s, ti = 0.08 s, kp_recover within [30, 716] N m s",
            "grip analyze --vehicle my-car.toml",
        ] {
            assert!(w.contains(says), "{says}: {w}");
        }
        assert_eq!(w.lines().count(), 1, "{w}");
        // J_w alone: kp moves (12), ti does not, 20 is inside [12, 286.4]
        let heavy = VehicleParams { j_w: 1.2, ..v() };
        let keys: Vec<&str> = src_gains_off(&heavy, &src)
            .unwrap()
            .iter()
            .map(SrcGainOff::key)
            .collect();
        assert_eq!(keys, ["kp"]);
    }

    #[test]
    fn kp_and_ti_are_checked_as_a_ratio_kp_recover_against_its_interval() {
        let at = |kp, ti, kp_recover| {
            let src = crate::SrcParams {
                kp,
                ti,
                kp_recover,
                ..crate::SrcParams::default()
            };
            src_gains_off(&v(), &src).unwrap()
        };
        // within 1.25x either way of 6 N m s and 0.2 s: nothing
        assert!(at(7.4, 0.17, 20.0).is_empty());
        assert!(at(4.9, 0.24, 20.0).is_empty());
        assert_eq!(at(7.6, 0.2, 20.0)[0].key(), "kp");
        assert_eq!(at(4.7, 0.2, 20.0)[0].key(), "kp");
        assert_eq!(at(6.0, 0.15, 20.0)[0].key(), "ti");
        assert_eq!(at(6.0, 0.26, 20.0)[0].key(), "ti");
        // kp_recover: anywhere in [6, 280.4], its ends included; no ratio
        for inside in [6.0, 7.4, 100.0, 280.4] {
            assert!(at(6.0, 0.2, inside).is_empty(), "{inside}");
        }
        for (outside, says) in [
            (5.9, "is below J_w/(2 tau_m) = 6 N m s"),
            (281.0, "is above (J_w + (M/n) r^2)/(2 tau_m) = 280.4 N m s"),
        ] {
            let src = crate::SrcParams {
                kp_recover: outside,
                ..crate::SrcParams::default()
            };
            let off = src_gains_off(&v(), &src).unwrap();
            assert_eq!(off.len(), 1, "{off:?}");
            assert_eq!(off[0].key(), "kp_recover");
            let w = src_gain_warning(&v(), "car.toml".as_ref(), &src, "ctl.toml".as_ref())
                .unwrap()
                .unwrap();
            assert!(w.contains(says), "{says}: {w}");
            assert!(w.contains("M/n = 350 kg, r = 0.28 m"), "{w}");
            assert!(w.starts_with("ctl.toml: [src] kp_recover = "), "{w}");
            assert!(w.contains("vehicle of car.toml"), "{w}");
        }
        // with kp_recover fine, M/n and r are not the warning's business
        let w = src_gain_warning(
            &v(),
            "car.toml".as_ref(),
            &crate::SrcParams {
                kp: 12.0,
                ..crate::SrcParams::default()
            },
            "ctl.toml".as_ref(),
        )
        .unwrap()
        .unwrap();
        assert!(!w.contains("M/n"), "{w}");
        // no motor lag, no symmetric optimum: an error naming tau_m
        let e = src_gains(&VehicleParams { tau_m: 0.0, ..v() }).unwrap_err();
        assert!(e.to_string().contains("tau_m"), "{e}");
    }

    /// The tolerance of [`SRC_GAIN_RATIO`] in the loop the gains are
    /// derived for: the slip at the friction peak, k/s with k = (1 − λ)/(J_w ω),
    /// behind the motor lag 1/(τ_m s + 1), under the PI
    /// K_p (1 + 1/(T_i s)) with K_p = c/(2 k τ_m), T_i = d · 4 τ_m. At c = d = 1
    /// (the symmetric optimum) the phase margin is 36.9° at ω_c = 1/(2 τ_m);
    /// anywhere in c, d ∈ [1/1.25, 1.25] it is 30.9-41.8° with ω_c
    /// 0.82-1.21 times that.
    #[test]
    fn the_src_gain_ratio_keeps_the_symmetric_optimums_margin() {
        let tau = v().tau_m;
        let margin = |c: f64, d: f64| {
            let open = |w: f64| {
                let s = Complex::new(0.0, w);
                c / (2.0 * tau) * (1.0 + 1.0 / (d * 4.0 * tau * s)) / (s * (tau * s + 1.0))
            };
            // |L| falls with ω: bisect for the crossover
            let (mut lo, mut hi) = (1e-3 / tau, 1e3 / tau);
            for _ in 0..200 {
                let mid = (lo * hi).sqrt();
                if open(mid).norm() > 1.0 {
                    lo = mid
                } else {
                    hi = mid
                }
            }
            (180.0 + open(lo).arg().to_degrees(), lo * 2.0 * tau)
        };
        let (pm, wc) = margin(1.0, 1.0);
        assert!(
            (pm - 36.87).abs() < 0.01 && (wc - 1.0).abs() < 1e-6,
            "{pm} {wc}"
        );
        let r = SRC_GAIN_RATIO;
        let steps: Vec<f64> = (0..=8)
            .map(|i| (1.0 / r) * (r * r).powf(i as f64 / 8.0))
            .collect();
        let (mut pm_lo, mut pm_hi, mut wc_lo, mut wc_hi) = (f64::MAX, 0.0_f64, f64::MAX, 0.0_f64);
        for &c in &steps {
            for &d in &steps {
                let (pm, wc) = margin(c, d);
                (pm_lo, pm_hi, wc_lo, wc_hi) =
                    (pm_lo.min(pm), pm_hi.max(pm), wc_lo.min(wc), wc_hi.max(wc));
            }
        }
        assert!(
            (30.85..30.95).contains(&pm_lo) && (41.75..41.85).contains(&pm_hi),
            "{pm_lo} {pm_hi}"
        );
        assert!(
            (0.815..0.825).contains(&wc_lo) && (1.2..1.215).contains(&wc_hi),
            "{wc_lo} {wc_hi}"
        );
    }

    #[test]
    fn kmfc_bound_is_the_double_root() {
        let v = v();
        let (jm, jr) = (v.j_model(), j_real(&v, 0.4));
        let b = kmfc_bound(jm, jr, v.tau_m, 1.0, 1.0).unwrap();
        // at the bound the bracket has a double real root
        let tf = mfc_omega_diff(&v, 1.0, jm, jr, b.bound, 1.0).unwrap();
        let d = tf.den.coeffs_desc(); // [a2, a1, a0, 0]
        let disc = d[1] * d[1] - 4.0 * d[0] * d[2];
        assert!(disc.abs() < 1e-9 * d[1] * d[1], "{disc}");
        let over = mfc_omega_diff(&v, 1.0, jm, jr, 1.01 * b.bound, 1.0).unwrap();
        let poles = over.poles().unwrap();
        assert!(poles.iter().any(|p| p.im.abs() > 0.0));
        assert!(poles.iter().all(|p| p.re <= 0.0)); // still stable
        assert!((b.delta - (jm / jr - 1.0)).abs() < 1e-15);
        // free-spinning wheel, tau2 = 1 s: the configured K_MFC = 2.5 is 0.9 x this
        let free = kmfc_bound(jm, v.j_w, v.tau_m, 1.0, 1.0).unwrap();
        // 28.04 · 0.95² / (4 · 0.05 · (28.04/0.6 − 1)) = 2.7667
        assert!((free.bound - 2.7667).abs() < 1e-3, "{}", free.bound);
    }

    #[test]
    fn src_forms_agree() {
        let v = v();
        let s = src_slip(&v, 0.1, 3.0, 6.0).unwrap();
        let tf = src_slip_tf(&s, &v, false).unwrap();
        for w in [0.0, 2.0, 300.0] {
            let x = Complex::new(0.0, w);
            let want = s.gain / (1.0 + s.tau * x);
            assert!((tf.eval_c(x) - want).norm() < 1e-12 * want.norm());
        }
        // past the peak: unstable
        let s = src_slip(&v, 0.3, -0.2, 6.0).unwrap();
        assert_eq!(src_slip_tf(&s, &v, true).unwrap().rhp_poles().unwrap(), 1);
    }

    /// The slip plant against a direct linearisation of the one-wheel model
    /// with (1 − λ) frozen at λ_o (the paper's assumption):
    /// dλ/dt = [(1−λ_o) r T / J_w − μ(λ) N ((1−λ_o) r²/J_w + 1/m)] / V_w.
    #[test]
    fn src_matches_linearised_ode() {
        let v = v();
        let (lo, a, vw) = (0.08, 2.5, 5.0);
        let s = src_slip(&v, lo, a, vw).unwrap();
        let m = v.mass_share();
        let n = v.normal_force();
        let b_t = (1.0 - lo) * v.r / v.j_w / vw; // ∂λ̇/∂T
        let b_l = -a * n * ((1.0 - lo) * v.r * v.r / v.j_w + 1.0 / m) / vw; // ∂λ̇/∂λ
        assert!((s.gain - b_t / -b_l).abs() < 1e-12 * s.gain);
        assert!((s.tau - 1.0 / -b_l).abs() < 1e-12 * s.tau);
    }

    /// N in the SRC slip plant (eq. 8's N_e and the per-μ scale r N) is
    /// the vehicle's own normal force, the one the plant's tyre force uses:
    /// share · M g / n, not (M/n) g, which is twice it on a rear-driven car
    /// with half its weight on the driven axle (front-mic.toml).
    #[test]
    fn src_uses_the_plants_normal_force() {
        use grip_physics::{Plant, PlantState, Road};
        for v in [
            v(),
            VehicleParams {
                n_driven: 2.0,
                driven_load_share: 0.5,
                mic_lead_m: 2.77,
                ..v()
            },
        ] {
            let snow = Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap();
            let mut plant = Plant::new(v, PlantState::rolling(5.0, v.r)).unwrap();
            plant.step(1e-3, 100.0, &snow, 0.0);
            let n_plant = plant.fx() / plant.mu();
            assert!((n_plant - v.normal_force()).abs() < 1e-9 * n_plant);
            let (lo, a) = (0.1, 3.0);
            let s = src_slip(&v, lo, a, 6.0).unwrap();
            let m = v.mass_share();
            let n = s.n_e * m / (s.m_w + m * (1.0 - lo));
            assert!((n - n_plant).abs() < 1e-9 * n_plant, "{n} vs {n_plant}");
            let x = Complex::new(0.0, 0.0);
            let per_t = src_slip_tf(&s, &v, false).unwrap().eval_c(x);
            let per_mu = src_slip_tf(&s, &v, true).unwrap().eval_c(x);
            let scale = (per_mu / per_t).re;
            assert!((scale - v.r * n_plant).abs() < 1e-9 * scale, "{scale}");
        }
    }

    #[test]
    fn mtte_tzw_matches_block_diagram() {
        let v = v();
        let (alpha, tl, to, lambda) = (0.9, 0.05, 0.01, 0.1);
        let k = mtte_gain(&v, alpha).unwrap();
        let jn = j_real(&v, lambda);
        let paper = mtte_tzw_paper(&v, alpha, tl, lambda).unwrap();
        let grip = mtte_tzw_grip(&v, alpha, to, tl, lambda).unwrap();
        for w in [0.1, 3.0, 40.0] {
            let s = Complex::new(0.0, w);
            let motor = 1.0 / (v.tau_m * s + 1.0);
            // paper: observer on the command: T* = K (T* − J_w s ω)/(r(τ s+1)),
            // ω = (T + w)/(J_n s), T = motor T*  =>  z/w with z = T
            let a = k * v.j_w / jn; // T* (r(τs+1) − K) = −a (T + w)
            let l = r_lp(v.r, tl, s) - k;
            let want = -a * motor / (l + a * motor);
            assert!(
                (paper.eval_c(s) - want).norm() < 1e-9 * want.norm(),
                "paper ω={w}"
            );
            // grip: observer on the measured torque, filtered; LPF on T_max
            let q = v.r * (to * s + 1.0) * (tl * s + 1.0) / motor;
            let want = -k * v.j_w / (jn * q - (jn - v.j_w) * k);
            assert!(
                (grip.eval_c(s) - want).norm() < 1e-9 * want.norm(),
                "grip ω={w}"
            );
        }
        // constant term J_w r (1 − (1 − λ)/α)
        let c0 = paper.den.coeff(0);
        assert!((c0 - v.j_w * v.r * (1.0 - (1.0 - lambda) / alpha)).abs() < 1e-12);
        // α = 1 − λ: marginal (pole at 0); α < 1 − λ: a right-half-plane pole
        assert_eq!(
            mtte_tzw_paper(&v, 0.85, tl, lambda)
                .unwrap()
                .rhp_poles()
                .unwrap(),
            1
        );
        assert_eq!(
            mtte_tzw_paper(&v, 0.9, tl, lambda)
                .unwrap()
                .imag_axis_poles()
                .unwrap(),
            1
        );
    }

    fn r_lp(r: f64, t: f64, s: Complex<f64>) -> Complex<f64> {
        r * (t * s + 1.0)
    }

    #[test]
    fn bad_parameters_are_named() {
        let v = v();
        let e = mfc_plant(&v, 1.0, 1.2).unwrap_err();
        assert!(e.to_string().contains("lambda"), "{e}");
        let e = src_slip(&v, 0.1, f64::NAN, 5.0).unwrap_err();
        assert!(e.to_string().contains("`a`"), "{e}");
        let bad = VehicleParams { mass: -1.0, ..v };
        assert!(mfc_plant(&bad, 1.0, 0.1).is_err());
    }
}
