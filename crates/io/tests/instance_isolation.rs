//! `GRIP_INSTANCE` isolates concurrent grip instances: a subscriber in
//! instance B never sees a publisher of instance A on the same topic name,
//! while one in instance A does. Each role runs in its own process (the
//! instance is read once per process), spawned from this test binary.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use grip_io::ipc::{INSTANCE_ENV, IpcNode, SubscriberMode};
use grip_msgs::GroundTruth;

const ROLE: &str = "GRIP_IO_INSTANCE_ROLE";
const WAIT: &str = "GRIP_IO_INSTANCE_WAIT_MS";

fn child(role: &str) {
    let (kind, topic) = role.split_once(':').expect("role kind:topic");
    let node = IpcNode::create("instance-test").unwrap();
    match kind {
        "pub" => {
            let p = node.publisher::<GroundTruth>(topic).unwrap();
            println!("ready");
            let mut g = GroundTruth::zeroed();
            g.seq = 7;
            // publish until killed (bounded: 20 s)
            for _ in 0..2000 {
                p.publish(&g).unwrap();
                std::thread::sleep(Duration::from_millis(10));
            }
        }
        "sub" => {
            let s = node
                .subscriber::<GroundTruth>(topic, SubscriberMode::Deep)
                .unwrap();
            // how long to listen: short where nothing may arrive, long
            // where something must (a loaded machine may be slow)
            let wait_ms: u64 = std::env::var(WAIT).unwrap().parse().unwrap();
            let t0 = Instant::now();
            while t0.elapsed() < Duration::from_millis(wait_ms) {
                if let Some(g) = s.recv().unwrap() {
                    println!("got {}", g.seq);
                    return;
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            println!("none");
        }
        other => panic!("unknown role {other}"),
    }
}

fn run(role: &str, instance: &str, wait_ms: u64) -> std::process::Child {
    Command::new(std::env::current_exe().unwrap())
        .env(ROLE, role)
        .env(WAIT, wait_ms.to_string())
        .env(INSTANCE_ENV, instance)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap()
}

fn first_line(c: &mut std::process::Child) -> String {
    let mut line = String::new();
    BufReader::new(c.stdout.as_mut().unwrap())
        .read_line(&mut line)
        .unwrap();
    line.trim().to_string()
}

#[path = "support/harness.rs"]
mod harness;

fn main() {
    if let Ok(role) = std::env::var(ROLE) {
        child(&role);
        return;
    }
    harness::run_tests(&[(
        "grip_instance_separates_namespaces",
        grip_instance_separates_namespaces,
    )]);
}

fn grip_instance_separates_namespaces() {
    let pid = std::process::id();
    let topic = format!("grip/test/instance_{pid}");
    let (a, b) = (format!("isoA{pid}"), format!("isoB{pid}"));
    let mut publisher = run(&format!("pub:{topic}"), &a, 0);
    assert_eq!(first_line(&mut publisher), "ready");

    let mut other = run(&format!("sub:{topic}"), &b, 800);
    let seen_by_other = first_line(&mut other);
    other.wait().unwrap();
    let mut same = run(&format!("sub:{topic}"), &a, 10_000);
    let seen_by_same = first_line(&mut same);
    same.wait().unwrap();
    publisher.kill().unwrap();
    publisher.wait().unwrap();

    println!("instance B saw: {seen_by_other}; instance A saw: {seen_by_same}");
    assert_eq!(seen_by_other, "none", "instance B saw instance A's topic");
    assert_eq!(
        seen_by_same, "got 7",
        "instance A did not see its own topic"
    );
    println!("test result: ok. 1 passed; 0 failed");
}
