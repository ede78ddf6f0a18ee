//! SocketCAN tests on a real (virtual) interface. Built only with
//! `--features hil`; the HIL harness runs them where `vcan0` exists (a VM or
//! a kernel with CONFIG_CAN):
//!
//!     ip link add dev vcan0 type vcan && ip link set vcan0 up
//!     cargo test -p grip-io --features hil --test vcan
//!
//! The interface name comes from `GRIP_VCAN_IFACE` (default `vcan0`). These
//! tests FAIL (never skip) when the interface or AF_CAN is missing.

use std::time::{Duration, Instant};

use grip_io::can::protocol::*;
use grip_io::can::{
    BusKind, CanBus, CanBusConfig, CanError, RxFilter, SocketCanBus, Transport, af_can_available,
    open_bus,
};
use grip_io::ipc::IpcNode;
use grip_msgs::{CanFrame, can_dir};

/// Counts allocations per thread, so tests running in parallel in this
/// binary never pollute a count.
#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

fn iface() -> String {
    std::env::var("GRIP_VCAN_IFACE").unwrap_or_else(|_| "vcan0".into())
}

/// A bus that receives every frame (no receive filter).
fn open() -> SocketCanBus {
    open_for(RxFilter::All)
}

fn open_for(rx: RxFilter) -> SocketCanBus {
    SocketCanBus::open(&iface(), 0, rx).unwrap_or_else(|e| panic!("HIL test needs SocketCAN: {e}"))
}

#[test]
fn af_can_is_available() {
    af_can_available().expect("the HIL kernel must have AF_CAN");
}

#[test]
fn protocol_frames_cross_the_kernel_bus() {
    let mut tcs = open();
    let mut inv = open();
    // drain anything left from other tests on the shared interface
    while inv.try_recv().unwrap().is_some() {}
    while tcs.try_recv().unwrap().is_some() {}
    let mut tx = E2eSender::<TorqueCommand>::new();
    let mut rx = ProtocolRx::for_inverter();
    for i in 0..200 {
        let cmd = TorqueCommand {
            torque_request: f64::from(i) - 100.0,
            enable: i % 2 == 0,
        };
        tcs.send(&tx.encode(&cmd, 0)).unwrap();
        let f = loop {
            let f = inv
                .recv_timeout(Duration::from_secs(2))
                .unwrap()
                .expect("frame within 2 s");
            if f.id == TORQUE_COMMAND.id {
                break f;
            }
        };
        assert_eq!(f.direction, can_dir::RX);
        match rx.receive(&f, f.stamp_ns) {
            Ok(Some(InverterMsg::TorqueCommand(c))) => {
                assert!((c.torque_request - cmd.torque_request).abs() < 0.051);
                assert_eq!(c.enable, cmd.enable);
            }
            other => panic!("frame {i}: {other:?}"),
        }
    }
    assert_eq!(rx.faults().total(), 0);
}

#[test]
fn sender_does_not_receive_its_own_frames() {
    let mut a = open();
    let mut b = open();
    while a.try_recv().unwrap().is_some() {}
    a.send(&CanFrame::new(0x321, &[1, 2, 3])).unwrap();
    // other tests of this binary share vcan0: skip their frames
    let t0 = Instant::now();
    let got = loop {
        let f = b
            .recv_timeout(Duration::from_secs(1))
            .unwrap()
            .expect("b receives");
        if f.id == 0x321 || t0.elapsed() > Duration::from_secs(5) {
            break f;
        }
    };
    assert_eq!((got.id, got.payload()), (0x321, &[1u8, 2, 3][..]));
    // a sees nothing of its own (other tests may send other ids)
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_millis(50) {
        if let Some(f) = a.recv_timeout(Duration::from_millis(10)).unwrap() {
            assert_ne!(f.id, 0x321, "own frame echoed back");
        }
    }
}

#[test]
fn recv_timeout_honours_the_timeout() {
    let mut a = open();
    let t0 = Instant::now();
    // other tests may talk; only check the call returns within bounds
    let _ = a.recv_timeout(Duration::from_millis(20)).unwrap();
    assert!(t0.elapsed() < Duration::from_secs(1));
}

