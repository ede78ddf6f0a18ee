//! A stopped peer must not stall the recorder (found under systemd as PID 1,
//! `tests/pid1_systemd.rs`: while a SIGSTOPped publisher waited for its
//! watchdog kill, the recorder's receive thread stopped advancing, its own
//! watchdog went unfed and systemd killed it too).
//!
//! The recorder binary records, with `WATCHDOG_USEC` set and this test as
//! its `NOTIFY_SOCKET`, from a publisher in another process (this test
//! binary again, [`publisher_child`]) in an isolated `GRIP_INSTANCE`. The
//! publisher is SIGSTOPped several times, at random points of its publishing
//! loop; during each stop the recorder must keep pinging `WATCHDOG=1` and
//! must not log a stalled receive thread. Then the publisher is killed
//! (`kill -9`, a dead node) and a new one started: the recorder records
//! the new one, and finishes its file on SIGTERM.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use grip_io::ipc::IpcNode;
use grip_msgs::{AudioBlock, CanFrame, CycleRecord, GroundTruth, RoadEstimate, topics};
use grip_testkit::svc::{NotifySocket, Service, shipped_config_dir};

const CHILD_ENV: &str = "GRIP_REC_TEST_PUBLISHER";

fn kill(pid: u32, sig: i32) {
    unsafe extern "C" {
        #[link_name = "kill"]
        fn libc_kill(pid: i32, sig: i32) -> i32;
    }
    let pid = i32::try_from(pid).expect("pid fits i32");
    // SAFETY: plain kill(2) on a child of this test.
    unsafe { libc_kill(pid, sig) };
}

const SIGKILL: i32 = 9;
const SIGTERM: i32 = 15;
const SIGCONT: i32 = 18;
const SIGSTOP: i32 = 19;

/// The publisher process: every topic the recorder records, at the rates
/// of a drive (cycle records 1 kHz, CAN 3 kHz, ground truth 100 Hz, road
/// estimates and audio blocks about 10 Hz), until killed. Run only by
/// [`stopped_publisher_does_not_stall_the_recorder`] (as a child process,
/// with `GRIP_REC_TEST_PUBLISHER=1`).
#[test]
#[ignore = "the publisher child process of stopped_publisher_does_not_stall_the_recorder"]
fn publisher_child() {
    assert_eq!(
        std::env::var(CHILD_ENV).as_deref(),
        Ok("1"),
        "run by stopped_publisher_does_not_stall_the_recorder only"
    );
    let node = IpcNode::create("rec-test-peer").unwrap();
    let cyc = node.publisher::<CycleRecord>(topics::CYCLE).unwrap();
    let can = node.publisher::<CanFrame>(topics::CAN_LOG).unwrap();
    let truth = node.publisher::<GroundTruth>(topics::TRUTH).unwrap();
    let road = node.publisher::<RoadEstimate>(topics::ROAD).unwrap();
    let audio = node.publisher::<AudioBlock>(topics::AUDIO).unwrap();
    println!("PUBLISHING");
    let t0 = Instant::now();
    for s in 0u64.. {
        let stamp = 1_000_000_000 + s * 1_000_000;
        let mut c = CycleRecord::zeroed();
        c.seq = s;
        c.stamp_ns = stamp;
        cyc.publish(&c).unwrap();
        for k in 0..3u8 {
            let mut f = CanFrame::new(0x100 + u32::from(k), &[0, (s & 15) as u8, 0, 0, 0, 0, 0, 0]);
            f.stamp_ns = stamp;
            can.publish(&f).unwrap();
        }
        if s % 10 == 0 {
            let mut g = GroundTruth::zeroed();
            g.seq = s / 10;
            g.stamp_ns = stamp;
            truth.publish(&g).unwrap();
        }
        if s % 100 == 0 {
            let mut r = RoadEstimate::zeroed();
            r.seq = s / 100;
            r.stamp_ns = stamp;
            road.publish(&r).unwrap();
            let mut a = AudioBlock::zeroed();
            a.seq = s / 100;
            a.stamp_ns = stamp;
            a.sample_rate = 44_100;
            a.n_samples = 16;
            audio.publish(&a).unwrap();
        }
        // paced to about 1 kHz on average
        let due = t0 + Duration::from_millis(s + 1);
        if let Some(d) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    }
}

