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

/// The fastest start a scenario may have, m/s (360 km/h): every start
/// speed grip takes (a scenario file's `v0_kmh`, `grip sim --random
/// v0_kmh`, `grip generate --v0-kmh`) is checked against it.
pub const V0_MAX_MPS: f64 = 100.0;

/// [`V0_MAX_MPS`] in km/h, the unit the files and flags give a start in.
pub const V0_MAX_KMH: f64 = V0_MAX_MPS * 3.6;

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

    /// When the driver first asks for torque: the earliest instant from
    /// which the demand is above 0 (its infimum: a ramp from 0 N m is above
    /// 0 just after its `start`), with the field of the scenario file's
    /// `[demand]` that sets it (`torque`, `from`, `start`, `rise`,
    /// `times[i]`). `None` for a demand of 0 N m throughout.
    pub fn onset(&self) -> Option<(f64, String)> {
        match self {
            Self::Constant { torque } => (*torque > 0.0).then(|| (0.0, "torque".to_owned())),
            Self::Ramp {
                from, to, start, ..
            } => {
                if *from > 0.0 {
                    Some((0.0, "from".to_owned()))
                } else if *to > 0.0 {
                    Some((*start, "start".to_owned()))
                } else {
                    None
                }
            }
            Self::StopAndGo { torque, rise, .. } => (*torque > 0.0)
                .then(|| (0.0, if *rise > 0.0 { "rise" } else { "torque" }.to_owned())),
            Self::Steps { times, torques } => times
                .iter()
                .zip(torques)
                .position(|(_, &q)| q > 0.0)
                .map(|i| (times[i], format!("times[{i}]"))),
        }
    }

    /// The changes of the profile that begin at or after `end` (s), so that
    /// a run of that length never sees them: a ramp whose `start` is there
    /// (when `from` and `to` differ), a stop-and-go whose first release
    /// (`on`) is there (when `off` > 0), a step whose switch time
    /// (`times[i]`, i > 0) is there (when its torque differs from the one
    /// before). Each is the field (as in `[demand]`) and why. A constant
    /// demand has none.
    pub fn changes_from(&self, end: f64) -> Vec<InvalidField> {
        let at_or_after = |t: f64| t >= end;
        match self {
            Self::Constant { .. } => Vec::new(),
            Self::Ramp {
                from,
                to,
                start,
                duration,
            } => {
                if from != to && at_or_after(*start) {
                    vec![InvalidField::new(
                        "start",
                        format!(
                            "the ramp from {} to {} N m (over {duration} s) begins at {start} s, at or after the end of the run (duration = {end} s): the demand stays {} N m throughout",
                            shown(*from),
                            shown(*to),
                            shown(*from)
                        ),
                    )]
                } else {
                    Vec::new()
                }
            }
            Self::StopAndGo {
                torque, on, off, ..
            } => {
                if *off > 0.0 && at_or_after(*on) {
                    vec![InvalidField::new(
                        "on",
                        format!(
                            "the first release (0 N m for off = {off} s) comes at on = {on} s, at or after the end of the run (duration = {end} s): the driver never lets go of the {} N m",
                            shown(*torque)
                        ),
                    )]
                } else {
                    Vec::new()
                }
            }
            Self::Steps { times, torques } => (1..times.len().min(torques.len()))
                .filter(|&i| at_or_after(times[i]) && torques[i] != torques[i - 1])
                .map(|i| {
                    InvalidField::new(
                        format!("times[{i}]"),
                        format!(
                            "the step to {} N m at {} s is at or after the end of the run (duration = {end} s): it never happens",
                            shown(torques[i]),
                            times[i]
                        ),
                    )
                })
                .collect(),
        }
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

    /// The words of [`Demand::check_limit`]'s reason, by which a reader of
    /// the error (which carries no kind) tells the motor's limit from the
    /// demand's other faults, to name the vehicle file beside the scenario.
    pub const ABOVE_MOTOR_LIMIT: &'static str = "is above the motor limit";

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
                        "{} N m {}, the vehicle's torque_max = {} N m (the plant would clamp the command there while the controllers and the command's metrics see the demand)",
                        shown(value),
                        Self::ABOVE_MOTOR_LIMIT,
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
        validate::in_range("v0", v0, 0.0, V0_MAX_MPS)?;
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

    /// The scenario for a microphone `mic_lead_m` (m) ahead of the driven
    /// wheel: with a lead, a scenario in time segments is refused (field
    /// `segments_by`): it cannot say where a road begins before the wheel
    /// gets there, which is what the microphone hears. The one home of the
    /// rule: [`Self::check_for`] (every reader that runs a scenario) and
    /// plant-sim's plant, which can be built from an unchecked scenario.
    pub fn check_mic_lead(&self, mic_lead_m: f64) -> Result<(), InvalidField> {
        if mic_lead_m > 0.0 && self.segments_by == SegmentMode::Time {
            return Err(InvalidField::new(
                "segments_by",
                format!(
                    "scenario `{}` is in time segments, which cannot say where a road begins before the wheel gets there; the microphone is {} m ahead of the driven wheel (vehicle.mic_lead_m): use a scenario in distance segments (segments_by = \"distance\"), or a vehicle with mic_lead_m = 0",
                    self.name,
                    shown(mic_lead_m)
                ),
            ));
        }
        Ok(())
    }

    /// Whether `e`, an error of [`Self::check_for`], is about the vehicle
    /// as much as the scenario (a demand above its motor's limit, a
    /// microphone lead with time segments): its reader names the vehicle
    /// file too.
    pub fn involves_vehicle(e: &InvalidField) -> bool {
        e.reason.contains(Demand::ABOVE_MOTOR_LIMIT) || e.field == "segments_by"
    }

    /// The scenario against the vehicle that drives it and the loop that
    /// runs it at period `dt` (s): the microphone's lead against the
    /// segments ([`Self::check_mic_lead`], field `segments_by`), every demand within the vehicle's
    /// `torque_max` ([`Demand::check_limit`], fields `demand.*`), and a run
    /// of `round(duration / dt)` cycles within 1 ..= [`MAX_CYCLES`] (field
    /// `duration`), and torque asked for before the run's last cycle (a
    /// demand that asks for none until then, field `demand.start` or
    /// `demand.times[i]`, would run 0 N m throughout; a demand of 0 N m
    /// throughout is a coast and allowed). Gives that cycle count. Every
    /// reader of a scenario
    /// checks it here: `grip sim`'s setup, plant-sim's start-up (and so
    /// `grip drive` and `grip generate`), through `grip_config`'s
    /// `ConfigDir::scenario_for`.
    pub fn check_for(&self, vehicle: &VehicleParams, dt: f64) -> Result<usize, InvalidField> {
        self.check_mic_lead(vehicle.mic_lead_m)?;
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
        // a demand that asks for torque only after the run's last cycle:
        // a run of zeros is never what was meant (a demand of 0 N m
        // throughout is a coast, asked for as such, and allowed)
        let last = (cycles - 1.0) * dt;
        if let Some((onset, field)) = self.demand.onset()
            && onset >= last
            && self.demand.at(last) == 0.0
        {
            return Err(InvalidField::new(
                format!("demand.{field}"),
                format!(
                    "the driver first asks for torque at {} s, at or after the end of the run (duration = {} s, last loop cycle at {} s): the run would demand 0 N m throughout; start the demand earlier or lengthen `duration`",
                    shown(onset),
                    shown(self.duration),
                    shown(last)
                ),
            ));
        }
        Ok(cycles as usize)
    }

    /// What the scenario has at or after its end, which a run of
    /// `duration` never gets to: in time segments, each segment that begins
    /// at or after `duration` (field `segment[i]`; a last segment that
    /// merely extends past the end, "snow to the end", is normal and not
    /// listed), and each change of the demand that begins at or after it
    /// ([`Demand::changes_from`], fields `demand.*`; none when the demand
    /// asks for no torque before the end, which [`Scenario::check_for`]
    /// refuses). Not errors: a reader warns of them. Distance segments are
    /// reached or not by how far the car goes, known only after a run.
    pub fn past_the_end(&self) -> Vec<InvalidField> {
        let end = self.duration;
        let mut notes = Vec::new();
        if self.segments_by == SegmentMode::Time {
            // a start a rounding error short of the end is at the end
            let eps = 1e-9 * end.abs().max(1.0);
            for (i, s) in self.segments.iter().enumerate().skip(1) {
                let start = self.segment_start(i);
                if start >= end - eps {
                    notes.push(InvalidField::new(
                        format!("segment[{i}]"),
                        format!(
                            "road `{}` begins at {} s, at or after the end of the run (duration = {} s): it is never driven",
                            s.road_name,
                            shown(start),
                            shown(end)
                        ),
                    ));
                }
            }
        }
        let asks = self.demand.onset().is_some_and(|(t, _)| t < end);
        if asks {
            notes.extend(
                self.demand
                    .changes_from(end)
                    .into_iter()
                    .map(|n| n.prefixed("demand")),
            );
        }
        notes
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

    /// A microphone ahead of the driven wheel needs distance segments:
    /// time segments are refused by `check_mic_lead` and so by `check_for`
    /// (field `segments_by`, the remedy named, the vehicle involved); at
    /// lead 0, or in distance segments, both pass.
    #[test]
    fn a_microphone_lead_needs_distance_segments() {
        let ahead = VehicleParams {
            mic_lead_m: 2.77,
            ..VehicleParams::default()
        };
        let time = scenario(SegmentMode::Time);
        let e = time.check_mic_lead(ahead.mic_lead_m).unwrap_err();
        assert_eq!(e.field, "segments_by");
        assert!(
            e.reason.contains("scenario `t` is in time segments")
                && e.reason.contains("2.77 m ahead")
                && e.reason.contains("segments_by = \"distance\""),
            "{e}"
        );
        assert!(Scenario::involves_vehicle(&e));
        assert_eq!(time.check_for(&ahead, 1e-3), Err(e));
        assert_eq!(time.check_mic_lead(0.0), Ok(()));
        let dist = scenario(SegmentMode::Distance);
        assert_eq!(dist.check_mic_lead(ahead.mic_lead_m), Ok(()));
        assert_eq!(dist.check_for(&ahead, 1e-3), Ok(3000));
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

#[cfg(test)]
mod past_the_end {
    use super::*;

    fn seg(name: &str, span: f64) -> Segment {
        Segment {
            road_name: name.to_owned(),
            road: 0,
            span,
            grade_pct: 0.0,
        }
    }

    fn scenario(mode: SegmentMode, duration: f64, spans: &[f64], demand: Demand) -> Scenario {
        let names = ["asphalt", "snow", "ice", "gravel"];
        let segments = spans
            .iter()
            .enumerate()
            .map(|(i, &s)| seg(names[i % names.len()], s))
            .collect();
        Scenario::new("t", "", duration, 0.0, mode, segments, demand, 1).unwrap()
    }

    const TORQUE: Demand = Demand::Constant { torque: 250.0 };

    fn fields(s: &Scenario) -> Vec<String> {
        s.past_the_end().into_iter().map(|n| n.field).collect()
    }

    #[test]
    fn a_time_segment_that_begins_at_or_after_the_end_is_named() {
        let s = scenario(SegmentMode::Time, 1.0, &[0.5, 0.5, 2.0], TORQUE);
        let notes = s.past_the_end();
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert_eq!(notes[0].field, "segment[2]");
        assert_eq!(
            notes[0].reason,
            "road `ice` begins at 1 s, at or after the end of the run (duration = 1 s): it is never driven"
        );
        let s = scenario(SegmentMode::Time, 1.0, &[0.5, 1.0, 2.0, 1.0], TORQUE);
        assert_eq!(fields(&s), ["segment[2]", "segment[3]"]);
        // a rounding error short of the end is at the end
        let s = scenario(SegmentMode::Time, 0.3, &[0.1, 0.2, 1.0], TORQUE);
        assert_eq!(fields(&s), ["segment[2]"]);
    }

    #[test]
    fn a_last_segment_past_the_end_and_distance_segments_are_normal() {
        // "snow to the end": the last segment extends past the end
        let s = scenario(SegmentMode::Time, 1.0, &[0.5, 2.0], TORQUE);
        assert!(s.past_the_end().is_empty());
        // the segments sum to the duration exactly
        let s = scenario(SegmentMode::Time, 1.5, &[0.5, 1.0], TORQUE);
        assert!(s.past_the_end().is_empty());
        // a run shorter than the first segment
        let s = scenario(SegmentMode::Time, 0.2, &[0.5], TORQUE);
        assert!(s.past_the_end().is_empty());
        // distance: known only after a run
        let s = scenario(SegmentMode::Distance, 1.0, &[2.0, 50.0, 100.0], TORQUE);
        assert!(s.past_the_end().is_empty());
    }

    #[test]
    fn every_demand_kind_s_late_change_is_named() {
        let at = |demand| fields(&scenario(SegmentMode::Time, 1.0, &[1.0], demand));
        let ramp = |from, start| Demand::Ramp {
            from,
            to: 300.0,
            start,
            duration: 1.0,
        };
        assert_eq!(at(ramp(100.0, 1.0)), ["demand.start"]);
        assert_eq!(at(ramp(100.0, 5.0)), ["demand.start"]);
        assert!(at(ramp(100.0, 0.9)).is_empty());
        // from 0: no torque before the end at all, check_for's error
        assert!(at(ramp(0.0, 5.0)).is_empty());
        let flat = Demand::Ramp {
            from: 300.0,
            to: 300.0,
            start: 5.0,
            duration: 1.0,
        };
        assert!(at(flat).is_empty(), "no change");
        let sg = |on, off| Demand::StopAndGo {
            torque: 300.0,
            on,
            off,
            rise: 0.0,
        };
        assert_eq!(at(sg(1.0, 1.0)), ["demand.on"]);
        assert!(at(sg(0.5, 1.0)).is_empty());
        assert!(at(sg(2.0, 0.0)).is_empty(), "never released anyway");
        let steps = |times: Vec<f64>, torques: Vec<f64>| Demand::Steps { times, torques };
        assert_eq!(
            at(steps(
                vec![0.0, 0.5, 1.0, 2.0],
                vec![100.0, 200.0, 300.0, 0.0]
            )),
            ["demand.times[2]", "demand.times[3]"]
        );
        assert!(at(steps(vec![0.0, 2.0], vec![100.0, 100.0])).is_empty());
        assert!(at(TORQUE).is_empty());
        let r = scenario(SegmentMode::Time, 1.0, &[1.0], ramp(100.0, 5.0)).past_the_end();
        assert_eq!(
            r[0].reason,
            "the ramp from 100 to 300 N m (over 1 s) begins at 5 s, at or after the end of the run (duration = 1 s): the demand stays 100 N m throughout"
        );
    }

    #[test]
    fn a_demand_that_asks_for_torque_only_after_the_end_is_refused() {
        let vehicle = VehicleParams::default();
        let run =
            |demand| scenario(SegmentMode::Time, 1.0, &[1.0], demand).check_for(&vehicle, 1e-3);
        let ramp = |start| Demand::Ramp {
            from: 0.0,
            to: 300.0,
            start,
            duration: 1.0,
        };
        let e = run(ramp(5.0)).unwrap_err();
        assert_eq!(e.field, "demand.start");
        assert_eq!(
            e.reason,
            "the driver first asks for torque at 5 s, at or after the end of the run (duration = 1 s, last loop cycle at 0.999 s): the run would demand 0 N m throughout; start the demand earlier or lengthen `duration`"
        );
        // a ramp starting at the last cycle is still 0 there
        assert_eq!(run(ramp(0.999)).unwrap_err().field, "demand.start");
        assert_eq!(run(ramp(0.998)), Ok(1000));
        let steps = Demand::Steps {
            times: vec![0.0, 1.0],
            torques: vec![0.0, 300.0],
        };
        assert_eq!(run(steps).unwrap_err().field, "demand.times[1]");
        let steps = Demand::Steps {
            times: vec![0.0, 0.5],
            torques: vec![0.0, 300.0],
        };
        assert_eq!(run(steps), Ok(1000));
        // 0 N m throughout is a coast, asked for as such
        assert_eq!(run(Demand::Constant { torque: 0.0 }), Ok(1000));
        let stopgo = Demand::StopAndGo {
            torque: 300.0,
            on: 0.5,
            off: 0.5,
            rise: 0.2,
        };
        assert_eq!(run(stopgo), Ok(1000));
    }

    #[test]
    fn onsets() {
        assert_eq!(
            Demand::Constant { torque: 1.0 }.onset(),
            Some((0.0, "torque".to_owned()))
        );
        assert_eq!(Demand::Constant { torque: 0.0 }.onset(), None);
        let steps = Demand::Steps {
            times: vec![0.0, 1.0, 2.0],
            torques: vec![0.0, 0.0, 5.0],
        };
        assert_eq!(steps.onset(), Some((2.0, "times[2]".to_owned())));
    }
}
