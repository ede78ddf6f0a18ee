//! tcs-loop's loop struct and plant-sim's loop struct in closed loop over
//! the real simulated CAN bus (iceoryx2 SimBus, two nodes in this process),
//! lock-stepped on a manual clock through the shipped paper scenario
//! (2.4 s: asphalt, snow, gravel, stone, snow at a constant 300 N m demand).

use grip_config::ConfigDir;
use grip_io::can::SimBus;
use grip_io::clock::{Clock, ManualClock};
use grip_io::ipc::IpcNode;
use grip_io::service::ServiceConfig;
use grip_msgs::{GroundTruth, RoadEstimate};
use grip_physics::{Plant, PlantState};
use grip_plant_sim::{Outcome, Phase, PlantSim, PlantSimConfig, StartOn, TruthSink};
use grip_tcs::ControllerKind;
use grip_tcs_loop::{NullSink, RoadSource, TcsLoop, TcsLoopConfig};

const MS: u64 = 1_000_000;

fn dir() -> ConfigDir {
    ConfigDir::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../config"))
}

#[derive(Default)]
struct Truths(Vec<GroundTruth>);
impl TruthSink for Truths {
    fn truth(&mut self, g: &GroundTruth) {
        self.0.push(*g);
    }
}

/// A perfect road estimator: the true road, confidence 1, stamped now.
struct Perfect(Option<RoadEstimate>);
impl RoadSource for Perfect {
    fn poll_next(&mut self) -> Option<RoadEstimate> {
        self.0.take()
    }
}

#[derive(Debug)]
struct Outcome_ {
    /// Mean |λ| over the scenario (the metric's "slip deviation").
    mean_abs_slip: f64,
    /// Largest true slip in the last 0.3 s of each snow patch.
    late_snow_slip: f64,
    /// Largest true motor torque there, N m.
    late_snow_torque: f64,
    v_end_kmh: f64,
    x_end: f64,
    /// Distance covered during the scenario's 2.4 s, m.
    distance: f64,
    safe_entries: u64,
    faults: u64,
    inverter_faults: u64,
    cmd_timeouts: u64,
    used_arte_cycles: u64,
}

/// A SimBus between a plant-sim node and a tcs-loop node (the ends, then
/// the nodes they live on), named uniquely per run: tests run in parallel
/// and some run the same controller.
fn bus_pair(tag: &str) -> ((IpcNode, IpcNode), SimBus, SimBus) {
    static RUN: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let run_id = RUN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = format!("{tag}-{}-{run_id}", std::process::id());
    let node_p = IpcNode::create("plant-sim").unwrap();
    let node_t = IpcNode::create("tcs-loop").unwrap();
    let bus_p = SimBus::open(&node_p, &name, 0).unwrap();
    let bus_t = SimBus::open(&node_t, &name, 0).unwrap();
    ((node_p, node_t), bus_p, bus_t)
}

