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
}