#[test]
fn invalid_frames_are_rejected_before_the_kernel() {
    let mut a = open();
    assert!(matches!(
        a.send(&CanFrame::new(0x800, &[0])),
        Err(CanError::InvalidFrame { .. })
    ));
    let mut f = CanFrame::new(0x10, &[0; 8]);
    f.dlc = 9;
    assert!(a.send(&f).is_err());
}

#[test]
fn missing_interface_error_names_it_and_the_fix() {
    let e = SocketCanBus::open("gripnope9", 0, RxFilter::All)
        .unwrap_err()
        .to_string();
    assert!(e.contains("gripnope9") && e.contains("ip link add"), "{e}");
}

#[test]
fn auto_transport_chooses_socketcan_when_available() {
    let node = IpcNode::create("vcan-auto").unwrap();
    let cfg = CanBusConfig {
        transport: Transport::Auto,
        interface: iface(),
        sim_bus: None,
        bus_id: 0,
        ..CanBusConfig::default()
    };
    assert_eq!(
        open_bus(&cfg, &node, RxFilter::Role(Role::Tcs))
            .unwrap()
            .kind(),
        BusKind::SocketCan
    );
}

/// A bus opened for a role gets the kernel's receive filter
/// (`CAN_RAW_FILTER`): of the frames a second, plain raw socket writes on
/// the interface, the filtered bus receives the role's protocol ids, in
/// order, and none of the foreign ones (0x7FF, 0x000, 0x5A5, extended ids,
/// one of them numbered like a grip id, a remote frame of a grip id, the
/// other role's message), while an unfiltered bus on the same interface
/// receives every one of them. The other tests of this binary share the
/// interface and send 0x100, 0x321 and 0x555 meanwhile: whatever it
/// receives, the filtered bus never gets an id its role does not receive.
#[test]
fn a_bus_opened_for_a_role_receives_only_its_ids_through_the_kernel_filter() {
    use socketcan::{
        CanFrame as SockFrame, CanSocket, EmbeddedFrame, ExtendedId, Frame as _, Socket, StandardId,
    };
    let writer = CanSocket::open(&iface()).expect("second raw socket");
    let std_id = |id: u32| StandardId::new(id as u16).unwrap();
    let ext_id = |id: u32| ExtendedId::new(id).unwrap();
    for (k, role) in [Role::Tcs, Role::Inverter].into_iter().enumerate() {
        let mut filtered = open_for(RxFilter::Role(role));
        let mut all = open();
        // this round's frames carry a mark in their last byte
        let mark = 0xA0 + k as u8;
        let data = |n: u8| [n, 0, 0, 0, 0, 0, 0, mark];
        let mut sent: Vec<(SockFrame, bool)> = Vec::new();
        let mut push = |f: SockFrame, passes: bool| sent.push((f, passes));
        push(SockFrame::new(std_id(0x7FF), &data(1)).unwrap(), false);
        push(
            SockFrame::new(ext_id(0x1ABC_DEF0), &data(2)).unwrap(),
            false,
        );
        push(
            SockFrame::new(ext_id(MOTOR_STATUS.id), &data(3)).unwrap(),
            false,
        );
        push(
            SockFrame::new(ext_id(TORQUE_COMMAND.id), &data(4)).unwrap(),
            false,
        );
        push(
            SockFrame::new_remote(std_id(WHEEL_SPEEDS.id), 8).unwrap(),
            false,
        );
        push(
            SockFrame::new_remote(std_id(TORQUE_COMMAND.id), 8).unwrap(),
            false,
        );
        push(SockFrame::new(std_id(0x000), &data(5)).unwrap(), false);
        for (n, m) in MESSAGES.iter().enumerate() {
            push(
                SockFrame::new(std_id(m.id), &data(10 + n as u8)).unwrap(),
                m.receiver == role,
            );
        }
        push(SockFrame::new(std_id(0x5A5), &data(6)).unwrap(), false);
        push(SockFrame::new(std_id(0x7FF), &data(7)).unwrap(), false);
        for (f, _) in &sent {
            writer.write_frame(f).expect("write on the interface");
        }
        let want: Vec<(u32, u8)> = sent
            .iter()
            .filter(|(_, p)| *p)
            .map(|(f, _)| (f.raw_id(), f.data()[0]))
            .collect();
        assert!(!want.is_empty());
        // the filtered bus: the role's frames of this round, nothing foreign
        let mut got = Vec::new();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(3) {
            let Some(f) = filtered.recv_timeout(Duration::from_millis(200)).unwrap() else {
                if got.len() >= want.len() {
                    break;
                }
                continue;
            };
            assert!(
                role.receives_id(f.id) && f.flags == 0,
                "{role:?}: received id {:#x} flags {:#x}, which the filter must drop",
                f.id,
                f.flags
            );
            if f.data[7] == mark && f.dlc == 8 {
                got.push((f.id, f.data[0]));
            }
        }
        assert_eq!(got, want, "{role:?}: the role's frames, in order");
        // the unfiltered bus saw every frame written (the remote frames are
        // not data: SocketCanBus does not hand those over to anyone)
        let mut seen = 0;
        let t0 = Instant::now();
        let n_data = sent.iter().filter(|(f, _)| !f.is_remote_frame()).count();
        while seen < n_data && t0.elapsed() < Duration::from_secs(3) {
            if let Some(f) = all.recv_timeout(Duration::from_millis(200)).unwrap()
                && f.dlc == 8
                && f.data[7] == mark
            {
                seen += 1;
            }
        }
        assert_eq!(seen, n_data, "{role:?}: frames on the bus without a filter");
    }
}