fn closed_loop(kind: ControllerKind, arte: bool) -> Outcome_ {
    let d = dir();
    let roads = d.roads().unwrap();
    let scenario = d.scenario_with("paper", &roads).unwrap();
    let (vehicle, sensors) = d.vehicle().unwrap();
    let controllers = grip_config::load_controllers(d.file("controllers.toml")).unwrap();
    let own = TcsLoopConfig::load(&d.file("tcs-loop.toml")).unwrap();
    let pcfg = PlantSimConfig {
        start_on: StartOn::Commands,
        exit_at_end: true,
        ..PlantSimConfig::load(&d.file("plant-sim.toml")).unwrap()
    };
    let mut plant = PlantSim::new(&pcfg, scenario, roads.clone(), &vehicle, &sensors).unwrap();
    let mut tcs = TcsLoop::new(kind, arte, &controllers, &vehicle, &own.safety).unwrap();

    let (_nodes, mut bus_p, mut bus_t) = bus_pair(&format!("cl-{kind}-{arte}"));

    let clock = ManualClock::new(10_000 * MS);
    let mut truths = Truths::default();
    let mut road = Perfect(None);
    let mut sink = NullSink;
    let mut used = 0;
    for _ in 0..10_000 {
        let now = clock.now_ns();
        let o = plant.cycle(
            &grip_plant_sim::PlantTick::at(now),
            &clock,
            &mut bus_p,
            &mut truths,
        );
        if o == Outcome::Finished {
            break;
        }
        let g = *truths.0.last().unwrap();
        let r = &roads[g.road_index as usize];
        road.0 = Some(RoadEstimate {
            stamp_ns: now,
            class_index: g.road_index,
            confidence: 1.0,
            lambda_opt: r.lambda_opt(),
            mu_peak: r.mu_peak(),
            alpha: 1.0 - r.lambda_opt(),
            ..RoadEstimate::zeroed()
        });
        let rec = tcs.cycle(
            &grip_tcs_loop::CycleTick::at(now),
            &clock,
            &mut bus_t,
            &mut road,
            &mut sink,
        );
        used += u64::from(rec.used_arte);
        if std::env::var("CL_DEBUG").is_ok() && truths.0.len() % 50 == 0 {
            eprintln!(
                "k={} safe={} T_d={:.1} T*={:.1} int={:.1} mu={:.3} om={:.2} T={:.1} | true lam={:.3} T={:.1} road={:?}",
                truths.0.len(),
                rec.safe_state,
                rec.demand,
                rec.torque_cmd,
                rec.internal,
                rec.mu_hat,
                rec.omega,
                rec.torque,
                g.lambda,
                g.torque,
                g.road_name()
            );
        }
        clock.advance_ns(MS);
    }
    assert_eq!(plant.phase(), Phase::Ended, "scenario ran to its end");
    // the scenario's 2.4 s: from the first cycle the plant moved on
    let x0 = truths.0[0].x;
    let first = truths.0.iter().position(|g| g.x != x0).unwrap();
    let n = (plant.scenario().duration * 1000.0).round() as usize;
    assert!(
        truths.0.len() >= first + n,
        "ran {} cycles",
        truths.0.len() - first
    );
    let run = &truths.0[first..first + n];
    for g in run {
        assert!(
            g.v.is_finite() && g.omega.is_finite() && g.lambda.is_finite() && g.torque.is_finite(),
            "{g:?}"
        );
    }
    let snow = roads.index_of("snow").unwrap();
    let road: Vec<usize> = run.iter().map(|g| g.road_index as usize).collect();
    let late = late_snow(&road, snow);
    let last = truths.0.last().unwrap();
    Outcome_ {
        mean_abs_slip: run.iter().map(|g| g.lambda.abs()).sum::<f64>() / n as f64,
        late_snow_slip: late_max(run, &late, |g| g.lambda),
        late_snow_torque: late_max(run, &late, |g| g.torque),
        v_end_kmh: last.v * 3.6,
        x_end: last.x,
        distance: run[n - 1].x - x0,
        safe_entries: tcs.safe_entries(),
        faults: tcs.protocol_rx().faults().total(),
        inverter_faults: plant.protocol_rx().faults().total(),
        cmd_timeouts: plant.cmd_timeouts(),
        used_arte_cycles: used,
    }
}

/// Cycle-index windows of the last 0.3 s of every snow patch.
/// The last 0.3 s (300 cycles) of every stretch of snow the run was on,
/// from the run's own road per cycle (the scenario's segments are places).
fn late_snow(road_per_cycle: &[usize], snow: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut k = 0;
    while k < road_per_cycle.len() {
        if road_per_cycle[k] != snow {
            k += 1;
            continue;
        }
        let start = k;
        while k < road_per_cycle.len() && road_per_cycle[k] == snow {
            k += 1;
        }
        out.push((start.max(k.saturating_sub(300)), k));
    }
    out
}

fn late_max(run: &[GroundTruth], w: &[(usize, usize)], f: impl Fn(&GroundTruth) -> f64) -> f64 {
    w.iter()
        .flat_map(|&(a, b)| run[a..b.min(run.len())].iter())
        .map(f)
        .fold(f64::MIN, f64::max)
}

