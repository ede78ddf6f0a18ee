//! Simulated CAN bus and iceoryx2 ports within one process (threads).

use std::time::Duration;

use grip_io::can::protocol::*;
use grip_io::can::{
    BusKind, CanBus, CanBusConfig, RxFilter, SimBus, Transport, open_bus, open_bus_as,
};
use grip_io::ipc::{IpcNode, SubscriberMode};
use grip_msgs::{CanFrame, CycleRecord, can_dir, can_flags};

fn unique(name: &str) -> String {
    format!("test_{}_{}", name, std::process::id())
}

#[test]
fn two_threads_exchange_protocol_frames_both_ways() {
    let bus = unique("twothreads");
    let b2 = bus.clone();
    let node = IpcNode::create("simbus-test-a").unwrap();
    let mut a = SimBus::open(&node, &bus, 0).unwrap();
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    // "inverter" thread: answers every TorqueCommand with a MotorStatus
    let h = std::thread::spawn(move || {
        let node = IpcNode::create("simbus-test-b").unwrap();
        let mut b = SimBus::open(&node, &b2, 0).unwrap();
        ready_tx.send(()).unwrap();
        let mut rx = ProtocolRx::for_inverter();
        let mut tx = E2eSender::<MotorStatus>::new();
        let mut n = 0;
        while n < 100 {
            let Some(f) = b.recv_timeout(Duration::from_secs(5)).unwrap() else {
                panic!("inverter: no frame within 5 s after {n}");
            };
            assert_eq!(f.direction, can_dir::RX);
            if let Ok(Some(InverterMsg::TorqueCommand(c))) = rx.receive(&f, f.stamp_ns) {
                let s = MotorStatus {
                    ready: true,
                    torque_actual: c.torque_request,
                    ..MotorStatus::default()
                };
                b.send(&tx.encode(&s, 0)).unwrap();
                n += 1;
            }
        }
        rx.faults()
    });
    ready_rx.recv().unwrap();
    std::thread::sleep(Duration::from_millis(50));
    let mut tx = E2eSender::<TorqueCommand>::new();
    let mut rx = ProtocolRx::for_tcs();
    for i in 0..100 {
        let cmd = TorqueCommand {
            torque_request: f64::from(i) * 1.5,
            enable: true,
        };
        a.send(&tx.encode(&cmd, 0)).unwrap();
        // never our own frame back: the next frame must be the answer
        let f = a
            .recv_timeout(Duration::from_secs(5))
            .unwrap()
            .expect("answer within 5 s");
        match rx.receive(&f, f.stamp_ns) {
            Ok(Some(InverterMsg::MotorStatus(s))) => {
                assert!((s.torque_actual - cmd.torque_request).abs() < 0.051, "{i}");
            }
            other => panic!("cycle {i}: {other:?}"),
        }
    }
    let inv_faults = h.join().unwrap();
    assert_eq!(
        inv_faults.total(),
        0,
        "inverter saw E2E faults: {inv_faults:?}"
    );
    assert_eq!(rx.faults().total(), 0, "tcs saw E2E faults");
    assert_eq!(a.try_recv().unwrap(), None);
}

#[test]
fn recv_timeout_returns_none_in_time_when_bus_is_silent() {
    let node = IpcNode::create("simbus-test-silent").unwrap();
    let mut a = SimBus::open(&node, &unique("silent"), 0).unwrap();
    let t0 = std::time::Instant::now();
    assert_eq!(a.recv_timeout(Duration::from_millis(30)).unwrap(), None);
    let dt = t0.elapsed();
    assert!(dt >= Duration::from_millis(30), "{dt:?}");
    assert!(dt < Duration::from_secs(2), "{dt:?}");
}

#[test]
fn three_participants_each_see_the_others_frames() {
    let bus = unique("three");
    let node = IpcNode::create("simbus-test-three").unwrap();
    let mut p: Vec<SimBus> = (0..3)
        .map(|_| SimBus::open(&node, &bus, 0).unwrap())
        .collect();
    for (i, b) in p.iter_mut().enumerate() {
        b.send(&CanFrame::new(0x200 + i as u32, &[i as u8; 8]))
            .unwrap();
    }
    for (i, b) in p.iter_mut().enumerate() {
        let mut ids = Vec::new();
        while let Some(f) = b.try_recv().unwrap() {
            ids.push(f.id);
        }
        ids.sort();
        let want: Vec<u32> = (0..3)
            .filter(|&j| j != i)
            .map(|j| 0x200 + j as u32)
            .collect();
        assert_eq!(ids, want, "participant {i}");
    }
}

