//! What an ideal controller reaches on a scenario: a reference beside the
//! simulated controllers (README.md, "How close to the ideal").
//!
//! The ideal knows every road of the scenario exactly and at once (where
//! each begins, its whole μ-λ curve) and holds each road at a fixed point of
//! its curve: `share · μ_peak · N` ([`Hold::Share`], the ARTE variants'
//! `cap_share`) or where the curve has flattened to a slope ([`Hold::Slope`]).
//! It leaves out the wheel's slip dynamics: its slip is always the least
//! that carries its tyre force, on the curve's stable branch (the wheel
//! equation keeps only the `J_w a / r` that speeds the wheel up with the
//! car). What it keeps of the car is what no controller can wish away: the
//! motor's first-order lag `tau_m` (its command anywhere in `[0, T_d]`: a
//! TCS never adds torque), the wheel's inertia, the motor's torque and
//! power limits and the driving resistance, grade included, as the plant
//! has them. Before a lower-μ road it drops as late as the lag allows (each
//! cycle the most command after which a zero command still brings the
//! torque to that road's hold by arrival: a zero command, then the hold);
//! on a road that carries more it commands the demand on arrival.
//!
//! For a controller that also never asks a road for more than the same
//! hold, what the ideal leaves out (slip dynamics, a late, wrong or
//! misplaced estimate, noise, the controller's own dynamics) only adds slip
//! and costs acceleration, so such a controller is dominated by the
//! ideal's curve swept over the hold (more slip at equal mean
//! acceleration). A controller that lets the wheel spin past a road's hold
//! is not bound by it: it keeps the full torque up to a lower-μ road and a
//! curve that is flat past its peak still carries nearly the peak (on
//! `config/scenarios/winter.toml`'s ice MFC-ARTE and MTTE-ARTE get more
//! acceleration than the ideal at share 1). So the ideal is a reference,
//! not a proof; and the allocation across roads (one share, or one slope,
//! for every road) is not a proven optimum over all allocations.
//!
//! Allocation: [`ideal_run`] allocates nothing per cycle
//! (`tests/no_alloc.rs`).

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
    /// much (the ideal's own drops move it more).
    pub least_cmd_tv_per_s: f64,
    /// The most the motor's torque stood above a road's hold on the first
    /// cycle on it, over the road changes of the run, N m (negative when
    /// every road was reached under its hold; -inf without a change): the
    /// drops' check, at most a rounding above 0.
    pub arrival_over_hold: f64,
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

/// How far ahead the ideal looks for a lower-μ road: this many motor time
/// constants (a zero command takes the torque to e^-10 of itself in it).
const LOOK_AHEAD_TAU: f64 = 10.0;

/// A hold the torque must reach before a road the ideal does not drive at
/// all (a `slope=K` steeper than the road's curve ever is) stands for 0 as
/// this, N m: the exponential lag never reaches 0 itself.
const ZERO_HOLD: f64 = 1.0;