/// The same scenario with the driver's 300 N m applied directly (no TCS):
/// (mean |λ|, largest slip in the late snow windows).
fn open_loop() -> (f64, f64) {
    let d = dir();
    let roads = d.roads().unwrap();
    let sc = d.scenario_with("paper", &roads).unwrap();
    let (vehicle, _) = d.vehicle().unwrap();
    let mut p = Plant::new(vehicle, PlantState::rolling(sc.v0, vehicle.r)).unwrap();
    let n = (sc.duration * 1000.0).round() as usize;
    let mut lam = Vec::with_capacity(n);
    let mut road = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 * 1e-3;
        let seg = sc.segment_at(t, p.state().x);
        road.push(sc.segments[seg].road);
        p.step(1e-3, sc.demand_at(t), &roads[sc.segments[seg].road], 0.0);
        lam.push(p.lambda());
    }
    let late = late_snow(&road, roads.index_of("snow").unwrap())
        .iter()
        .flat_map(|&(a, b)| lam[a..b].iter().copied())
        .fold(f64::MIN, f64::max);
    (lam.iter().map(|l| l.abs()).sum::<f64>() / n as f64, late)
}

fn check_common(o: &Outcome_) {
    assert_eq!(o.safe_entries, 0, "no safe state once running: {o:?}");
    assert_eq!(o.faults, 0, "no E2E fault on a clean bus: {o:?}");
    assert_eq!(o.inverter_faults, 0, "{o:?}");
    assert_eq!(o.cmd_timeouts, 0, "{o:?}");
    // the car accelerates from 10 km/h and stays in the paper's bracket
    assert!(o.v_end_kmh > 11.0 && o.v_end_kmh < 35.0, "{o:?}");
    assert!(o.x_end > 5.0 && o.x_end < 25.0, "{o:?}");
}

#[test]
fn mtte_keeps_the_wheel_from_running_away_on_snow() {
    let (ol_slip, ol_snow) = open_loop();
    let o = closed_loop(ControllerKind::Mtte, false);
    eprintln!("MTTE: {o:?}\nopen loop: mean |slip| {ol_slip:.4}, late snow slip {ol_snow:.3}");
    check_common(&o);
    assert_eq!(o.used_arte_cycles, 0);
    // open loop the wheel runs away on snow (300 N m > 183 N m it carries)
    assert!(ol_snow > 0.8, "{ol_snow}");
    // with MTTE the slip stays bounded well below that and the torque
    // settles near what snow carries (0.19 * 3434 N * 0.28 m = 183 N m)
    assert!(o.late_snow_slip < 0.7 * ol_snow, "{o:?} vs {ol_snow}");
    assert!(o.late_snow_torque < 200.0, "{o:?}");
    assert!(o.mean_abs_slip < 0.6 * ol_slip, "{o:?} vs {ol_slip}");
}

#[test]
fn mtte_with_perfect_arte_uses_it_and_stays_sensible() {
    let (ol_slip, ol_snow) = open_loop();
    let o = closed_loop(ControllerKind::Mtte, true);
    eprintln!("MTTE-ARTE: {o:?}");
    check_common(&o);
    assert!(o.used_arte_cycles > 2_000, "{o:?}");
    assert!(o.late_snow_slip < 0.7 * ol_snow, "{o:?}");
    assert!(o.mean_abs_slip < 0.6 * ol_slip, "{o:?}");
}

#[test]
fn src_and_mfc_run_the_scenario_with_finite_results() {
    let (ol_slip, _) = open_loop();
    for kind in [ControllerKind::Src, ControllerKind::Mfc] {
        let o = closed_loop(kind, false);
        eprintln!("{kind}: {o:?}");
        check_common(&o);
        assert!(o.mean_abs_slip < ol_slip, "{kind}: {o:?} vs {ol_slip}");
    }
}

