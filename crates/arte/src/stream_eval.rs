//! Evaluation of the streaming estimator on road-change recordings: what
//! `grip dataset delay` reports, as plain functions and an accumulator.
//!
//! Ground truth is a recording's segments `(t_start, t_end, class, extra)`
//! in time order, not overlapping (the extra field, e.g. the speed, is not
//! used here). A decision is judged against the segment holding its
//! `t_end` (the moment it becomes available), except for the accuracy
//! inside segments, which counts only decisions whose whole frame lies
//! inside one segment. A decision in a gap between segments, or more than
//! `tail_s` (one hop) past the last segment's end, is unjudged: no truth
//! is known there, so it counts in no accuracy, confidence bin or
//! calibration (see [`segment_at`]).
//!
//! - [`crate::stream::detection_delays`]: delay of each change (the rule
//!   lives beside the estimator).
//! - [`count_false_switches`]: switches of the smoothed decision to a road
//!   that is not the true one.
//! - [`KnowledgeUse`]: what a controller that applies a `min_confidence`
//!   gate is given (share used, right when used, wrong road in use near a
//!   change or elsewhere, optimistic or cautious), and the accuracy per
//!   confidence bin ([`CONFIDENCE_BINS`]).
//! - [`bootstrap_percentile`]: a percentile's 95 % interval by resampling
//!   recordings.
//! - [`ChangeEval`]: all of the above over a set of recordings, plus the
//!   confusion matrices of the smoothed and single-frame decisions inside
//!   segments.

use crate::eval::Confusion;
use crate::stream::{detection_delays, percentile};

/// A ground-truth segment: `(t_start, t_end, class, extra)` in seconds.
pub type Seg<T> = (f64, f64, usize, T);

/// The segment holding time `t` (`t_start <= t < t_end`) and its index.
/// Up to `tail_s` past the last segment's end (a recording a few samples
/// longer than its segments; pass the stream's hop), the last one. `None`
/// (unjudged: no truth is known) in a gap between segments, before the
/// first, further past the last, or without segments.
pub fn segment_at<T>(segments: &[Seg<T>], t: f64, tail_s: f64) -> Option<(usize, &Seg<T>)> {
    if let Some(found) = segments
        .iter()
        .enumerate()
        .find(|(_, s)| t >= s.0 && t < s.1)
    {
        return Some(found);
    }
    segments
        .iter()
        .enumerate()
        .last()
        .filter(|(_, s)| t >= s.1 && t <= s.1 + tail_s.max(0.0) + 1e-9)
}

/// Smoothed decisions `(t_end, class)` in time order that differ from the
/// previous decision and name a road other than the true one at `t_end`.
/// A switch to the right road, late or not, is not counted; nor is the
/// first decision, nor an unjudged one (`tail_s`: see [`segment_at`]).
/// Returned as (within `near_s` after a true change, i.e. on the way from
/// the old road to the new one; elsewhere).
pub fn count_false_switches<T>(
    dec: &[(f64, usize)],
    segments: &[Seg<T>],
    near_s: f64,
    tail_s: f64,
) -> (usize, usize) {
    let (mut near, mut inside) = (0, 0);
    for w in dec.windows(2) {
        let (t, c) = w[1];
        let Some((i, seg)) = segment_at(segments, t, tail_s) else {
            continue;
        };
        if c != w[0].1 && c != seg.2 {
            if i > 0 && t - seg.0 <= near_s {
                near += 1;
            } else {
                inside += 1;
            }
        }
    }
    (near, inside)
}

/// Lower edges of the confidence bins of [`KnowledgeUse::bins`].
pub const CONFIDENCE_BINS: [f64; 5] = [0.0, 0.6, 0.8, 0.9, 0.99];

/// What a controller that uses decisions of at least a minimum confidence
/// is given, counted over every decision against the true road at the
/// decision's time (`t_end`).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct KnowledgeUse {
    /// Decisions counted.
    pub decisions: usize,
    /// Of them, confident enough to be used.
    pub used: usize,
    /// Used and naming the true road.
    pub used_right: usize,
    /// Used, naming another road, within `near_s` after a true change.
    pub used_wrong_near: usize,
    /// Used, naming a road with a higher peak friction than the true one
    /// (the controller expects grip the road does not have).
    pub used_wrong_optimistic: usize,
    /// Per confidence bin ([`CONFIDENCE_BINS`]): (decisions, right).
    pub bins: [(usize, usize); CONFIDENCE_BINS.len()],
}

