//! Vehicle parameters (paper Table IV; README.md, "Plant").

use crate::validate::{self, InvalidField};

/// Parameters of the vehicle and its driven wheel. Defaults are the paper's
/// Table IV plus the choices in README.md, "Plant" (n = 4 driven wheels).
///
/// Deserialises from TOML (`[vehicle]` in `config/vehicle.toml`); a missing
/// field takes its default, an unknown one is an error. Call
/// [`VehicleParams::validate`] after loading.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleParams {
    /// Vehicle mass M, kg.
    pub mass: f64,
    /// Driven wheels sharing the vehicle, n (the wheel carries M/n).
    pub n_driven: f64,
    /// Wheel + shaft inertia J_w, kg m^2.
    pub j_w: f64,
    /// Tyre radius r of the driven wheel, m.
    pub r: f64,
    /// Rolling radius of the non-driven reference wheel whose speed gives
    /// the vehicle speed (CAN `OmegaRef`: V = r_ref · OmegaRef), m. `None`
    /// (the field left out, every shipped file) = the driven tyre's `r`;
    /// set it for staggered tyres, where a 4 % radius difference would
    /// otherwise read as a constant slip of about 0.04. Used by tcs-loop
    /// (V from OmegaRef) and plant-sim (OmegaRef = V / r_ref); the plant
    /// and `grip sim` work with V itself. See [`VehicleParams::ref_radius`].
    pub r_ref: Option<f64>,
    /// Wheel mass m, kg. Informational: it is part of M and is not used
    /// separately by the quarter-vehicle plant (the paper lists it in Table IV).
    pub m_wheel: f64,
    /// Motor torque lag tau_m, s (first order).
    pub tau_m: f64,
    /// Rolling resistance coefficient C_rr.
    pub c_rr: f64,
    /// Air density rho, kg/m^3.
    pub rho: f64,
    /// Drag area C_d A, m^2.
    pub c_d_a: f64,
    /// Speed floor in the slip denominator, m/s.
    pub v_eps: f64,
    /// Torque limit of ONE driven wheel, N m (|T| is clamped to this).
    /// grip's torques are per driven wheel (the quarter car): for one motor
    /// driving `n_driven` wheels through a gear ratio i, torque_max =
    /// motor torque limit × i ÷ n_driven (a motor per wheel: its own limit
    /// × its ratio).
    pub torque_max: f64,
    /// Power limit of ONE driven wheel's drive, W: above the base speed
    /// ω_b = power_max / torque_max the torque the drive can give falls as
    /// power_max / |ω| (an electric drive: constant torque to its base
    /// speed, constant power above it, by field weakening). grip's powers
    /// are per driven wheel like its torques: one motor driving `n_driven`
    /// wheels gives each power_max = motor power ÷ n_driven. `None` (the
    /// field left out; `config/vehicle.toml`, the paper's Table IV has no
    /// power limit) = no limit but `torque_max`. See
    /// [`VehicleParams::torque_limit`].
    pub power_max: Option<f64>,
    /// Share of the vehicle's weight carried by the driven wheels together,
    /// (0, 1]: the driven wheel's normal force is N = share · M g / n. 1
    /// (default: every wheel driven, n = 4, the paper's set-up) gives
    /// N = M g / n; a rear-driven car with n = 2 and 50 % on the rear axle
    /// has 0.5.
    pub driven_load_share: f64,
    /// Where the microphone hears the road, m along the path ahead of the
    /// driven (controlled) wheel's contact patch: 0 (default) = at the
    /// driven wheel, the paper's set-up; a front-wheel-arch microphone on a
    /// rear-driven car hears the road one wheelbase ahead. Not used by the
    /// plant; the simulator, plant-sim's ground truth, audio-acq's synthetic
    /// source and the preview queue of the controllers use it.
    pub mic_lead_m: f64,
}