/// The live path (CAN encoding, E2E, SimBus, the service loops) against the
/// offline simulator (`grip_sim::run`: the same controller, plant and sensor
/// models called directly) on the same scenario. They differ in the sensor
/// noise sequence (different seeds and sampling), in the phase of the 10 ms
/// DriverDemand frame (the live demand reaches the controller up to 10 ms
/// later) and in where the one-cycle delay sits (offline: a sensor sample;
/// live: the command frame), so they agree within tolerances, not bitwise.
#[test]
fn live_loop_matches_the_offline_simulator() {
    let d = dir();
    let roads = d.roads().unwrap();
    let sc = d.scenario_with("paper", &roads).unwrap();
    let (vehicle, sensors) = d.vehicle().unwrap();
    let controllers = grip_config::load_controllers(d.file("controllers.toml")).unwrap();
    let setup = grip_sim::SimSetup::new(
        vehicle,
        sensors,
        roads,
        sc,
        controllers,
        &grip_tcs::KnowledgeConfig::default(),
    )
    .unwrap();
    for kind in ControllerKind::ALL {
        let mut est = grip_sim::PerfectArte::new(0.1);
        let off = grip_sim::run(&setup, grip_sim::Variant::new(kind, false), 1, &mut est).unwrap();
        let live = closed_loop(kind, false);
        let m = off.metrics;
        eprintln!(
            "{kind}: slip dev offline {:.4} live {:.4}; distance {:.3} / {:.3} m; V end {:.2} / {:.2} km/h",
            m.slip_deviation,
            live.mean_abs_slip,
            m.distance,
            live.distance,
            off.final_state.v * 3.6,
            live.v_end_kmh
        );
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-9);
        assert!(
            rel(live.mean_abs_slip, m.slip_deviation) < 0.10,
            "{kind}: slip"
        );
        assert!(rel(live.distance, m.distance) < 0.02, "{kind}: distance");
    }
}

/// An acoustic estimator that hears perfectly what arte would hear: every
/// 100 ms the road at the **microphone** (plant-sim's `mic_road_index`) at
/// the frame's end, confidence 1, stamped as arte stamps it with the
/// loop's odometer at the frame's start and end (from the cycle records).
struct HeardAhead {
    next: Option<RoadEstimate>,
    names: Vec<[u8; grip_msgs::NAME_LEN]>,
    /// (stamp, odometer) of every cycle record.
    odo: Vec<(u64, f64)>,
    seq: u64,
}

impl RoadSource for HeardAhead {
    fn poll_next(&mut self) -> Option<RoadEstimate> {
        self.next.take()
    }
}

impl HeardAhead {
    fn frame_ends(&mut self, now: u64, mic_road: usize) {
        let t0 = now.saturating_sub(100 * MS);
        let at = |t: u64| {
            self.odo
                .iter()
                .rev()
                .find(|(s, _)| *s <= t)
                .map_or(f64::NAN, |&(_, x)| x)
        };
        let (x_from, x_to) = (at(t0), at(now));
        self.seq += 1;
        self.next = Some(RoadEstimate {
            seq: self.seq,
            stamp_ns: now,
            frame_t0_ns: t0,
            frame_t1_ns: now,
            class_index: mic_road as u32,
            class_name: self.names[mic_road],
            confidence: 1.0,
            x_from,
            x_to,
            ..RoadEstimate::zeroed()
        });
    }
}

/// What [`front_mic_closed_loop`] saw.
#[derive(Debug)]
struct FrontMic {
    /// Mean |λ| and mean acceleration over the scenario's 2.4 s.
    mean_abs_slip: f64,
    mean_accel: f64,
    /// Largest true motor torque and command in the last 20 ms before the
    /// wheel reaches the first snow (x = 1.28 m), N m.
    torque_before_snow: f64,
    cmd_before_snow: f64,
    /// Largest true slip in the first 0.2 s on the first snow.
    snow_entry_slip: f64,
    /// The loop's odometer minus the plant's x, spread (max − min) from
    /// the pre-roll's start to the end, m.
    odometer_offset_spread: f64,
    safe_entries: u64,
    /// Where plant-sim held the wheel before the start, m.
    x_hold: f64,
}