impl KnowledgeUse {
    /// Adds one recording's smoothed decisions `(t_end, class)` with their
    /// confidences, against its segments; `mu_peak[class]` is each class's
    /// peak friction (empty: unknown, no optimistic count). Unjudged
    /// decisions (`tail_s`: see [`segment_at`]) are skipped; returns how
    /// many.
    #[allow(clippy::too_many_arguments)]
    pub fn add<T>(
        &mut self,
        dec: &[(f64, usize)],
        confidence: &[f64],
        segments: &[Seg<T>],
        mu_peak: &[f64],
        min_confidence: f64,
        near_s: f64,
        tail_s: f64,
    ) -> usize {
        let mut unjudged = 0;
        for (&(t, c), &p) in dec.iter().zip(confidence) {
            let Some((i, seg)) = segment_at(segments, t, tail_s) else {
                unjudged += 1;
                continue;
            };
            self.decisions += 1;
            let b = CONFIDENCE_BINS.iter().rposition(|&lo| p >= lo).unwrap_or(0);
            self.bins[b].0 += 1;
            self.bins[b].1 += usize::from(c == seg.2);
            if p < min_confidence {
                continue;
            }
            self.used += 1;
            if c == seg.2 {
                self.used_right += 1;
                continue;
            }
            if i > 0 && t - seg.0 <= near_s {
                self.used_wrong_near += 1;
            }
            if let (Some(used), Some(truth)) = (mu_peak.get(c), mu_peak.get(seg.2))
                && used > truth
            {
                self.used_wrong_optimistic += 1;
            }
        }
        unjudged
    }

    /// Used decisions naming another road than the true one.
    pub fn used_wrong(&self) -> usize {
        self.used - self.used_right
    }
}

/// Percentile `p` of the pooled values, as a 95 % interval by resampling
/// the groups (recordings) with replacement `n` times (seeded, so the
/// interval is reproducible). `None` without values.
pub fn bootstrap_percentile(
    groups: &[Vec<f64>],
    p: f64,
    n: usize,
    seed: u64,
) -> Option<(f64, f64)> {
    use rand::{Rng, SeedableRng};
    if groups.iter().all(Vec::is_empty) {
        return None;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut stats = Vec::with_capacity(n);
    let mut pool = Vec::new();
    for _ in 0..n {
        pool.clear();
        for _ in 0..groups.len() {
            pool.extend_from_slice(&groups[rng.random_range(0..groups.len())]);
        }
        if let Some(v) = percentile(&pool, p) {
            stats.push(v);
        }
    }
    Some((percentile(&stats, 2.5)?, percentile(&stats, 97.5)?))
}

/// One decision of the streaming estimator as the evaluation needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Judged {
    /// Start of the decision's frame (s).
    pub t_start: f64,
    /// End of the frame (s), when the decision is available.
    pub t_end: f64,
    /// Smoothed class.
    pub class: usize,
    /// The frame's own class.
    pub raw_class: usize,
    /// Confidence of the smoothed class (what the controller is given).
    pub confidence: f64,
}

