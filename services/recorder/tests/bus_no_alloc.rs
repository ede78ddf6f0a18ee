//! The recorder's bus path on its receive thread allocates nothing per
//! frame: `BusTap::pass` (the monitor's read, the "foreign" filter against
//! the active protocol, the counters, the queue's `offer`) over frames of
//! the simulated bus, counted by grip-testkit's counting allocator on this
//! thread only. (The read on SocketCAN, `try_recv_monitor`, is counted the
//! same way in grip-io's HIL test `vcan.rs`; sending on the simulated bus
//! allocates inside iceoryx2, which is why the frames are sent outside the
//! count.)

use std::sync::atomic::AtomicU64;
use std::time::Instant;

use grip_io::can::{CanBus, CanBusConfig, SimBus, Transport};
use grip_io::ipc::IpcNode;
use grip_msgs::{CanFrame, can_flags};
use grip_recorder::bus::{BusSetup, BusTap};
use grip_recorder::config::BusRecord;
use grip_recorder::cycle::{Msg, queue};
use grip_testkit::allocations;

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

#[test]
fn the_bus_path_of_the_receive_thread_allocates_nothing() {
    let instance = format!("recbusalloc{}", std::process::id());
    // SAFETY: set before any thread of this test process reads the
    // environment (the first iceoryx2 call below reads it once).
    unsafe { std::env::set_var(grip_io::ipc::INSTANCE_ENV, &instance) };
    let node = IpcNode::create("rec-bus-alloc").unwrap();
    let can = CanBusConfig {
        transport: Transport::Sim,
        interface: "allocbus".into(),
        ..CanBusConfig::default()
    };
    let mut tap = BusTap::new(BusSetup {
        can,
        mode: BusRecord::Foreign,
        under_systemd: false,
    });
    tap.poll_open(&node, Instant::now());
    assert!(
        tap.stats().transport.is_some(),
        "the tap did not open the bus"
    );
    let mut ecu = SimBus::open(&node, "allocbus", 0).unwrap();
    let (q, rx, _depth, _high) = queue(1 << 16);
    let beat = AtomicU64::new(0);
    let mut ext = CanFrame::new(0x18DA_F110, &[1, 2, 3]);
    ext.flags = can_flags::EXTENDED;
    let frames = [
        CanFrame::new(0x3E9, &[9; 8]),
        CanFrame::new(0x120, &[1; 8]), // grip's WheelSpeeds: skipped
        ext,
    ];
    // warm-up: the subscriber builds its connections on its first receive
    for f in &frames {
        ecu.send(f).unwrap();
    }
    let mut n = 0;
    while n < 3 {
        n += tap.pass(&q, 4096, &beat);
    }
    const ROUNDS: usize = 20;
    let mut read = 0;
    let mut allocs = 0;
    for _ in 0..ROUNDS {
        // 300 frames a round: within the bus subscriber's 1024
        for k in 0..300 {
            ecu.send(&frames[k % 3]).unwrap();
        }
        allocs += allocations(|| {
            read += tap.pass(&q, 4096, &beat);
        });
        while rx.try_recv().is_ok() {}
    }
    assert_eq!(read, ROUNDS * 300, "frames read by the tap");
    assert_eq!(allocs, 0, "allocations on the bus path");
    let s = tap.stats();
    assert_eq!(s.received, 3 + ROUNDS as u64 * 300);
    assert_eq!(
        s.skipped_own,
        1 + ROUNDS as u64 * 100,
        "grip's frames skipped"
    );
    assert_eq!(s.queue_dropped, 0);
    // what was queued is the foreign frames, as bus records
    for f in &frames {
        ecu.send(f).unwrap();
    }
    while tap.pass(&q, 4096, &beat) == 0 {}
    let queued: Vec<Msg> = rx.try_iter().collect();
    assert_eq!(queued.len(), 2, "{queued:?}");
    assert!(matches!(queued[0], Msg::Bus(b) if b.id == 0x3E9 && b.flags == 0));
    assert!(
        matches!(queued[1], Msg::Bus(b) if b.id == 0x18DA_F110 && b.flags == can_flags::EXTENDED)
    );

    // a queue half full (a writer far behind): the bus's frames are
    // dropped and counted, the other half stays the loops'
    let (q2, rx2, _, _) = queue(1024);
    for _ in 0..512 {
        assert!(q2.offer(Msg::Cycle(grip_msgs::CycleRecord::zeroed())));
    }
    let before = tap.stats().queue_dropped;
    for f in &frames {
        ecu.send(f).unwrap();
    }
    while tap.pass(&q2, 4096, &beat) == 0 {}
    assert_eq!(
        tap.stats().queue_dropped - before,
        2,
        "foreign frames dropped"
    );
    assert_eq!(
        rx2.try_iter().count(),
        512,
        "only the loops' messages queued"
    );
}