/// tcs-loop **with its road knowledge** (`with_road_aware`, as `run` builds
/// it with `--arte on`) and plant-sim with the front-mic vehicle
/// (microphone 2.77 m ahead of the driven wheel) over the SimBus, lock-step
/// on a manual clock through the paper scenario: held 200 ms, then
/// started the way `grip drive` starts it (commands + request), with the
/// pre-roll; estimates from [`HeardAhead`].
fn front_mic_closed_loop(kind: ControllerKind) -> FrontMic {
    let d = dir();
    let roads = d.roads().unwrap();
    let table = d.road_table(&roads).unwrap();
    let scenario = d.scenario_with("paper", &roads).unwrap();
    let (vehicle, sensors) = grip_config::load_vehicle(d.file("vehicles/front-mic.toml")).unwrap();
    let controllers = grip_config::load_controllers(d.file("controllers.toml")).unwrap();
    let own = TcsLoopConfig::load(&d.file("tcs-loop.toml")).unwrap();
    let pcfg = PlantSimConfig {
        start_on: StartOn::Signal,
        exit_at_end: true,
        ..PlantSimConfig::load(&d.file("plant-sim.toml")).unwrap()
    };
    let mut plant = PlantSim::new(&pcfg, scenario, roads.clone(), &vehicle, &sensors).unwrap();
    let mut tcs = TcsLoop::new(kind, true, &controllers, &vehicle, &own.safety)
        .unwrap()
        .with_road_aware(&roads, table, &controllers, &vehicle)
        .unwrap();
    assert!(tcs.road_aware());

    let (_nodes, mut bus_p, mut bus_t) = bus_pair(&format!("fm-{kind}"));

    let clock = ManualClock::new(10_000 * MS);
    let mut truths = Truths::default();
    let mut heard = HeardAhead {
        next: None,
        names: roads
            .iter()
            .map(|r| grip_msgs::name_to_bytes(r.name()))
            .collect(),
        odo: Vec::new(),
        seq: 0,
    };
    let mut sink = NullSink;
    // (truth x, true torque, command, odometer) per cycle
    let mut trace: Vec<(f64, f64, f64, f64)> = Vec::new();
    for k in 0..10_000u64 {
        let now = clock.now_ns();
        if k == 200 {
            plant.request_start();
        }
        let o = plant.cycle(
            &grip_plant_sim::PlantTick::at(now),
            &clock,
            &mut bus_p,
            &mut truths,
        );
        if o == Outcome::Finished {
            break;
        }
        let g = *truths.0.last().unwrap();
        if k % 100 == 99 {
            heard.frame_ends(now, g.mic_road_index as usize);
        }
        let rec = *tcs.cycle(
            &grip_tcs_loop::CycleTick::at(now),
            &clock,
            &mut bus_t,
            &mut heard,
            &mut sink,
        );
        heard.odo.push((rec.stamp_ns, rec.odometer));
        trace.push((g.x, g.torque, rec.torque_cmd, rec.odometer));
        clock.advance_ns(MS);
    }
    assert_eq!(plant.phase(), Phase::Ended, "scenario ran to its end");
    let n = (plant.scenario().duration * 1000.0).round() as usize;
    let x_hold = truths.0[0].x;
    // the scenario starts at the last sample at x = 0 (end of the pre-roll)
    let first = truths.0.iter().position(|g| g.x > 0.0).unwrap() - 1;
    assert_eq!(truths.0[first].x, 0.0);
    let run = &truths.0[first..first + n];
    let mean_abs_slip = run.iter().map(|g| g.lambda.abs()).sum::<f64>() / n as f64;
    let mean_accel = (run[n - 1].v - run[0].v) / plant.scenario().duration;
    let snow_at = 1.28;
    let dx = run[0].v * 0.02;
    let before: Vec<_> = trace
        .iter()
        .filter(|s| s.0 >= snow_at - dx && s.0 < snow_at)
        .collect();
    assert!(
        before.len() >= 10,
        "{} cycles before the snow",
        before.len()
    );
    let entry = run.iter().position(|g| g.x >= snow_at).unwrap();
    let pre_roll_start = truths.0.iter().position(|g| g.x != x_hold).unwrap();
    let offsets: Vec<f64> = trace[pre_roll_start..].iter().map(|s| s.3 - s.0).collect();
    let spread = offsets.iter().copied().fold(f64::MIN, f64::max)
        - offsets.iter().copied().fold(f64::MAX, f64::min);
    FrontMic {
        mean_abs_slip,
        mean_accel,
        torque_before_snow: before.iter().map(|s| s.1).fold(f64::MIN, f64::max),
        cmd_before_snow: before.iter().map(|s| s.2).fold(f64::MIN, f64::max),
        snow_entry_slip: run[entry..entry + 200]
            .iter()
            .map(|g| g.lambda)
            .fold(f64::MIN, f64::max),
        odometer_offset_spread: spread,
        safe_entries: tcs.safe_entries(),
        x_hold,
    }
}