/// Everything `grip dataset delay` reports, accumulated over recordings.
#[derive(Clone, Debug)]
pub struct ChangeEval {
    /// Peak friction per class (empty: unknown).
    mu_peak: Vec<f64>,
    /// The controller's gate.
    min_confidence: f64,
    /// How long a new road must hold to count as detected (s); also the
    /// "near a change" window of false switches and wrong roads in use.
    hold_s: f64,
    /// How far past the last segment a decision is still judged (s; the
    /// stream's hop, see [`segment_at`]).
    tail_s: f64,
    /// Delays of the detected changes (s).
    pub delays: Vec<f64>,
    /// Changes never detected.
    pub missed: usize,
    /// Changes (the first segment of a recording is not a change).
    pub n_changes: usize,
    /// Per recording: its changes' delays (missed = ∞), for the bootstrap.
    pub per_recording: Vec<Vec<f64>>,
    /// False switches within `hold_s` after a true change.
    pub false_near: usize,
    /// False switches elsewhere.
    pub false_inside: usize,
    /// Audio evaluated (s).
    pub audio_s: f64,
    /// What the controller is given.
    pub used: KnowledgeUse,
    /// Smoothed decisions whose frame lies inside one segment.
    pub smoothed: Confusion,
    /// Single-frame decisions of the same frames.
    pub single_frame: Confusion,
    /// Decisions with no segment at their `t_end` (in a gap, or past the
    /// last segment): counted nowhere else.
    pub unjudged: usize,
    /// Every decision's confidence (with a segment at its `t_end`) ...
    pub confidence: Vec<f64>,
    /// ... and whether it named the true road at that time (the pairs a
    /// reliability table and the ECE are computed from).
    pub right: Vec<bool>,
}

impl ChangeEval {
    /// Empty accumulator for a model's `classes`; `mu_peak` per class (or
    /// empty), the controller's gate, the hold time (s) and the stream's
    /// hop (s; how far past the last segment a decision is still judged).
    pub fn new(
        classes: Vec<String>,
        mu_peak: Vec<f64>,
        min_confidence: f64,
        hold_s: f64,
        hop_s: f64,
    ) -> Self {
        Self {
            mu_peak,
            min_confidence,
            hold_s,
            tail_s: hop_s,
            delays: Vec::new(),
            missed: 0,
            n_changes: 0,
            per_recording: Vec::new(),
            false_near: 0,
            false_inside: 0,
            audio_s: 0.0,
            used: KnowledgeUse::default(),
            unjudged: 0,
            smoothed: Confusion::new(classes.clone()),
            single_frame: Confusion::new(classes),
            confidence: Vec::new(),
            right: Vec::new(),
        }
    }

    /// Adds one recording: its decisions in time order, its segments in
    /// time order, and its length (s).
    pub fn add_recording<T>(&mut self, decisions: &[Judged], segments: &[Seg<T>], duration_s: f64) {
        let dec: Vec<(f64, usize)> = decisions.iter().map(|d| (d.t_end, d.class)).collect();
        let confidence: Vec<f64> = decisions.iter().map(|d| d.confidence).collect();
        for d in decisions {
            if let Some((_, seg)) = segment_at(segments, d.t_end, self.tail_s) {
                self.confidence.push(d.confidence);
                self.right.push(d.class == seg.2);
            }
        }
        // Accuracy over decisions whose frame lies inside one segment.
        for d in decisions {
            if let Some(seg) = segments
                .iter()
                .find(|s| d.t_start >= s.0 - 1e-9 && d.t_end <= s.1 + 1e-9)
            {
                self.smoothed.add(d.class, seg.2);
                self.single_frame.add(d.raw_class, seg.2);
            }
        }
        self.unjudged += self.used.add(
            &dec,
            &confidence,
            segments,
            &self.mu_peak,
            self.min_confidence,
            self.hold_s,
            self.tail_s,
        );
        let (near, inside) = count_false_switches(&dec, segments, self.hold_s, self.tail_s);
        self.false_near += near;
        self.false_inside += inside;
        self.audio_s += duration_s;
        let changes: Vec<(f64, usize)> = segments.iter().map(|s| (s.0, s.2)).collect();
        let end = segments.last().map_or(0.0, |s| s.1);
        let mut mine = Vec::new();
        for d in detection_delays(&dec, &changes, end, self.hold_s)
            .into_iter()
            .skip(1)
        {
            self.n_changes += 1;
            match d {
                Some(v) => self.delays.push(v),
                None => self.missed += 1,
            }
            mine.push(d.unwrap_or(f64::INFINITY));
        }
        self.per_recording.push(mine);
    }

    /// Whether the peak friction of every class is known (optimistic and
    /// cautious mistakes told apart).
    pub fn mu_peak_known(&self) -> bool {
        !self.mu_peak.is_empty()
    }

