//! `run_for` beyond the clock's range: [`grip_arte_svc::run`] with a run
//! length of `inf` or 1e300 s (what a library caller may pass; the command
//! line's parser refuses both) runs until stopped. Before the deadline was
//! computed saturating, `now + (s * 1e9) as u64` wrapped: the service
//! stopped at once (a release build) or panicked on the overflow (a debug
//! build, this test's).
//!
//! One test function: the iceoryx2 namespace is chosen once per process.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use grip_arte_svc::{Options, run};
use grip_io::ipc::IpcNode;
use grip_io::service::ConfigArgs;
use grip_msgs::{AudioBlock, topics};

#[test]
fn a_run_length_beyond_the_clock_runs_until_stopped() {
    // SAFETY: the only test function of this process; set before any
    // iceoryx2 use or other thread.
    unsafe {
        std::env::set_var(
            grip_io::ipc::INSTANCE_ENV,
            format!("arte_run_for_{}", std::process::id()),
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("arte-svc.toml");
    // the shipped model and roads; no [rt]
    std::fs::write(&cfg, "[input]\npoll_interval_ms = 2.0\n").unwrap();
    let opts = |run_for: f64| Options {
        config: ConfigArgs {
            config_dir: Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config"),
            config: Some(cfg.clone()),
        },
        model: None,
        run_for: Some(run_for),
    };
    let node = IpcNode::create("arte-run-for-test").unwrap();
    let audio = node.publisher::<AudioBlock>(topics::AUDIO).unwrap();
    for run_for in [f64::INFINITY, 1e300] {
        let stop = Arc::new(AtomicBool::new(false));
        let svc = {
            let (opts, stop) = (opts(run_for), Arc::clone(&stop));
            std::thread::spawn(move || run(&opts, stop))
        };
        // running: its audio subscriber is there (the deadline is set
        // right after), then half a second more
        let t0 = Instant::now();
        while audio.peers().subscribers == 0 && !svc.is_finished() {
            assert!(t0.elapsed() < Duration::from_secs(60), "arte did not start");
            std::thread::sleep(Duration::from_millis(10));
        }
        std::thread::sleep(Duration::from_millis(500));
        assert!(
            !svc.is_finished(),
            "run_for {run_for}: the run ended by itself at once: {:?}",
            svc.join()
        );
        stop.store(true, Ordering::Relaxed);
        svc.join()
            .unwrap_or_else(|_| panic!("run_for {run_for}: the service panicked"))
            .unwrap_or_else(|e| panic!("run_for {run_for}: {e}"));
    }
    // a run length in range still ends the run by itself
    let t0 = Instant::now();
    run(&opts(0.3), Arc::new(AtomicBool::new(false))).unwrap();
    let took = t0.elapsed();
    assert!(
        took >= Duration::from_millis(300) && took < Duration::from_secs(60),
        "a 0.3 s run took {took:?}"
    );
}
