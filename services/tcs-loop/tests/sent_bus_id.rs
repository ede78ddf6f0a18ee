//! The commands tcs-loop sends go on the CAN log with the number of the bus
//! they were sent on, `can.toml`'s `bus_id`, as the frames it receives do
//! (the bus stamps those): over a simulated bus of `bus_id = 3`, every
//! frame of the log, sent or received, says bus 3. Until 2026-12-07 a sent
//! command was logged with bus 0 whatever `bus_id` said.
//!
//! One test in this file: it installs the process's protocol (`load`) and
//! chooses the iceoryx2 namespace.

mod common;

use common::CONFIG;
use grip_io::can::protocol::{E2eSender, MotorStatus};
use grip_io::can::{BusKind, CanBus, RxFilter, SimBus, open_bus};
use grip_io::clock::{Clock, MonotonicClock};
use grip_io::ipc::IpcNode;
use grip_io::service::ConfigArgs;
use grip_msgs::{CanFrame, CycleRecord, can_dir};
use grip_tcs_loop::{CycleTick, NoRoad, Options, RecordSink};

/// Every CAN log copy, in order.
#[derive(Default)]
struct Frames(Vec<CanFrame>);

impl RecordSink for Frames {
    fn cycle(&mut self, _: &CycleRecord) {}
    fn can(&mut self, f: &CanFrame) {
        self.0.push(*f);
    }
}

#[test]
fn sent_frames_carry_the_bus_id_of_the_bus_they_went_on() {
    // SAFETY: the only test function of this process; set before any
    // iceoryx2 use or other thread.
    unsafe {
        std::env::set_var(
            grip_io::ipc::INSTANCE_ENV,
            format!("tcs_sent_bus_id_{}", std::process::id()),
        )
    };
    let t = grip_testkit::svc::copy_config(&CONFIG);
    let dir = t.path();
    let name = format!("tcs-sent-bus-id-{}", std::process::id());
    let shipped = std::fs::read_to_string(dir.join("can.toml")).unwrap();
    let mut can = shipped.clone();
    for (from, to) in [
        ("transport = \"auto\"", "transport = \"sim\"".to_owned()),
        ("sim_bus = \"vcan0\"", format!("sim_bus = {name:?}")),
        ("bus_id = 0", "bus_id = 3".to_owned()),
    ] {
        assert!(can.contains(&format!("\n{from}\n")), "{from}: {shipped}");
        can = can.replacen(&format!("\n{from}\n"), &format!("\n{to}\n"), 1);
    }
    std::fs::write(dir.join("can.toml"), can).unwrap();

    // the service's start-up: configuration, loop, bus
    let cfg = grip_tcs_loop::load(&Options {
        config: ConfigArgs::in_dir(dir),
        ..Options::default()
    })
    .unwrap();
    assert_eq!(cfg.can.bus_id, 3);
    let mut lp = grip_tcs_loop::build(&cfg).unwrap();
    assert_eq!(lp.bus_id(), 3);
    let node = IpcNode::create("tcs-sent-bus-id-test").unwrap();
    let mut bus = open_bus(&cfg.can, &node, RxFilter::Role(grip_tcs_loop::ROLE)).unwrap();
    assert_eq!(bus.kind(), BusKind::Sim);

    // the inverter on the same bus: a MotorStatus before each cycle
    let mut inverter = SimBus::open(&node, &name, 3).unwrap();
    let mut status = E2eSender::<MotorStatus>::new();
    let clock = MonotonicClock;
    let mut sink = Frames::default();
    for _ in 0..3 {
        let ms = MotorStatus {
            ready: true,
            ..MotorStatus::default()
        };
        inverter.send(&status.encode(&ms, clock.now_ns())).unwrap();
        lp.cycle(
            &CycleTick::at(clock.now_ns()),
            &clock,
            &mut bus,
            &mut NoRoad,
            &mut sink,
        );
    }
    assert!(lp.shutdown(clock.now_ns(), &mut bus, &mut sink), "sent");

    // the log: three received MotorStatus, four sent commands, all bus 3
    let dirs: Vec<u8> = sink.0.iter().map(|f| f.direction).collect();
    let (rx, tx) = (can_dir::RX, can_dir::TX);
    assert_eq!(dirs, [rx, tx, rx, tx, rx, tx, tx], "{:?}", sink.0);
    for f in &sink.0 {
        assert_eq!(f.bus, 3, "{f:?}");
    }
    // and the commands went over the bus to the inverter
    let mut got = Vec::new();
    while let Some(f) = inverter.try_recv().unwrap() {
        got.push(f);
    }
    let sent: Vec<_> = sink.0.iter().filter(|f| f.direction == tx).collect();
    assert_eq!(got.len(), sent.len(), "{got:?}");
    for (g, s) in got.iter().zip(sent) {
        assert_eq!((g.id, g.data), (s.id, s.data));
    }
}
