//! Random road sequences (`grip sim --scenario random`): one scenario per
//! run seed, so that results can be checked on roads nobody tuned to.
//!
//! The recipe ([`RandomSpec::default`], documented in this crate's README):
//!
//! - roads: the catalogue's roads that have a sound, i.e. that
//!   [`grip_arte::synth::road_index`] knows (asphalt, gravel, snow, stone,
//!   wet_asphalt, wet_stone), in catalogue order; the first segment's road
//!   is drawn uniformly among them, each next one uniformly among the
//!   *others* (every segment boundary is a road change);
//! - lengths: uniform in [`RandomSpec::min_len_m`, `RandomSpec::max_len_m`]
//!   (1-4 m: 0.36-1.4 s at 10 km/h, 0.12-0.5 s at 30 km/h), drawn until the
//!   segments cover [`RandomSpec::cover_m`] (24 m, more than any variant
//!   travels in 2.4 s from 10 km/h at 300 N m), raised by
//!   [`RandomSpec::sized_for`] to the most distance the car can cover
//!   ([`RandomSpec::reach_m`]) unless `cover_m` was given;
//! - distance segments (`segments_by = "distance"`, so a microphone ahead
//!   of the driven wheel hears each road first), level, constant 300 N m
//!   demand, v0 10 km/h, 2.4 s: the reference scenario's drive.
//!
//! The draws come from a ChaCha8 generator seeded with
//! `sub_seed(seed, SCENARIO_STREAM)` ([`crate::sub_seed`], stream 3; the
//! sensor noise is stream 1, the road estimator stream 2), so seed `s`
//! always gives the same road sequence, identical for every variant of `s`,
//! and independent of the sensor noise and ARTE draws of that seed.

use grip_physics::{Demand, RoadCatalogue, Scenario, Segment, SegmentMode, VehicleParams};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::{SimError, sub_seed};

/// Sub-seed stream of the random scenario (see [`crate::sub_seed`]).
pub const SCENARIO_STREAM: u64 = 3;

/// What a random scenario is drawn from.
#[derive(Debug, Clone, PartialEq)]
pub struct RandomSpec {
    /// Shortest segment, m (> 0).
    pub min_len_m: f64,
    /// Longest segment, m (>= `min_len_m`).
    pub max_len_m: f64,
    /// Segments are drawn until they cover this distance, m.
    pub cover_m: f64,
    /// Whether [`RandomSpec::sized_for`] may raise `cover_m` to the most
    /// distance the car can cover (true unless `cover_m` was given).
    pub cover_to_reach: bool,
    /// Initial speed, km/h.
    pub v0_kmh: f64,
    /// Constant driver demand, N m.
    pub torque: f64,
    /// Run duration, s.
    pub duration: f64,
}

impl Default for RandomSpec {
    fn default() -> Self {
        Self {
            min_len_m: 1.0,
            max_len_m: 4.0,
            cover_m: 24.0,
            cover_to_reach: true,
            v0_kmh: 10.0,
            torque: 300.0,
            duration: 2.4,
        }
    }
}

/// Indices (catalogue order) of the roads of `roads` that have a sound
/// (that the tyre-road synthesiser knows).
pub fn sounding_roads(roads: &RoadCatalogue) -> Vec<usize> {
    roads
        .iter()
        .enumerate()
        .filter(|(_, r)| grip_arte::synth::road_index(r.name()).is_some())
        .map(|(i, _)| i)
        .collect()
}

/// The largest constant driver demand a random scenario takes, N m (the
/// demand on one driven wheel; far above any car's, whose `torque_max`
/// limits it further). `grip generate --torque` has the same bound.
pub const TORQUE_MAX_NM: f64 = 10_000.0;

