//! The road-estimate source of the closed loop, and the confusion-matrix ARTE.
//!
//! [`RoadEstimator`] is what the simulator calls once per controller cycle.
//! It is told the true road (a simulator has the ground truth) so that a
//! stand-in classifier can corrupt it; an acoustic estimator instead
//! synthesises tyre-road audio for that road and speed and classifies it.
//!
//! [`ConfusionArte`]: until the acoustic ARTE is in the loop, "with ARTE"
//! means the true road passed through a seeded confusion matrix, by default
//! the paper's Table II (ANN, 30 test frames per class, rows predicted,
//! columns actual):
//!
//! ```text
//!                 actual: asphalt snow stone gravel
//! predicted asphalt        28     0     1     1
//!           snow            0    26     3     4
//!           stone           1     3    26     2
//!           gravel          1     1     0    23
//! ```
//!
//! - One decision per frame of `frame_s` (0.1 s, the paper's frame). The
//!   frame's *actual* road is the one the wheel was on for the larger part of
//!   the frame (ties go to the later road); the decision is available at the
//!   frame's end (`t_stamp`) and the simulator hands it to the controller from
//!   the next cycle on, so a road change is seen 0.1-0.2 s late, as in the
//!   paper ("switching between roads caught within 0.2 s").
//! - The predicted class is drawn from P(predicted | actual) = count /
//!   column sum with a `ChaCha8Rng` seeded by [`RoadEstimator::reset`], one
//!   uniform draw per frame.
//! - Confidence is the predicted class's **precision** P(actual = p |
//!   predicted = p) under equal class priors, i.e. Σ-normalised over the
//!   row of the column-normalised matrix. It is a property of the classifier
//!   (what a calibrated classifier reports for that output), never of the
//!   frame's truth: a wrong "snow" carries the same confidence as a right one.
//!   Table II gives asphalt 0.933, snow 0.788, stone 0.812, gravel 0.920.
//! - Roads outside the matrix's classes (wet asphalt, ice, ...) either go
//!   through the matrix as a configured class (`[confusion.map]`, e.g.
//!   `wet_asphalt = "asphalt"`: the classifier cannot tell them apart, the
//!   controller gets the class's curve) or, by default, pass through as
//!   themselves with `outside_confidence` (default: the matrix's balanced
//!   accuracy, 0.858 for Table II: such a road is assumed recognised as well
//!   as the average trained class, an assumption and not a measurement).

use std::collections::BTreeMap;

use grip_physics::RoadCatalogue;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::SimError;

/// One road decision of an estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Index of the estimated road in the catalogue.
    pub road_index: usize,
    /// Confidence in [0, 1].
    pub confidence: f64,
    /// Time the decision became available (end of its frame), s.
    pub t_stamp: f64,
    /// Length of audio the decision analysed (its frame), s: the decision
    /// describes the road heard over `[t_stamp − frame_s, t_stamp]`.
    pub frame_s: f64,
}

/// A road-estimate source, called by the simulator once per controller cycle.
///
/// Implementations must allocate nothing in `update` (the simulator's cycle
/// is allocation-free) and be deterministic given the seed of `reset`.
pub trait RoadEstimator {
    /// Start a new run at t = 0 with random seed `seed`.
    fn reset(&mut self, seed: u64);
    /// The cycle `[t, t + dt)` has passed on road `true_road_index` (catalogue
    /// index) at vehicle speed `speed_mps`. Returns a new decision when one
    /// completed during this cycle (its `t_stamp` <= t + dt), else `None`.
    fn update(
        &mut self,
        t: f64,
        dt: f64,
        true_road_index: usize,
        speed_mps: f64,
    ) -> Option<Estimate>;
    /// Short name for reports (`confusion`, `acoustic`, ...).
    fn name(&self) -> &str;
    /// What the estimator recorded about the run since the last reset, if
    /// it records anything ([`crate::InLoopProbe`] does); taken once, at the
    /// end of every ARTE run, into [`crate::RunResult::inloop`].
    fn take_stats(&mut self) -> Option<crate::InLoopStats> {
        None
    }
}