/// Snow entry with the microphone ahead, closed loop over the live path:
/// for every controller the torque is at snow's transmissible limit
/// (μ_peak · N · r ≈ 183 N m) in the last 20 ms before the wheel reaches
/// the first snow (1.28 m into the paper scenario, heard only because
/// plant-sim pre-rolls the lead: without the pre-roll the microphone starts
/// over the snow, never hears the change, and the wheel meets the snow with
/// 300 N m); the loop's odometer keeps one offset to the plant's x from the
/// pre-roll on; and the result agrees with the offline simulator's
/// "with ARTE" variant (same vehicle, perfect estimator, its own pre-roll).
#[test]
fn front_mic_snow_entry_is_capped_before_the_wheel_arrives() {
    let d = dir();
    let roads = d.roads().unwrap();
    let table = d.road_table(&roads).unwrap();
    let (vehicle, sensors) = grip_config::load_vehicle(d.file("vehicles/front-mic.toml")).unwrap();
    let snow = roads.index_of("snow").unwrap();
    let limit = table.info(snow).mu_peak * vehicle.normal_force() * vehicle.r;
    assert!((limit - 183.0).abs() < 1.0, "snow carries {limit} N m");
    let setup = grip_sim::SimSetup::new(
        vehicle,
        sensors,
        roads.clone(),
        d.scenario_with("paper", &roads).unwrap(),
        grip_config::load_controllers(d.file("controllers.toml")).unwrap(),
        &grip_tcs::KnowledgeConfig::default(),
    )
    .unwrap();
    for kind in ControllerKind::ALL {
        let o = front_mic_closed_loop(kind);
        let mut est = grip_sim::PerfectArte::new(0.1);
        let off = grip_sim::run(&setup, grip_sim::Variant::new(kind, true), 1, &mut est)
            .unwrap()
            .metrics;
        eprintln!(
            "{kind}-ARTE front-mic: {o:?}; offline slip {:.4} accel {:.3}",
            off.slip_deviation, off.mean_accel
        );
        assert_eq!(o.safe_entries, 0, "{kind}: {o:?}");
        assert!(o.cmd_before_snow <= limit + 1e-6, "{kind}: {o:?}");
        assert!(
            o.torque_before_snow <= limit * 1.02 && o.torque_before_snow >= limit * 0.8,
            "{kind}: torque at snow's limit ({limit:.1} N m) before the wheel arrives: {o:?}"
        );
        assert!(o.snow_entry_slip < 0.1, "{kind}: {o:?}");
        // only the integrated sensor noise of the measured V (mm), not the
        // metres a hold or a missing pre-roll would put between them
        assert!(o.odometer_offset_spread < 0.02, "{kind}: {o:?}");
        assert!(o.x_hold <= -2.77, "{kind}: held a lead before x = 0: {o:?}");
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-9);
        assert!(
            rel(o.mean_accel, off.mean_accel) < 0.03,
            "{kind}: traction live {} offline {}",
            o.mean_accel,
            off.mean_accel
        );
        assert!(
            rel(o.mean_abs_slip, off.slip_deviation) < 0.3,
            "{kind}: slip live {} offline {}",
            o.mean_abs_slip,
            off.slip_deviation
        );
    }
}
