//! `run_for` beyond the clock's range: [`grip_audio_acq::run`] with a run
//! length of `inf` or 1e300 s (what a library caller may pass; the command
//! line's parser refuses both) runs until stopped. Before the deadline was
//! computed saturating, `now + (s * 1e9) as u64` wrapped: the service
//! stopped at once (a release build) or panicked on the overflow (a debug
//! build, this test's).
//!
//! One test function: the iceoryx2 namespace is chosen once per process.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use grip_audio_acq::{Options, SourceKind, run};
use grip_io::ipc::{IpcNode, SubscriberMode};
use grip_io::service::ConfigArgs;
use grip_msgs::{AudioBlock, topics};
use grip_testkit::svc::{copy_config, strip_rt};

#[test]
fn a_run_length_beyond_the_clock_runs_until_stopped() {
    // SAFETY: the only test function of this process; set before any
    // iceoryx2 use or other thread.
    unsafe {
        std::env::set_var(
            grip_io::ipc::INSTANCE_ENV,
            format!("acq_run_for_{}", std::process::id()),
        )
    };
    let t = copy_config(&["audio-acq.toml", "roads.toml"]);
    strip_rt(&t.path().join("audio-acq.toml"));
    let opts = |run_for: f64| Options {
        config: ConfigArgs::in_dir(t.path()),
        source: Some(SourceKind::Synth),
        run_for: Some(run_for),
        ..Options::default()
    };
    let node = IpcNode::create("acq-run-for-test").unwrap();
    let blocks = node
        .subscriber::<AudioBlock>(topics::AUDIO, SubscriberMode::Latest)
        .unwrap();
    for run_for in [f64::INFINITY, 1e300] {
        let stop = Arc::new(AtomicBool::new(false));
        let svc = {
            let (opts, stop) = (opts(run_for), Arc::clone(&stop));
            std::thread::spawn(move || run(&opts, stop))
        };
        // running: a block has arrived (the deadline is set before the
        // first), then half a second more
        let t0 = Instant::now();
        while blocks.recv().unwrap().is_none() && !svc.is_finished() {
            assert!(t0.elapsed() < Duration::from_secs(60), "no audio block");
            std::thread::sleep(Duration::from_millis(5));
        }
        std::thread::sleep(Duration::from_millis(500));
        assert!(
            !svc.is_finished(),
            "run_for {run_for}: the run ended by itself at once: {:?}",
            svc.join()
        );
        stop.store(true, Ordering::Relaxed);
        let summary = svc
            .join()
            .unwrap_or_else(|_| panic!("run_for {run_for}: the service panicked"))
            .unwrap_or_else(|e| panic!("run_for {run_for}: {e}"));
        assert!(summary.blocks >= 1, "run_for {run_for}: {summary:?}");
        assert!(!summary.source_ended);
    }
    // a run length in range still ends the run by itself
    let t0 = Instant::now();
    let summary = run(&opts(0.3), Arc::new(AtomicBool::new(false))).unwrap();
    let took = t0.elapsed();
    assert!(
        took >= Duration::from_millis(300) && took < Duration::from_secs(30),
        "a 0.3 s run took {took:?}"
    );
    assert!(summary.blocks >= 1, "{summary:?}");
}