/// `config/sim-confusion.toml`: the confusion-matrix source of `grip sim` (the
/// road-knowledge rule is `grip_tcs::knowledge`, configured in the arte
/// service's `[knowledge]`, so that a drive and a simulation share it).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArteConfig {
    /// `[confusion]`: the confusion-matrix estimator.
    pub confusion: ConfusionConfig,
}

impl ArteConfig {
    /// The paper's Table II with the documented defaults (the content of
    /// `config/sim-confusion.toml` as shipped).
    pub fn paper() -> Self {
        Self {
            confusion: ConfusionConfig::paper_table_ii(),
        }
    }

    /// Check against the catalogue the names refer to.
    pub fn validate(&self, roads: &RoadCatalogue) -> Result<(), SimError> {
        self.confusion.validate(roads)
    }
}

/// `[confusion]`: a confusion matrix with class names.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfusionConfig {
    /// Frame length, s: one decision per frame (> 0).
    pub frame_s: f64,
    /// Class names (road names from the catalogue), in matrix order.
    pub classes: Vec<String>,
    /// Counts (or probabilities), rows predicted, columns actual; square,
    /// finite, >= 0, every column sum > 0.
    pub counts: Vec<Vec<f64>>,
    /// Confidence reported for a road outside the classes that passes
    /// through as itself; default: the matrix's balanced accuracy.
    #[serde(default)]
    pub outside_confidence: Option<f64>,
    /// Roads outside the classes that the classifier hears as a class:
    /// road name -> class name.
    #[serde(default)]
    pub map: BTreeMap<String, String>,
}

impl ConfusionConfig {
    /// The paper's Table II (ANN), frames of 0.1 s, no mapping.
    pub fn paper_table_ii() -> Self {
        Self {
            frame_s: 0.1,
            classes: ["asphalt", "snow", "stone", "gravel"]
                .map(str::to_owned)
                .to_vec(),
            counts: vec![
                vec![28.0, 0.0, 1.0, 1.0],
                vec![0.0, 26.0, 3.0, 4.0],
                vec![1.0, 3.0, 26.0, 2.0],
                vec![1.0, 1.0, 0.0, 23.0],
            ],
            outside_confidence: None,
            map: BTreeMap::new(),
        }
    }