impl Default for VehicleParams {
    fn default() -> Self {
        Self {
            mass: 1400.0,
            n_driven: 4.0,
            j_w: 0.6,
            r: 0.28,
            r_ref: None,
            m_wheel: 10.0,
            tau_m: 0.05,
            c_rr: 0.015,
            rho: 1.2,
            c_d_a: 0.7,
            v_eps: 0.1,
            torque_max: 1000.0,
            power_max: None,
            driven_load_share: 1.0,
            mic_lead_m: 0.0,
        }
    }
}

impl VehicleParams {
    /// Mass carried by one driven wheel, M/n, kg.
    pub fn mass_share(&self) -> f64 {
        self.mass / self.n_driven
    }
    /// Cycles of `dt` it takes, rolling at `v0` m/s, to cover the
    /// microphone's lead (`mic_lead_m`): `⌈lead / (v0 dt)⌉`, 0 without a lead
    /// or from standstill. The pre-roll of `grip sim` and plant-sim: the car
    /// rolls this far before the scenario's x = 0, so that the microphone has
    /// heard the road from 0 to the lead when the wheel gets there.
    pub fn pre_roll_cycles(&self, v0: f64, dt: f64) -> u64 {
        let lead = self.mic_lead_m;
        if lead > 0.0 && v0 > 0.0 && dt > 0.0 {
            (lead / (v0 * dt)).ceil() as u64
        } else {
            0
        }
    }
    /// Rolling radius of the reference wheel, m: `r_ref`, or the driven
    /// tyre's `r` when the file leaves it out.
    pub fn ref_radius(&self) -> f64 {
        self.r_ref.unwrap_or(self.r)
    }
    /// The torque the drive can give at wheel speed `omega` (rad/s), N m:
    /// `torque_max`, or power_max / |ω| above the base speed power_max /
    /// torque_max when the file sets [`VehicleParams::power_max`]. A
    /// non-finite ω gives `torque_max`.
    pub fn torque_limit(&self, omega: f64) -> f64 {
        match self.power_max {
            Some(power) if omega.abs() * self.torque_max > power => power / omega.abs(),
            _ => self.torque_max,
        }
    }
    /// Normal force on the driven wheel, N = share · M g / n
    /// ([`VehicleParams::driven_load_share`]; M g / n by default).
    pub fn normal_force(&self) -> f64 {
        self.driven_load_share * self.mass * crate::G / self.n_driven
    }
    /// The vehicle in one line, as reports name it beside their figures:
    /// mass and driven wheels with the driven wheel's normal force, tyre
    /// radius, motor lag, the drive's torque limit and power limit (with
    /// the speed it starts to derate at, or that there is none), and where
    /// the microphone hears the road.
    pub fn describe(&self) -> String {
        let power = match self.power_max {
            Some(p) => {
                let base = p / self.torque_max;
                format!(
                    "power_max {} kW per driven wheel (derates above {:.0} rad/s, {:.0} km/h)",
                    p / 1e3,
                    base,
                    base * self.r * 3.6
                )
            }
            None => "no power limit (power_max not set)".to_owned(),
        };
        let mic = if self.mic_lead_m > 0.0 {
            format!("microphone {} m ahead of the driven wheel", self.mic_lead_m)
        } else {
            "microphone at the driven wheel (lead 0)".to_owned()
        };
        format!(
            "M {} kg, {} driven wheel{} with {}% of the weight on them (N {:.1} N each), r {} m, tau_m {} s, torque_max {} N m per driven wheel, {power}, {mic}",
            self.mass,
            self.n_driven,
            if self.n_driven == 1.0 { "" } else { "s" },
            self.driven_load_share * 100.0,
            self.normal_force(),
            self.r,
            self.tau_m,
            self.torque_max,
        )
    }
    /// Inertia of the vehicle share reflected to the wheel, J_w + (M/n) r^2 (paper eq. 2).
    pub fn j_model(&self) -> f64 {
        self.j_w + self.mass_share() * self.r * self.r
    }

