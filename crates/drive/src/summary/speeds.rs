//! The drive's speeds against the speeds arte's model was trained at
//! (`Summary::training_speeds`, printed in the ARTE section).
//!
//! A model's estimates and their calibrated confidence hold for the
//! vehicle speeds of its training recordings (`grip_arte::speeds`); a drive
//! that runs faster or slower than those gets extrapolation there. This
//! section says how much of the drive did, from the model the log itself
//! carries (the one [`super::model_of`] names: `arte-svc.toml`'s `model`,
//! attached; for a `grip replay --out` log the replay's model, found among
//! the attachments by name or SHA-256) and the vehicle speed:
//!
//! - with a scenario window: the ground truth's speed |V| over it, each
//!   sample holding until the next one, at most five plant periods (the
//!   metrics' rule), not past the window's end;
//! - without one (a car's log): the loop's measured V (cycles with a valid
//!   V) over the time the driver demanded more than
//!   [`super::measured::DEMAND_MIN_NM`] (the measured section's window),
//!   each cycle holding until the next one, at most five periods.
//!
//! Notes only: nothing here changes an estimate, a figure or whether a
//! drive passes.

use grip_arte::model::Model;
use grip_arte::speeds::{SpeedCheck, TrainingSpeeds};

use super::measured::{DEMAND_MIN_NM, median_period_ns};
use crate::log::DriveLog;

/// A sample holds for at most this many periods (the metrics' and the
/// measured section's rule).
const MAX_HOLD_PERIODS: u64 = 5;

/// What the summary knows of the model's training speeds.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelSpeeds {
    /// The model file is not attached to the log (its name).
    NotAttached(String),
    /// The attached file does not load as a model (its name, why).
    Unreadable(String, String),
    /// What the model says ([`Model::training_speeds`]).
    Model(TrainingSpeeds),
}

/// The drive's speeds against the model's training speeds.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveSpeeds {
    /// The model's training speeds, as far as the log tells.
    pub model: ModelSpeeds,
    /// What time the check covers and whose speed, for the note: (`the
    /// scenario window`, `ground-truth speed`), or the driver-demand
    /// window and the measured V.
    pub what: (String, String),
    /// The time below and above the training speeds (None: the model
    /// gives no range, or no sample has a speed).
    pub check: Option<SpeedCheck>,
}

impl DriveSpeeds {
    /// The report's lines: one note per side the drive ran outside the
    /// training speeds, or why the speeds were not checked; none when all
    /// of the drive was inside them.
    pub fn lines(&self) -> Vec<String> {
        match &self.model {
            ModelSpeeds::NotAttached(name) => vec![format!(
                "the model's training speeds: unknown (its file {name} is not attached to the log); the drive's speeds are not checked against them"
            )],
            ModelSpeeds::Unreadable(name, why) => vec![format!(
                "the model's training speeds: unknown (the attached {name} does not load: {why}); the drive's speeds are not checked against them"
            )],
            ModelSpeeds::Model(TrainingSpeeds::NotRecorded) => vec![format!(
                "the model's {} (a model file from before grip train wrote them): the drive's speeds are not checked against them",
                grip_arte::speeds::NOT_RECORDED
            )],
            ModelSpeeds::Model(_) => self
                .check
                .map(|c| {
                    c.notes(&self.what.0, &self.what.1)
                        .into_iter()
                        .map(|n| format!("note: {n}"))
                        .collect()
                })
                .unwrap_or_default(),
        }
    }
}

/// The drive's speeds against the training speeds of the model the log
/// carries (see the module); `window_ns` is the summary's scenario window.
/// None when the log names no model.
pub fn drive_speeds(log: &DriveLog, window_ns: Option<(u64, u64)>) -> Option<DriveSpeeds> {
    // the model the summary's header names ([`super::model_of`]), its bytes
    let info = super::model_of(log)?;
    let name = info.name.clone();
    let model = match info.bytes(log).map(Model::from_bytes) {
        None => ModelSpeeds::NotAttached(name),
        Some(Err(e)) => ModelSpeeds::Unreadable(name, e.to_string()),
        Some(Ok(m)) => ModelSpeeds::Model(m.training_speeds()),
    };
    let range = match &model {
        ModelSpeeds::Model(t) => t.range(),
        _ => None,
    };
    let mut what = (String::new(), String::new());
    let check = range.and_then(|r| {
        let mut c = SpeedCheck::new(r);
        what = match window_ns {
            Some(w) => {
                truth_speeds(log, w, &mut c);
                (
                    "the scenario window".to_owned(),
                    "ground-truth speed".to_owned(),
                )
            }
            None => {
                measured_speeds(log, &mut c);
                (
                    format!("the time the driver demanded more than {DEMAND_MIN_NM} N m"),
                    "measured V; no scenario window".to_owned(),
                )
            }
        };
        (c.total_s > 0.0).then_some(c)
    });
    Some(DriveSpeeds { model, what, check })
}

