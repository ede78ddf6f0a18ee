//! The vehicle speeds a model was trained at, and how much of a drive or a
//! simulation ran outside them.
//!
//! A model's estimates and their calibrated confidence hold for the speeds
//! of its training recordings; outside them they are extrapolation (the
//! crate README's held-out sets below and above the training range show
//! what that costs). Nothing here changes an estimate: the drive summary
//! (`grip inspect`, `grip drive`), `grip sim --arte acoustic` and the arte
//! service's start-up only say so.
//!
//! The range is [`crate::model::TrainingMeta::speeds`], which `grip train`
//! writes from the training manifest's `speed_kmh` of every recording that
//! gave frames. A model written before that field existed has none; if
//! its training notes carry the line `grip train` has printed and stored
//! since speed normalisation came in (`training speeds: A-B km/h`, to
//! 0.1 km/h: both shipped models have it), the range is read from that
//! ([`TrainingSpeeds::FromNote`]); otherwise the speeds are not recorded
//! ([`TrainingSpeeds::NotRecorded`], worded [`NOT_RECORDED`]).

use serde::{Deserialize, Serialize};

/// The words every report uses for a model without training speeds.
pub const NOT_RECORDED: &str = "training speeds not recorded";

/// The prefix of `grip train`'s note on the training speeds (the note is
/// `training speeds: {min:.1}-{max:.1} km/h`).
pub const NOTE_PREFIX: &str = "training speeds: ";

/// The slowest and fastest training recording, km/h.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedRange {
    /// Slowest recording, km/h.
    pub min_kmh: f64,
    /// Fastest recording, km/h.
    pub max_kmh: f64,
}

impl SpeedRange {
    /// A range of finite speeds with `0 <= min_kmh <= max_kmh`, else None.
    pub fn new(min_kmh: f64, max_kmh: f64) -> Option<Self> {
        let r = Self { min_kmh, max_kmh };
        r.is_valid().then_some(r)
    }

    /// Whether the speeds are finite and `0 <= min_kmh <= max_kmh`.
    pub fn is_valid(&self) -> bool {
        self.min_kmh.is_finite()
            && self.max_kmh.is_finite()
            && self.min_kmh >= 0.0
            && self.min_kmh <= self.max_kmh
    }

    /// The range of `speeds` (km/h); None when there is none, or one is
    /// not a speed.
    pub fn of(speeds: impl IntoIterator<Item = f64>) -> Option<Self> {
        let mut range: Option<(f64, f64)> = None;
        for v in speeds {
            if !v.is_finite() {
                return None;
            }
            range = Some(range.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))));
        }
        let (lo, hi) = range?;
        Self::new(lo, hi)
    }

    /// `4.0-29.8 km/h`.
    pub fn label(&self) -> String {
        format!("{:.1}-{:.1} km/h", self.min_kmh, self.max_kmh)
    }

    /// `grip train`'s note: `training speeds: 4.0-29.8 km/h`.
    pub fn note(&self) -> String {
        format!("{NOTE_PREFIX}{}", self.label())
    }

    /// The range `grip train`'s note gives (None: not that note).
    pub fn from_note(note: &str) -> Option<Self> {
        let (lo, hi) = note
            .strip_prefix(NOTE_PREFIX)?
            .strip_suffix(" km/h")?
            .split_once('-')?;
        Self::new(lo.trim().parse().ok()?, hi.trim().parse().ok()?)
    }
}

/// What a model says of its training speeds ([`crate::model::Model::training_speeds`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TrainingSpeeds {
    /// The model file's `meta.speeds`.
    Recorded(SpeedRange),
    /// Read from `grip train`'s note in `meta.notes` (a model written
    /// before `meta.speeds` existed), to 0.1 km/h.
    FromNote(SpeedRange),
    /// Neither: the speeds are not recorded.
    NotRecorded,
}

impl TrainingSpeeds {
    /// The range, if recorded.
    pub fn range(&self) -> Option<SpeedRange> {
        match self {
            Self::Recorded(r) | Self::FromNote(r) => Some(*r),
            Self::NotRecorded => None,
        }
    }

