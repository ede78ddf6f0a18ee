//! Scenarios: a road sequence (by time or by distance), an optional grade per
//! segment, an initial speed and a driver torque-demand profile.
//!
//! Built by `grip-config` from `config/scenarios/*.toml` (road names resolved
//! against the catalogue), or directly with [`Scenario::new`]. All queries
//! (`segment_at`, `road_at`, `grade_at`, `demand_at`) are allocation-free.
//!
//! The last segment extends past its nominal end: a run longer than the sum
//! of the segments stays on the last road.
//!
//! Demands are driving torques >= 0 N m: braking and regenerative (negative)
//! demand are out of scope for a traction controller and are rejected.

use crate::validate::{self, InvalidField};
use crate::vehicle::VehicleParams;

/// The most loop cycles one run of a scenario may take (and the fewest: 1),
/// at the period of the loop that runs it ([`Scenario::check_for`]).
pub const MAX_CYCLES: f64 = 1e9;

/// `x` as a reason shows it: plainly, or in exponent form when plain would
/// be long (`1e300`, not three hundred digits).
fn shown(x: f64) -> String {
    if x.is_finite() && x.abs() >= 1e15 {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// How segment spans are measured (one mode per scenario).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SegmentMode {
    /// Spans are durations, s.
    Time,
    /// Spans are lengths, m (travelled distance x of the plant).
    Distance,
}

/// One stretch of road.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Road name (as in the catalogue).
    pub road_name: String,
    /// Index of the road in the catalogue the scenario was resolved against.
    pub road: usize,
    /// Duration (s) or length (m), by the scenario's [`SegmentMode`]; > 0.
    pub span: f64,
    /// Grade, percent (100 · rise / run), positive uphill.
    pub grade_pct: f64,
}

impl Segment {
    /// Grade angle θ = atan(grade_pct / 100), rad.
    pub fn grade_rad(&self) -> f64 {
        (self.grade_pct / 100.0).atan()
    }
}

/// Driver torque demand T_d(t), N m (>= 0).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Demand {
    /// T_d = torque.
    Constant {
        /// N m.
        torque: f64,
    },
    /// `from` until `start`, linear to `to` over `duration`, then `to`.
    Ramp {
        /// N m before the ramp.
        from: f64,
        /// N m after the ramp.
        to: f64,
        /// Ramp start, s.
        start: f64,
        /// Ramp duration, s (0 = step).
        duration: f64,
    },
    /// Stop-and-go traffic: the driver demands `torque` for `on` seconds, then
    /// releases (0 N m) for `off` seconds, repeating from t = 0. Each on-phase
    /// rises linearly over `rise` seconds (default 0: a step).
    StopAndGo {
        /// N m while on.
        torque: f64,
        /// On time per cycle, s.
        on: f64,
        /// Off time per cycle, s.
        off: f64,
        /// Rise time at the start of each on-phase, s (<= on).
        #[serde(default)]
        rise: f64,
    },
    /// Piecewise constant: `torques[i]` from `times[i]` on (times strictly
    /// increasing, first 0).
    Steps {
        /// Switch times, s.
        times: Vec<f64>,
        /// Demand after each switch time, N m.
        torques: Vec<f64>,
    },
}

impl Demand {
    /// When the driver first demands torque, s: the first time on a grid of
    /// `dt` in `[0, until)` where the demand is above 0 (0 for a demand from
    /// the start, a ramp with `start` > 0 or steps from 0 N m later; `None`
    /// when there is none before `until`, or `dt` is not positive).
    pub fn begins(&self, until: f64, dt: f64) -> Option<f64> {
        if !(dt > 0.0 && dt.is_finite() && until.is_finite()) {
            return None;
        }
        (0..)
            .map(|k| k as f64 * dt)
            .take_while(|&t| t < until)
            .find(|&t| self.at(t) > 0.0)
    }

