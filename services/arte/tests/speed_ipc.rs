//! The vehicle speed over real iceoryx2 (`GRIP_INSTANCE` isolated):
//!
//! 1. the loop's cycle subscription ([`ArteLoop::poll_cycles`] on a
//!    latest-value subscriber of `grip/tcs/cycle`, a manual clock): a
//!    published record's speed reaches the estimator; of records published
//!    between two drains the newest wins; invalid ones keep the last valid
//!    speed until it is older than the timeout, then none;
//! 2. the whole service ([`grip_arte_svc::run`], the shipped model, a
//!    stand-in tcs-loop publishing at 1 kHz on the real clock): blocks
//!    before any record, after tcs-loop's V went invalid for longer than
//!    `speed_timeout_s`, and with a valid V are counted as such in the run
//!    summary, the last block had the last speed, and the speed log lines
//!    and the exit summary are written.
//!
//! One test function: the iceoryx2 namespace is chosen once per process.

mod common;

use std::io::Write;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::*;
use grip_arte::stream::StreamConfig;
use grip_arte_svc::{ArteCounters, ArteLoop, EstimateSink, Options, load_model};
use grip_io::clock::{ManualClock, monotonic_now_ns};
use grip_io::ipc::{IpcError, IpcNode, SubscriberMode};
use grip_msgs::{AudioBlock, CycleRecord, RoadEstimate, topics};

struct Null;
impl EstimateSink for Null {
    fn send(&mut self, _e: &RoadEstimate) -> Result<(), IpcError> {
        Ok(())
    }
}

fn record(seq: u64, v: f64, valid: bool, stamp_ns: u64) -> CycleRecord {
    let mut r = CycleRecord::zeroed();
    r.seq = seq;
    r.stamp_ns = stamp_ns;
    r.v = if valid { v } else { f64::NAN };
    r.v_valid = u8::from(valid);
    r
}

/// Log lines of this process, for the checks on the service's messages.
#[derive(Clone, Default)]
struct Logs(Arc<Mutex<Vec<u8>>>);
impl Write for Logs {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}
impl Logs {
    fn text(&self) -> String {
        String::from_utf8_lossy(&self.0.lock().unwrap()).into_owned()
    }
}

