//! [`InLoopProbe`] wraps any [`RoadEstimator`] and records its decisions and
//! the true road changes of a run, for the in-loop accuracy and detection
//! delays `grip sim` reports ([`InLoopStats`], returned with every run's
//! [`crate::RunResult`]); it allocates nothing per cycle (buffers sized to
//! the run's cycle count, reserved at the first reset: a probe that no ARTE
//! run resets holds none).

use grip_arte::stream::detection_delays;

use crate::estimator::{Estimate, RoadEstimator};

/// Width of the speed bins of [`InLoopStats::heard_speed_s`], km/h.
pub const SPEED_BIN_KMH: f64 = 0.1;

/// Speed bins: 0 to 400 km/h (anything faster counts in the last).
pub const SPEED_BINS: usize = 4000;

/// What an estimator did in one run, as seen from the loop.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InLoopStats {
    /// Decisions received.
    pub decisions: u64,
    /// Decisions equal to the true road of the cycle they arrived in.
    pub correct: u64,
    /// Decisions whose whole analysis frame lay on one road.
    pub single_road: u64,
    /// Of those, correct.
    pub single_road_correct: u64,
    /// Per true road change (not the start): time from the change to the
    /// first decision of the new road, s (`None`: none before the next change
    /// or the end).
    pub first_delays: Vec<Option<f64>>,
    /// The same with the decision required to hold for `hold_s` (the ARTE
    /// crate's detection-delay definition, `stream::detection_delays`).
    pub stable_delays: Vec<Option<f64>>,
    /// In-loop confusion counts, `confusion[estimated][true]` (catalogue
    /// indices; rows estimated, columns true: the paper's Table II layout),
    /// over every decision against the true road of its arrival cycle.
    pub confusion: Vec<Vec<u64>>,
    /// Time the estimator heard each catalogue road, s (catalogue index;
    /// the pre-roll included).
    pub heard_s: Vec<f64>,
    /// Time the estimator heard at each vehicle speed |v|, s: (bin, time)
    /// for every bin with time, bins ascending; bin k holds speeds in
    /// [k, k + 1) · [`SPEED_BIN_KMH`] (the last one also every faster
    /// speed), the pre-roll included. What `grip sim --arte acoustic`
    /// checks against the model's training speeds
    /// ([`crate::speeds::training_speeds_note`]).
    pub heard_speed_s: Vec<(usize, f64)>,
}

/// Records an estimator's decisions and the true road changes of a run
/// (see [`InLoopStats`]); forwards everything to the wrapped estimator.
pub struct InLoopProbe {
    inner: Box<dyn RoadEstimator>,
    frame_s: f64,
    hold_s: f64,
    decisions: Vec<(f64, usize)>,
    changes: Vec<(f64, usize)>,
    /// Decisions received (all of them, also any beyond `decisions`' room).
    n_decisions: u64,
    correct: u64,
    single_road: u64,
    single_road_correct: u64,
    last_road: Option<usize>,
    last_change: f64,
    end: f64,
    /// Row-major n × n, `[estimated * n + true]`.
    confusion: Vec<u64>,
    /// Per catalogue road, s.
    heard_s: Vec<f64>,
    /// Per speed bin, s ([`SPEED_BINS`] once reset; empty before).
    heard_speed: Vec<f64>,
    n_roads: usize,
    /// Room the buffers get at the first reset, cycles.
    room: usize,
}

impl std::fmt::Debug for InLoopProbe {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InLoopProbe")
            .field("inner", &self.inner.name())
            .field("decisions", &self.decisions.len())
            .finish_non_exhaustive()
    }
}