/// One field `RandomSpec::parse` sets: its name, the range it accepts, and
/// the field.
type SpecField = (&'static str, f64, f64, fn(&mut RandomSpec) -> &mut f64);

impl RandomSpec {
    /// The fields [`RandomSpec::parse`] sets: name as in the struct, the
    /// range it accepts, and the field itself.
    const FIELDS: [SpecField; 6] = [
        ("v0_kmh", 0.0, grip_physics::scenario::V0_MAX_KMH, |s| {
            &mut s.v0_kmh
        }),
        ("torque", 0.0, TORQUE_MAX_NM, |s| &mut s.torque),
        ("min_len_m", 0.01, 10_000.0, |s| &mut s.min_len_m),
        ("max_len_m", 0.01, 10_000.0, |s| &mut s.max_len_m),
        ("cover_m", 0.01, 10_000.0, |s| &mut s.cover_m),
        ("duration", 0.01, 600.0, |s| &mut s.duration),
    ];

    /// The keys [`RandomSpec::parse`] takes, as in the struct.
    pub fn keys() -> String {
        Self::FIELDS.map(|f| f.0).join(", ")
    }

    /// `KEY=VALUE[,KEY=VALUE...]` (`grip sim --random`) on top of the
    /// default recipe, e.g. `v0_kmh=30,min_len_m=3,max_len_m=12`. Each key is
    /// a field of this struct ([`RandomSpec::keys`]) and may appear once.
    /// When `v0_kmh` or `duration` is set and `cover_m` is not, the segments
    /// cover at least 1.5 times the distance the run's initial speed alone
    /// would travel plus 12 m (the default's 24 m at least); that alone
    /// ignores the car speeding up, so [`RandomSpec::sized_for`] raises it
    /// further to what the car can reach. A given `cover_m` is kept as
    /// given. With nothing set the result is the default, so seeds keep
    /// their roads.
    pub fn parse(text: &str) -> Result<RandomSpec, SimError> {
        let mut spec = RandomSpec::default();
        let mut seen: Vec<&str> = Vec::new();
        for item in text.split(',').map(str::trim).filter(|i| !i.is_empty()) {
            let Some((key, value)) = item.split_once('=') else {
                return Err(SimError::invalid(
                    "random",
                    format!("`{item}` is not KEY=VALUE (keys: {})", Self::keys()),
                ));
            };
            let key = key.trim();
            let field = format!("random.{key}");
            let Some(&(name, lo, hi, slot)) = Self::FIELDS.iter().find(|f| f.0 == key) else {
                return Err(SimError::invalid(
                    field,
                    format!("unknown key (keys: {})", Self::keys()),
                ));
            };
            if seen.contains(&name) {
                return Err(SimError::invalid(field, "given twice"));
            }
            seen.push(name);
            let v: f64 = value.trim().parse().map_err(|_| {
                SimError::invalid(&field, format!("`{}` is not a number", value.trim()))
            })?;
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                return Err(SimError::invalid(
                    field,
                    format!("must be in {lo}..={hi} (got {v})"),
                ));
            }
            *slot(&mut spec) = v;
        }
        if seen.contains(&"cover_m") {
            spec.cover_to_reach = false;
        }
        if !seen.contains(&"cover_m") && (seen.contains(&"v0_kmh") || seen.contains(&"duration")) {
            spec = spec.covering_travel();
        }
        if spec.max_len_m < spec.min_len_m {
            return Err(SimError::invalid(
                "random.max_len_m",
                format!(
                    "must be at least min_len_m ({} < {})",
                    spec.max_len_m, spec.min_len_m
                ),
            ));
        }
        Ok(spec)
    }

    /// This recipe with `cover_m` raised to at least 1.5 times the distance
    /// the initial speed alone travels in `duration`, plus 12 m (never
    /// lowered: the default's 24 m stays), so a faster or longer run still
    /// meets road changes to its end.
    pub fn covering_travel(self) -> RandomSpec {
        let travel = self.v0_kmh / 3.6 * self.duration;
        RandomSpec {
            cover_m: self.cover_m.max((1.5 * travel + 12.0).ceil()),
            ..self
        }
    }

    /// The most distance (m) a run of this recipe can cover on `vehicle`,
    /// plus the microphone's lead (the road it hears ahead of the wheel):
    /// an upper bound, for sizing the road list. The driven wheel's share
    /// of the car, M/n, is pushed by at most the demand (clamped to
    /// `torque_max`) over the tyre radius and at most what the grippiest
    /// road the recipe draws from transmits (μ_peak N), less the drag
    /// (rolling resistance and grade left out); the wheel's own inertia
    /// may add its spin-down, J ω0 / (r M/n), to the start speed; 5 % and
    /// 1 m on top.
    pub fn reach_m(&self, vehicle: &VehicleParams, roads: &RoadCatalogue) -> f64 {
        let v = vehicle;
        let share = v.mass / v.n_driven;
        let normal = v.driven_load_share * v.mass * grip_physics::G / v.n_driven;
        let mu_best = sounding_roads(roads)
            .into_iter()
            .filter_map(|i| roads.by_index(i).map(|r| r.mu_peak()))
            .fold(0.0, f64::max);
        let force = (self.torque.min(v.torque_max) / v.r).min(mu_best * normal);
        let a_push = force / share;
        let k_drag = 0.5 * v.rho * v.c_d_a / v.mass;
        let v0 = self.v0_kmh / 3.6;
        // Explicit Euler on dv/dt = a_push - k v², whose right-hand side
        // falls as v grows: each step's slope is the interval's largest, and
        // the distance takes each step's end speed, so both stay above the
        // exact solution.
        const STEPS: usize = 10_000;
        let h = self.duration / STEPS as f64;
        let mut speed = v0 + v.j_w * v0 / (v.r * v.r * share);
        let mut x = 0.0;
        for _ in 0..STEPS {
            speed += h * (a_push - k_drag * speed * speed).max(0.0);
            x += h * speed;
        }
        1.05 * x + 1.0 + v.mic_lead_m.max(0.0)
    }

    /// This recipe with `cover_m` raised to [`RandomSpec::reach_m`] on
    /// `vehicle` (rounded up to a metre), unless `cover_m` was given
    /// (`cover_to_reach` false); never lowered, so a recipe whose cover
    /// already reaches far enough (the default's 24 m on the shipped
    /// vehicles) draws the same roads. A longer cover only appends segments:
    /// the draws of the first ones are the same.
    pub fn sized_for(self, vehicle: &VehicleParams, roads: &RoadCatalogue) -> RandomSpec {
        if !self.cover_to_reach {
            return self;
        }
        let reach = self.reach_m(vehicle, roads).ceil();
        RandomSpec {
            cover_m: self.cover_m.max(reach),
            ..self
        }
    }

    /// One line: the recipe's values, as the report prints them.
    pub fn describe(&self) -> String {
        format!(
            "distance segments of {}-{} m from the roads with a sound (covering {} m), constant {} N m from {} km/h, {} s",
            self.min_len_m, self.max_len_m, self.cover_m, self.torque, self.v0_kmh, self.duration
        )
    }

    /// The scenario of run seed `seed`, resolved against `roads`. Fails when
    /// the catalogue has fewer than two roads with a sound or the spec is
    /// out of range.
    pub fn scenario(&self, seed: u64, roads: &RoadCatalogue) -> Result<Scenario, SimError> {
        if !(self.min_len_m > 0.0
            && self.max_len_m >= self.min_len_m
            && self.max_len_m.is_finite()
            && self.cover_m > 0.0
            && self.cover_m.is_finite())
        {
            return Err(SimError::invalid(
                "random",
                format!(
                    "segment lengths need 0 < min <= max and a finite cover > 0 (got {}..{} m, cover {} m)",
                    self.min_len_m, self.max_len_m, self.cover_m
                ),
            ));
        }
        let pool = sounding_roads(roads);
        if pool.len() < 2 {
            return Err(SimError::invalid(
                "random.roads",
                format!(
                    "need at least two catalogue roads with a sound ({}); the catalogue has {} ({})",
                    grip_arte::synth::ROADS.join(", "),
                    pool.len(),
                    roads.names()
                ),
            ));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(sub_seed(seed, SCENARIO_STREAM));
        let mut segments = Vec::new();
        let mut covered = 0.0;
        let mut prev: Option<usize> = None;
        while covered < self.cover_m {
            let road = match prev {
                None => pool[rng.random_range(0..pool.len())],
                Some(p) => {
                    // Uniform among the other roads: skip the previous one.
                    let k = rng.random_range(0..pool.len() - 1);
                    let pos = pool.iter().position(|&i| i == p).unwrap_or(pool.len());
                    pool[if k >= pos { k + 1 } else { k }]
                }
            };
            let span = if self.max_len_m > self.min_len_m {
                rng.random_range(self.min_len_m..=self.max_len_m)
            } else {
                self.min_len_m
            };
            // Centimetres, like the shipped scenarios.
            let span = ((span * 100.0).round() / 100.0).clamp(self.min_len_m, self.max_len_m);
            let name = roads.by_index(road).map_or("?", |r| r.name()).to_owned();
            segments.push(Segment {
                road_name: name,
                road,
                span,
                grade_pct: 0.0,
            });
            covered += span;
            prev = Some(road);
        }
        let description = format!(
            "Random roads of seed {seed} (sub-seed stream {SCENARIO_STREAM}): {}; constant {} N m from {} km/h",
            describe_segments(&segments),
            self.torque,
            self.v0_kmh
        );
        Scenario::new(
            "random",
            description,
            self.duration,
            self.v0_kmh / 3.6,
            SegmentMode::Distance,
            segments,
            Demand::Constant {
                torque: self.torque,
            },
            roads.len(),
        )
        .map_err(|e| SimError::from_field("random", e))
    }
}

/// `road length m, ...` of a segment list (one line).
pub fn describe_segments(segments: &[Segment]) -> String {
    segments
        .iter()
        .map(|s| format!("{} {:.2} m", s.road_name, s.span))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_sets_the_named_fields_and_nothing_else() {
        assert_eq!(RandomSpec::parse("").unwrap(), RandomSpec::default());
        let s = RandomSpec::parse("torque=250, min_len_m=2,max_len_m=8").unwrap();
        assert_eq!(s.torque, 250.0);
        assert_eq!((s.min_len_m, s.max_len_m), (2.0, 8.0));
        assert_eq!(s.cover_m, 24.0, "cover unchanged without speed or duration");
        assert_eq!((s.v0_kmh, s.duration), (10.0, 2.4));
    }

    #[test]
    fn a_faster_run_covers_more_road_unless_told() {
        let s = RandomSpec::parse("v0_kmh=30").unwrap();
        // 30 km/h for 2.4 s: 20 m; 1.5 x 20 + 12 = 42 m.
        assert_eq!(s.cover_m, 42.0);
        let s = RandomSpec::parse("v0_kmh=30,cover_m=30").unwrap();
        assert_eq!(s.cover_m, 30.0);
        // the default's speed and duration stay at the default's cover
        assert_eq!(RandomSpec::parse("v0_kmh=10").unwrap().cover_m, 24.0);
        assert_eq!(
            RandomSpec::default().covering_travel(),
            RandomSpec::default()
        );
    }

    #[test]
    fn bad_input_names_the_key_and_the_reason() {
        let field = |t: &str| RandomSpec::parse(t).unwrap_err().to_string();
        assert!(
            field("speed=3").contains("`random.speed`"),
            "{}",
            field("speed=3")
        );
        assert!(field("speed=3").contains("v0_kmh"));
        assert!(field("v0_kmh").contains("not KEY=VALUE"));
        assert!(field("v0_kmh=fast").contains("not a number"));
        assert!(field("v0_kmh=-1").contains("`random.v0_kmh`"));
        assert!(field("duration=0").contains("`random.duration`"));
        assert!(field("torque=NaN").contains("`random.torque`"));
        assert!(field("torque=1,torque=2").contains("given twice"));
        assert!(field("min_len_m=5,max_len_m=2").contains("`random.max_len_m`"));
    }

    /// The recipe's start speed has a scenario's limit (it had 200 km/h
    /// while a scenario file and `grip generate --v0-kmh` took 360): the
    /// fastest start draws a scenario that validates, one faster is
    /// refused with the limit.
    #[test]
    fn the_fastest_start_is_a_scenarios() {
        let roads = grip_physics::RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let s = RandomSpec::parse("v0_kmh=360").unwrap();
        assert_eq!(s.v0_kmh, 360.0);
        let sc = s.scenario(1, &roads).unwrap();
        assert_eq!(sc.v0, grip_physics::scenario::V0_MAX_MPS);
        let e = RandomSpec::parse("v0_kmh=360.5").unwrap_err().to_string();
        assert!(e.contains("0..=360"), "{e}");
    }
}