fn wait_for(what: &str, mut cond: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !cond() {
        assert!(t0.elapsed() < Duration::from_secs(60), "timed out: {what}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// What the stand-in tcs-loop publishes: nothing, invalid V, or V (m/s).
const OFF: u64 = u64::MAX;
const INVALID: u64 = u64::MAX - 1;

#[test]
fn cycle_records_over_iceoryx2_give_the_estimator_its_speed() {
    // SAFETY: the only test function of this process; set before any
    // iceoryx2 use or other thread.
    unsafe {
        std::env::set_var(
            grip_io::ipc::INSTANCE_ENV,
            format!("arte_speed_{}", std::process::id()),
        )
    };
    let logs = Logs::default();
    let w = logs.clone();
    tracing_subscriber::fmt()
        .with_writer(move || w.clone())
        .with_ansi(false)
        .with_max_level(tracing::Level::INFO)
        .init();

    // 1. the loop and its subscription, manual clock
    let model = load_model(&config_dir().join("models/default.model")).unwrap();
    let roads = roads_for(&model);
    let node = IpcNode::create("arte-speed-test").unwrap();
    {
        let tcs = node.publisher::<CycleRecord>(topics::CYCLE).unwrap();
        let cycles = node
            .subscriber::<CycleRecord>(topics::CYCLE, SubscriberMode::Latest)
            .unwrap();
        let t0 = 1_000_000_000;
        let clock = ManualClock::new(t0);
        let mut lp =
            ArteLoop::from_model(&model, &StreamConfig::default(), roads, 0.2, clock.clone())
                .unwrap();
        let stats = ArteCounters::default();
        let bl = blocks(3, &[("asphalt", 12.0, 0.5)], 1024, t0);
        let mut blk = bl.iter();
        let mut step = |lp: &mut ArteLoop<_, _>| {
            lp.poll_cycles(&cycles, &stats);
            lp.on_block(blk.next().unwrap(), &mut Null, &stats);
            stats.speed_in_use()
        };
        // nothing published yet
        assert_eq!(step(&mut lp), None);
        // one record at 12.5 m/s
        tcs.publish(&record(0, 12.5, true, t0)).unwrap();
        assert_eq!(step(&mut lp), Some(12.5));
        // three between two drains: the newest
        clock.set_ns(t0 + 30_000_000);
        for (k, v) in [(1, 13.0), (2, 14.0), (3, 15.0)] {
            tcs.publish(&record(k, v, true, t0 + k * 10_000_000))
                .unwrap();
        }
        assert_eq!(step(&mut lp), Some(15.0));
        // V invalid from now on: the last valid speed holds for 0.2 s...
        clock.set_ns(t0 + 200_000_000);
        tcs.publish(&record(4, 0.0, false, t0 + 200_000_000))
            .unwrap();
        assert_eq!(step(&mut lp), Some(15.0));
        // ...then none
        clock.set_ns(t0 + 230_000_001);
        tcs.publish(&record(5, 0.0, false, t0 + 230_000_000))
            .unwrap();
        assert_eq!(step(&mut lp), None);
        // valid again
        tcs.publish(&record(6, 16.0, true, t0 + 230_000_000))
            .unwrap();
        assert_eq!(step(&mut lp), Some(16.0));
        assert_eq!(stats.blocks_with_speed.load(Ordering::Relaxed), 4);
        assert_eq!(stats.blocks_without_speed.load(Ordering::Relaxed), 2);
        // the latest-value subscriber handed over one record per drain
        assert_eq!(stats.cycle_records.load(Ordering::Relaxed), 5);
        assert_eq!(stats.cycle_receive_errors.load(Ordering::Relaxed), 0);
    }

    // 2. the service
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("arte-svc.toml");
    std::fs::write(
        &cfg,
        "[input]\npoll_interval_ms = 1.0\nspeed_timeout_s = 1.0\n",
    )
    .unwrap();
    let opts = Options {
        config: grip_io::service::ConfigArgs {
            config_dir: config_dir(),
            config: Some(cfg),
        },
        model: None,
        run_for: Some(60.0), // a backstop; stopped below
    };
    let stop = Arc::new(AtomicBool::new(false));
    let svc = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || grip_arte_svc::run(&opts, stop))
    };
    let audio = node.publisher::<AudioBlock>(topics::AUDIO).unwrap();
    wait_for("arte's audio subscriber", || {
        audio.peers().subscribers >= 1 || svc.is_finished()
    });
    // the stand-in tcs-loop: one record per ms, stamped with the real clock
    let mode = Arc::new(AtomicU64::new(OFF));
    let quit = Arc::new(AtomicBool::new(false));
    let connected = Arc::new(AtomicBool::new(false));
    let tcs = {
        let (mode, quit, connected) =
            (Arc::clone(&mode), Arc::clone(&quit), Arc::clone(&connected));
        std::thread::spawn(move || {
            let node = IpcNode::create("arte-speed-tcs").unwrap();
            let p = node.publisher::<CycleRecord>(topics::CYCLE).unwrap();
            let mut seq = 0;
            while !quit.load(Ordering::Relaxed) {
                connected.store(p.peers().subscribers >= 1, Ordering::Relaxed);
                let m = mode.load(Ordering::Relaxed);
                if m != OFF {
                    let r = if m == INVALID {
                        record(seq, 0.0, false, monotonic_now_ns())
                    } else {
                        record(seq, f64::from_bits(m), true, monotonic_now_ns())
                    };
                    p.publish(&r).unwrap();
                    seq += 1;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
        })
    };
    wait_for("arte's cycle subscriber", || {
        connected.load(Ordering::Relaxed)
    });
    let bl = blocks(4, &[("asphalt", 12.0, 1.2)], 1024, monotonic_now_ns());
    let mut blk = bl.iter();
    let mut send = |n: usize| {
        for _ in 0..n {
            // stamped as audio-acq stamps a block: its first sample's time
            // on the monotonic clock, just after its last one was captured
            // (the service drops audio that ended more than max_lag_s ago)
            let mut b = *blk.next().unwrap();
            let span_ns = u64::from(b.n_samples) * 1_000_000_000 / u64::from(b.sample_rate);
            b.stamp_ns = monotonic_now_ns().saturating_sub(span_ns);
            audio.publish(&b).unwrap();
            std::thread::sleep(Duration::from_millis(23));
        }
        // Let the service take this phase's last block before the next
        // phase changes the speed: a block taken late would be counted
        // with the next phase's speed (a loaded machine delays an ordinary
        // thread by tens of ms).
        std::thread::sleep(Duration::from_millis(500));
    };
    // A: no record at all
    send(10);
    // B: V = 13.5 m/s
    mode.store(13.5f64.to_bits(), Ordering::Relaxed);
    std::thread::sleep(Duration::from_millis(200));
    send(20);
    // C: V invalid for longer than the timeout (1 s)
    mode.store(INVALID, Ordering::Relaxed);
    std::thread::sleep(Duration::from_millis(1500));
    send(10);
    // D: V = 20 m/s
    mode.store(20.0f64.to_bits(), Ordering::Relaxed);
    std::thread::sleep(Duration::from_millis(200));
    send(10);
    // let the loop finish and the helper (1 s report period) log
    std::thread::sleep(Duration::from_millis(1500));
    stop.store(true, Ordering::Relaxed);
    let summary = svc.join().unwrap().unwrap();
    quit.store(true, Ordering::Relaxed);
    tcs.join().unwrap();
    let text = logs.text();
    println!("{summary:?}\n{text}");
    assert_eq!(summary.blocks, 50, "{text}");
    assert_eq!(summary.blocks_with_speed, 30, "{summary:?}");
    assert_eq!(summary.blocks_without_speed, 20, "{summary:?}");
    assert_eq!(summary.last_speed_mps, Some(20.0));
    assert!(summary.estimates > 0);
    assert!(summary.cycle_records > 0);
    assert!(
        text.contains("vehicle speed available from grip/tcs/cycle") && text.contains("v_mps=13.5"),
        "{text}"
    );
    assert!(text.contains("vehicle speed stale or invalid"), "{text}");
    let stopped = text
        .lines()
        .find(|l| l.contains("arte stopped"))
        .unwrap_or_else(|| panic!("no exit summary:\n{text}"));
    assert!(
        stopped.contains("blocks_with_speed=30") && stopped.contains("blocks_without_speed=20"),
        "{stopped}"
    );
}