/// The ground truth's speed over the window [start, end).
fn truth_speeds(log: &DriveLog, (start, end): (u64, u64), c: &mut SpeedCheck) {
    let max_hold = super::TRUTH_PERIOD_NS * MAX_HOLD_PERIODS;
    for (k, g) in log.truth.iter().enumerate() {
        if !(start..end).contains(&g.stamp_ns) {
            continue;
        }
        let next = log
            .truth
            .get(k + 1)
            .map_or(g.stamp_ns.saturating_add(super::TRUTH_PERIOD_NS), |n| {
                n.stamp_ns.max(g.stamp_ns)
            })
            .min(g.stamp_ns.saturating_add(max_hold))
            .min(end);
        c.add(g.v * 3.6, (next - g.stamp_ns) as f64 * 1e-9);
    }
}

/// The loop's measured V (valid) over the time the driver demanded torque.
fn measured_speeds(log: &DriveLog, c: &mut SpeedCheck) {
    let cycles = &log.cycles;
    let period = median_period_ns(cycles.iter().map(|c| c.stamp_ns));
    let max_hold = period.saturating_mul(MAX_HOLD_PERIODS);
    for (i, cy) in cycles.iter().enumerate() {
        if cy.v_valid == 0 || !(cy.demand.is_finite() && cy.demand > DEMAND_MIN_NM) {
            continue;
        }
        let next = cycles
            .get(i + 1)
            .map_or(cy.stamp_ns.saturating_add(period), |n| {
                n.stamp_ns.max(cy.stamp_ns)
            })
            .min(cy.stamp_ns.saturating_add(max_hold));
        c.add(cy.v * 3.6, (next - cy.stamp_ns) as f64 * 1e-9);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_arte::speeds::SpeedRange;
    use grip_msgs::{CycleRecord, GroundTruth, RoadEstimate};
    use grip_physics::VehicleParams;

    /// The shipped paper model (3 KB; its training speeds, 4.0-29.8 km/h,
    /// in its notes), edited by `edit`, as file bytes.
    fn model_bytes(edit: impl FnOnce(&mut Model)) -> Vec<u8> {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../config/models/paper.model");
        let mut m = Model::from_bytes(&std::fs::read(p).unwrap()).unwrap();
        edit(&mut m);
        m.to_bytes().unwrap()
    }

    /// 1 s of ground truth at 1 kHz, moving from the first sample: 100 ms
    /// creeping at 2 km/h, 700 ms at 20 km/h, 200 ms from 36 to 47.94
    /// km/h; a scenario of 1 s; one road estimate a cycle; arte-svc.toml
    /// naming `models/m.model`, attached with `model` (None: not attached).
    fn log_with(model: Option<Vec<u8>>) -> DriveLog {
        let mut log = DriveLog::default();
        for k in 0..1000u64 {
            let kmh = match k {
                0..100 => 2.0,
                100..800 => 20.0,
                _ => 36.0 + (k - 800) as f64 * 0.06,
            };
            let mut g = GroundTruth::zeroed();
            g.seq = k;
            g.stamp_ns = k * 1_000_000;
            g.x = k as f64 * 0.005;
            g.v = kmh / 3.6;
            g.omega = g.v / 0.3;
            g.road_name = grip_msgs::name_to_bytes("asphalt");
            g.mic_road_name = g.road_name;
            log.truth.push(g);
            let mut c = CycleRecord::zeroed();
            c.seq = k;
            c.stamp_ns = k * 1_000_000;
            c.v = g.v;
            c.v_valid = 1;
            c.demand = 300.0;
            log.cycles.push(c);
            let mut e = RoadEstimate::zeroed();
            e.seq = k;
            e.frame_t1_ns = k * 1_000_000;
            e.stamp_ns = k * 1_000_000 + 1;
            e.class_name = g.road_name;
            log.roads.push(e);
        }
        log.run.insert("scenario_duration_s".into(), "1.0".into());
        log.attachments.insert(
            "arte-svc.toml".into(),
            b"model = \"models/m.model\"\n".to_vec(),
        );
        if let Some(m) = model {
            log.attachments.insert("models/m.model".into(), m);
        }
        log
    }

    const BELOW: &str = "note: 10 % of the scenario window (0.1 of 1.0 s, ground-truth speed) at 2.0 km/h, below the model's training speeds (4.0-29.8 km/h): its estimates there are extrapolation";
    const ABOVE: &str = "note: 20 % of the scenario window (0.2 of 1.0 s, ground-truth speed) at 36.0-47.9 km/h, above the model's training speeds (4.0-29.8 km/h): its estimates there are extrapolation";

    /// The summary notes the time below and above the training speeds of
    /// the attached model, in the ARTE section of the report; a model
    /// with `meta.speeds` and an old one with only `grip train`'s note on
    /// them say the same.
    #[test]
    fn time_outside_the_training_speeds_is_noted() {
        for edit in [(|_: &mut Model| {}) as fn(&mut Model), |m: &mut Model| {
            m.meta.notes.clear();
            m.meta.speeds = SpeedRange::new(4.0, 29.8);
        }] {
            let log = log_with(Some(model_bytes(edit)));
            let s = crate::summarize(&log, &VehicleParams::default(), "test", None);
            let sp = s.training_speeds.as_ref().unwrap();
            assert_eq!(sp.lines(), [BELOW, ABOVE]);
            let c = sp.check.unwrap();
            assert!((c.total_s - 1.0).abs() < 1e-9, "{c:?}");
            let r = s.render();
            let arte = &r[r.find("\nARTE (").unwrap()..];
            assert!(arte.contains(BELOW) && arte.contains(ABOVE), "{r}");
        }
    }

    /// All of the drive inside the training speeds: no note.
    #[test]
    fn a_drive_inside_the_training_speeds_gets_no_note() {
        let mut log = log_with(Some(model_bytes(|m| {
            m.meta.speeds = SpeedRange::new(1.0, 50.0);
        })));
        let s = crate::summarize(&log, &VehicleParams::default(), "test", None);
        assert_eq!(
            s.training_speeds.as_ref().unwrap().lines(),
            Vec::<String>::new()
        );
        assert!(!s.render().contains("training speeds"), "{}", s.render());
        // a log without a model named: nothing at all
        log.attachments.clear();
        assert_eq!(drive_speeds(&log, Some((0, 1_000_000_000))), None);
    }

    /// A model without recorded training speeds, one not attached and one
    /// that does not load: said, and nothing checked.
    #[test]
    fn speeds_not_recorded_or_unknown_are_said() {
        let w = Some((0, 1_000_000_000));
        let old = log_with(Some(model_bytes(|m| m.meta.notes.clear())));
        let sp = drive_speeds(&old, w).unwrap();
        assert_eq!(sp.check, None);
        assert_eq!(
            sp.lines(),
            [
                "the model's training speeds not recorded (a model file from before grip train wrote them): the drive's speeds are not checked against them"
            ]
        );
        let r = crate::summarize(&old, &VehicleParams::default(), "test", None).render();
        assert!(r.contains("training speeds not recorded"), "{r}");
        let sp = drive_speeds(&log_with(None), w).unwrap();
        assert_eq!(sp.model, ModelSpeeds::NotAttached("models/m.model".into()));
        assert!(sp.lines()[0].contains("is not attached to the log"));
        let sp = drive_speeds(&log_with(Some(b"junk".to_vec())), w).unwrap();
        assert!(matches!(sp.model, ModelSpeeds::Unreadable(..)), "{sp:?}");
        assert!(sp.lines()[0].contains("does not load"), "{:?}", sp.lines());
    }

    /// Without a scenario window (a car's log) the loop's measured V over
    /// the time the driver demanded torque; a replay's model is found by
    /// its SHA-256 among the attachments.
    #[test]
    fn measured_speed_without_a_window_and_a_replays_model() {
        let mut log = log_with(Some(model_bytes(|_| {})));
        // the driver lets go for the last 100 ms, and V is invalid for the
        // first 50: 50 ms below, 100 ms above, of 850 ms
        for c in &mut log.cycles[900..] {
            c.demand = 0.0;
        }
        for c in &mut log.cycles[..50] {
            c.v_valid = 0;
        }
        let sp = drive_speeds(&log, None).unwrap();
        let c = sp.check.unwrap();
        assert!((c.total_s - 0.85).abs() < 1e-9, "{c:?}");
        assert!((c.below.unwrap().time_s - 0.05).abs() < 1e-9, "{c:?}");
        assert!((c.above.unwrap().time_s - 0.1).abs() < 1e-9, "{c:?}");
        assert!(
            sp.lines()[0].contains("of the time the driver demanded more than 10 N m (")
                && sp.lines()[0].contains(" s, measured V; no scenario window) at 2.0 km/h, below"),
            "{:?}",
            sp.lines()
        );
        let bytes = log.attachments.remove("models/m.model").unwrap();
        log.attachments
            .insert("models/default.model".into(), bytes.clone());
        let mut rec = grip_io::mcaplog::MetadataMap::new();
        rec.insert("model".into(), "/elsewhere/replayed.model".into());
        rec.insert("model_sha256".into(), grip_digest::sha256_hex(&bytes));
        log.metadata.insert("grip.replay".into(), rec);
        let sp = drive_speeds(&log, Some((0, 1_000_000_000))).unwrap();
        assert_eq!(sp.lines(), [BELOW, ABOVE]);
    }
}