/// SocketCAN send / try_recv / recv_timeout allocate nothing (counted on
/// this test's thread only).
#[test]
fn socketcan_hot_path_allocates_nothing() {
    let mut a = open();
    let mut b = open();
    let f = CanFrame::new(0x555, &[9; 8]);
    for _ in 0..10 {
        a.send(&f).unwrap();
        b.recv_timeout(Duration::from_millis(100)).unwrap();
    }
    let mut got = 0;
    let n = grip_testkit::allocations(|| {
        for _ in 0..500 {
            a.send(&f).unwrap();
            while let Some(r) = b.recv_timeout(Duration::from_millis(100)).unwrap() {
                if r.id == 0x555 {
                    got += 1;
                    break;
                }
            }
            let _ = b.try_recv().unwrap();
        }
    });
    assert_eq!(got, 500);
    assert_eq!(n, 0);
}

/// A bus monitor (the recorder's bus log, `SocketCanBus::open_monitor`):
/// it reads every frame kind another socket writes (11-bit, 29-bit,
/// remote; flags and payload as sent), each stamped with the kernel's
/// receive time (between the writer's clock readings around its write,
/// although it reads them 50 ms later: not the time of the read), counts
/// what the kernel dropped on its full receive queue (`SO_RXQ_OVFL`), and
/// its read allocates nothing.
#[test]
fn a_monitor_reads_every_frame_kind_with_kernel_stamps_counts_drops_and_allocates_nothing() {
    use grip_msgs::can_flags;
    use socketcan::{
        CanFrame as SockFrame, CanSocket, EmbeddedFrame, ExtendedId, Socket, StandardId,
    };
    let writer = CanSocket::open(&iface()).expect("second raw socket");
    let mut mon = SocketCanBus::open_monitor(&iface(), 3, &[]).expect("monitor");
    let mark = 0xC7;
    let frames = [
        SockFrame::new(StandardId::new(0x3E9).unwrap(), &[1, 2, 3, mark]).unwrap(),
        SockFrame::new(ExtendedId::new(0x18DA_F110).unwrap(), &[4, mark]).unwrap(),
        SockFrame::new_remote(StandardId::new(0x7AB).unwrap(), 4).unwrap(),
        SockFrame::new(StandardId::new(0x000).unwrap(), &[mark]).unwrap(),
    ];
    let mut windows = Vec::new();
    for f in &frames {
        let before = grip_io::clock::monotonic_now_ns();
        writer.write_frame(f).expect("write");
        windows.push((before, grip_io::clock::monotonic_now_ns()));
    }
    std::thread::sleep(Duration::from_millis(50));
    let mut got = Vec::new();
    let t0 = Instant::now();
    while got.len() < frames.len() && t0.elapsed() < Duration::from_secs(3) {
        match mon.try_recv_monitor().unwrap() {
            Some(f) if f.flags & can_flags::RTR != 0 && f.id == 0x7AB => got.push(f),
            Some(f) if f.dlc > 0 && f.payload().last() == Some(&mark) => got.push(f),
            Some(_) => {} // another test's frame
            None => std::thread::sleep(Duration::from_millis(1)),
        }
    }
    assert_eq!(got.len(), frames.len(), "{got:?}");
    let want = [
        (0x3E9, 0, 4, vec![1, 2, 3, mark]),
        (0x18DA_F110, can_flags::EXTENDED, 2, vec![4, mark]),
        (0x7AB, can_flags::RTR, 4, vec![0, 0, 0, 0]),
        (0x000, 0, 1, vec![mark]),
    ];
    for (k, (f, (id, flags, dlc, data))) in got.iter().zip(want).enumerate() {
        assert_eq!(
            (f.id, f.flags, f.dlc, f.bus),
            (id, flags, dlc, 3),
            "frame {k}"
        );
        assert_eq!(&f.data[..usize::from(dlc)], &data[..], "frame {k}");
        let (before, after) = windows[k];
        // the kernel stamped it in the write (vcan receives in the
        // sender's call); a stamp at read would be >= 50 ms later
        assert!(
            f.stamp_ns + 200_000 >= before && f.stamp_ns <= after + 200_000,
            "frame {k} stamped {} ns, written in {before}..{after}",
            f.stamp_ns
        );
    }
    assert!(mon.kernel_stamped() >= 4);
    assert_eq!(mon.rx_overflows(), 0);

    // allocation-free reads
    let f = SockFrame::new(StandardId::new(0x555).unwrap(), &[9; 8]).unwrap();
    let mut n_read = 0;
    let n = grip_testkit::allocations(|| {
        for _ in 0..300 {
            writer.write_frame(&f).unwrap();
            while let Some(r) = mon.try_recv_monitor().unwrap() {
                n_read += usize::from(r.id == 0x555);
            }
        }
    });
    assert_eq!(n, 0, "allocations in the monitor's read");
    assert!(n_read >= 300, "{n_read} of 300 read");

    // a monitor excluding 0x555 (as the recorder excludes grip's ids): the
    // kernel drops that 11-bit data frame, not the 29-bit one of that number
    let mut ex = SocketCanBus::open_monitor(&iface(), 0, &[0x555]).expect("monitor");
    writer.write_frame(&f).unwrap();
    let ext = SockFrame::new(ExtendedId::new(0x555).unwrap(), &[0xE5]).unwrap();
    writer.write_frame(&ext).unwrap();
    std::thread::sleep(Duration::from_millis(20));
    let mut seen = Vec::new();
    while let Some(r) = ex.try_recv_monitor().unwrap() {
        if r.id == 0x555 {
            seen.push(r.flags);
        }
    }
    assert_eq!(
        seen,
        vec![can_flags::EXTENDED],
        "the excluded id reached the monitor"
    );

    // a queue that overflows: frames written without reading beyond its
    // size are counted as the kernel's drops once a frame behind them is read
    let flood = 20_000u32;
    for k in 0..flood {
        let b = k.to_le_bytes();
        let f = SockFrame::new(
            ExtendedId::new(0x1F00_0000).unwrap(),
            &[b[0], b[1], b[2], 0xEE],
        )
        .unwrap();
        // vcan never blocks; a full *writer* queue (ENOBUFS) is retried
        while writer.write_frame(&f).is_err() {
            std::thread::sleep(Duration::from_micros(200));
        }
    }
    let mut read = 0u32;
    while let Some(r) = mon.try_recv_monitor().unwrap() {
        read += u32::from(r.id == 0x1F00_0000 && r.flags == can_flags::EXTENDED);
    }
    let dropped = mon.rx_overflows();
    println!("monitor flood: {flood} written, {read} read, {dropped} dropped by the kernel");
    assert!(dropped > 0 && read < flood, "no overflow in {flood} frames");
    assert!(
        u64::from(read) + dropped >= u64::from(flood),
        "{read} read + {dropped} dropped < {flood} written"
    );
}

