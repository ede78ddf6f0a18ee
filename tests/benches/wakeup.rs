//! Wake-up latency of tcs-loop at its configured rate (1 kHz) beside
//! `cyclictest` on the same machine, in the same invocation.
//!
//! ```text
//! cargo bench -p grip-tests --bench wakeup          # 60 s + 60 s
//! GRIP_BENCH_SECS=10 cargo bench -p grip-tests --bench wakeup
//! ```
//!
//! 1. plant-sim's `run` (shipped `config/plant-sim.toml`: SCHED_FIFO 70,
//!    CPU 0, immediate start) runs in a thread for the whole benchmark, so
//!    tcs-loop works on real traffic over the simulated CAN bus.
//! 2. tcs-loop's `run` — the very code of the service binary, with the
//!    shipped `config/tcs-loop.toml` (SCHED_FIFO 80, CPU 1, mlockall,
//!    cpu_dma_latency 0) — runs in another thread for `GRIP_BENCH_SECS`
//!    (default 60) seconds; its periodic timer's histogram gives the wake-up
//!    latency (woken − absolute deadline).
//! 3. Then `cyclictest -m -p 80 -i 1000 -l <secs·1000> -t 1 -q --histogram=10000`
//!    (Debian `rt-tests`; installed with tools/apt-install if missing) runs for the
//!    same time, plant-sim still running.
//!
//! Percentiles of both come from 1 µs histogram buckets and are reported as
//! the bucket's upper edge (capped at the exact maximum) — the convention of
//! `grip_io::rt::LatencyHistogram`, applied to cyclictest's buckets too.
//! Speed targets are printed, never asserted.

use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

struct Stats {
    count: u64,
    p50_us: f64,
    p99_us: f64,
    p999_us: f64,
    max_us: f64,
    over_1ms: u64,
}

fn ensure_cyclictest() -> Result<(), String> {
    if Command::new("cyclictest").arg("--help").output().is_ok() {
        return Ok(());
    }
    // tools/apt-install: only what is missing, never a removal or upgrade
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../tools/apt-install");
    eprintln!("cyclictest not found: installing Debian's rt-tests ({script} rt-tests)");
    let ok = Command::new(script)
        .args(["--for", "the wake-up bench", "rt-tests"])
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if ok {
        Ok(())
    } else {
        Err("cyclictest is missing and `tools/apt-install rt-tests` did not install it".into())
    }
}

fn cyclictest(secs: u64) -> Result<Stats, String> {
    ensure_cyclictest()?;
    // the command line and the histogram reader of the ECU bench (tools/bench)
    let out = Command::new("cyclictest")
        .args(grip_bench::cyclictest::args(
            80,
            1000,
            secs * 1000,
            None,
            10_000,
        ))
        .output()
        .map_err(|e| format!("cyclictest: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "cyclictest failed: {}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let s = grip_bench::cyclictest::parse(&String::from_utf8_lossy(&out.stdout), 1000)?;
    Ok(Stats {
        count: s.count,
        p50_us: s.p50_us,
        p99_us: s.p99_us,
        p999_us: s.p999_us,
        max_us: s.max_us,
        over_1ms: s.over_limit,
    })
}

fn main() {
    let secs: u64 = std::env::var("GRIP_BENCH_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(60);
    // SAFETY: single-threaded at this point; isolates this run's iceoryx2
    // services from any other grip instance on the machine.
    unsafe {
        std::env::set_var(
            "GRIP_INSTANCE",
            format!("bench-wakeup-{}", std::process::id()),
        )
    };
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(tracing_subscriber::EnvFilter::new("warn"))
        .init();
    let config_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../config");

    // plant-sim for the whole benchmark
    let plant_stop = Arc::new(AtomicBool::new(false));
    let plant = {
        let stop = Arc::clone(&plant_stop);
        let opts = grip_plant_sim::Options {
            config: grip_io::service::ConfigArgs::in_dir(&config_dir),
            start_on: Some(grip_plant_sim::StartOn::Immediate),
            ..Default::default()
        };
        std::thread::spawn(move || {
            let start = Arc::new(AtomicBool::new(true));
            if let Err(e) = grip_plant_sim::run(&opts, &stop, &start) {
                eprintln!("plant-sim failed: {e}");
            }
        })
    };
    std::thread::sleep(Duration::from_millis(500));

    eprintln!("tcs-loop: {secs} s at the configured rate ...");
    let tcs = {
        let opts = grip_tcs_loop::Options {
            config: grip_io::service::ConfigArgs::in_dir(&config_dir),
            run_for_s: Some(secs as f64),
            ..Default::default()
        };
        std::thread::spawn(move || {
            let stop = Arc::new(AtomicBool::new(false));
            grip_tcs_loop::run(&opts, &stop)
        })
    };
    let summary = match tcs.join() {
        Ok(Ok(s)) => s,
        Ok(Err(e)) => {
            eprintln!("error: tcs-loop: {e}");
            std::process::exit(1);
        }
        Err(_) => {
            eprintln!("error: tcs-loop thread panicked");
            std::process::exit(1);
        }
    };
    let h = &summary.latency;
    let ours = Stats {
        count: h.count(),
        p50_us: h.p50_ns() as f64 / 1e3,
        p99_us: h.p99_ns() as f64 / 1e3,
        p999_us: h.quantile_ns(0.999) as f64 / 1e3,
        max_us: h.max_ns() as f64 / 1e3,
        over_1ms: summary.late_1ms,
    };

    eprintln!("cyclictest: {secs} s ...");
    let ct = cyclictest(secs);
    plant_stop.store(true, Ordering::Relaxed);
    let _ = plant.join();

    println!();
    println!(
        "conditions: SCHED_FIFO {}, cpu_dma_latency=0 {}, plant-sim running (FIFO 70, CPU 0)",
        if summary.fifo {
            "applied"
        } else {
            "NOT applied"
        },
        if summary.dma_latency {
            "held"
        } else {
            "NOT held"
        },
    );
    println!("| | samples | p50 (µs) | p99 (µs) | p99.9 (µs) | max (µs) | > 1 ms |");
    println!("|---|---|---|---|---|---|---|");
    let row = |name: &str, s: &Stats| {
        println!(
            "| {name} | {} | {:.0} | {:.0} | {:.0} | {:.0} | {} |",
            s.count, s.p50_us, s.p99_us, s.p999_us, s.max_us, s.over_1ms
        );
    };
    row("tcs-loop (1 kHz)", &ours);
    println!(
        "tcs-loop deadline misses: {}, safe-state entries: {}, E2E faults: {}",
        summary.deadline_misses, summary.safe_entries, summary.faults_total
    );
    match ct {
        Ok(c) => {
            row("cyclictest -m -p 80 -i 1000 -t 1", &c);
            let ratio = ours.p99_us / c.p99_us;
            println!(
                "p99 ratio tcs-loop / cyclictest = {ratio:.2} (target <= 1.5: {})",
                if ratio <= 1.5 { "met" } else { "NOT met" }
            );
        }
        Err(e) => println!("cyclictest: {e}"),
    }
}