/// A frame is stamped when it is published (the simulated bus has no
/// delay: that is its arrival), whatever stamp the sender gave it, and a
/// receiver that reads it 50 ms later (a stalled loop) still sees when it
/// came, not when it read it; the stamp is on the bus, so every receiver
/// sees the same. Until 2026-12-07 the receiver stamped it at read.
#[test]
fn sim_bus_frames_carry_their_publish_time_not_their_read_time() {
    let bus = unique("stamps");
    let node = IpcNode::create("simbus-test-stamps").unwrap();
    let mut a = SimBus::open(&node, &bus, 0).unwrap();
    let mut b = SimBus::open(&node, &bus, 4).unwrap();
    let mut c = SimBus::open(&node, &bus, 5).unwrap();
    let mut sent = Vec::new();
    for k in 0..3u8 {
        let mut f = CanFrame::new(0x210 + u32::from(k), &[k; 8]);
        f.stamp_ns = 7; // the sender's stamp is not the bus's
        let before = grip_io::clock::monotonic_now_ns();
        a.send(&f).unwrap();
        sent.push((before, grip_io::clock::monotonic_now_ns()));
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(50));
    let read_from = grip_io::clock::monotonic_now_ns();
    for (r, bus_id) in [(&mut b, 4), (&mut c, 5)] {
        for (k, &(before, after)) in sent.iter().enumerate() {
            let f = r.try_recv().unwrap().expect("frame");
            assert_eq!(
                (f.id, f.bus, f.direction),
                (0x210 + k as u32, bus_id, can_dir::RX)
            );
            assert!(
                (before..=after).contains(&f.stamp_ns),
                "frame {k} stamped {}, published in {before}..{after}",
                f.stamp_ns
            );
            assert!(f.stamp_ns + 40_000_000 < read_from);
        }
        assert!(r.try_recv().unwrap().is_none());
    }
}

#[test]
fn sim_bus_rejects_oversized_dlc() {
    let node = IpcNode::create("simbus-test-dlc").unwrap();
    let mut a = SimBus::open(&node, &unique("dlc"), 0).unwrap();
    let mut f = CanFrame::new(1, &[0; 8]);
    f.dlc = 9;
    assert!(a.send(&f).is_err());
}

#[test]
fn auto_transport_falls_back_to_sim_without_the_interface() {
    let node = IpcNode::create("simbus-test-auto").unwrap();
    let cfg = CanBusConfig {
        transport: Transport::Auto,
        interface: "gripnonexist0".into(),
        sim_bus: Some(unique("auto")),
        bus_id: 3,
        ..CanBusConfig::default()
    };
    let mut bus = open_bus_as(&cfg, &node, false, RxFilter::Role(Role::Tcs)).unwrap();
    assert_eq!(bus.kind(), BusKind::Sim);
    let mut other = SimBus::open(&node, cfg.sim_bus_name(), 3).unwrap();
    other.send(&CanFrame::new(0x120, &[1; 8])).unwrap();
    let f = bus.try_recv().unwrap().unwrap();
    assert_eq!((f.id, f.bus), (0x120, 3));
    // SocketCAN forced: the error names the interface and the fix
    let forced = CanBusConfig {
        transport: Transport::Socketcan,
        ..cfg
    };
    let e = open_bus(&forced, &node, RxFilter::All)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("AF_CAN") || (e.contains("gripnonexist0") && e.contains("ip link add")),
        "{e}"
    );
}

/// As a systemd unit (the car) `auto` does not fall back to the simulated
/// bus, whose frames never reach an inverter: an error saying why and what
/// to set (systemd's Restart= then retries until the interface is up).
#[test]
fn auto_transport_does_not_fall_back_under_systemd() {
    let node = IpcNode::create("simbus-test-auto-unit").unwrap();
    let cfg = CanBusConfig {
        transport: Transport::Auto,
        interface: "gripnonexist1".into(),
        sim_bus: Some(unique("auto-unit")),
        bus_id: 0,
        ..CanBusConfig::default()
    };
    let e = open_bus_as(&cfg, &node, true, RxFilter::All)
        .unwrap_err()
        .to_string();
    assert!(e.contains("transport = \"auto\""), "{e}");
    assert!(e.contains("systemd unit"), "{e}");
    assert!(
        e.contains("AF_CAN") || e.contains("\"gripnonexist1\" does not exist"),
        "{e}"
    );
    assert!(e.contains("transport = \"socketcan\""), "{e}");
    // a simulated bus asked for by name is still one (a bench without CAN)
    let sim = CanBusConfig {
        transport: Transport::Sim,
        ..cfg
    };
    assert_eq!(
        open_bus_as(&sim, &node, true, RxFilter::All)
            .unwrap()
            .kind(),
        BusKind::Sim
    );
}

/// What a shared bus carries besides grip's own frames: a foreign 11-bit
/// id, extended (29-bit) frames (one numbered like a grip id), a remote
/// frame of a grip id; and every protocol message once.
fn mixed_traffic() -> Vec<CanFrame> {
    let ext = |id: u32| {
        let mut f = CanFrame::new(id, &[0xEE; 8]);
        f.flags = can_flags::EXTENDED;
        f
    };
    let mut rtr = CanFrame::new(WHEEL_SPEEDS.id, &[]);
    rtr.flags = can_flags::RTR;
    let mut out = vec![
        CanFrame::new(0x7FF, &[0xDE, 0xAD, 0xBE, 0xEF]),
        ext(0x1ABC_DEF0),
        ext(MOTOR_STATUS.id),
        rtr,
        CanFrame::new(0x000, &[1]),
    ];
    out.extend(MESSAGES.iter().map(|m| CanFrame::new(m.id, &[0x11; 8])));
    out.push(CanFrame::new(0x5A5, &[2; 8]));
    out
}