impl InLoopProbe {
    /// Wrap `inner` whose decisions analyse frames of `frame_s`; room for
    /// `cycles` cycles, the pre-roll's included (at most one decision and
    /// one change per cycle, so recording never allocates; counts go on
    /// beyond it, the delays then see the first `cycles` decisions only),
    /// reserved at the first [`RoadEstimator::reset`] (which every ARTE run
    /// calls before its first cycle), [`InLoopProbe::bytes_for`] of them;
    /// stable detection needs `hold_s`; the catalogue has `n_roads` roads
    /// (larger indices are not counted in the confusion matrix).
    pub fn new(
        inner: Box<dyn RoadEstimator>,
        frame_s: f64,
        cycles: usize,
        hold_s: f64,
        n_roads: usize,
    ) -> Self {
        Self {
            inner,
            frame_s,
            hold_s,
            decisions: Vec::new(),
            changes: Vec::new(),
            n_decisions: 0,
            correct: 0,
            single_road: 0,
            single_road_correct: 0,
            last_road: None,
            last_change: f64::NEG_INFINITY,
            end: 0.0,
            confusion: vec![0; n_roads * n_roads],
            heard_s: vec![0.0; n_roads],
            heard_speed: Vec::new(),
            n_roads,
            room: cycles,
        }
    }

    /// Bytes a probe with room for `cycles` cycles holds once reset (its
    /// decision and change buffers, and its speed bins).
    pub fn bytes_for(cycles: usize) -> u64 {
        2 * cycles as u64 * std::mem::size_of::<(f64, usize)>() as u64
            + (SPEED_BINS * std::mem::size_of::<f64>()) as u64
    }

    /// The statistics of the run since the last reset, or `None` when the
    /// estimator was never asked (a variant without ARTE).
    fn collect_stats(&self) -> Option<InLoopStats> {
        self.last_road?;
        let first = detection_delays(&self.decisions, &self.changes, self.end, 0.0);
        let stable = detection_delays(&self.decisions, &self.changes, self.end, self.hold_s);
        Some(InLoopStats {
            decisions: self.n_decisions,
            correct: self.correct,
            single_road: self.single_road,
            single_road_correct: self.single_road_correct,
            first_delays: first,
            stable_delays: stable,
            confusion: self
                .confusion
                .chunks(self.n_roads.max(1))
                .map(<[u64]>::to_vec)
                .collect(),
            heard_s: self.heard_s.clone(),
            heard_speed_s: self
                .heard_speed
                .iter()
                .enumerate()
                .filter(|(_, s)| **s > 0.0)
                .map(|(b, s)| (b, *s))
                .collect(),
        })
    }
}

impl RoadEstimator for InLoopProbe {
    fn reset(&mut self, seed: u64) {
        self.inner.reset(seed);
        self.decisions.clear();
        self.changes.clear();
        // Room for the run, once (a later reset keeps it).
        self.decisions.reserve_exact(self.room);
        self.changes.reserve_exact(self.room);
        self.heard_s.fill(0.0);
        if self.heard_speed.is_empty() {
            self.heard_speed = vec![0.0; SPEED_BINS];
        } else {
            self.heard_speed.fill(0.0);
        }
        self.n_decisions = 0;
        self.correct = 0;
        self.single_road = 0;
        self.single_road_correct = 0;
        self.last_road = None;
        self.last_change = f64::NEG_INFINITY;
        self.end = 0.0;
        self.confusion.fill(0);
    }