    /// The `[vehicle]` fields that take their default when a file leaves
    /// them out, in the order of `config/vehicle.toml`, with their values
    /// here (`r_ref` is not among them: left out, it is `r`). The loader
    /// names those a file left out (`grip-config`).
    pub fn defaultable_fields(&self) -> [(&'static str, f64); 13] {
        [
            ("mass", self.mass),
            ("n_driven", self.n_driven),
            ("j_w", self.j_w),
            ("r", self.r),
            ("m_wheel", self.m_wheel),
            ("tau_m", self.tau_m),
            ("c_rr", self.c_rr),
            ("rho", self.rho),
            ("c_d_a", self.c_d_a),
            ("v_eps", self.v_eps),
            ("torque_max", self.torque_max),
            ("driven_load_share", self.driven_load_share),
            ("mic_lead_m", self.mic_lead_m),
        ]
    }

    /// Check that every value is one a real road vehicle can have, with
    /// margin (NaN and infinities fail everywhere; the ranges and their
    /// reasons: crates/physics/README.md, "Plausible values"):
    ///
    /// | field | range |
    /// |---|---|
    /// | mass | [20, 300 000] kg |
    /// | n_driven | a whole number 1 to 8 |
    /// | j_w | [0.01, 100] kg m² |
    /// | r, r_ref | [0.1, 1.0] m |
    /// | m_wheel | [0, mass) kg |
    /// | tau_m | [0, 0.5] s |
    /// | c_rr | [0, 0.05] |
    /// | rho | [0.5, 1.6] kg/m³ |
    /// | c_d_a | [0, 15] m² |
    /// | v_eps | (0, 1] m/s |
    /// | torque_max | (0, 100 000] N m (one driven wheel) |
    /// | power_max | [1 000, 10 000 000] W (one driven wheel) |
    /// | driven_load_share | (0, 1] |
    /// | mic_lead_m | [0, 20] m |
    ///
    /// A value out of range fails naming the field, the value, the range,
    /// what real vehicles have and, where the value is plausible in another
    /// unit (`r = 334`: millimetres), that unit.
    pub fn validate(&self) -> Result<(), InvalidField> {
        plausible(
            "mass",
            self.mass,
            Range::closed(20.0, 300_000.0),
            "kg",
            "a car has 800-3500 kg, a motorcycle 100-400 kg, an articulated truck up to 44 t, a road train up to 200 t",
            &[(1000.0, "t"), (1e-3, "g"), (0.4536, "lb")],
        )?;
        if !(self.n_driven.is_finite()
            && self.n_driven.fract() == 0.0
            && (1.0..=8.0).contains(&self.n_driven))
        {
            return Err(InvalidField::new(
                "n_driven",
                format!(
                    "{} is not a whole number of driven wheels from 1 to 8, the range that holds every real road vehicle with margin (a motorcycle 1, a two-wheel-drive car 2, an all-wheel-drive car 4, an 8x8 truck 8; the weight is shared among whole wheels)",
                    self.n_driven
                ),
            ));
        }
        plausible(
            "j_w",
            self.j_w,
            Range::closed(0.01, 100.0),
            "kg m^2",
            "a car's wheel and tyre 0.5-1.5 kg m^2, more with the motor's rotor reflected through its gear ratio; a truck's twin wheels 20-40 kg m^2",
            &[(1e-4, "kg cm^2"), (1e-6, "g cm^2")],
        )?;
        let radius = "a car's tyre rolls at 0.27-0.36 m, a motorcycle's 0.28-0.33 m, a truck's 0.45-0.55 m, a road-going tractor's up to 0.9 m; the radius, not the diameter";
        let radius_units: &[(f64, &str)] = &[(1e-3, "mm"), (1e-2, "cm"), (0.0254, "inch")];
        plausible(
            "r",
            self.r,
            Range::closed(0.1, 1.0),
            "m",
            radius,
            radius_units,
        )?;
        if let Some(r_ref) = self.r_ref {
            plausible(
                "r_ref",
                r_ref,
                Range::closed(0.1, 1.0),
                "m",
                radius,
                radius_units,
            )?;
        }
        validate::non_negative("m_wheel", self.m_wheel)?;
        if self.m_wheel >= self.mass {
            return Err(InvalidField::new(
                "m_wheel",
                format!(
                    "must be smaller than the vehicle mass {} (got {})",
                    self.mass, self.m_wheel
                ),
            ));
        }
        plausible(
            "tau_m",
            self.tau_m,
            Range::closed(0.0, 0.5),
            "s",
            "an electric drive's torque settles in 1-50 ms (the paper: 0.05 s), a combustion engine's in 0.1-0.3 s",
            &[(1e-3, "ms")],
        )?;
        plausible(
            "c_rr",
            self.c_rr,
            Range::closed(0.0, 0.05),
            "",
            "road tyres roll at 0.006-0.015 on asphalt, up to about 0.03 on gravel or snow; the rolling resistance coefficient, not the road's friction coefficient (that is roads.toml's)",
            &[(0.01, "%")],
        )?;
        plausible(
            "rho",
            self.rho,
            Range::closed(0.5, 1.6),
            "kg/m^3",
            "air is 1.2 kg/m^3 at sea level and 20 °C, 0.74 at 5000 m, 1.5 at -40 °C",
            &[(1e-3, "g/m^3")],
        )?;
        plausible(
            "c_d_a",
            self.c_d_a,
            Range::closed(0.0, 15.0),
            "m^2",
            "the drag area C_d A: a car 0.5-1.0 m^2, a truck or bus 5-10 m^2; 0 switches air drag off",
            &[],
        )?;
        plausible(
            "v_eps",
            self.v_eps,
            Range::open_closed(0.0, 1.0),
            "m/s",
            "a numerical floor of the slip denominator, the paper's 0.1 m/s; above 1 m/s it changes the slip at driving speeds",
            &[(1.0 / 3.6, "km/h")],
        )?;
        plausible(
            "torque_max",
            self.torque_max,
            Range::open_closed(0.0, 100_000.0),
            "N m",
            "ONE driven wheel's torque limit, motor torque x gear ratio / n_driven for one motor driving n_driven wheels: a car 500-5000 N m, a heavy truck up to about 40 000 N m",
            &[],
        )?;
        if let Some(power) = self.power_max {
            let watts = Range::closed(1e3, 1e7);
            plausible(
                "power_max",
                power,
                watts,
                "W",
                "ONE driven wheel's share of the drive's power, in watts: motor power / n_driven for one motor driving n_driven wheels; a car's motor has 50-400 kW in all, a heavy truck's up to about 700 kW; leave the field out for no power limit",
                &[(1e3, "kW"), (745.7, "hp")],
            )
            .map_err(|mut e| {
                // a motor's total in kW, given for the whole car: name the
                // per-wheel value too
                let per_wheel = power * 1e3 / self.n_driven;
                if self.n_driven > 1.0 && watts.contains(per_wheel) {
                    e.reason.push_str(&format!(
                        "; a motor of {power} kW over the n_driven = {} driven wheels is {} W per wheel",
                        self.n_driven,
                        round_sig(per_wheel)
                    ));
                }
                e
            })?;
        }
        plausible(
            "driven_load_share",
            self.driven_load_share,
            Range::open_closed(0.0, 1.0),
            "",
            "the share of the car's weight on the driven wheels together: 1 with every wheel driven, about 0.4-0.6 on one driven axle",
            &[(0.01, "%")],
        )?;
        plausible(
            "mic_lead_m",
            self.mic_lead_m,
            Range::closed(0.0, 20.0),
            "m",
            "0 at the driven wheel; a car's wheelbase is 2.3-3.2 m, a truck's up to about 6 m",
            &[],
        )?;
        Ok(())
    }
}

/// A plausible range, inclusive unless `lo_open`.
#[derive(Debug, Clone, Copy)]
struct Range {
    lo: f64,
    hi: f64,
    lo_open: bool,
}

impl Range {
    fn closed(lo: f64, hi: f64) -> Self {
        Self {
            lo,
            hi,
            lo_open: false,
        }
    }
    fn open_closed(lo: f64, hi: f64) -> Self {
        Self {
            lo,
            hi,
            lo_open: true,
        }
    }
    fn contains(&self, x: f64) -> bool {
        x.is_finite()
            && (if self.lo_open {
                x > self.lo
            } else {
                x >= self.lo
            })
            && x <= self.hi
    }
}

impl std::fmt::Display for Range {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let open = if self.lo_open { "(" } else { "[" };
        write!(f, "{open}{}, {}]", self.lo, self.hi)
    }
}