    /// `4.0-29.8 km/h`, `4.0-29.8 km/h (from the model's training notes)`
    /// or `training speeds not recorded`.
    pub fn describe(&self) -> String {
        match self {
            Self::Recorded(r) => r.label(),
            Self::FromNote(r) => format!("{} (from the model's training notes)", r.label()),
            Self::NotRecorded => NOT_RECORDED.to_owned(),
        }
    }
}

/// The time spent on one side of the training speeds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outside {
    /// Time, s.
    pub time_s: f64,
    /// Slowest speed there, km/h.
    pub min_kmh: f64,
    /// Fastest speed there, km/h.
    pub max_kmh: f64,
}

impl Outside {
    fn add(slot: &mut Option<Self>, kmh: f64, dt: f64) {
        match slot {
            Some(o) => {
                o.time_s += dt;
                o.min_kmh = o.min_kmh.min(kmh);
                o.max_kmh = o.max_kmh.max(kmh);
            }
            None => {
                *slot = Some(Self {
                    time_s: dt,
                    min_kmh: kmh,
                    max_kmh: kmh,
                });
            }
        }
    }
}

/// How much of a stretch of time (a drive's scenario window, the audio a
/// simulation's acoustic chain heard) was below and above a model's
/// training speeds: [`SpeedCheck::add`] each sample's speed and the time
/// it stands for, then [`SpeedCheck::notes`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedCheck {
    /// The model's training speeds.
    pub range: SpeedRange,
    /// Time added, s (samples with a finite speed and time).
    pub total_s: f64,
    /// Time below `range.min_kmh` (None: none).
    pub below: Option<Outside>,
    /// Time above `range.max_kmh` (None: none).
    pub above: Option<Outside>,
}

impl SpeedCheck {
    /// Nothing added yet.
    pub fn new(range: SpeedRange) -> Self {
        Self {
            range,
            total_s: 0.0,
            below: None,
            above: None,
        }
    }

    /// `dt` seconds at `kmh` (its magnitude: reversing counts as its
    /// speed); a non-finite speed, or a time that is not positive and
    /// finite, is left out.
    pub fn add(&mut self, kmh: f64, dt: f64) {
        if !(kmh.is_finite() && dt.is_finite() && dt > 0.0) {
            return;
        }
        let kmh = kmh.abs();
        self.total_s += dt;
        if kmh < self.range.min_kmh {
            Outside::add(&mut self.below, kmh, dt);
        } else if kmh > self.range.max_kmh {
            Outside::add(&mut self.above, kmh, dt);
        }
    }

    /// Whether any time was outside the training speeds.
    pub fn outside(&self) -> bool {
        self.below.is_some() || self.above.is_some()
    }

    /// One note per side with time outside the training speeds, e.g.
    /// `12 % of the scenario window (1.8 of 15.0 s, ground-truth speed) at
    /// 31.0-48.2 km/h, above the model's training speeds (4.0-29.8 km/h):
    /// its estimates there are extrapolation`; `what` names the time (`the
    /// scenario window`), `detail` (may be empty) says more of it after the
    /// seconds (`ground-truth speed`). None when all of it was inside (or
    /// nothing was added).
    pub fn notes(&self, what: &str, detail: &str) -> Vec<String> {
        let mut out = Vec::new();
        for (side, o) in [("below", &self.below), ("above", &self.above)] {
            let Some(o) = o else { continue };
            let one = |v: f64| format!("{v:.1}");
            // the edge next to the training speeds, rounded, can read as
            // theirs (29.81 above 29.795: "29.8-41.3 ... above 4.0-29.8")
            let (near, edge) = if side == "above" {
                (o.min_kmh, self.range.max_kmh)
            } else {
                (o.max_kmh, self.range.min_kmh)
            };
            let speeds = if one(o.min_kmh) == one(o.max_kmh) {
                format!("{} km/h", one(o.min_kmh))
            } else if one(near) == one(edge) && side == "above" {
                format!("speeds up to {} km/h", one(o.max_kmh))
            } else if one(near) == one(edge) {
                format!("speeds down to {} km/h", one(o.min_kmh))
            } else {
                format!("{}-{} km/h", one(o.min_kmh), one(o.max_kmh))
            };
            out.push(format!(
                "{} of {what} ({:.1} of {:.1} s{}{detail}) at {speeds}, {side} the model's training speeds ({}): its estimates there are extrapolation",
                percent(o.time_s / self.total_s),
                o.time_s,
                self.total_s,
                if detail.is_empty() { "" } else { ", " },
                self.range.label()
            ));
        }
        out
    }
}