/// A bus opened for the loops (`SocketCanBus::open`, what tcs-loop and
/// plant-sim read through `try_recv`) stamps each frame with the kernel's
/// receive time too, not the time it was read: frames written, then read
/// 50 ms later (as by a loop that was stalled), carry stamps between the
/// writer's clock readings around each write, in order; a remote frame in
/// between is skipped (not part of the protocol); `recv_timeout` returns a
/// frame that arrives while it waits, stamped at its arrival. Until
/// 2026-12-07 these were stamped at read: a CAN log showed a stall's
/// frames all at its end.
#[test]
fn a_loop_bus_stamps_frames_with_their_arrival_not_their_read() {
    use socketcan::{CanFrame as SockFrame, CanSocket, EmbeddedFrame, Socket, StandardId};
    let writer = CanSocket::open(&iface()).expect("second raw socket");
    let mut bus = open();
    while bus.try_recv().unwrap().is_some() {}
    let mark = 0x5D;
    let frames = [
        SockFrame::new(StandardId::new(0x3EA).unwrap(), &[1, mark]).unwrap(),
        SockFrame::new_remote(StandardId::new(0x3EA).unwrap(), 2).unwrap(),
        SockFrame::new(StandardId::new(0x3EB).unwrap(), &[2, mark]).unwrap(),
        SockFrame::new(StandardId::new(0x3EC).unwrap(), &[3, mark]).unwrap(),
    ];
    let mut windows = Vec::new();
    for f in &frames {
        let before = grip_io::clock::monotonic_now_ns();
        writer.write_frame(f).expect("write");
        windows.push((before, grip_io::clock::monotonic_now_ns()));
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(50));
    let read_from = grip_io::clock::monotonic_now_ns();
    let mut got = Vec::new();
    let t0 = Instant::now();
    while got.len() < 3 && t0.elapsed() < Duration::from_secs(3) {
        match bus.try_recv().unwrap() {
            Some(f) if (0x3EA..=0x3EC).contains(&f.id) => got.push(f),
            Some(_) => {} // another test's frame
            None => std::thread::sleep(Duration::from_millis(1)),
        }
    }
    assert_eq!(
        got.iter().map(|f| (f.id, f.dlc)).collect::<Vec<_>>(),
        [(0x3EA, 2), (0x3EB, 2), (0x3EC, 2)],
        "the data frames, the remote frame skipped: {got:?}"
    );
    for (f, k) in got.iter().zip([0, 2, 3]) {
        let (before, after) = windows[k];
        assert!(
            f.stamp_ns + 200_000 >= before && f.stamp_ns <= after + 200_000,
            "frame {:#x} stamped {} ns, written in {before}..{after}, read from {read_from}",
            f.id,
            f.stamp_ns
        );
        assert!(f.stamp_ns + 40_000_000 < read_from, "{f:?}");
    }
    assert!(bus.kernel_stamped() >= 3);

    // a frame that arrives while recv_timeout waits
    let w = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(30));
        let before = grip_io::clock::monotonic_now_ns();
        let f = SockFrame::new(StandardId::new(0x3ED).unwrap(), &[4, mark]).unwrap();
        writer.write_frame(&f).expect("write");
        (before, grip_io::clock::monotonic_now_ns())
    });
    let t0 = Instant::now();
    let f = loop {
        match bus.recv_timeout(Duration::from_secs(2)).unwrap() {
            Some(f) if f.id == 0x3ED => break f,
            Some(_) => {}
            None => panic!("no frame within 2 s"),
        }
    };
    let (before, after) = w.join().unwrap();
    assert!(t0.elapsed() < Duration::from_secs(1));
    assert!(
        f.stamp_ns + 200_000 >= before && f.stamp_ns <= after + 200_000,
        "stamped {} ns, written in {before}..{after}",
        f.stamp_ns
    );
}