/// `value` of `field` must lie in `range` (of `unit`, "" when
/// dimensionless); the error says what real vehicles have (`typical`) and,
/// for each `(factor, other)` of `units` under which `value` in unit
/// `other` (× factor) would be in range, that reading.
fn plausible(
    field: &str,
    value: f64,
    range: Range,
    unit: &str,
    typical: &str,
    units: &[(f64, &str)],
) -> Result<(), InvalidField> {
    if range.contains(value) {
        return Ok(());
    }
    let sp = if unit.is_empty() { "" } else { " " };
    let mut reason = if value.is_finite() {
        format!("{value}{sp}{unit} is outside {range}{sp}{unit}")
    } else {
        format!("must be a finite number in {range}{sp}{unit} (got {value})")
    };
    reason.push_str(&format!(
        ", the range that holds every real road vehicle with margin ({typical})"
    ));
    let readings: Vec<String> = units
        .iter()
        .filter(|(factor, _)| range.contains(value * factor))
        .map(|(factor, other)| {
            let sep = if other.starts_with('%') { "" } else { " " };
            format!(
                "{value}{sep}{other} is {}{sp}{unit}",
                round_sig(value * factor)
            )
        })
        .collect();
    if !readings.is_empty() {
        let what = if unit.is_empty() {
            "a fraction".to_owned()
        } else {
            format!("in {unit}")
        };
        reason.push_str(&format!(
            "; `{field}` is {what}: was this meant in another unit? {}",
            readings.join(", ")
        ));
    }
    Err(InvalidField::new(field, reason))
}

