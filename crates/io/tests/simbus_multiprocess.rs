//! SimBus and iceoryx2 ports between two processes. The test binary spawns
//! itself as the peer (environment variable `GRIP_IO_CHILD`), so no extra
//! binary is needed (`harness = false`: this `main` runs the tests).
//!
//! 1. echo: a child echoes every frame with id + 1; 300 round trips.
//! 2. killed peer: a child publishes, is `kill -9`ed; the survivor sees a
//!    dead node on the topic (never hangs: only timed waits), removes its
//!    stale resources, and afterwards sees no dead node and no publisher.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use grip_io::can::{CanBus, SimBus};
use grip_io::ipc::{INSTANCE_ENV, IpcNode, SubscriberMode, cleanup_dead_nodes};
use grip_msgs::{CanFrame, GroundTruth};

const ENV: &str = "GRIP_IO_CHILD";

fn child(role: &str) {
    let (kind, name) = role.split_once(':').expect("role kind:name");
    match kind {
        "echo" => {
            let node = IpcNode::create("mp-echo-child").unwrap();
            let mut bus = SimBus::open(&node, name, 0).unwrap();
            println!("ready");
            loop {
                match bus.recv_timeout(Duration::from_secs(10)).unwrap() {
                    Some(f) if f.id == 0x7FF => break,
                    Some(mut f) => {
                        f.id += 1;
                        bus.send(&f).unwrap();
                    }
                    None => {
                        eprintln!("echo child: 10 s without a frame, giving up");
                        std::process::exit(2);
                    }
                }
            }
        }
        "hang" => {
            let node = IpcNode::create("mp-hang-child").unwrap();
            let p = node.publisher::<GroundTruth>(name).unwrap();
            let mut g = GroundTruth::zeroed();
            g.seq = 42;
            p.publish(&g).unwrap();
            println!("ready");
            loop {
                std::thread::sleep(Duration::from_secs(1));
            }
        }
        other => panic!("unknown child role {other}"),
    }
}

fn spawn(role: &str) -> (Child, BufReader<std::process::ChildStdout>) {
    let exe = std::env::current_exe().unwrap();
    let mut c = Command::new(exe)
        .env(ENV, role)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(c.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    assert_eq!(line.trim(), "ready", "child did not start");
    (c, out)
}

fn echo_between_processes() {
    let bus_name = format!("mp_echo_{}", std::process::id());
    let node = IpcNode::create("mp-echo-parent").unwrap();
    let mut bus = SimBus::open(&node, &bus_name, 0).unwrap();
    let (mut c, _out) = spawn(&format!("echo:{bus_name}"));
    let t0 = Instant::now();
    for i in 0..300u32 {
        let f = CanFrame::new(0x100 + (i % 16), &i.to_le_bytes());
        bus.send(&f).unwrap();
        let r = bus
            .recv_timeout(Duration::from_secs(5))
            .unwrap()
            .unwrap_or_else(|| panic!("no echo for frame {i}"));
        assert_eq!(r.id, f.id + 1);
        assert_eq!(r.data, f.data);
    }
    eprintln!("  300 cross-process round trips in {:?}", t0.elapsed());
    bus.send(&CanFrame::new(0x7FF, &[])).unwrap();
    let st = c.wait().unwrap();
    assert!(st.success(), "echo child exited with {st}");
}

fn killed_peer_is_detected_and_cleaned() {
    let topic = format!("grip/test/mp_kill_{}", std::process::id());
    let node = IpcNode::create("mp-kill-parent").unwrap();
    let sub = node
        .subscriber::<GroundTruth>(&topic, SubscriberMode::Deep)
        .unwrap();
    let (mut c, _out) = spawn(&format!("hang:{topic}"));
    // the child's sample arrives (bounded wait)
    let t0 = Instant::now();
    let got = loop {
        if let Some(g) = sub.recv().unwrap() {
            break g;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "no sample from child"
        );
        std::thread::sleep(Duration::from_millis(1));
    };
    assert_eq!(got.seq, 42);
    let before = sub.peers();
    assert_eq!(before.dead, 0);
    assert!(before.alive >= 2, "{before:?}");
    assert_eq!(before.publishers, 1);
    c.kill().unwrap(); // SIGKILL: no cleanup in the child
    c.wait().unwrap();
    let after = sub.peers();
    assert_eq!(after.dead, 1, "dead child not detected: {after:?}");
    // nothing more arrives, and reading does not hang
    assert_eq!(sub.recv().unwrap(), None);
    let rep = cleanup_dead_nodes();
    assert!(rep.cleaned >= 1, "{rep:?}");
    let cleaned = sub.peers();
    assert_eq!((cleaned.dead, cleaned.publishers), (0, 0), "{cleaned:?}");
}

#[path = "support/harness.rs"]
mod harness;

fn main() {
    if let Ok(role) = std::env::var(ENV) {
        child(&role);
        return;
    }
    // An iceoryx2 namespace of its own (the children inherit it): another
    // test process creating a node cleans up dead nodes of its namespace,
    // and could take the killed child before this test looks for it.
    // SAFETY: single-threaded here, before any iceoryx2 use.
    unsafe { std::env::set_var(INSTANCE_ENV, format!("mp{}", std::process::id())) };
    harness::run_tests(&[
        ("echo_between_processes", echo_between_processes),
        (
            "killed_peer_is_detected_and_cleaned",
            killed_peer_is_detected_and_cleaned,
        ),
    ]);
}
