//! The tcs-loop cycle allocates nothing after warm-up: a counting global
//! allocator (current thread only) around 20 000 cycles of every path —
//! normal control with ARTE estimates, corrupted frames, a sensor outage
//! with safe state and recovery — for each controller, with and without
//! the road knowledge of `grip sim`'s "with ARTE" path (`RoadAware`: the
//! preview queue fed with estimates of changing roads, some with arte's
//! odometer stamps and some without, the belief, the torque cap), the MFC
//! with its noise low-pass on the speed error.
//!
//! The ports here are in-memory doubles. With the real iceoryx2 ports each
//! *publish* allocates one 48-byte Arc inside iceoryx2 0.10 (pinned by
//! `crates/io/tests/no_alloc.rs`); grip's own code adds none.

mod common;

use grip_testkit::allocations;

use common::{LastSink, MemBus, SetRoad};
use grip_io::can::protocol::{DriverDemand, E2eSender, MotorStatus, WheelSpeeds};
use grip_io::clock::{Clock, ManualClock};
use grip_msgs::{CanFrame, RoadEstimate};
use grip_physics::VehicleParams;
use grip_tcs::{ControllerKind, ControllersConfig};
use grip_tcs_loop::{CycleTick, SafetyConfig, TcsLoop};

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

struct Rig {
    clock: ManualClock,
    bus: MemBus,
    sink: LastSink,
    road: SetRoad,
    lp: TcsLoop,
    ws: E2eSender<WheelSpeeds>,
    ms: E2eSender<MotorStatus>,
    dd: E2eSender<DriverDemand>,
    k: u64,
    caps: u64,
    /// The most road estimates a cycle took.
    most_taken: u8,
}

impl Rig {
    fn step(&mut self) {
        let now = self.clock.now_ns();
        let k = self.k;
        let outage = (5_000..5_030).contains(&(k % 10_000));
        let omega = 10.0 + (k % 500) as f64 * 0.01;
        if !outage {
            let f = self.ws.encode(
                &WheelSpeeds {
                    driven_valid: true,
                    ref_valid: true,
                    omega_driven: omega,
                    omega_ref: 9.8,
                },
                now,
            );
            self.bus.inject(f);
        }
        let f = self.ms.encode(
            &MotorStatus {
                ready: true,
                torque_actual: 120.0,
                motor_speed: omega,
                ..MotorStatus::default()
            },
            now,
        );
        self.bus.inject(f);
        if k.is_multiple_of(10) {
            let f = self.dd.encode(
                &DriverDemand {
                    tcs_enable: true,
                    torque_demand: 300.0,
                    ..DriverDemand::default()
                },
                now,
            );
            self.bus.inject(f);
        }
        if k % 1000 == 333 {
            // corrupted and unknown frames
            let mut f = self.ws.encode(&WheelSpeeds::default(), now);
            f.data[4] ^= 0xFF;
            self.bus.inject(f);
            self.bus.inject(CanFrame::new(0x7FF, &[0; 8]));
        }
        if k.is_multiple_of(100) {
            // asphalt, snow, gravel, stone in turn; every third without
            // odometer stamps (arte had no fresh cycle record)
            let names = ["asphalt", "snow", "gravel", "stone"];
            let name = names[(k / 700) as usize % names.len()];
            let x = self.lp.odometer();
            let (x_from, x_to) = if k.is_multiple_of(300) {
                (f64::NAN, f64::NAN)
            } else {
                (x - 0.3, x)
            };
            let e = RoadEstimate {
                stamp_ns: now,
                frame_t0_ns: now.saturating_sub(100 * MS),
                frame_t1_ns: now,
                class_name: grip_msgs::name_to_bytes(name),
                x_from,
                x_to,
                class_index: 1,
                confidence: 0.9,
                lambda_opt: 0.17,
                mu_peak: 1.17,
                alpha: 0.83,
                ..RoadEstimate::zeroed()
            };
            self.road.next = Some(e);
            if k.is_multiple_of(500) {
                // a burst (arte caught up): four more frames, heard before
                for i in 1..=4 {
                    let back = 0.1 * f64::from(i);
                    self.road.burst.push_back(RoadEstimate {
                        x_from: e.x_from - back,
                        x_to: e.x_to - back,
                        ..e
                    });
                }
            }
        }
        self.lp.cycle(
            &CycleTick::at(now),
            &self.clock,
            &mut self.bus,
            &mut self.road,
            &mut self.sink,
        );
        self.bus.tx.borrow_mut().clear();
        if self.lp.last_record().torque_cap.is_finite() {
            self.caps += 1;
        }
        self.most_taken = self.most_taken.max(self.lp.last_record().roads_taken);
        self.clock.advance_ns(MS);
        self.k += 1;
    }
}

#[test]
fn cycle_allocates_nothing_after_warm_up() {
    let dir = grip_config::ConfigDir::new(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config"),
    );
    let roads = dir.roads().unwrap();
    let table = dir.road_table(&roads).unwrap();
    let (front_mic, _) = grip_config::load_vehicle(dir.file("vehicles/front-mic.toml")).unwrap();
    let controllers = ControllersConfig::default();
    // The MFC runs with its noise low-pass (its state is part of the proof).
    assert!(controllers.mfc.tau_noise > 0.0);
    for (kind, aware) in ControllerKind::ALL
        .into_iter()
        .flat_map(|k| [(k, false), (k, true)])
    {
        let vehicle = if aware {
            front_mic
        } else {
            VehicleParams::default()
        };
        let mut lp =
            TcsLoop::new(kind, true, &controllers, &vehicle, &SafetyConfig::default()).unwrap();
        if aware {
            lp = lp
                .with_road_aware(&roads, table.clone(), &controllers, &vehicle)
                .unwrap();
        }
        assert_eq!(lp.road_aware(), aware);
        let mut r = Rig {
            clock: ManualClock::new(1_000 * MS),
            bus: MemBus::new(),
            sink: LastSink::default(),
            road: SetRoad {
                burst: std::collections::VecDeque::with_capacity(8),
                ..SetRoad::default()
            },
            lp,
            ws: E2eSender::new(),
            ms: E2eSender::new(),
            dd: E2eSender::new(),
            k: 0,
            caps: 0,
            most_taken: 0,
        };
        for _ in 0..1_000 {
            r.step();
        }
        let n = allocations(|| {
            for _ in 0..20_000 {
                r.step();
            }
        });
        assert_eq!(n, 0, "{kind}: {n} allocations in 20 000 cycles");
        // the paths were exercised
        assert!(
            r.lp.safe_entries() >= 2,
            "{kind}: outages entered the safe state"
        );
        let f = r.lp.last_record().faults;
        assert!(f.crc >= 20 && f.unknown_id >= 20, "{kind}: {f:?}");
        assert!(r.sink.records >= 21_000);
        assert_eq!(r.most_taken, 5, "{kind}: bursts of five estimates taken");
        assert!(r.lp.odometer() > 40.0, "{kind}: the odometer runs");
        if aware {
            let rec = r.lp.last_record();
            assert!(
                rec.belief_road != grip_msgs::NO_CLASS && rec.belief_prob > 0.0,
                "{kind}: the road knowledge stepped: {rec:?}"
            );
            assert!(r.caps > 0, "{kind}: the torque was capped in some cycles");
        }
    }
}
