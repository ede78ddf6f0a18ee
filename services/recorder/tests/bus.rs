//! The recorder's bus log on the simulated bus, in an isolated
//! `GRIP_INSTANCE`: frames another process (this test) puts on the bus,
//! 11- and 29-bit, data and remote, reach the log byte for byte, in order
//! and all of them; grip's own ids are left out with `bus = "foreign"`
//! and kept with `"all"`; `"off"` opens no bus at all. The recorder runs
//! three times, once per mode, on one configuration directory whose
//! `recorder.toml` changes between the runs.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use grip_io::ipc::{IpcNode, Publisher};
use grip_io::mcaplog::{LogMessage, McapLog, MetadataMap};
use grip_msgs::{BusFrame, CanFrame, CycleRecord, can_flags, topics};

fn shipped() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

/// A configuration directory: the shipped recorder.toml with `bus = mode`,
/// can.toml on the simulated bus, the shipped DBC.
fn config_dir(dir: &Path, mode: Option<&str>) {
    let rec = std::fs::read_to_string(shipped().join("recorder.toml")).unwrap();
    let rec = match mode {
        Some(m) => {
            assert!(
                rec.contains("\nbus = \"foreign\"\n"),
                "shipped recorder.toml sets bus"
            );
            rec.replace("\nbus = \"foreign\"\n", &format!("\nbus = \"{m}\"\n"))
        }
        // the key absent: its default
        None => rec.replace("\nbus = \"foreign\"\n", "\n"),
    };
    std::fs::write(dir.join("recorder.toml"), rec).unwrap();
    let can = std::fs::read_to_string(shipped().join("can.toml")).unwrap();
    assert!(can.contains("transport = \"auto\""));
    std::fs::write(
        dir.join("can.toml"),
        can.replace("transport = \"auto\"", "transport = \"sim\""),
    )
    .unwrap();
    std::fs::copy(shipped().join("inverter.dbc"), dir.join("inverter.dbc")).unwrap();
}

/// The frames the test puts on the bus: foreign 11-bit (data and remote),
/// foreign 29-bit (one with the number of a grip id), and grip's own
/// TorqueCommand and WheelSpeeds, interleaved; each with distinct data.
fn traffic(n: u32) -> Vec<CanFrame> {
    (0..n)
        .map(|i| {
            let b = i.to_le_bytes();
            let mut f = match i % 6 {
                0 => CanFrame::new(0x3E9, &[b[0], b[1], 0xA5, 0x5A, 0, 0xFF]),
                1 => CanFrame::new(0x100, &[b[0], b[1], 1, 2, 3, 4, 5, 6]),
                2 => {
                    let mut f = CanFrame::new(0x18DA_F110, &[b[0], b[1], 7]);
                    f.flags = can_flags::EXTENDED;
                    f
                }
                3 => CanFrame::new(0x120, &[b[0], b[1], 9, 9, 9, 9, 9, 9]),
                4 => {
                    // a 29-bit frame numbered like grip's WheelSpeeds: foreign
                    let mut f = CanFrame::new(0x120, &[b[0], b[1]]);
                    f.flags = can_flags::EXTENDED;
                    f
                }
                _ if i % 12 == 5 => {
                    let mut f = CanFrame::new(0x7FF, &[]);
                    f.flags = can_flags::RTR;
                    f.dlc = 4;
                    f
                }
                _ => CanFrame::new(0x000, &[b[0]]),
            };
            f.stamp_ns = 1;
            f
        })
        .collect()
}

fn is_grips(f: &CanFrame) -> bool {
    f.flags == 0 && (f.id == 0x100 || f.id == 0x120)
}