    /// Range checks: torques finite and >= 0, times and durations finite and >= 0.
    pub fn validate(&self) -> Result<(), InvalidField> {
        match self {
            Self::Constant { torque } => validate::non_negative("torque", *torque),
            Self::Ramp {
                from,
                to,
                start,
                duration,
            } => {
                validate::non_negative("from", *from)?;
                validate::non_negative("to", *to)?;
                validate::non_negative("start", *start)?;
                validate::non_negative("duration", *duration)
            }
            Self::StopAndGo {
                torque,
                on,
                off,
                rise,
            } => {
                validate::non_negative("torque", *torque)?;
                validate::positive("on", *on)?;
                validate::non_negative("off", *off)?;
                validate::non_negative("rise", *rise)?;
                if rise > on {
                    return Err(InvalidField::new(
                        "rise",
                        format!("must be <= on ({on}) (got {rise})"),
                    ));
                }
                Ok(())
            }
            Self::Steps { times, torques } => {
                if times.is_empty() || times.len() != torques.len() {
                    return Err(InvalidField::new(
                        "torques",
                        format!(
                            "needs one torque per time, at least one (got {} times, {} torques)",
                            times.len(),
                            torques.len()
                        ),
                    ));
                }
                for (i, (&t, &q)) in times.iter().zip(torques).enumerate() {
                    validate::non_negative(&format!("times[{i}]"), t)?;
                    validate::non_negative(&format!("torques[{i}]"), q)?;
                    if i > 0 && t <= times[i - 1] {
                        return Err(InvalidField::new(
                            format!("times[{i}]"),
                            format!(
                                "must be strictly increasing (got {t} after {})",
                                times[i - 1]
                            ),
                        ));
                    }
                }
                if times[0] != 0.0 {
                    return Err(InvalidField::new(
                        "times[0]",
                        format!("must be 0 (got {})", times[0]),
                    ));
                }
                Ok(())
            }
        }
    }

    /// Demand at time `t` (s; t < 0 is treated as 0). Allocation-free.
    pub fn at(&self, t: f64) -> f64 {
        let t = if t.is_finite() { t.max(0.0) } else { 0.0 };
        match *self {
            Self::Constant { torque } => torque,
            Self::Ramp {
                from,
                to,
                start,
                duration,
            } => {
                if t <= start {
                    from
                } else if t >= start + duration {
                    to
                } else {
                    from + (to - from) * (t - start) / duration
                }
            }
            Self::StopAndGo {
                torque,
                on,
                off,
                rise,
            } => {
                let phase = t % (on + off);
                if phase >= on {
                    0.0
                } else if rise > 0.0 && phase < rise {
                    torque * phase / rise
                } else {
                    torque
                }
            }
            Self::Steps {
                ref times,
                ref torques,
            } => {
                let k = times.partition_point(|&s| s <= t).max(1);
                torques[k - 1]
            }
        }
    }

    /// Every torque of the profile within the motor's limit `torque_max`
    /// (N m): the plant clamps the command there, so a larger demand would
    /// drive the motor at its limit while the controllers and the
    /// command's metrics see the demand. The field is named as in the
    /// scenario file's `[demand]` (`torque`, `from`, `to`, `torques[i]`).
    pub fn check_limit(&self, torque_max: f64) -> Result<(), InvalidField> {
        let named = |field: &str, value: f64| {
            if value.is_nan() || value.abs() > torque_max {
                Err(InvalidField::new(
                    field,
                    format!(
                        "{} N m is above the motor limit, the vehicle's torque_max = {} N m (the plant would clamp the command there while the controllers and the command's metrics see the demand)",
                        shown(value),
                        shown(torque_max)
                    ),
                ))
            } else {
                Ok(())
            }
        };
        match self {
            Self::Constant { torque } | Self::StopAndGo { torque, .. } => named("torque", *torque),
            Self::Ramp { from, to, .. } => {
                named("from", *from)?;
                named("to", *to)
            }
            Self::Steps { torques, .. } => torques
                .iter()
                .enumerate()
                .try_for_each(|(i, &q)| named(&format!("torques[{i}]"), q)),
        }
    }

