//! What an ideal controller could reach on a scenario: the quasi-static
//! bound beside the simulated controllers (README.md, "How close to the
//! ideal").
//!
//! The ideal knows every road of the scenario exactly and at once (where
//! each begins, its whole μ-λ curve), holds each road at `share` of what it
//! transmits (`share · μ_peak · N`, the family of the ARTE variants'
//! `cap_share`), and has a tyre without transients: the slip of a force is
//! the least slip that carries it, on the curve's stable branch. What it
//! keeps of the real car is what no controller can wish away: the motor's
//! first-order lag `tau_m` (its command is anywhere in `[0, T_d]`, a TCS
//! never adds torque), the wheel's inertia (the torque that speeds the
//! wheel up with the car, `J_w a / r`), the motor's torque and power limits
//! and the driving resistance, grade included, all as the plant has them.
//! Before a road that carries less it drops in the least time the lag
//! allows: a zero command from the moment a zero command would only just
//! bring the torque to that road's cap at arrival, then the cap; on a road
//! that carries more it commands the demand on arrival and the lag does the
//! rest.
//!
//! Slip is only ever added by what the ideal leaves out (a tyre's
//! relaxation, a late or wrong estimate, noise, a controller's own
//! dynamics), and traction only lost by it, so a controller's
//! (slip, acceleration) point lies on the far side of the ideal's curve
//! swept over `share`: a target the ideal does not reach at any share is
//! out of reach of every controller that holds every road at one share,
//! with any estimator. That allocation across roads is the ARTE variants'
//! (`cap_share`), not a proven optimum over all allocations (README.md
//! gives what another one changed).
//!
//! Allocation: [`ideal_run`] allocates nothing per cycle.

use crate::SimSetup;
use crate::report::{VariantSummary, render};
use grip_physics::{Road, Scenario, SegmentMode, VehicleParams};
use grip_tcs::road_aware::slip_at_share;

/// One ideal run's figures, defined as `grip_tcs::metrics` defines them
/// for a simulated run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdealResult {
    /// (1/T) Σ |λ| dt over the cycles.
    pub slip_deviation: f64,
    /// (V of the last cycle − V of the first) / the time between them.
    pub mean_accel: f64,
    /// Distance travelled, m.
    pub distance: f64,
    /// The least total variation per second of a command that reaches each
    /// road's level (the demand, or the road's hold when that is lower) and
    /// moves only between them, monotonically: Σ |Δ level| / T, N m/s. Any
    /// controller that holds the roads so moves its command at least this
    /// much (the ideal's own least-time drops move it more).
    pub least_cmd_tv_per_s: f64,
}

/// The stable-branch slip that carries friction coefficient `mu` on `road`
/// (about 0 for `mu <= 0`; `road.lambda_opt()` at or above the peak):
/// [`grip_tcs::road_aware::slip_at_share`], the controllers' own inverse.
pub fn least_slip(road: &Road, mu: f64) -> f64 {
    if mu <= 0.0 {
        return 0.0;
    }
    slip_at_share(
        |l| road.mu(l),
        road.lambda_opt(),
        road.mu_peak(),
        mu / road.mu_peak(),
    )
}

/// Where the ideal holds each road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Hold {
    /// At this share (0, 1] of the road's peak force, `share · μ_peak · N`:
    /// the ARTE variants' `cap_share`.
    Share(f64),
    /// Where the road's curve has flattened to this slope dμ/dλ (> 0): the
    /// same extra slip for each extra newton on every road, the allocation
    /// that spends a given traction for the least slip when the time on
    /// each road is fixed (a Lagrange condition); a road whose curve starts
    /// flatter than that is not driven.
    Slope(f64),
}

impl Hold {
    /// The friction coefficient the ideal holds `road` at.
    pub fn mu_cap(&self, road: &Road) -> f64 {
        match *self {
            Hold::Share(share) => share * road.mu_peak(),
            Hold::Slope(k) => {
                let (mut lo, mut hi) = (0.0, road.lambda_opt());
                if road.dmu_dlambda(0.0) <= k {
                    return 0.0;
                }
                if road.dmu_dlambda(hi) >= k {
                    return road.mu_peak();
                }
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if road.dmu_dlambda(mid) >= k {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                road.mu(lo)
            }
        }
    }
}

impl std::fmt::Display for Hold {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Hold::Share(s) => write!(f, "share {s}"),
            Hold::Slope(k) => write!(f, "slope {k}"),
        }
    }
}