/// `x` to 6 significant digits, without float noise (0.334, not 0.33400000000000002).
fn round_sig(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let scale = 10f64.powi(5 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_match_models_md() {
        let p = VehicleParams::default();
        p.validate().unwrap();
        // README.md, "Plant": N = M g / 4 = 3433 N; snow carries 0.19 * N * r = 183 N m.
        assert!((p.normal_force() - 3433.5).abs() < 0.1);
        assert!((0.19 * p.normal_force() * p.r - 182.7).abs() < 0.5);
        assert_eq!(p.r_ref, None);
        assert_eq!(p.ref_radius(), p.r);
        assert_eq!(p.power_max, None);
        assert_eq!(p.torque_limit(1e6), p.torque_max);
    }

    /// The one-line description says whether the drive has a power limit
    /// (and where it starts to derate) and where the microphone is.
    #[test]
    fn the_description_names_the_power_limit_and_the_microphone() {
        let paper = VehicleParams::default().describe();
        assert!(
            paper.contains("4 driven wheels with 100% of the weight"),
            "{paper}"
        );
        assert!(paper.contains("no power limit"), "{paper}");
        assert!(paper.contains("at the driven wheel (lead 0)"), "{paper}");
        let ev = VehicleParams {
            n_driven: 2.0,
            driven_load_share: 0.5,
            power_max: Some(75_000.0),
            mic_lead_m: 2.77,
            ..VehicleParams::default()
        }
        .describe();
        // 75 kW / 1000 N m = 75 rad/s, x 0.28 m = 21 m/s = 75.6 km/h
        assert!(
            ev.contains("power_max 75 kW per driven wheel (derates above 75 rad/s, 76 km/h)"),
            "{ev}"
        );
        assert!(
            ev.contains("2 driven wheels with 50% of the weight on them (N 3433.5 N each)"),
            "{ev}"
        );
        assert!(
            ev.contains("microphone 2.77 m ahead of the driven wheel"),
            "{ev}"
        );
    }

    /// A power given in kilowatts (`power_max = 75`) is refused with the
    /// reading in watts.
    #[test]
    fn a_power_in_kilowatts_is_named() {
        let p = VehicleParams {
            power_max: Some(75.0),
            ..VehicleParams::default()
        };
        let e = p.validate().unwrap_err();
        assert_eq!(e.field, "power_max");
        assert!(e.reason.contains("75 kW is 75000 W"), "{}", e.reason);
        // one motor over two driven wheels: the per-wheel value is named
        let two = VehicleParams {
            power_max: Some(110.0),
            n_driven: 2.0,
            ..VehicleParams::default()
        };
        let e = two.validate().unwrap_err();
        assert!(
            e.reason.contains(
                "a motor of 110 kW over the n_driven = 2 driven wheels is 55000 W per wheel"
            ),
            "{}",
            e.reason
        );
    }

    #[test]
    fn bad_values_fail_with_the_field_named() {
        type Mutation = fn(&mut VehicleParams);
        let cases: [(&str, Mutation); 15] = [
            ("power_max", |p| p.power_max = Some(0.0)),
            ("power_max", |p| p.power_max = Some(f64::INFINITY)),
            ("power_max", |p| p.power_max = Some(-75_000.0)),
            ("driven_load_share", |p| p.driven_load_share = 0.0),
            ("driven_load_share", |p| p.driven_load_share = f64::NAN),
            ("mic_lead_m", |p| p.mic_lead_m = -1.0),
            ("mass", |p| p.mass = -5.0),
            ("mass", |p| p.mass = f64::NAN),
            ("r", |p| p.r = 0.0),
            ("r_ref", |p| p.r_ref = Some(0.0)),
            ("r_ref", |p| p.r_ref = Some(f64::NAN)),
            ("n_driven", |p| p.n_driven = 0.5),
            ("v_eps", |p| p.v_eps = 0.0),
            ("m_wheel", |p| p.m_wheel = 2000.0),
            ("torque_max", |p| p.torque_max = 0.0),
        ];
        for (field, f) in cases {
            let mut p = VehicleParams::default();
            f(&mut p);
            assert_eq!(p.validate().unwrap_err().field, field);
        }
    }

    /// The review's values (a user's own car): each was accepted and the
    /// drive "worked" (`r = 334.0`: a snow limit of 287 983 N m). Each now
    /// fails naming the field, the value, the range, and the unit it
    /// probably was in.
    #[test]
    fn implausible_values_from_the_review_fail_with_range_and_hint() {
        type Mutation = fn(&mut VehicleParams);
        let cases: [(&str, Mutation, &[&str]); 8] = [
            (
                "r",
                |p| p.r = 334.0,
                &["334 m is outside [0.1, 1] m", "334 mm is 0.334 m"],
            ),
            (
                "r_ref",
                |p| p.r_ref = Some(291.2),
                &["291.2 m is outside [0.1, 1] m", "291.2 mm is 0.2912 m"],
            ),
            (
                "tau_m",
                |p| p.tau_m = 50.0,
                &["50 s is outside [0, 0.5] s", "50 ms is 0.05 s"],
            ),
            (
                "j_w",
                |p| p.j_w = 600.0,
                &[
                    "600 kg m^2 is outside [0.01, 100] kg m^2",
                    "600 kg cm^2 is 0.06 kg m^2",
                ],
            ),
            (
                "v_eps",
                |p| p.v_eps = 100.0,
                &["100 m/s is outside (0, 1] m/s"],
            ),
            (
                "c_rr",
                |p| p.c_rr = 0.9,
                &[
                    "0.9 is outside [0, 0.05]",
                    "0.9% is 0.009",
                    "not the road's friction",
                ],
            ),
            (
                "n_driven",
                |p| p.n_driven = 2.5,
                &["2.5 is not a whole number of driven wheels from 1 to 8"],
            ),
            (
                "mass",
                |p| p.mass = 1.4,
                &["1.4 kg is outside [20, 300000] kg", "1.4 t is 1400 kg"],
            ),
        ];
        for (field, f, says) in cases {
            let mut p = VehicleParams::default();
            f(&mut p);
            let e = p.validate().unwrap_err();
            assert_eq!(e.field, field, "{e}");
            assert!(e.reason.contains("every real road vehicle"), "{e}");
            for s in says {
                assert!(e.reason.contains(s), "{s}: {e}");
            }
        }
        let p = VehicleParams {
            mass: f64::NAN,
            ..VehicleParams::default()
        };
        let e = p.validate().unwrap_err();
        assert!(e.reason.contains("(got NaN)"), "{e}");
    }

    /// Real vehicles at the edges of the ranges all pass.
    #[test]
    fn real_vehicles_pass() {
        let d = VehicleParams::default();
        let cars = [
            // a motorcycle: one driven wheel carrying about 60 % of 250 kg
            VehicleParams {
                mass: 250.0,
                n_driven: 1.0,
                j_w: 0.8,
                r: 0.31,
                m_wheel: 12.0,
                tau_m: 0.02,
                c_d_a: 0.5,
                torque_max: 1200.0,
                driven_load_share: 0.6,
                mic_lead_m: 1.45,
                ..d
            },
            // staggered sports car: 4 % larger rear (driven) tyres
            VehicleParams {
                mass: 1600.0,
                n_driven: 2.0,
                r: 0.3458,
                r_ref: Some(0.3325),
                driven_load_share: 0.55,
                mic_lead_m: 2.45,
                torque_max: 2500.0,
                ..d
            },
            // an 8x8 heavy truck on snow tyres, diesel-slow torque
            VehicleParams {
                mass: 44_000.0,
                n_driven: 8.0,
                j_w: 60.0,
                r: 0.53,
                m_wheel: 250.0,
                tau_m: 0.3,
                c_rr: 0.03,
                rho: 1.45,
                c_d_a: 9.0,
                torque_max: 40_000.0,
                mic_lead_m: 5.8,
                ..d
            },
            // an electric kick scooter on the road
            VehicleParams {
                mass: 25.0,
                n_driven: 1.0,
                j_w: 0.015,
                r: 0.11,
                m_wheel: 2.0,
                tau_m: 0.0,
                c_d_a: 0.0,
                rho: 0.74,
                torque_max: 30.0,
                driven_load_share: 0.5,
                ..d
            },
        ];
        for c in cars {
            c.validate().unwrap_or_else(|e| panic!("{c:?}: {e}"));
        }
    }

    /// Every field of the struct is in `defaultable_fields` except the
    /// optional `r_ref` and `power_max` (the destructuring breaks at compile time when a
    /// field is added), with its own value.
    #[test]
    fn defaultable_fields_name_every_field() {
        let p = VehicleParams {
            r_ref: Some(0.3),
            ..VehicleParams::default()
        };
        let VehicleParams {
            mass,
            n_driven,
            j_w,
            r,
            r_ref: _,
            power_max: _,
            m_wheel,
            tau_m,
            c_rr,
            rho,
            c_d_a,
            v_eps,
            torque_max,
            driven_load_share,
            mic_lead_m,
        } = p;
        let want = [
            mass,
            n_driven,
            j_w,
            r,
            m_wheel,
            tau_m,
            c_rr,
            rho,
            c_d_a,
            v_eps,
            torque_max,
            driven_load_share,
            mic_lead_m,
        ];
        let got = p.defaultable_fields();
        assert_eq!(got.map(|(_, v)| v), want);
        let mut names: Vec<&str> = got.iter().map(|(n, _)| *n).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), 13);
    }
}