fn start(dir: &Path, out: &Path, instance: &str) -> Child {
    Command::new(env!("CARGO_BIN_EXE_recorder"))
        .arg("--config-dir")
        .arg(dir)
        .arg("--out")
        .arg(out)
        .env(grip_io::ipc::INSTANCE_ENV, instance)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn stop(mut child: Child) -> String {
    let st = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "recorder did not stop"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    use std::io::Read;
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert!(status.success(), "recorder exit {status}: {err}");
    err
}

/// Waits until `pred` holds (the recorder's ports are up), at most 60 s.
fn wait(child: &mut Child, what: &str, pred: impl Fn() -> bool) {
    let t0 = Instant::now();
    while !pred() {
        assert!(t0.elapsed() < Duration::from_secs(60), "{what} within 60 s");
        if let Ok(Some(st)) = child.try_wait() {
            panic!("recorder exited early: {st}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Publishes `frames` on the simulated bus at about 1 kHz (the recorder's
/// 1024-deep bus subscriber then holds a second of what it has not read),
/// each stamped when it is published, as `SimBus::send` stamps a frame
/// (its arrival on a bus without delay).
fn send(bus: &Publisher<CanFrame>, frames: &mut [CanFrame]) {
    for (i, f) in frames.iter_mut().enumerate() {
        f.stamp_ns = grip_io::clock::monotonic_now_ns();
        bus.publish(f).unwrap();
        if i % 2 == 1 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

fn bus_log(out: &Path) -> (Vec<BusFrame>, MetadataMap) {
    let log = McapLog::open(out).unwrap();
    let (msgs, rep) = log.messages().unwrap();
    assert!(rep.truncated.is_none() && rep.bad == 0, "{rep:?}");
    let frames = msgs
        .iter()
        .filter_map(|m| match &m.msg {
            LogMessage::Bus(b) => {
                assert_eq!(m.topic, topics::BUS);
                Some(*b)
            }
            _ => None,
        })
        .collect();
    let rec = log
        .metadata()
        .unwrap()
        .into_iter()
        .find(|(n, _)| n == "grip.recorder")
        .expect("grip.recorder metadata")
        .1;
    (frames, rec)
}

/// What the log must hold of `sent`: id, flags, DLC and payload of every
/// frame, in order.
fn same(logged: &[BusFrame], sent: &[&CanFrame]) {
    assert_eq!(logged.len(), sent.len(), "frame count");
    let mut last = 0;
    for (k, (l, s)) in logged.iter().zip(sent).enumerate() {
        assert_eq!(
            (l.id, l.flags, l.dlc, l.payload(), l.bus),
            (
                s.id,
                s.flags,
                s.dlc,
                if s.flags & can_flags::RTR != 0 {
                    &[][..]
                } else {
                    s.payload()
                },
                0
            ),
            "frame {k}"
        );
        // the bus's stamp (its publish time), never backwards
        assert!(
            l.stamp_ns == s.stamp_ns && l.stamp_ns >= last,
            "frame {k} stamp {}, published at {}",
            l.stamp_ns,
            s.stamp_ns
        );
        last = l.stamp_ns;
    }
}

#[test]
fn the_bus_log_holds_foreign_frames_byte_for_byte_and_obeys_its_mode() {
    let instance = format!("recbus{}", std::process::id());
    // SAFETY: set before any thread of this test process reads the
    // environment (the first iceoryx2 call below reads it once).
    unsafe { std::env::set_var(grip_io::ipc::INSTANCE_ENV, &instance) };
    let node = IpcNode::create("rec-bus-test").unwrap();
    let bus_topic = format!("{}vcan0", topics::SIM_BUS_PREFIX);
    let bus = node.publisher::<CanFrame>(&bus_topic).unwrap();
    let cyc = node.publisher::<CycleRecord>(topics::CYCLE).unwrap();
    let mut frames = traffic(1200);
    let n_grip = frames.iter().filter(|f| is_grips(f)).count();
    assert!(n_grip > 300 && n_grip < 1200);

    for mode in [None, Some("all"), Some("off")] {
        let dir = tempfile::tempdir().unwrap();
        config_dir(dir.path(), mode);
        let out = dir.path().join("rec.mcap");
        let mut child = start(dir.path(), &out, &instance);
        wait(&mut child, "recorder subscribed", || {
            cyc.peers().subscribers > 0
        });
        if mode == Some("off") {
            // READY: every topic subscribed; a bus would have been opened
            // before (crate::bus): none is
            std::thread::sleep(Duration::from_millis(500));
            assert_eq!(bus.peers().subscribers, 0, "bus = \"off\" opened the bus");
        } else {
            wait(&mut child, "recorder on the bus", || {
                bus.peers().subscribers > 0
            });
        }
        send(&bus, &mut frames);
        // the recorder polls every 2 ms: let it read the last frames
        std::thread::sleep(Duration::from_millis(300));
        let err = stop(child);
        let (logged, rec) = bus_log(&out);
        let key = |k: &str| rec.get(&format!("{}.{k}", topics::BUS)).cloned();
        match mode {
            None => {
                let want: Vec<&CanFrame> = frames.iter().filter(|f| !is_grips(f)).collect();
                same(&logged, &want);
                assert_eq!(key("mode").as_deref(), Some("foreign"), "{err}");
                assert_eq!(key("transport").as_deref(), Some("sim"));
                assert_eq!(key("received"), Some(frames.len().to_string()));
                assert_eq!(key("skipped_own"), Some(n_grip.to_string()));
                assert_eq!(key("written"), Some(want.len().to_string()));
                assert_eq!(key("queue_dropped").as_deref(), Some("0"));
                assert!(
                    err.contains("bus_received=1200") && err.contains("bus_written=800"),
                    "the stop line lacks the bus counters: {err}"
                );
            }
            Some("all") => {
                let want: Vec<&CanFrame> = frames.iter().collect();
                same(&logged, &want);
                assert_eq!(key("mode").as_deref(), Some("all"));
                assert_eq!(key("skipped_own").as_deref(), Some("0"));
                assert_eq!(key("written"), Some(frames.len().to_string()));
            }
            _ => {
                assert!(
                    logged.is_empty(),
                    "bus = \"off\" logged {} frames",
                    logged.len()
                );
                assert_eq!(key("mode"), None, "bus = \"off\" has no bus counters");
                assert!(err.contains("bus log off"), "{err}");
            }
        }
    }

    // a bus that cannot be opened (an interface no machine has, transport
    // socketcan): a warning, and everything else is recorded
    let dir = tempfile::tempdir().unwrap();
    config_dir(dir.path(), None);
    let can = std::fs::read_to_string(dir.path().join("can.toml")).unwrap();
    assert!(can.contains("interface = \"vcan0\""));
    let can = can
        .replace("transport = \"sim\"", "transport = \"socketcan\"")
        .replace("interface = \"vcan0\"", "interface = \"gripnone9\"");
    std::fs::write(dir.path().join("can.toml"), can).unwrap();
    let out = dir.path().join("rec.mcap");
    let mut child = start(dir.path(), &out, &instance);
    wait(&mut child, "recorder subscribed", || {
        cyc.peers().subscribers > 0
    });
    for s in 0..100u64 {
        let mut c = CycleRecord::zeroed();
        c.seq = s;
        c.stamp_ns = 1_000_000_000 + s * 1_000_000;
        cyc.publish(&c).unwrap();
    }
    // more than two retry periods
    std::thread::sleep(Duration::from_millis(2500));
    let err = stop(child);
    let (logged, rec) = bus_log(&out);
    assert!(logged.is_empty());
    assert!(
        err.contains("bus log: cannot open the vehicle bus") && err.contains("gripnone9"),
        "{err}"
    );
    assert_eq!(
        err.matches("cannot open the vehicle bus").count(),
        1,
        "warned once: {err}"
    );
    let key = |k: &str| rec.get(&format!("{}.{k}", topics::BUS)).cloned();
    assert_eq!(key("transport").as_deref(), Some("none (never opened)"));
    let tries: u64 = key("open_failures").unwrap().parse().unwrap();
    assert!(tries >= 3, "tried {tries} times in 2.5 s");
    assert_eq!(rec[&format!("{}.written", topics::CYCLE)], "100", "{err}");
}