/// `12 %`, `0.4 %`, `<0.1 %`.
fn percent(share: f64) -> String {
    let p = 100.0 * share;
    if p >= 1.0 {
        format!("{p:.0} %")
    } else if p >= 0.1 {
        format!("{p:.1} %")
    } else {
        "<0.1 %".to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_and_notes_parse() {
        let r = SpeedRange::of([12.0, 4.02, 29.81]).unwrap();
        assert_eq!((r.min_kmh, r.max_kmh), (4.02, 29.81));
        assert_eq!(r.note(), "training speeds: 4.0-29.8 km/h");
        assert_eq!(SpeedRange::from_note(&r.note()), SpeedRange::new(4.0, 29.8));
        assert_eq!(SpeedRange::of([]), None);
        assert_eq!(SpeedRange::of([3.0, f64::NAN]), None);
        assert_eq!(SpeedRange::of([f64::NAN, 3.0]), None);
        assert_eq!(SpeedRange::of([-1.0, 3.0]), None);
        assert_eq!(SpeedRange::new(5.0, 4.0), None);
        for bad in [
            "training speeds: 30-4 km/h",
            "training speeds: x-4 km/h",
            "training speeds: 4.0-29.8",
            "speed normalisation: frequencies warped by (20 km/h / v)^0.1",
            "training speeds not recorded: 3 of 240 recordings have no speed_kmh",
        ] {
            assert_eq!(SpeedRange::from_note(bad), None, "{bad}");
        }
    }

    #[test]
    fn time_below_and_above_is_noted() {
        let r = SpeedRange::new(4.0, 30.0).unwrap();
        let mut c = SpeedCheck::new(r);
        // 2 s creeping at 2-3 km/h, 6 s inside (the edges included), 2 s
        // at 31-48 km/h; a NaN speed and a zero time are left out
        for (kmh, dt) in [
            (2.0, 1.0),
            (-3.0, 1.0),
            (4.0, 3.0),
            (30.0, 3.0),
            (31.0, 1.0),
            (48.0, 1.0),
            (f64::NAN, 5.0),
            (60.0, 0.0),
        ] {
            c.add(kmh, dt);
        }
        assert_eq!(c.total_s, 10.0);
        let n = c.notes("the scenario window", "ground-truth speed");
        assert_eq!(
            n,
            [
                "20 % of the scenario window (2.0 of 10.0 s, ground-truth speed) at 2.0-3.0 km/h, below the model's training speeds (4.0-30.0 km/h): its estimates there are extrapolation",
                "20 % of the scenario window (2.0 of 10.0 s, ground-truth speed) at 31.0-48.0 km/h, above the model's training speeds (4.0-30.0 km/h): its estimates there are extrapolation",
            ]
        );
        let mut one = SpeedCheck::new(r);
        one.add(60.0, 1.0);
        one.add(10.0, 3.0);
        assert_eq!(
            one.notes("the run", ""),
            [
                "25 % of the run (1.0 of 4.0 s) at 60.0 km/h, above the model's training speeds (4.0-30.0 km/h): its estimates there are extrapolation"
            ]
        );
        // just past an edge, rounded to it: not written as if inside
        let mut edges = SpeedCheck::new(r);
        edges.add(30.01, 1.0);
        edges.add(41.3, 1.0);
        edges.add(3.98, 1.0);
        edges.add(2.5, 1.0);
        let n = edges.notes("the run", "");
        assert!(
            n[0].contains("at speeds down to 2.5 km/h, below"),
            "{}",
            n[0]
        );
        assert!(
            n[1].contains("at speeds up to 41.3 km/h, above"),
            "{}",
            n[1]
        );
        let mut inside = SpeedCheck::new(r);
        inside.add(10.0, 5.0);
        assert!(!inside.outside());
        assert!(inside.notes("x", "").is_empty());
        assert!(SpeedCheck::new(r).notes("x", "").is_empty());
        assert_eq!(percent(0.004), "0.4 %");
        assert_eq!(percent(0.0001), "<0.1 %");
    }
}
