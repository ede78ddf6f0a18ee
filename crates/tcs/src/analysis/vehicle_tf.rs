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
use super::poly::Poly;
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