    fn update(
        &mut self,
        t: f64,
        dt: f64,
        true_road_index: usize,
        speed_mps: f64,
    ) -> Option<Estimate> {
        match self.last_road {
            Some(r) if r != true_road_index => {
                if self.changes.len() < self.changes.capacity() {
                    self.changes.push((t, true_road_index));
                }
                self.last_change = t;
            }
            None => self.last_road = Some(true_road_index),
            _ => {}
        }
        self.last_road = Some(true_road_index);
        self.end = t + dt;
        if let Some(h) = self.heard_s.get_mut(true_road_index) {
            *h += dt;
        }
        let kmh = speed_mps.abs() * 3.6;
        if kmh.is_finite()
            && let Some(h) = self
                .heard_speed
                .get_mut(((kmh / SPEED_BIN_KMH) as usize).min(SPEED_BINS - 1))
        {
            *h += dt;
        }
        let e = self.inner.update(t, dt, true_road_index, speed_mps)?;
        self.n_decisions += 1;
        if self.decisions.len() < self.decisions.capacity() {
            self.decisions.push((e.t_stamp, e.road_index));
        }
        let ok = e.road_index == true_road_index;
        if e.road_index < self.n_roads
            && true_road_index < self.n_roads
            && let Some(c) = self
                .confusion
                .get_mut(e.road_index * self.n_roads + true_road_index)
        {
            *c += 1;
        }
        self.correct += u64::from(ok);
        // Frame [t_stamp − frame_s, t_stamp] on one road: no change after its start.
        if self.last_change <= e.t_stamp - self.frame_s + 1e-9 {
            self.single_road += 1;
            self.single_road_correct += u64::from(ok);
        }
        Some(e)
    }

    fn name(&self) -> &str {
        self.inner.name()
    }

    fn take_stats(&mut self) -> Option<InLoopStats> {
        self.collect_stats()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acoustic::tests::drive;

    #[test]
    fn probe_counts_and_measures_delays() {
        // Perfect source with 0.1 s frames: a change is seen at the next
        // frame end; frames straddling a change are not single-road.
        let mut p = InLoopProbe::new(Box::new(crate::PerfectArte::new(0.1)), 0.1, 1000, 0.2, 3);
        assert!(p.take_stats().is_none());
        let plan = [(0.0, 0), (0.33, 2)];
        let est = drive(&mut p, 1, &plan, 1.0);
        assert_eq!(est.len(), 10);
        let s = p.take_stats().unwrap();
        assert_eq!(s.decisions, 10);
        // The frame ending at 0.4 s arrives in the cycle [0.399, 0.4) on snow.
        assert_eq!(s.correct, 10);
        assert_eq!(s.single_road, 9);
        assert_eq!(s.first_delays.len(), 1);
        let d = s.first_delays[0].unwrap();
        assert!((d - 0.07).abs() < 1e-6, "{d}");
        assert_eq!(s.stable_delays[0], s.first_delays[0]);
        assert_eq!(s.confusion, vec![vec![3, 0, 0], vec![0; 3], vec![0, 0, 7]]);
        // Reset clears everything.
        p.reset(2);
        assert!(p.take_stats().is_none());
        drive(&mut p, 1, &[(0.0, 1)], 0.3);
        let s = p.take_stats().unwrap();
        assert_eq!(s.confusion, vec![vec![0; 3], vec![0, 3, 0], vec![0; 3]]);
        assert!(s.first_delays.is_empty());
        // the time heard per speed bin: `drive` runs at 4 + t m/s, 14.4 to
        // 15.48 km/h over its 0.3 s
        let heard: f64 = s.heard_speed_s.iter().map(|(_, t)| t).sum();
        assert!((heard - 0.3).abs() < 1e-9, "{:?}", s.heard_speed_s);
        let bins: Vec<usize> = s.heard_speed_s.iter().map(|&(b, _)| b).collect();
        assert!(
            (143..=144).contains(&bins[0]) && bins[bins.len() - 1] == 154,
            "{bins:?}"
        );
        assert!(bins.windows(2).all(|w| w[0] < w[1]), "{bins:?}");
    }

    #[test]
    fn decisions_beyond_the_room_still_count() {
        // The oracle decides every cycle: 500 decisions into room for 200
        // (a pre-roll longer than planned); the counts stay consistent.
        let mut p = InLoopProbe::new(
            Box::new(crate::PerfectArte::oracle(1e-3)),
            1e-3,
            200,
            0.2,
            3,
        );
        drive(&mut p, 1, &[(0.0, 0), (0.25, 2)], 0.5);
        let s = p.take_stats().unwrap();
        assert_eq!(s.decisions, 500);
        assert_eq!(s.correct, 500);
        assert_eq!(s.confusion[0][0] + s.confusion[2][2], 500);
    }
}