/// How far ahead the ideal looks for a road that carries less (segments).
const LOOK_AHEAD: usize = 4;

/// One ideal run of `scenario` for `vehicle` on the catalogue's `roads`
/// (indexed by the segments' `road`), `cycles` cycles of `dt` s, each road
/// held as `hold` says. The caller has
/// validated the three together (a [`crate::SimSetup`] has).
pub fn ideal_run(
    vehicle: &VehicleParams,
    roads: &[Road],
    scenario: &Scenario,
    dt: f64,
    cycles: usize,
    hold: Hold,
) -> IdealResult {
    let p = vehicle;
    let g = grip_physics::G;
    let ms = p.mass_share();
    let r = p.r;
    let k1 = p.j_w / (ms * r);
    let tau = p.tau_m;
    let (mut v, mut x, mut torque) = (scenario.v0, 0.0_f64, 0.0_f64);
    let (mut sum_lambda, mut v_first, mut v_last) = (0.0, scenario.v0, scenario.v0);
    let (mut level_tv, mut last_level) = (0.0, f64::NAN);
    for k in 0..cycles {
        let t = k as f64 * dt;
        if k == 0 {
            v_first = v;
        }
        v_last = v;
        let i = scenario.segment_at(t, x);
        let seg = &scenario.segments[i];
        let road = &roads[seg.road];
        let (sin_t, cos_t) = seg.grade_rad().sin_cos();
        let n_force = p.driven_load_share * p.mass * g * cos_t / p.n_driven;
        let f_res = (p.c_rr * p.mass * g * cos_t * v / v.abs().max(1e-2)
            + 0.5 * p.rho * p.c_d_a * v * v.abs()
            + p.mass * g * sin_t)
            / p.n_driven;
        // wheel torque that delivers tyre force f with the wheel speeding up
        // with the car: T = r f + J_w a / r, a = (f - f_res) / (M/n)
        let torque_for = |f: f64| f * (r + k1) - k1 * f_res;
        let cap_force = |rd: &Road| hold.mu_cap(rd) * n_force;
        let limit = p.torque_limit(v / r);
        let level = scenario
            .demand_at(t)
            .min(limit)
            .min(torque_for(cap_force(road)))
            .max(0.0);
        if last_level.is_finite() {
            level_tv += (level - last_level).abs();
        }
        last_level = level;
        let mut cmd = level;
        for j in i + 1..(i + 1 + LOOK_AHEAD).min(scenario.segments.len()) {
            let ahead = &roads[scenario.segments[j].road];
            let target = torque_for(cap_force(ahead));
            if target >= torque {
                continue;
            }
            let to_go = match scenario.segments_by {
                SegmentMode::Distance => (scenario.segment_start(j) - x) / v.max(0.1),
                SegmentMode::Time => scenario.segment_start(j) - t,
            };
            let at_arrival = if tau > 0.0 {
                torque * (-to_go.max(0.0) / tau).exp()
            } else {
                0.0
            };
            if at_arrival >= target {
                cmd = cmd.min(if at_arrival > target + 0.5 {
                    0.0
                } else {
                    target
                });
            }
        }
        torque = if tau > 0.0 {
            cmd + (torque - cmd) * (-dt / tau).exp()
        } else {
            cmd
        };
        let force = ((torque + k1 * f_res) / (r + k1)).min(cap_force(road));
        sum_lambda += least_slip(road, force / n_force).abs() * dt;
        let a = (force - f_res) / ms;
        let v_new = v + a * dt;
        x += 0.5 * (v + v_new) * dt;
        v = v_new;
    }
    let span = (cycles.saturating_sub(1)) as f64 * dt;
    IdealResult {
        slip_deviation: sum_lambda / (cycles as f64 * dt),
        mean_accel: if span > 0.0 {
            (v_last - v_first) / span
        } else {
            f64::NAN
        },
        distance: x,
        least_cmd_tv_per_s: level_tv / (cycles as f64 * dt),
    }
}