/// One ideal run of `scenario` for `vehicle` on the catalogue's `roads`
/// (indexed by the segments' `road`), `cycles` cycles of `dt` s, each road
/// held as `hold` says.
///
/// The caller has validated the three together and the hold (a
/// [`crate::SimSetup`] has; `grip sim --ideal` checks the hold): a segment
/// whose road index is not in `roads` panics, and a share outside (0, 1]
/// gives figures that mean nothing.
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
    // the torque level segment `j` asks for at speed `v`: the demand (within
    // the motor's limit), or the torque that delivers the road's hold with
    // the wheel speeding up with the car, T = r F + J_w a / r with
    // a = (F - F_res) / (M/n), on that segment's grade
    let env = |j: usize, v: f64| {
        let (sin_t, cos_t) = scenario.segments[j].grade_rad().sin_cos();
        let n_force = p.normal_force() * cos_t;
        let f_res = (p.c_rr * p.mass * g * cos_t * v / v.abs().max(1e-2)
            + 0.5 * p.rho * p.c_d_a * v * v.abs()
            + p.mass * g * sin_t)
            / p.n_driven;
        let cap_force = hold.mu_cap(&roads[scenario.segments[j].road]) * n_force;
        (n_force, f_res, cap_force, cap_force * (r + k1) - k1 * f_res)
    };
    let (mut v, mut x, mut torque) = (scenario.v0, 0.0_f64, 0.0_f64);
    let (mut sum_lambda, mut v_first, mut v_last) = (0.0, scenario.v0, scenario.v0);
    let (mut level_tv, mut last_level) = (0.0, f64::NAN);
    let (mut over_hold, mut last_segment) = (f64::NEG_INFINITY, usize::MAX);
    let mut accel = 0.0_f64;
    for k in 0..cycles {
        let t = k as f64 * dt;
        if k == 0 {
            v_first = v;
        }
        v_last = v;
        let i = scenario.segment_at(t, x);
        let road = &roads[scenario.segments[i].road];
        let (n_force, f_res, cap_force, cap_torque) = env(i, v);
        let level = scenario
            .demand_at(t)
            .min(p.torque_limit(v / r))
            .min(cap_torque)
            .max(0.0);
        if last_level.is_finite() {
            level_tv += (level - last_level).abs();
        }
        if i != last_segment && k > 0 {
            over_hold = over_hold.max(torque - cap_torque);
        }
        last_segment = i;
        last_level = level;
        let mut cmd = level;
        if tau > 0.0 {
            // the latest-starting drop to each lower road ahead: each cycle
            // the most command after which a zero command still brings the
            // torque to the road's hold by arrival (a zero command until the
            // torque is there, then the hold)
            let decay = (-dt / tau).exp();
            for j in i + 1..scenario.segments.len() {
                let to_go = match scenario.segments_by {
                    SegmentMode::Distance => {
                        // at the car's present acceleration (it only falls
                        // while the torque drops: the estimate errs early)
                        let d = (scenario.segment_start(j) - x).max(0.0);
                        let vv = v.max(0.1);
                        if accel > 1e-9 {
                            ((vv * vv + 2.0 * accel * d).sqrt() - vv) / accel
                        } else {
                            d / vv
                        }
                    }
                    SegmentMode::Time => scenario.segment_start(j) - t,
                };
                if to_go > LOOK_AHEAD_TAU * tau {
                    break;
                }
                let target = env(j, v).3.max(ZERO_HOLD);
                if target >= cmd {
                    continue;
                }
                let next_max = target * ((to_go - dt) / tau).exp();
                let most = (next_max - torque * decay) / (1.0 - decay);
                cmd = cmd.min(most.max(0.0));
            }
        }
        torque = if tau > 0.0 {
            cmd + (torque - cmd) * (-dt / tau).exp()
        } else {
            cmd
        };
        let force = ((torque + k1 * f_res) / (r + k1)).min(cap_force);
        sum_lambda += least_slip(road, force / n_force).abs() * dt;
        let a = (force - f_res) / ms;
        accel = a;
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
        arrival_over_hold: over_hold,
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
         road known exactly and at once and held at a share of its peak force (or where its curve's slope falls to K),\n\
         always at the least slip that carries its force (no slip dynamics), dropping to a lower-μ road as late as the\n\
         motor's lag allows; the lag, the wheel's inertia, the torque and power limits and the driving resistance as the\n\
         plant has them. Means over the same seeds' scenarios. A controller that never asks a road for more than the same\n\
         hold, with any road estimate, has more slip at equal mean acceleration; one that lets the wheel spin is not bound\n\
         by it. cmd TV (N m/s): the command's total variation per second; the ideal's is the least a command needs that\n\
         reaches each road's level and moves only between them:\n{}",
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
    fn the_drop_before_snow_reaches_its_hold_by_arrival_and_no_earlier() {
        // the latest-starting drop: the torque is at (not over) snow's hold
        // on the first cycle on snow
        let roads = RoadCatalogue::burckhardt(&["asphalt", "snow"]).unwrap();
        let sc = scenario(&roads, &[("asphalt", 3.0), ("snow", 30.0)], 300.0);
        let v = vehicle();
        for share in [1.0, 0.8, 0.6] {
            let r = ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Share(share));
            assert!(
                r.arrival_over_hold <= 0.05 && r.arrival_over_hold > -5.0,
                "share {share}: {r:?}"
            );
        }
        // no earlier than the lag needs: a slower motor must start its drop
        // earlier and so gives up more before snow (the same hold reached)
        let slow = VehicleParams {
            tau_m: 0.1,
            ..vehicle()
        };
        let fast = ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Share(0.8));
        let late = ideal_run(&slow, roads.roads(), &sc, 1e-3, 2400, Hold::Share(0.8));
        assert!(late.mean_accel < fast.mean_accel, "{late:?} {fast:?}");
        assert!(late.arrival_over_hold <= 0.05, "{late:?}");
        // and a drop that began at the start (snow's hold all along) gives
        // up more than the ideal's
        let all_snow = scenario(&roads, &[("snow", 33.0)], 300.0);
        let snow_only = ideal_run(&v, roads.roads(), &all_snow, 1e-3, 2400, Hold::Share(0.8));
        assert!(fast.mean_accel > snow_only.mean_accel);
    }

    #[test]
    fn many_short_segments_and_time_segments_still_get_their_drop() {
        // ice after 60 segments of 1 cm (the look-ahead is by time, not by
        // segment count), and the same roads in time segments
        let roads = RoadCatalogue::burckhardt(&["asphalt", "stone", "ice"]).unwrap();
        let mut short: Vec<(&str, f64)> = (0..60)
            .map(|k| (if k % 2 == 0 { "asphalt" } else { "stone" }, 0.01))
            .collect();
        short.insert(0, ("asphalt", 2.0));
        short.push(("ice", 30.0));
        let sc = scenario(&roads, &short, 300.0);
        let v = vehicle();
        let r = ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Share(1.0));
        assert!(r.arrival_over_hold <= 0.05, "{r:?}");
        assert!(r.mean_accel > 0.0, "{r:?}");
        let timed = Scenario::new(
            "t",
            "",
            2.4,
            10.0 / 3.6,
            SegmentMode::Time,
            vec![
                Segment {
                    road_name: "asphalt".into(),
                    road: 0,
                    span: 0.7,
                    grade_pct: 0.0,
                },
                Segment {
                    road_name: "ice".into(),
                    road: 2,
                    span: 2.0,
                    grade_pct: 5.0,
                },
            ],
            Demand::Constant { torque: 300.0 },
            roads.len(),
        )
        .unwrap();
        let r = ideal_run(&v, roads.roads(), &timed, 1e-3, 2400, Hold::Share(1.0));
        assert!(r.arrival_over_hold <= 0.05, "{r:?}");
    }

    #[test]
    fn a_road_the_slope_hold_does_not_drive_stops_the_torque_only_near_it() {
        // stone's curve starts at dμ/dλ = 8.2: a slope of 9 does not drive
        // it. Asphalt before it is driven until the drop to about 0 begins
        // (a few motor time constants ahead), not from four segments off.
        let roads = RoadCatalogue::burckhardt(&["asphalt", "stone"]).unwrap();
        let stone = roads.get("stone").unwrap();
        assert!(stone.dmu_dlambda(0.0) < 9.0);
        assert_eq!(Hold::Slope(9.0).mu_cap(stone), 0.0);
        let v = vehicle();
        let sc = scenario(&roads, &[("asphalt", 5.0), ("stone", 30.0)], 300.0);
        let r = ideal_run(&v, roads.roads(), &sc, 1e-3, 2400, Hold::Slope(9.0));
        // (the hold is a little under 0 N m: the torque that holds the car
        // against its rolling resistance through the wheel)
        assert!(r.arrival_over_hold <= ZERO_HOLD + 0.5, "{r:?}");
        // 5 m of asphalt at full demand first: faster than the car creeps
        // with no torque, and stops on stone
        let flat = scenario(&roads, &[("asphalt", 40.0)], 300.0);
        let full = ideal_run(&v, roads.roads(), &flat, 1e-3, 2400, Hold::Slope(9.0));
        assert!(
            r.distance > 5.0 && r.distance < full.distance,
            "{r:?} {full:?}"
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