fn spawn_publisher(instance: &str, log: &Path) -> Child {
    Command::new(std::env::current_exe().unwrap())
        .args(["--ignored", "--exact", "publisher_child", "--nocapture"])
        .env(CHILD_ENV, "1")
        .env(grip_io::ipc::INSTANCE_ENV, instance)
        .stdout(Stdio::from(std::fs::File::create(log).unwrap()))
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

fn wait_publishing(log: &Path) {
    let t0 = Instant::now();
    while !std::fs::read_to_string(log)
        .unwrap_or_default()
        .contains("PUBLISHING")
    {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the publisher did not start within 60 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn stopped_publisher_does_not_stall_the_recorder() {
    let instance = format!("rec-stop-{}", std::process::id());
    let dir = tempfile::tempdir().unwrap();
    let sock = NotifySocket::bind(dir.path());
    let out = dir.path().join("rec.mcap");
    let rec_log = dir.path().join("recorder.log");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_recorder"));
    cmd.arg("--config-dir")
        .arg(shipped_config_dir())
        .arg("--out")
        .arg(&out)
        .env("NOTIFY_SOCKET", sock.path())
        // pings due every 0.5 s while the receive thread advances
        .env("WATCHDOG_USEC", "1000000")
        .env("RUST_LOG", "info")
        .env(grip_io::ipc::INSTANCE_ENV, &instance);
    let mut rec = Service::spawn(cmd);
    // stderr to a file (a pipe nobody reads could fill and block it)
    let mut rec_err = rec.0.stderr.take().unwrap();
    let rec_log2 = rec_log.clone();
    let copier = std::thread::spawn(move || {
        let mut f = std::fs::File::create(rec_log2).unwrap();
        let _ = std::io::copy(&mut rec_err, &mut f);
    });
    assert!(
        sock.wait_for("READY=1", Duration::from_secs(30)),
        "no READY=1 within 30 s"
    );

    let pub_log = dir.path().join("publisher.log");
    let mut publisher = spawn_publisher(&instance, &pub_log);
    wait_publishing(&pub_log);
    std::thread::sleep(Duration::from_millis(1500));

    // 2 pings expected per second; allow a loaded machine to lose half
    let mut worst = usize::MAX;
    for round in 0..4u64 {
        // a different point of the publishing loop each time
        std::thread::sleep(Duration::from_millis(137 * (round + 1)));
        kill(publisher.id(), SIGSTOP);
        let pings = sock.count("WATCHDOG=1", Duration::from_secs(4));
        kill(publisher.id(), SIGCONT);
        eprintln!("publisher stopped 4 s (round {round}): {pings} WATCHDOG=1 from the recorder");
        worst = worst.min(pings);
    }
    // a stopped publisher that is then killed, and a new one
    kill(publisher.id(), SIGSTOP);
    let pings_before_kill = sock.count("WATCHDOG=1", Duration::from_secs(3));
    kill(publisher.id(), SIGKILL);
    let _ = publisher.wait();
    let pub_log2 = dir.path().join("publisher2.log");
    let mut publisher2 = spawn_publisher(&instance, &pub_log2);
    wait_publishing(&pub_log2);
    let pings_after = sock.count("WATCHDOG=1", Duration::from_secs(3));
    kill(publisher2.id(), SIGKILL);
    let _ = publisher2.wait();

    rec.signal(SIGTERM);
    let (status, _) = rec.wait();
    copier.join().unwrap();
    let log = std::fs::read_to_string(&rec_log).unwrap();
    eprintln!("recorder's log:\n{log}");
    assert_eq!(status.code(), Some(0), "recorder exit {status}");
    assert!(
        !log.contains("stalled"),
        "the recorder's receive thread stalled while a publisher was stopped"
    );
    assert!(
        worst >= 4,
        "only {worst} WATCHDOG=1 in 4 s while the publisher was stopped (8 due)"
    );
    assert!(
        pings_before_kill >= 3,
        "only {pings_before_kill} WATCHDOG=1 in 3 s while the publisher was stopped (6 due)"
    );
    assert!(
        pings_after >= 3,
        "only {pings_after} WATCHDOG=1 in 3 s after the publisher was replaced (6 due)"
    );
}