/// A simulated bus opened for a role, as the services open theirs
/// (`open_bus_as`, transport sim), delivers exactly the protocol messages
/// that role receives, in order; foreign ids, extended and remote frames
/// and the messages of the other role are dropped. A participant without
/// a filter (a recorder) still sees every frame.
#[test]
fn a_bus_opened_for_a_role_receives_only_that_roles_ids() {
    let node = IpcNode::create("simbus-test-filter").unwrap();
    for (role, want) in [
        (
            Role::Tcs,
            vec![
                MOTOR_STATUS.id,
                WHEEL_SPEEDS.id,
                VEHICLE_SPEED.id,
                DRIVER_DEMAND.id,
            ],
        ),
        (Role::Inverter, vec![TORQUE_COMMAND.id]),
    ] {
        let cfg = CanBusConfig {
            transport: Transport::Sim,
            interface: "gripnonexist2".into(),
            sim_bus: Some(unique(&format!("filter-{}", role.node()))),
            bus_id: 0,
            ..CanBusConfig::default()
        };
        let mut bus = open_bus_as(&cfg, &node, false, RxFilter::Role(role)).unwrap();
        let mut all = SimBus::open(&node, cfg.sim_bus_name(), 0).unwrap();
        let mut other = SimBus::open(&node, cfg.sim_bus_name(), 0).unwrap();
        let sent = mixed_traffic();
        for f in &sent {
            other.send(f).unwrap();
        }
        let got: Vec<u32> = std::iter::from_fn(|| bus.try_recv().unwrap())
            .map(|f| f.id)
            .collect();
        assert_eq!(got, want, "{role:?}");
        let seen: Vec<CanFrame> = std::iter::from_fn(|| all.try_recv().unwrap()).collect();
        assert_eq!(seen.len(), sent.len(), "the unfiltered participant");
        assert!(
            seen.iter()
                .zip(&sent)
                .all(|(a, b)| (a.id, a.flags) == (b.id, b.flags))
        );
        // recv_timeout skips a foreign frame too and waits for a grip one
        other.send(&CanFrame::new(0x7FF, &[0; 8])).unwrap();
        assert_eq!(
            bus.recv_timeout(Duration::from_millis(20)).unwrap(),
            None,
            "{role:?}: a foreign frame woke the receiver with a frame"
        );
    }
}

#[test]
fn can_config_parses_and_denies_unknown_fields() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/can.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let cfg: CanBusConfig = toml_like(&text);
    assert_eq!(cfg.interface, "vcan0");
    assert_eq!(cfg.transport, Transport::Auto);
    let bad = serde_json::from_str::<CanBusConfig>(r#"{"interface":"can0","bitrate":5}"#);
    assert!(bad.unwrap_err().to_string().contains("bitrate"));
}

/// Minimal reader for the flat `key = "value"` can.toml (the io crate does
/// not depend on a TOML parser; grip-config owns TOML loading).
fn toml_like(text: &str) -> CanBusConfig {
    let mut m = serde_json::Map::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap().trim();
        if let Some((k, v)) = line.split_once('=') {
            let v = v.trim();
            let val = if let Some(s) = v.strip_prefix('"').and_then(|s| s.strip_suffix('"')) {
                serde_json::Value::String(s.into())
            } else {
                serde_json::Value::from(v.parse::<u64>().unwrap())
            };
            m.insert(k.trim().into(), val);
        }
    }
    serde_json::from_value(serde_json::Value::Object(m)).unwrap()
}

#[test]
fn latest_subscriber_gets_newest_deep_subscriber_gets_all() {
    let topic = format!("grip/test/{}", unique("ports"));
    let node = IpcNode::create("ports-test").unwrap();
    let publisher = node.publisher::<CycleRecord>(&topic).unwrap();
    let latest = node
        .subscriber::<CycleRecord>(&topic, SubscriberMode::Latest)
        .unwrap();
    let deep = node
        .subscriber::<CycleRecord>(&topic, SubscriberMode::Deep)
        .unwrap();
    for i in 0..500u64 {
        let mut r = CycleRecord::zeroed();
        r.seq = i;
        assert_eq!(publisher.publish(&r).unwrap(), 2);
    }
    assert_eq!(latest.recv().unwrap().map(|r| r.seq), Some(499));
    assert_eq!(latest.recv().unwrap(), None);
    let mut seqs = Vec::new();
    deep.drain(|r| seqs.push(r.seq)).unwrap();
    assert_eq!(seqs, (0..500).collect::<Vec<_>>());
    let peers = deep.peers();
    assert_eq!((peers.publishers, peers.subscribers, peers.dead), (1, 2, 0));
    assert!(peers.alive >= 1);
}
