//! What a subscriber connecting costs the publishing loop: a 1 kHz
//! publisher of `CycleRecord`s (tcs-loop's cycle-record topic, the
//! recorder's deep subscriber) timed call by call, first with no new
//! subscriber, then while another process keeps creating and dropping one,
//! as a recorder that starts or restarts does.
//!
//! ```text
//! cargo bench -p grip-io --bench subscriber_churn
//! GRIP_BENCH_N=3000 (cycles per phase)  GRIP_BENCH_HOLD_MS=100 (each subscriber's life and the gap after it)
//! ```
//!
//! iceoryx2 (0.10) sets up the connection to a new subscriber in the
//! publisher's next `send` (`update_connections`), i.e. in the loop's
//! cycle; under `mlockall(MCL_FUTURE)` (what the services do) every new
//! mapping is populated there too. The publisher runs as the services do
//! where this machine permits: `mlockall`, SCHED_FIFO 60; the report says
//! which applied. It prints, per phase, the `publish()` durations (p50,
//! p99, p99.9, max) and how many exceeded 100 µs and 1 ms, and the ratio
//! of the churn phase's worst call to the quiet phase's.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use grip_io::clock::monotonic_now_ns;
use grip_io::ipc::{IpcNode, Publisher, SubscriberMode};
use grip_io::rt::{LatencyHistogram, lock_memory, set_fifo_priority};
use grip_msgs::CycleRecord;

const PERIOD_NS: u64 = 1_000_000;

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn sleep_until(t_ns: u64) {
    let now = monotonic_now_ns();
    if t_ns > now {
        std::thread::sleep(Duration::from_nanos(t_ns - now));
    }
}

/// What one phase measured.
struct Phase {
    /// Duration of every `publish()` call.
    hist: LatencyHistogram,
    /// Calls over 100 µs and over 1 ms.
    over_100us: u64,
    over_1ms: u64,
    /// Records the subscribers got.
    delivered: u64,
}

/// One phase: `n` cycles at 1 kHz, each publishing one record.
fn phase(p: &Publisher<CycleRecord>, n: u64) -> anyhow::Result<Phase> {
    let mut ph = Phase {
        hist: LatencyHistogram::new(100_000),
        over_100us: 0,
        over_1ms: 0,
        delivered: 0,
    };
    let mut rec = CycleRecord::zeroed();
    let mut next = monotonic_now_ns() + PERIOD_NS;
    for k in 0..n {
        sleep_until(next);
        next += PERIOD_NS;
        rec.seq = k;
        let t0 = monotonic_now_ns();
        let got = p.publish(&rec)?;
        let t1 = monotonic_now_ns();
        let d = t1 - t0;
        ph.hist.record(d as i64);
        ph.over_100us += u64::from(d > 100_000);
        ph.over_1ms += u64::from(d > 1_000_000);
        ph.delivered += got as u64;
    }
    Ok(ph)
}

/// The child: a subscriber created, held (drained every ms) for `hold_ms`,
/// dropped, then `hold_ms` without, until `total_ms` have passed; prints
/// how many it created.
fn churn(topic: &str, hold_ms: u64, total_ms: u64) -> anyhow::Result<()> {
    let node = IpcNode::create("bench_churn_sub")?;
    let end = monotonic_now_ns() + total_ms * 1_000_000;
    let mut created = 0u32;
    while monotonic_now_ns() < end {
        let sub = node.subscriber::<CycleRecord>(topic, SubscriberMode::Deep)?;
        created += 1;
        let until = monotonic_now_ns() + hold_ms * 1_000_000;
        while monotonic_now_ns() < until {
            sub.drain(|_| {})?;
            std::thread::sleep(Duration::from_millis(1));
        }
        drop(sub);
        std::thread::sleep(Duration::from_millis(hold_ms));
    }
    println!("created {created}");
    Ok(())
}

fn row(name: &str, ph: &Phase) {
    let h = &ph.hist;
    let us = |ns: u64| ns as f64 / 1e3;
    println!(
        "| {name} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} |",
        h.count(),
        us(h.p50_ns()),
        us(h.p99_ns()),
        us(h.quantile_ns(0.999)),
        us(h.max_ns()),
        ph.over_100us,
        ph.over_1ms,
    );
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--churn-child") {
        let topic = &args[i + 1];
        let hold: u64 = args[i + 2].parse()?;
        let total: u64 = args[i + 3].parse()?;
        return churn(topic, hold, total);
    }
    let n = env_or("GRIP_BENCH_N", 3000);
    let hold = env_or("GRIP_BENCH_HOLD_MS", 100);
    let topic = format!("grip/bench/churn/{}", std::process::id());

    let lock = lock_memory();
    let fifo = set_fifo_priority(60);
    let node = IpcNode::create("bench_churn_pub")?;
    let publisher = node.publisher::<CycleRecord>(&topic)?;
    // warm-up: the first loans and sends touch the data segment
    phase(&publisher, 200)?;

    let quiet = phase(&publisher, n)?;
    let mut child = Command::new(std::env::current_exe()?)
        .args([
            "--churn-child",
            &topic,
            &hold.to_string(),
            &(n + 500).to_string(),
        ])
        .stdout(Stdio::piped())
        .spawn()?;
    std::thread::sleep(Duration::from_millis(100));
    let busy = phase(&publisher, n)?;
    let out = child.stdout.take().expect("piped");
    let created = BufReader::new(out)
        .lines()
        .map_while(Result::ok)
        .find_map(|l| {
            l.strip_prefix("created ")
                .and_then(|v| v.parse::<u32>().ok())
        })
        .unwrap_or(0);
    let st = child.wait()?;
    anyhow::ensure!(st.success(), "the subscriber process exited with {st}");

    println!(
        "subscriber churn: mlockall {}, SCHED_FIFO 60 {}; {n} cycles at 1 kHz per phase; {created} subscribers created and dropped ({hold} ms each, {hold} ms apart), {} records delivered to them",
        if lock.is_applied() {
            "applied"
        } else {
            "not applied"
        },
        if fifo.is_applied() {
            "applied"
        } else {
            "not applied"
        },
        busy.delivered,
    );
    println!("| phase | calls | p50 µs | p99 µs | p99.9 µs | max µs | > 100 µs | > 1 ms |");
    println!("|---|---|---|---|---|---|---|---|");
    row("no new subscriber", &quiet);
    row(
        &format!("a subscriber connecting every {} ms", 2 * hold),
        &busy,
    );
    println!(
        "worst publish with churn / without: {:.1}",
        busy.hist.max_ns() as f64 / quiet.hist.max_ns().max(1) as f64
    );
    Ok(())
}
