//! The plant-sim cycle allocates nothing after warm-up: a counting global
//! allocator (current thread only) around 20 000 cycles with commands,
//! corrupted frames, command outages (inverter timeout) and the scenario
//! running through all its segments to its end.
//!
//! The ports are in-memory doubles; with the real iceoryx2 ports each
//! publish allocates one 48-byte Arc inside iceoryx2 0.10 (see
//! `crates/io/tests/no_alloc.rs`).

mod common;

use grip_testkit::allocations;

use common::{LastTruth, MemBus, sim};
use grip_io::can::protocol::{E2eSender, TorqueCommand};
use grip_io::clock::{Clock, ManualClock};
use grip_msgs::CanFrame;
use grip_plant_sim::{Phase, PlantSimConfig, PlantTick, StartOn};

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

const MS: u64 = 1_000_000;

#[test]
fn the_counter_sees_allocations() {
    let n = allocations(|| {
        std::hint::black_box(vec![1u8; 64]);
    });
    assert_eq!(n, 1);
}

#[test]
fn cycle_allocates_nothing_after_warm_up() {
    let cfg = PlantSimConfig {
        start_on: StartOn::Commands,
        ..PlantSimConfig::with_scenario("paper")
    };
    let mut s = sim(&cfg);
    let clock = ManualClock::new(1_000 * MS);
    let mut bus = MemBus::new();
    let mut truth = LastTruth::default();
    let mut tx = E2eSender::<TorqueCommand>::new();
    let mut k = 0u64;
    let mut step = |s: &mut grip_plant_sim::PlantSim, bus: &mut MemBus, truth: &mut LastTruth| {
        let now = clock.now_ns();
        let outage = (1_500..1_540).contains(&(k % 3_000));
        if !outage {
            let f = tx.encode(
                &TorqueCommand {
                    torque_request: 150.0 + (k % 100) as f64,
                    enable: true,
                },
                now,
            );
            bus.inject(f);
        }
        if k % 700 == 11 {
            let mut f = tx.encode(&TorqueCommand::default(), now);
            f.data[5] ^= 1;
            bus.inject(f);
            bus.inject(CanFrame::new(0x42, &[0; 3]));
        }
        s.cycle(&PlantTick::at(now), &clock, bus, truth);
        bus.tx.borrow_mut().clear();
        clock.advance_ns(MS);
        k += 1;
    };
    for _ in 0..500 {
        step(&mut s, &mut bus, &mut truth);
    }
    assert_eq!(s.phase(), Phase::Running);
    let n = allocations(|| {
        for _ in 0..20_000 {
            step(&mut s, &mut bus, &mut truth);
        }
    });
    assert_eq!(n, 0, "{n} allocations in 20 000 cycles");
    assert_eq!(s.phase(), Phase::Ended, "ran through the whole scenario");
    assert!(s.cmd_timeouts() >= 5, "outages: {}", s.cmd_timeouts());
    assert!(s.protocol_rx().faults().crc >= 20);
    assert!(truth.last.unwrap().v.is_finite());
}

/// The front-mic vehicle's hold, pre-roll and scenario: nothing allocated
/// from the first cycle after construction to the scenario's end.
#[test]
fn pre_roll_allocates_nothing() {
    let cfg = PlantSimConfig {
        start_on: StartOn::Commands,
        ..PlantSimConfig::with_scenario("paper")
    };
    let mut s = common::sim_with_vehicle(&cfg, "vehicles/front-mic.toml").unwrap();
    let clock = ManualClock::new(1_000 * MS);
    let mut bus = MemBus::new();
    let mut truth = LastTruth::default();
    let mut tx = E2eSender::<TorqueCommand>::new();
    // warm-up: one cycle (the bus double's queues)
    let f = tx.encode(&TorqueCommand::default(), clock.now_ns());
    bus.inject(f);
    s.cycle(&PlantTick::at(clock.now_ns()), &clock, &mut bus, &mut truth);
    bus.tx.borrow_mut().clear();
    clock.advance_ns(MS);
    let mut phases = [false; 4];
    let n = allocations(|| {
        for _ in 0..5_000 {
            let now = clock.now_ns();
            let f = tx.encode(
                &TorqueCommand {
                    torque_request: 200.0,
                    enable: true,
                },
                now,
            );
            bus.inject(f);
            s.cycle(&PlantTick::at(now), &clock, &mut bus, &mut truth);
            bus.tx.borrow_mut().clear();
            clock.advance_ns(MS);
            phases[s.phase() as usize] = true;
        }
    });
    assert_eq!(n, 0, "{n} allocations");
    assert!(phases.iter().all(|&p| p), "every phase seen: {phases:?}");
}