/// One share's ideal runs over the seeds: the mean slip deviation and mean
/// acceleration, and each seed's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct IdealPoint {
    /// Where the ideal holds each road.
    pub hold: Hold,
    /// Mean over the seeds of the slip deviation.
    pub slip_deviation: f64,
    /// Mean over the seeds of the mean acceleration.
    pub mean_accel: f64,
    /// Mean over the seeds of [`IdealResult::least_cmd_tv_per_s`].
    pub least_cmd_tv_per_s: f64,
    /// (seed, figures) per seed, in the order given.
    pub per_seed: Vec<(u64, IdealResult)>,
}

/// The ideal at each of `holds` on each seed's setup (`setup_of(seed)`:
/// the vehicle, roads and scenario the simulated runs of that seed had).
pub fn ideal_points<'a>(
    holds: &[Hold],
    seeds: &[u64],
    setup_of: impl Fn(u64) -> &'a SimSetup,
) -> Vec<IdealPoint> {
    holds
        .iter()
        .map(|&hold| {
            let per_seed: Vec<(u64, IdealResult)> = seeds
                .iter()
                .map(|&seed| {
                    let s = setup_of(seed);
                    let r = ideal_run(
                        s.vehicle(),
                        s.roads().roads(),
                        s.scenario(),
                        s.dt(),
                        s.cycles(),
                        hold,
                    );
                    (seed, r)
                })
                .collect();
            let n = per_seed.len().max(1) as f64;
            IdealPoint {
                hold,
                slip_deviation: per_seed.iter().map(|(_, r)| r.slip_deviation).sum::<f64>() / n,
                mean_accel: per_seed.iter().map(|(_, r)| r.mean_accel).sum::<f64>() / n,
                least_cmd_tv_per_s: per_seed
                    .iter()
                    .map(|(_, r)| r.least_cmd_tv_per_s)
                    .sum::<f64>()
                    / n,
                per_seed,
            }
        })
        .collect()
}

/// The report's section: each share's ideal means and their ratios to every
/// baseline variant in `summaries`, then each simulated ARTE variant's
/// ratios to its own baseline (the same ratios as the sweep's), so a
/// controller can be read against the ideal's curve.
pub fn format_ideal(points: &[IdealPoint], summaries: &[VariantSummary]) -> String {
    let mean = |s: &VariantSummary, key: &str| s.stat(key).map_or(f64::NAN, |st| st.mean);
    let bases: Vec<&VariantSummary> = summaries.iter().filter(|s| !s.variant.arte).collect();
    let mut heads: Vec<String> = vec![
        "".into(),
        "slip dev.".into(),
        "mean accel".into(),
        "cmd TV".into(),
    ];
    heads.extend(
        bases
            .iter()
            .map(|b| format!("slip / accel / cmd TV vs {}", b.variant.label())),
    );
    let ratio = |a: f64, b: f64| {
        let r = a / b;
        if r.is_finite() {
            format!("{r:.3}x")
        } else {
            "-".into()
        }
    };
    let mut rows: Vec<Vec<String>> = Vec::new();
    for p in points {
        let mut row = vec![
            format!("ideal, {}", p.hold),
            format!("{:.4}", p.slip_deviation),
            format!("{:.4}", p.mean_accel),
            format!("{:.0}", p.least_cmd_tv_per_s),
        ];
        for b in &bases {
            row.push(format!(
                "{} / {} / {}",
                ratio(p.slip_deviation, mean(b, "slip_deviation")),
                ratio(p.mean_accel, mean(b, "mean_accel")),
                ratio(p.least_cmd_tv_per_s, mean(b, "cmd_tv_per_s"))
            ));
        }
        rows.push(row);
    }
    for s in summaries.iter().filter(|s| s.variant.arte) {
        let mut row = vec![
            format!("{} (simulated)", s.variant.label()),
            format!("{:.4}", mean(s, "slip_deviation")),
            format!("{:.4}", mean(s, "mean_accel")),
            format!("{:.0}", mean(s, "cmd_tv_per_s")),
        ];
        for b in &bases {
            row.push(if b.variant == s.variant.baseline() {
                format!(
                    "{} / {} / {}",
                    ratio(mean(s, "slip_deviation"), mean(b, "slip_deviation")),
                    ratio(mean(s, "mean_accel"), mean(b, "mean_accel")),
                    ratio(mean(s, "cmd_tv_per_s"), mean(b, "cmd_tv_per_s"))
                )
            } else {
                String::new()
            });
        }
        rows.push(row);
    }
    format!(
        "\nThe ideal controller beside them (grip_sim::ideal; crates/sim/README.md, \"How close to the ideal\"): every\n\
         road known exactly and at once and held at a share of its peak force, the least slip that carries each force\n\
         (no tyre transients), drops to a road that carries less timed through the motor's lag; the lag, the wheel's\n\
         inertia, the torque and power limits and the driving resistance as the plant has them. Means over the same\n\
         seeds' scenarios. What it leaves out only adds slip and costs traction: a controller that holds every road at\n\
         one share, with any road estimate, lies on the far side of its curve (more slip at the same acceleration).\n\
         Its cmd TV (N m/s) is the least a command needs that reaches each road's level and moves only between them:\n{}",
        render(&heads, &rows)
    )
}