    /// Check shapes, values and names against `roads`.
    pub fn validate(&self, roads: &RoadCatalogue) -> Result<(), SimError> {
        if !(self.frame_s.is_finite() && self.frame_s > 0.0) {
            return Err(SimError::invalid(
                "confusion.frame_s",
                format!("must be a finite number > 0 s (got {})", self.frame_s),
            ));
        }
        let n = self.classes.len();
        if n == 0 {
            return Err(SimError::invalid(
                "confusion.classes",
                "must name at least one class",
            ));
        }
        for (i, c) in self.classes.iter().enumerate() {
            if roads.index_of(c).is_none() {
                return Err(SimError::invalid(
                    format!("confusion.classes[{i}]"),
                    format!("unknown road `{c}` (known: {})", roads.names()),
                ));
            }
            if self.classes[..i].contains(c) {
                return Err(SimError::invalid(
                    format!("confusion.classes[{i}]"),
                    format!("duplicate class `{c}`"),
                ));
            }
        }
        if self.counts.len() != n {
            return Err(SimError::invalid(
                "confusion.counts",
                format!(
                    "needs {n} rows (one per class, predicted), got {}",
                    self.counts.len()
                ),
            ));
        }
        for (i, row) in self.counts.iter().enumerate() {
            if row.len() != n {
                return Err(SimError::invalid(
                    format!("confusion.counts[{i}]"),
                    format!(
                        "needs {n} columns (one per class, actual), got {}",
                        row.len()
                    ),
                ));
            }
            for (j, &x) in row.iter().enumerate() {
                if !(x.is_finite() && x >= 0.0) {
                    return Err(SimError::invalid(
                        format!("confusion.counts[{i}][{j}]"),
                        format!("must be a finite number >= 0 (got {x})"),
                    ));
                }
            }
        }
        for j in 0..n {
            let s: f64 = self.counts.iter().map(|r| r[j]).sum();
            if s.is_nan() || s <= 0.0 {
                return Err(SimError::invalid(
                    "confusion.counts",
                    format!(
                        "column {j} (actual `{}`) sums to 0: no sample of that class",
                        self.classes[j]
                    ),
                ));
            }
        }
        if let Some(c) = self.outside_confidence
            && !(c.is_finite() && (0.0..=1.0).contains(&c))
        {
            return Err(SimError::invalid(
                "confusion.outside_confidence",
                format!("must be in [0, 1] (got {c})"),
            ));
        }
        for (road, class) in &self.map {
            let field = format!("confusion.map.{road}");
            if roads.index_of(road).is_none() {
                return Err(SimError::invalid(
                    field,
                    format!("unknown road `{road}` (known: {})", roads.names()),
                ));
            }
            if self.classes.contains(road) {
                return Err(SimError::invalid(
                    field,
                    format!("`{road}` is a class of the matrix already"),
                ));
            }
            if !self.classes.contains(class) {
                return Err(SimError::invalid(
                    field,
                    format!(
                        "`{class}` is not a class of the matrix (classes: {})",
                        self.classes.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }

    /// P(predicted = i | actual = j), column-normalised (rows predicted).
    pub fn likelihoods(&self) -> Vec<Vec<f64>> {
        let n = self.classes.len();
        let col: Vec<f64> = (0..n)
            .map(|j| self.counts.iter().map(|r| r[j]).sum())
            .collect();
        self.counts
            .iter()
            .map(|r| (0..n).map(|j| r[j] / col[j]).collect())
            .collect()
    }

    /// Precision of each predicted class under equal class priors:
    /// P(i | i) / Σ_j P(i | j). A class that is never predicted gets 0.
    pub fn precisions(&self) -> Vec<f64> {
        self.likelihoods()
            .iter()
            .enumerate()
            .map(|(i, row)| {
                let s: f64 = row.iter().sum();
                if s > 0.0 { row[i] / s } else { 0.0 }
            })
            .collect()
    }

    /// Recall of each actual class, P(j | j).
    pub fn recalls(&self) -> Vec<f64> {
        let p = self.likelihoods();
        (0..self.classes.len()).map(|j| p[j][j]).collect()
    }

    /// Balanced accuracy: the mean recall.
    pub fn balanced_accuracy(&self) -> f64 {
        let r = self.recalls();
        r.iter().sum::<f64>() / r.len() as f64
    }
}

/// How a catalogue road goes through the matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Route {
    /// As matrix class (column) `j`.
    Class(usize),
    /// Outside the matrix: estimated as itself.
    PassThrough,
}

/// The confusion-matrix road estimator (see the module docs).
#[derive(Debug, Clone)]
pub struct ConfusionArte {
    frame_s: f64,
    /// Per catalogue road.
    route: Vec<Route>,
    /// Catalogue index of each class.
    class_road: Vec<usize>,
    /// Per actual class j: cumulative P(predicted <= i | j), i in class order.
    cum: Vec<Vec<f64>>,
    precision: Vec<f64>,
    outside_confidence: f64,
    /// Time on each catalogue road in the current frame, s.
    share: Vec<f64>,
    frames_done: u64,
    rng: ChaCha8Rng,
}

impl ConfusionArte {
    /// Build from a validated configuration against the catalogue `roads`.
    pub fn new(config: &ConfusionConfig, roads: &RoadCatalogue) -> Result<Self, SimError> {
        config.validate(roads)?;
        let class_road: Vec<usize> = config
            .classes
            .iter()
            .map(|c| roads.index_of(c).unwrap_or(0))
            .collect();
        let route = roads
            .iter()
            .map(|r| {
                let name = r.name();
                if let Some(j) = config.classes.iter().position(|c| c == name) {
                    Route::Class(j)
                } else if let Some(class) = config.map.get(name) {
                    Route::Class(config.classes.iter().position(|c| c == class).unwrap_or(0))
                } else {
                    Route::PassThrough
                }
            })
            .collect();
        let lik = config.likelihoods();
        let n = config.classes.len();
        let cum = (0..n)
            .map(|j| {
                let mut acc = 0.0;
                (0..n)
                    .map(|i| {
                        acc += lik[i][j];
                        acc
                    })
                    .collect()
            })
            .collect();
        Ok(Self {
            frame_s: config.frame_s,
            route,
            class_road,
            cum,
            precision: config.precisions(),
            outside_confidence: config
                .outside_confidence
                .unwrap_or_else(|| config.balanced_accuracy()),
            share: vec![0.0; roads.len()],
            frames_done: 0,
            rng: ChaCha8Rng::seed_from_u64(0),
        })
    }

    /// Frame length, s.
    pub fn frame_s(&self) -> f64 {
        self.frame_s
    }

    /// The catalogue roads (indices) outside the matrix's classes and not
    /// mapped onto one: estimated as themselves, always right, with
    /// [`ConfusionArte::outside_confidence`].
    pub fn pass_through(&self) -> Vec<usize> {
        self.route
            .iter()
            .enumerate()
            .filter(|(_, r)| **r == Route::PassThrough)
            .map(|(i, _)| i)
            .collect()
    }

    /// The confidence given with a road that passes through.
    pub fn outside_confidence(&self) -> f64 {
        self.outside_confidence
    }

    /// Classify one frame whose actual road is catalogue index `actual`.
    fn classify(&mut self, actual: usize) -> (usize, f64) {
        match self
            .route
            .get(actual)
            .copied()
            .unwrap_or(Route::PassThrough)
        {
            Route::PassThrough => (actual, self.outside_confidence),
            Route::Class(j) => {
                let u: f64 = self.rng.random();
                let cum = &self.cum[j];
                let total = cum[cum.len() - 1];
                let i = cum
                    .iter()
                    .position(|&c| u * total < c)
                    .unwrap_or(cum.len() - 1);
                (self.class_road[i], self.precision[i])
            }
        }
    }
}

impl RoadEstimator for ConfusionArte {
    fn reset(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
        self.share.iter_mut().for_each(|s| *s = 0.0);
        self.frames_done = 0;
    }

    fn update(
        &mut self,
        t: f64,
        dt: f64,
        true_road_index: usize,
        _speed_mps: f64,
    ) -> Option<Estimate> {
        if !(dt.is_finite() && dt > 0.0 && t.is_finite()) {
            return None;
        }
        if let Some(s) = self.share.get_mut(true_road_index) {
            *s += dt;
        }
        let t_end = t + dt;
        let boundary = (self.frames_done + 1) as f64 * self.frame_s;
        if t_end < boundary - 0.5 * dt {
            return None;
        }
        // Frame complete: its actual road is the one with the largest share
        // (a tie goes to the road of this cycle, the later one).
        let mut actual = true_road_index;
        let mut best = self.share.get(true_road_index).copied().unwrap_or(0.0);
        for (i, &s) in self.share.iter().enumerate() {
            if s > best {
                best = s;
                actual = i;
            }
        }
        self.share.iter_mut().for_each(|s| *s = 0.0);
        // Skip frames that ended within this cycle (frame shorter than dt).
        while (self.frames_done + 1) as f64 * self.frame_s <= t_end + 0.5 * dt {
            self.frames_done += 1;
        }
        let (road_index, confidence) = self.classify(actual);
        Some(Estimate {
            road_index,
            confidence,
            t_stamp: t_end,
            frame_s: self.frame_s,
        })
    }

    fn name(&self) -> &str {
        "confusion"
    }
}

/// A perfect estimator (the true road, confidence 1, frames of `frame_s`):
/// the upper bound of what ARTE can give the controllers; for tests and
/// `grip sim --arte perfect`.
#[derive(Debug, Clone)]
pub struct PerfectArte {
    frame_s: f64,
    frames_done: u64,
    name: &'static str,
}

impl PerfectArte {
    /// Decisions every `frame_s` seconds (> 0; non-finite or <= 0 gives 0.1 s).
    pub fn new(frame_s: f64) -> Self {
        Self {
            frame_s: if frame_s.is_finite() && frame_s > 0.0 {
                frame_s
            } else {
                0.1
            },
            frames_done: 0,
            name: "perfect",
        }
    }

    /// The oracle: the true road at every control cycle of `dt` seconds (a
    /// perfect and instant estimate; `grip sim --arte oracle`). Named
    /// `oracle` in reports.
    pub fn oracle(dt: f64) -> Self {
        Self {
            name: "oracle",
            ..Self::new(dt)
        }
    }
}

impl RoadEstimator for PerfectArte {
    fn reset(&mut self, _seed: u64) {
        self.frames_done = 0;
    }

    fn update(
        &mut self,
        t: f64,
        dt: f64,
        true_road_index: usize,
        _speed_mps: f64,
    ) -> Option<Estimate> {
        let t_end = t + dt;
        if t_end < (self.frames_done + 1) as f64 * self.frame_s - 0.5 * dt {
            return None;
        }
        while (self.frames_done + 1) as f64 * self.frame_s <= t_end + 0.5 * dt {
            self.frames_done += 1;
        }
        Some(Estimate {
            road_index: true_road_index,
            confidence: 1.0,
            t_stamp: t_end,
            frame_s: self.frame_s,
        })
    }

    fn name(&self) -> &str {
        self.name
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_physics::Road;

    fn roads() -> RoadCatalogue {
        RoadCatalogue::new(vec![
            Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap(),
            Road::burckhardt("gravel", 0.6212, 20.80, 0.0712).unwrap(),
            Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap(),
            Road::burckhardt("stone", 1.3713, 6.4565, 0.6691).unwrap(),
            Road::burckhardt("ice", 0.05, 306.39, 0.0).unwrap(),
            Road::burckhardt("wet_asphalt", 0.857, 33.822, 0.347).unwrap(),
        ])
        .unwrap()
    }

    #[test]
    fn table_ii_precisions_and_accuracy() {
        let c = ConfusionConfig::paper_table_ii();
        let p = c.precisions();
        let expect = [28.0 / 30.0, 26.0 / 33.0, 26.0 / 32.0, 23.0 / 25.0];
        for (a, b) in p.iter().zip(expect) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        assert!((c.balanced_accuracy() - 103.0 / 120.0).abs() < 1e-12);
    }

    /// Over many frames the empirical P(predicted | actual) matches the matrix.
    #[test]
    fn sampling_follows_the_matrix() {
        let roads = roads();
        let c = ConfusionConfig::paper_table_ii();
        let mut e = ConfusionArte::new(&c, &roads).unwrap();
        e.reset(42);
        let stone = roads.index_of("stone").unwrap();
        let n = 60_000;
        let mut counts = vec![0usize; roads.len()];
        let dt = 1e-3;
        let mut frames = 0;
        let mut k = 0u64;
        while frames < n {
            let t = k as f64 * dt;
            if let Some(est) = e.update(t, dt, stone, 5.0) {
                counts[est.road_index] += 1;
                frames += 1;
                // Confidence is the predicted class's precision.
                let class = c
                    .classes
                    .iter()
                    .position(|x| x == roads[est.road_index].name())
                    .unwrap();
                assert_eq!(est.confidence, c.precisions()[class]);
            }
            k += 1;
        }
        // Stone column: asphalt 1, snow 3, stone 26, gravel 0 (of 30).
        let frac = |name: &str| counts[roads.index_of(name).unwrap()] as f64 / n as f64;
        assert!((frac("stone") - 26.0 / 30.0).abs() < 0.01);
        assert!((frac("snow") - 3.0 / 30.0).abs() < 0.01);
        assert!((frac("asphalt") - 1.0 / 30.0).abs() < 0.005);
        assert_eq!(frac("gravel"), 0.0);
        // Frames of 0.1 s at 1 kHz: 100 cycles each.
        assert_eq!(k, n as u64 * 100);
    }

    #[test]
    fn frame_majority_and_timing() {
        let roads = roads();
        let mut c = ConfusionConfig::paper_table_ii();
        // Identity matrix: the estimate is the frame's actual road.
        c.counts = (0..4)
            .map(|i| (0..4).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
            .collect();
        let mut e = ConfusionArte::new(&c, &roads).unwrap();
        e.reset(1);
        let (asphalt, snow) = (
            roads.index_of("asphalt").unwrap(),
            roads.index_of("snow").unwrap(),
        );
        let dt = 1e-3;
        let mut out = Vec::new();
        for k in 0..300u64 {
            let t = k as f64 * dt;
            // Snow from t = 0.13 s: frame 2 ([0.1, 0.2)) is 70 % snow.
            let road = if t < 0.13 { asphalt } else { snow };
            if let Some(est) = e.update(t, dt, road, 3.0) {
                out.push(est);
            }
        }
        assert_eq!(out.len(), 3);
        assert_eq!(out[0].road_index, asphalt);
        assert_eq!(out[1].road_index, snow);
        assert_eq!(out[2].road_index, snow);
        assert!((out[0].t_stamp - 0.1).abs() < 1e-9);
        assert!((out[2].t_stamp - 0.3).abs() < 1e-9);
    }

    #[test]
    fn outside_roads_pass_through_or_map() {
        let roads = roads();
        let mut c = ConfusionConfig::paper_table_ii();
        let ice = roads.index_of("ice").unwrap();
        let wet = roads.index_of("wet_asphalt").unwrap();
        c.map.insert("wet_asphalt".into(), "asphalt".into());
        let mut e = ConfusionArte::new(&c, &roads).unwrap();
        e.reset(3);
        let dt = 1e-3;
        let mut seen_wet_as = vec![0usize; roads.len()];
        for k in 0..100_000u64 {
            let t = k as f64 * dt;
            let road = if k < 50_000 { ice } else { wet };
            if let Some(est) = e.update(t, dt, road, 3.0) {
                if road == ice {
                    assert_eq!(est.road_index, ice);
                    assert!((est.confidence - 103.0 / 120.0).abs() < 1e-12);
                } else {
                    seen_wet_as[est.road_index] += 1;
                }
            }
        }
        assert_eq!(
            seen_wet_as[wet], 0,
            "mapped road is never estimated as itself"
        );
        assert!(seen_wet_as[roads.index_of("asphalt").unwrap()] > 400);
    }

    #[test]
    fn reset_reproduces() {
        let roads = roads();
        let mut e = ConfusionArte::new(&ConfusionConfig::paper_table_ii(), &roads).unwrap();
        let run = |e: &mut ConfusionArte, seed| {
            e.reset(seed);
            (0..20_000u64)
                .filter_map(|k| e.update(k as f64 * 1e-3, 1e-3, 2, 3.0))
                .map(|x| x.road_index)
                .collect::<Vec<_>>()
        };
        let a = run(&mut e, 5);
        let b = run(&mut e, 5);
        let c = run(&mut e, 6);
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn validation_names_the_field() {
        let roads = roads();
        let mut c = ConfusionConfig::paper_table_ii();
        c.classes[1] = "mud".into();
        assert_eq!(
            c.validate(&roads).unwrap_err().field(),
            "confusion.classes[1]"
        );
        let mut c = ConfusionConfig::paper_table_ii();
        c.counts[2].pop();
        assert_eq!(
            c.validate(&roads).unwrap_err().field(),
            "confusion.counts[2]"
        );
        let mut c = ConfusionConfig::paper_table_ii();
        c.counts[0][0] = f64::NAN;
        assert_eq!(
            c.validate(&roads).unwrap_err().field(),
            "confusion.counts[0][0]"
        );
        let mut c = ConfusionConfig::paper_table_ii();
        for r in &mut c.counts {
            r[3] = 0.0;
        }
        assert_eq!(c.validate(&roads).unwrap_err().field(), "confusion.counts");
        let mut c = ConfusionConfig::paper_table_ii();
        c.frame_s = 0.0;
        assert_eq!(c.validate(&roads).unwrap_err().field(), "confusion.frame_s");
        let mut c = ConfusionConfig::paper_table_ii();
        c.map.insert("ice".into(), "tarmac".into());
        assert_eq!(c.validate(&roads).unwrap_err().field(), "confusion.map.ice");
    }
}