    /// Largest demand the profile ever asks, N m.
    pub fn max(&self) -> f64 {
        match self {
            Self::Constant { torque } => *torque,
            Self::Ramp { from, to, .. } => from.max(*to),
            Self::StopAndGo { torque, .. } => *torque,
            Self::Steps { torques, .. } => torques.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// A drive: roads, grades, initial speed and driver demand.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Scenario name.
    pub name: String,
    /// Free-text description (may be empty).
    pub description: String,
    /// Run duration, s.
    pub duration: f64,
    /// Initial vehicle speed, m/s (the wheel starts rolling without slip).
    pub v0: f64,
    /// How segment spans are measured.
    pub segments_by: SegmentMode,
    /// Road segments in order (never empty).
    pub segments: Vec<Segment>,
    /// Driver torque demand.
    pub demand: Demand,
    /// Cumulative segment ends (s or m), same length as `segments`.
    ends: Vec<f64>,
}

impl Scenario {
    /// Build and validate a scenario. `road_count` is the size of the catalogue
    /// the segments' `road` indices refer to.
    pub fn new(
        name: impl Into<String>,
        description: impl Into<String>,
        duration: f64,
        v0: f64,
        segments_by: SegmentMode,
        segments: Vec<Segment>,
        demand: Demand,
        road_count: usize,
    ) -> Result<Self, InvalidField> {
        let name = name.into();
        if name.trim().is_empty() {
            return Err(InvalidField::new("name", "must not be empty"));
        }
        if segments.is_empty() {
            return Err(InvalidField::new(
                "segment",
                "the road list is empty: give at least one [[segment]]",
            ));
        }
        let mut ends = Vec::with_capacity(segments.len());
        let mut acc = 0.0;
        for (i, s) in segments.iter().enumerate() {
            let what = match segments_by {
                SegmentMode::Time => "duration",
                SegmentMode::Distance => "length",
            };
            validate::positive(&format!("segment[{i}].{what}"), s.span)?;
            validate::in_range(
                &format!("segment[{i}].grade_pct"),
                s.grade_pct,
                -100.0,
                100.0,
            )?;
            if s.road >= road_count {
                return Err(InvalidField::new(
                    format!("segment[{i}].road"),
                    format!(
                        "road index {} out of range (catalogue has {road_count})",
                        s.road
                    ),
                ));
            }
            acc += s.span;
            ends.push(acc);
        }
        validate::positive("duration", duration)?;
        validate::in_range("v0", v0, 0.0, 100.0)?;
        demand.validate().map_err(|e| e.prefixed("demand"))?;
        Ok(Self {
            name,
            description: description.into(),
            duration,
            v0,
            segments_by,
            segments,
            demand,
            ends,
        })
    }

    /// The scenario against the vehicle that drives it and the loop that
    /// runs it at period `dt` (s): every demand within the vehicle's
    /// `torque_max` ([`Demand::check_limit`], fields `demand.*`), and a run
    /// of `round(duration / dt)` cycles within 1 ..= [`MAX_CYCLES`] (field
    /// `duration`). Gives that cycle count. Every reader of a scenario
    /// checks it here: `grip sim`'s setup, plant-sim's start-up (and so
    /// `grip drive` and `grip generate`), through `grip_config`'s
    /// `ConfigDir::scenario_for`.
    pub fn check_for(&self, vehicle: &VehicleParams, dt: f64) -> Result<usize, InvalidField> {
        self.demand
            .check_limit(vehicle.torque_max)
            .map_err(|e| e.prefixed("demand"))?;
        let cycles = (self.duration / dt).round();
        if !(1.0..=MAX_CYCLES).contains(&cycles) {
            return Err(InvalidField::new(
                "duration",
                format!(
                    "{} s gives {} loop cycles at dt = {dt} s (need 1 ..= {MAX_CYCLES:e})",
                    shown(self.duration),
                    shown(cycles)
                ),
            ));
        }
        Ok(cycles as usize)
    }

    /// Index (into `segments`) of the segment at time `t` (s) and travelled
    /// distance `x` (m); the mode picks which one counts. Allocation-free.
    pub fn segment_at(&self, t: f64, x: f64) -> usize {
        let s = match self.segments_by {
            SegmentMode::Time => t,
            SegmentMode::Distance => x,
        };
        self.ends
            .partition_point(|&e| e <= s)
            .min(self.segments.len() - 1)
    }

    /// Same as [`Scenario::segment_at`] (index into `segments`; the catalogue
    /// index is `segments[i].road`).
    pub fn road_at(&self, t: f64, x: f64) -> usize {
        self.segment_at(t, x)
    }

    /// Grade at (t, x), rad.
    pub fn grade_at(&self, t: f64, x: f64) -> f64 {
        self.segments[self.segment_at(t, x)].grade_rad()
    }

    /// Driver demand at time `t`, N m.
    pub fn demand_at(&self, t: f64) -> f64 {
        self.demand.at(t)
    }

    /// Where segment `i` starts (s or m by mode).
    pub fn segment_start(&self, i: usize) -> f64 {
        if i == 0 { 0.0 } else { self.ends[i - 1] }
    }

    /// Sum of the segment spans (s or m by mode).
    pub fn total_span(&self) -> f64 {
        self.ends.last().copied().unwrap_or(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_demand_begins_when_the_driver_first_asks_for_torque() {
        let ms = 1e-3;
        let ramp = Demand::Ramp {
            from: 0.0,
            to: 250.0,
            start: 0.3,
            duration: 0.2,
        };
        let b = ramp.begins(2.0, ms).unwrap();
        assert!((b - 0.301).abs() < 1e-9, "{b}");
        let steps = Demand::Steps {
            times: vec![0.0, 0.25],
            torques: vec![0.0, 220.0],
        };
        assert!((steps.begins(2.0, ms).unwrap() - 0.25).abs() < 1e-9);
        assert_eq!(
            Demand::Constant { torque: 300.0 }.begins(2.0, ms),
            Some(0.0)
        );
        assert_eq!(Demand::Constant { torque: 0.0 }.begins(2.0, ms), None);
        assert_eq!(ramp.begins(0.2, ms), None, "not before until");
        assert_eq!(ramp.begins(2.0, 0.0), None);
    }

    fn seg(road: usize, span: f64) -> Segment {
        Segment {
            road_name: format!("r{road}"),
            road,
            span,
            grade_pct: 0.0,
        }
    }

    fn scenario(mode: SegmentMode) -> Scenario {
        Scenario::new(
            "t",
            "",
            3.0,
            10.0 / 3.6,
            mode,
            vec![seg(0, 0.5), seg(2, 1.0), seg(1, 0.5)],
            Demand::Constant { torque: 300.0 },
            3,
        )
        .unwrap()
    }

    #[test]
    fn road_at_by_time_and_distance() {
        let s = scenario(SegmentMode::Time);
        assert_eq!(s.road_at(0.0, 99.0), 0);
        assert_eq!(s.road_at(0.49, 0.0), 0);
        assert_eq!(s.road_at(0.5, 0.0), 1);
        assert_eq!(s.road_at(1.6, 0.0), 2);
        assert_eq!(s.road_at(10.0, 0.0), 2); // past the end: last segment
        assert_eq!(s.segments[s.road_at(0.7, 0.0)].road, 2);
        let d = scenario(SegmentMode::Distance);
        assert_eq!(d.road_at(99.0, 0.2), 0);
        assert_eq!(d.road_at(0.0, 1.2), 1);
        assert_eq!(d.segment_start(2), 1.5);
    }

    #[test]
    fn demands() {
        let r = Demand::Ramp {
            from: 0.0,
            to: 200.0,
            start: 1.0,
            duration: 2.0,
        };
        assert_eq!(r.at(0.5), 0.0);
        assert_eq!(r.at(2.0), 100.0);
        assert_eq!(r.at(5.0), 200.0);
        let sg = Demand::StopAndGo {
            torque: 300.0,
            on: 2.0,
            off: 1.0,
            rise: 0.5,
        };
        assert_eq!(sg.at(0.25), 150.0);
        assert_eq!(sg.at(1.0), 300.0);
        assert_eq!(sg.at(2.5), 0.0);
        assert_eq!(sg.at(3.25), 150.0);
        let st = Demand::Steps {
            times: vec![0.0, 1.0, 2.0],
            torques: vec![100.0, 0.0, 250.0],
        };
        assert_eq!(st.at(0.0), 100.0);
        assert_eq!(st.at(1.5), 0.0);
        assert_eq!(st.at(9.0), 250.0);
        assert_eq!(st.max(), 250.0);
    }

    #[test]
    fn rejections() {
        let e = Scenario::new(
            "t",
            "",
            3.0,
            1.0,
            SegmentMode::Time,
            vec![],
            Demand::Constant { torque: 1.0 },
            1,
        )
        .unwrap_err();
        assert_eq!(e.field, "segment");
        let e = Scenario::new(
            "t",
            "",
            3.0,
            1.0,
            SegmentMode::Time,
            vec![seg(0, 1.0)],
            Demand::Constant { torque: -1.0 },
            1,
        )
        .unwrap_err();
        assert_eq!(e.field, "demand.torque");
        let e = Scenario::new(
            "t",
            "",
            3.0,
            1.0,
            SegmentMode::Distance,
            vec![seg(0, 0.0)],
            Demand::Constant { torque: 1.0 },
            1,
        )
        .unwrap_err();
        assert_eq!(e.field, "segment[0].length");
        let e = Scenario::new(
            "t",
            "",
            f64::NAN,
            1.0,
            SegmentMode::Time,
            vec![seg(0, 1.0)],
            Demand::Constant { torque: 1.0 },
            1,
        )
        .unwrap_err();
        assert_eq!(e.field, "duration");
    }

    #[test]
    fn grade_conversion() {
        let s = Segment {
            road_name: "a".into(),
            road: 0,
            span: 1.0,
            grade_pct: 10.0,
        };
        assert!((s.grade_rad() - 0.0996687).abs() < 1e-6);
    }

    #[test]
    fn checked_against_the_vehicle_and_the_loop() {
        let vehicle = VehicleParams::default();
        let limit = vehicle.torque_max;
        let s = scenario(SegmentMode::Time);
        assert_eq!(s.check_for(&vehicle, 1e-3), Ok(3000));
        let with = |demand, duration| Scenario {
            demand,
            duration,
            ..s.clone()
        };
        let e = with(Demand::Constant { torque: 1e300 }, 3.0)
            .check_for(&vehicle, 1e-3)
            .unwrap_err();
        assert_eq!(e.field, "demand.torque");
        assert!(
            e.reason.starts_with("1e300 N m is above the motor limit")
                && e.reason.contains(&format!("torque_max = {limit} N m")),
            "{e}"
        );
        let ramp = Demand::Ramp {
            from: 0.0,
            to: limit + 1.0,
            start: 0.0,
            duration: 1.0,
        };
        assert_eq!(
            with(ramp, 3.0).check_for(&vehicle, 1e-3).unwrap_err().field,
            "demand.to"
        );
        let steps = Demand::Steps {
            times: vec![0.0, 1.0],
            torques: vec![10.0, 2.0 * limit],
        };
        let e = with(steps, 3.0).check_for(&vehicle, 1e-3).unwrap_err();
        assert_eq!(e.field, "demand.torques[1]");
        assert_eq!(
            with(Demand::Constant { torque: limit }, 3.0).check_for(&vehicle, 1e-3),
            Ok(3000),
            "at the limit"
        );
        let e = with(Demand::Constant { torque: 1.0 }, 1e300)
            .check_for(&vehicle, 1e-3)
            .unwrap_err();
        assert_eq!(e.field, "duration");
        assert_eq!(
            e.reason,
            "1e300 s gives 1e303 loop cycles at dt = 0.001 s (need 1 ..= 1e9)"
        );
        let e = with(Demand::Constant { torque: 1.0 }, 1e-4)
            .check_for(&vehicle, 1e-3)
            .unwrap_err();
        assert!(e.reason.contains("gives 0 loop cycles"), "{e}");
        assert_eq!(
            with(Demand::Constant { torque: 1.0 }, 1e6).check_for(&vehicle, 1e-3),
            Ok(1_000_000_000),
            "the bound itself"
        );
    }
}