/// `ideal.csv`: `hold,value,seed,slip_deviation,mean_accel,distance,least_cmd_tv_per_s`
/// (`hold` is `share` or `slope`).
pub fn ideal_csv(points: &[IdealPoint]) -> String {
    let mut out =
        String::from("hold,value,seed,slip_deviation,mean_accel,distance,least_cmd_tv_per_s\n");
    for p in points {
        let (kind, value) = match p.hold {
            Hold::Share(v) => ("share", v),
            Hold::Slope(v) => ("slope", v),
        };
        for (seed, r) in &p.per_seed {
            out.push_str(&format!(
                "{kind},{value},{seed},{},{},{},{}\n",
                r.slip_deviation, r.mean_accel, r.distance, r.least_cmd_tv_per_s
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use grip_physics::{Demand, RoadCatalogue, Segment};

    fn scenario(roads: &RoadCatalogue, names: &[(&str, f64)], torque: f64) -> Scenario {
        let segments = names
            .iter()
            .map(|(n, len)| Segment {
                road_name: n.to_string(),
                road: roads.index_of(n).unwrap(),
                span: *len,
                grade_pct: 0.0,
            })
            .collect();
        Scenario::new(
            "t",
            "",
            2.4,
            10.0 / 3.6,
            SegmentMode::Distance,
            segments,
            Demand::Constant { torque },
            roads.len(),
        )
        .unwrap()
    }

    fn vehicle() -> VehicleParams {
        VehicleParams::default()
    }

    #[test]
    fn least_slip_inverts_the_curve_on_its_stable_branch() {
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        for road in roads.iter() {
            for frac in [0.1, 0.5, 0.9, 0.999] {
                let mu = frac * road.mu_peak();
                let l = least_slip(road, mu);
                assert!((road.mu(l) - mu).abs() < 1e-9, "{} {frac}", road.name());
                assert!(l < road.lambda_opt());
            }
            assert_eq!(least_slip(road, 2.0), road.lambda_opt());
            assert_eq!(least_slip(road, 0.0), 0.0);
        }
    }

    #[test]
    fn a_lower_share_gives_less_slip_and_less_traction_on_snow() {
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let sc = scenario(&roads, &[("asphalt", 3.0), ("snow", 30.0)], 300.0);
        let v = vehicle();
        let run = |s| ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Share(s));
        let (full, cut) = (run(1.0), run(0.7));
        assert!(cut.slip_deviation < full.slip_deviation, "{cut:?} {full:?}");
        assert!(cut.mean_accel < full.mean_accel, "{cut:?} {full:?}");
    }

    #[test]
    fn on_a_road_that_carries_the_demand_the_share_changes_nothing() {
        // asphalt carries 300 N m at a small share of its peak: no cap binds
        let roads = RoadCatalogue::burckhardt(&["asphalt"]).unwrap();
        let sc = scenario(&roads, &[("asphalt", 40.0)], 300.0);
        let v = vehicle();
        let a = ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Share(1.0));
        let b = ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Share(0.6));
        assert_eq!(a, b);
        // and the speed gained is what the demand's torque gives the car
        // through the wheel's inertia, less the rolling resistance and the
        // motor's lag at the start (tau_m of the run's 2.4 s); drag at
        // 3-5 m/s is about 1 N: within 1 %
        let f_roll = v.c_rr * v.mass * grip_physics::G / v.n_driven;
        let k1 = v.j_w / (v.mass_share() * v.r);
        let steady = (300.0 - v.r * f_roll) / ((v.r + k1) * v.mass_share());
        let expected = steady * (1.0 - v.tau_m / 2.399);
        assert!(
            (a.mean_accel / expected - 1.0).abs() < 0.01,
            "{} vs {expected}",
            a.mean_accel
        );
    }

    #[test]
    fn the_drop_before_snow_reaches_its_cap_by_arrival_and_not_much_before() {
        // the time-optimal drop: the torque is at snow's cap when the wheel
        // arrives, so the slip on snow never exceeds the cap's slip
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let sc = scenario(&roads, &[("asphalt", 3.0), ("snow", 30.0)], 300.0);
        let v = vehicle();
        let share = 0.8;
        let with = ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Share(share));
        // the same drive with the snow's cap applied from the start gives
        // less traction (the drop came no earlier than it had to)
        let all_snow = scenario(&roads, &[("snow", 33.0)], 300.0);
        let snow_only = ideal_run(&v, roads.roads(), &all_snow, 1e-3, 2400, Hold::Share(share));
        assert!(with.mean_accel > snow_only.mean_accel);
        let snow = roads.get("snow").unwrap();
        let cap_slip = least_slip(snow, share * snow.mu_peak());
        assert!(
            with.slip_deviation <= cap_slip + 1e-12,
            "{with:?} {cap_slip}"
        );
    }

    #[test]
    fn a_slope_hold_stops_where_the_curve_has_flattened_to_it() {
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow", "stone"]).unwrap();
        for road in roads.iter() {
            let k = 0.25 * road.dmu_dlambda(0.0);
            let mu = Hold::Slope(k).mu_cap(road);
            let l = least_slip(road, mu);
            assert!(
                (road.dmu_dlambda(l) - k).abs() < 1e-6 * k.max(1.0),
                "{}",
                road.name()
            );
            assert!(mu > 0.0 && mu < road.mu_peak());
            // flatter than the curve's start: the road is not driven
            assert_eq!(Hold::Slope(2.0 * road.dmu_dlambda(0.0)).mu_cap(road), 0.0);
            // a slope under the peak's (c3 < 0 there): the peak
            assert!((Hold::Slope(1e-9).mu_cap(road) - road.mu_peak()).abs() < 1e-9);
        }
    }

    #[test]
    fn the_least_command_variation_is_one_step_down_and_up_per_low_road() {
        // asphalt, snow, asphalt at 300 N m: the command must reach snow's
        // level and come back. That level is snow's peak force through the
        // wheel (μ_peak N r plus J_w a / r at that force, less the rolling
        // resistance's share of it: 186 N m on the default car), and the
        // drag moves it by a fraction of 1 N m
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let sc = scenario(
            &roads,
            &[("asphalt", 2.0), ("snow", 2.0), ("asphalt", 30.0)],
            300.0,
        );
        let v = vehicle();
        let r = ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Share(1.0));
        let snow = roads.get("snow").unwrap();
        let k1 = v.j_w / (v.mass_share() * v.r);
        let f_roll = v.c_rr * v.mass * grip_physics::G / v.n_driven;
        let level = snow.mu_peak() * v.normal_force() * (v.r + k1) - k1 * f_roll;
        let moved = r.least_cmd_tv_per_s * 2.4;
        assert!(
            (moved - 2.0 * (300.0 - level)).abs() < 2.0,
            "{moved} N m, level {level}"
        );
        // on asphalt alone nothing binds: no step at all
        let flat = scenario(&roads, &[("asphalt", 40.0)], 300.0);
        let r = ideal_run(&v, roads.roads(), &flat, 1e-3, 2400, Hold::Share(1.0));
        assert!(r.least_cmd_tv_per_s * 2.4 < 1.0, "{r:?}");
    }
}