    /// Every change's delay, a missed one as ∞ (longer than any), for
    /// percentiles over all changes.
    pub fn all_delays(&self) -> Vec<f64> {
        let mut all = self.delays.clone();
        all.extend(std::iter::repeat_n(f64::INFINITY, self.missed));
        all
    }

    /// Percent of all changes detected within `limit_s`; `None` without changes.
    pub fn percent_within(&self, limit_s: f64) -> Option<f64> {
        (self.n_changes > 0).then(|| {
            100.0 * self.delays.iter().filter(|&&d| d <= limit_s).count() as f64
                / self.n_changes as f64
        })
    }

    /// False switches per minute of audio: (inside segments, within
    /// `hold_s` after a true change); `None` without audio.
    pub fn false_switches_per_minute(&self) -> Option<(f64, f64)> {
        (self.audio_s > 0.0).then(|| {
            let per_min = |n: usize| n as f64 * 60.0 / self.audio_s;
            (per_min(self.false_inside), per_min(self.false_near))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn false_switches_count_only_switches_to_a_wrong_road() {
        // Road 0 until 1 s, then road 1.
        let segs = [(0.0, 1.0, 0, ()), (1.0, 2.0, 1, ())];
        let dec = [
            (0.2, 0),
            (0.4, 2), // wrong switch
            (0.6, 0), // back to the right road: not counted
            (0.8, 0),
            (1.05, 0), // late, but no switch
            (1.1, 1),  // right switch
            (1.5, 0),  // wrong switch
            (1.9, 0),
        ];
        assert_eq!(count_false_switches(&dec, &segs, 0.2, 0.025), (0, 2));
        assert_eq!(count_false_switches(&dec, &segs, 0.6, 0.025), (1, 1));
        assert_eq!(count_false_switches(&dec[..1], &segs, 0.2, 0.025), (0, 0));
        // a switch in a gap is unjudged, not a false switch (and staying on
        // that road afterwards is no switch)
        let gap = [(0.0, 1.0, 0, ()), (1.5, 2.0, 1, ())];
        assert_eq!(
            count_false_switches(&[(0.9, 0), (1.2, 2), (1.6, 2)], &gap, 0.2, 0.025),
            (0, 0)
        );
        // against the last segment's road (the old rule) it was one
        assert_eq!(
            count_false_switches(&[(0.9, 0), (1.6, 2)], &gap, 0.2, 0.025),
            (1, 0)
        );
    }

    #[test]
    fn segment_at_finds_the_holding_segment_or_none_in_a_gap() {
        let segs = [(0.0, 1.0, 3, ()), (1.0, 2.0, 4, ())];
        assert_eq!(segment_at(&segs, 0.0, 0.025).map(|s| s.0), Some(0));
        assert_eq!(segment_at(&segs, 1.0, 0.025).map(|s| s.0), Some(1));
        // within one hop past the end: the last segment; further: unjudged
        assert_eq!(segment_at(&segs, 2.0, 0.025).map(|s| s.1.2), Some(4));
        assert_eq!(segment_at(&segs, 2.02, 0.025).map(|s| s.1.2), Some(4));
        assert!(segment_at(&segs, 2.03, 0.025).is_none());
        assert!(segment_at(&segs, 7.0, 0.025).is_none());
        assert!(segment_at::<()>(&[], 0.5, 0.025).is_none());
        // a gap between segments (unlabelled audio) is unjudged, not the
        // last segment's road
        let gap = [(0.0, 1.0, 3, ()), (1.5, 2.0, 4, ()), (3.0, 4.0, 5, ())];
        assert!(segment_at(&gap, 1.2, 0.025).is_none());
        assert!(segment_at(&gap, 2.5, 0.025).is_none());
        assert_eq!(segment_at(&gap, 1.5, 0.025).map(|s| s.0), Some(1));
        assert!(segment_at(&gap, -0.1, 0.025).is_none());
    }

    #[test]
    fn knowledge_use_counts_confident_decisions_against_the_true_road() {
        // road 0 until 1 s, then road 1
        let segs = [(0.0, 1.0, 0usize, ()), (1.0, 2.0, 1usize, ())];
        let dec = [
            (0.5, 0), // right, confident
            (0.6, 1), // wrong, not confident: not used
            (0.9, 1), // wrong, confident, before the change: elsewhere
            (1.1, 0), // wrong, confident, 0.1 s after the change: near
            (1.5, 0), // wrong, confident, 0.5 s after it: elsewhere
            (1.6, 1), // right, confident
            (2.5, 1), // past the end, within the tail: the last segment's road
        ];
        let confidence = [0.9, 0.5, 0.7, 0.8, 0.6, 0.99, 0.6];
        // road 0 grips more than road 1: hearing 0 on 1 is optimistic
        let mu_peak = [1.0, 0.5];
        let mut u = KnowledgeUse::default();
        assert_eq!(u.add(&dec, &confidence, &segs, &mu_peak, 0.6, 0.2, 0.5), 0);
        assert_eq!(
            u,
            KnowledgeUse {
                decisions: 7,
                used: 6,
                used_right: 3,
                used_wrong_near: 1,
                used_wrong_optimistic: 2,
                // bins 0-0.6, 0.6-0.8, 0.8-0.9, 0.9-0.99, 0.99-1
                bins: [(1, 0), (3, 1), (1, 0), (1, 1), (1, 1)],
            }
        );
        assert_eq!(u.used_wrong(), 3);
        // unknown frictions: no optimistic count
        let mut n = KnowledgeUse::default();
        n.add(&dec, &confidence, &segs, &[], 0.6, 0.2, 0.5);
        assert_eq!((n.used, n.used_wrong_optimistic), (6, 0));
        // no segments: nothing counted
        let mut e = KnowledgeUse::default();
        assert_eq!(
            e.add::<()>(&dec, &confidence, &[], &mu_peak, 0.6, 0.2, 0.5),
            7
        );
        assert_eq!(e.decisions, 0);
        // a tail of one short hop: 2.5 s is unjudged
        let mut t = KnowledgeUse::default();
        assert_eq!(
            t.add(&dec, &confidence, &segs, &mu_peak, 0.6, 0.2, 0.025),
            1
        );
        assert_eq!((t.decisions, t.used, t.used_right), (6, 5, 2));
    }

    #[test]
    fn bootstrap_interval_brackets_the_percentile_and_is_reproducible() {
        let groups: Vec<Vec<f64>> = (0..40)
            .map(|i| {
                (0..4)
                    .map(|j| 0.08 + 0.001 * f64::from(i * 4 + j))
                    .collect()
            })
            .collect();
        let pooled: Vec<f64> = groups.iter().flatten().copied().collect();
        let p95 = percentile(&pooled, 95.0).unwrap();
        let (lo, hi) = bootstrap_percentile(&groups, 95.0, 500, 7).unwrap();
        assert!(lo <= p95 && p95 <= hi && lo < hi, "{lo} {p95} {hi}");
        assert_eq!(bootstrap_percentile(&groups, 95.0, 500, 7), Some((lo, hi)));
        // A set where most changes are missed: the interval reaches ∞.
        let missed = vec![vec![f64::INFINITY, 0.1], vec![f64::INFINITY]];
        assert_eq!(
            bootstrap_percentile(&missed, 95.0, 100, 1).map(|x| x.1),
            Some(f64::INFINITY)
        );
        assert_eq!(bootstrap_percentile(&[vec![], vec![]], 95.0, 10, 1), None);
        // One group of one value: every resample is that value.
        assert_eq!(
            bootstrap_percentile(&[vec![0.25]], 95.0, 10, 1),
            Some((0.25, 0.25))
        );
    }

    fn judged(t_end: f64, class: usize, raw_class: usize, confidence: f64) -> Judged {
        Judged {
            t_start: t_end - 0.1,
            t_end,
            class,
            raw_class,
            confidence,
        }
    }

    #[test]
    fn change_eval_adds_up_one_recording_by_hand() {
        // road 0 on [0, 1), road 1 on [1, 2); decisions every 0.1 s from 0.1.
        let segs = [(0.0, 1.0, 0usize, ()), (1.0, 2.0, 1usize, ())];
        let mut d: Vec<Judged> = (1..=19)
            .map(|i| {
                let t = f64::from(i) / 10.0;
                // the new road is decided from 1.2 s on
                let c = usize::from(t > 1.15);
                judged(t, c, c, 0.95)
            })
            .collect();
        // one wrong, unconfident flip inside the first segment at 0.5 s
        d[4] = judged(0.5, 2, 2, 0.5);
        let mut e = ChangeEval::new(
            vec!["a".into(), "b".into(), "c".into()],
            vec![],
            0.6,
            0.2,
            0.1,
        );
        e.add_recording(&d, &segs, 2.0);
        assert_eq!((e.n_changes, e.missed), (1, 0));
        assert_eq!(e.delays.len(), 1);
        assert!((e.delays[0] - 0.2).abs() < 1e-9, "{:?}", e.delays);
        assert_eq!(e.per_recording.len(), 1);
        // 0.5 s: switch to road 2 (wrong, elsewhere); 0.6 s: back (right).
        assert_eq!((e.false_near, e.false_inside), (0, 1));
        let (inside, near) = e.false_switches_per_minute().unwrap();
        assert!((inside - 30.0).abs() < 1e-9 && near == 0.0);
        // 19 decisions, 18 used (0.5 s is below the gate); wrong in use:
        // 1.0 s (segment 1 begins at 1.0: road 0 there) and 1.1 s, both
        // within 0.2 s after the change.
        assert_eq!(
            (
                e.used.decisions,
                e.used.used,
                e.used.used_right,
                e.used.used_wrong_near
            ),
            (19, 18, 16, 2)
        );
        // Frames of 0.1 s ending on a 0.1 s grid: all 19 lie inside one
        // segment; the smoothed decisions at 0.5 and 1.1 s are wrong.
        assert_eq!(e.smoothed.total(), 19);
        assert_eq!(e.smoothed.metrics().accuracy, 17.0 / 19.0);
        assert_eq!(e.percent_within(0.2), Some(100.0));
        assert_eq!(e.percent_within(0.1), Some(0.0));
        assert_eq!(e.all_delays().len(), 1);
        // A recording whose change is never detected counts as missed (∞).
        let never: Vec<Judged> = (1..=19)
            .map(|i| judged(f64::from(i) / 10.0, 0, 0, 0.99))
            .collect();
        e.add_recording(&never, &segs, 2.0);
        assert_eq!((e.n_changes, e.missed), (2, 1));
        assert_eq!(e.all_delays().iter().filter(|d| d.is_infinite()).count(), 1);
        assert_eq!(e.percent_within(0.2), Some(50.0));
        assert_eq!(e.unjudged, 0);
    }

    #[test]
    fn change_eval_leaves_decisions_in_a_gap_unjudged() {
        // road 0 on [0, 1), unlabelled audio on [1, 2), road 1 on [2, 3);
        // decisions every 0.1 s from 0.1, all naming road 0.
        let segs = [(0.0, 1.0, 0usize, ()), (2.0, 3.0, 1usize, ())];
        let d: Vec<Judged> = (1..=30)
            .map(|i| judged(f64::from(i) / 10.0, 0, 0, 0.95))
            .collect();
        let mut e = ChangeEval::new(vec!["a".into(), "b".into()], vec![], 0.6, 0.2, 0.1);
        e.add_recording(&d, &segs, 3.0);
        // t_end 1.0 .. 1.9 lie in the gap: 10 unjudged; 0.1 .. 0.9 right,
        // 2.0 .. 3.0 (3.0 within one hop past the end) wrong.
        assert_eq!(e.unjudged, 10);
        assert_eq!(e.confidence.len(), 20);
        assert_eq!(e.right.iter().filter(|&&r| r).count(), 9);
        assert_eq!((e.used.decisions, e.used.used_right), (20, 9));
        // frames inside one segment only: [0, 1) gives 0.1 .. 1.0 (10),
        // [2, 3) gives 2.1 .. 3.0 (10)
        assert_eq!(e.smoothed.total(), 20);
        assert_eq!(e.smoothed.metrics().accuracy, 0.5);
    }
}
