//! Audio-block publish-to-receive latency between two processes: iceoryx2
//! (grip's `AUDIO` topic, the real `AudioBlock` payload, 1024 valid
//! samples) against a Unix datagram socket carrying the same bytes, in the
//! same run.
//!
//! ```text
//! cargo bench -p grip-audio-acq --bench ipc_latency
//! GRIP_BENCH_N=10000 GRIP_BENCH_PERIOD_US=1000 (defaults)
//! ```
//!
//! The bench process publishes (pinned to CPU 0, SCHED_FIFO 60 where
//! permitted, paced by an absolute 1 ms timer, holding
//! /dev/cpu_dma_latency = 0); it spawns itself as the receiver (pinned to
//! CPU 1). One-way latency = receiver's CLOCK_MONOTONIC at receipt − the
//! stamp the publisher wrote immediately before publishing (one clock for
//! both processes). 500 warm-up blocks are not counted. Modes:
//! - `iox-poll`: receiver busy-polls the iceoryx2 subscriber (SCHED_OTHER:
//!   spinning at FIFO priority would be throttled);
//! - `uds-poll`: receiver busy-polls a non-blocking Unix datagram socket;
//! - `iox-event`: publisher also notifies an iceoryx2 event; receiver
//!   (SCHED_FIFO 50) sleeps in `Listener::timed_wait`, then drains;
//! - `uds-block`: receiver (SCHED_FIFO 50) sleeps in a blocking `recv`.
//!
//! Each receive copies the 8 224-byte block out (as `arte` does).

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixDatagram;
use std::process::{Command, Stdio};
use std::time::Duration;

use grip_io::clock::{Clock, MonotonicClock, monotonic_now_ns};
use grip_io::ipc::{IpcNode, SubscriberMode};
use grip_msgs::{AudioBlock, topics};
use iceoryx2::prelude::*;

const WARM: usize = 500;
const SIZE: usize = core::mem::size_of::<AudioBlock>();
const MODES: [&str; 4] = ["iox-poll", "uds-poll", "iox-event", "uds-block"];
const EVENT: &str = "grip/bench/audio/wake";

fn as_bytes(b: &AudioBlock) -> &[u8] {
    // SAFETY: AudioBlock is repr(C), Copy, without padding (grip-msgs pins
    // its layout); viewing it as bytes is sound.
    unsafe { core::slice::from_raw_parts((b as *const AudioBlock).cast::<u8>(), SIZE) }
}

fn from_bytes(buf: &[u8]) -> AudioBlock {
    let mut b = AudioBlock::zeroed();
    // SAFETY: buf holds SIZE bytes of a block sent by as_bytes; every bit
    // pattern is a valid AudioBlock (integers only).
    unsafe {
        core::ptr::copy_nonoverlapping(buf.as_ptr(), (&mut b as *mut AudioBlock).cast::<u8>(), SIZE)
    };
    b
}

fn event_ports(
    node: &IpcNode,
) -> (
    iceoryx2::port::notifier::Notifier<ipc::Service>,
    iceoryx2::port::listener::Listener<ipc::Service>,
) {
    let name: ServiceName = EVENT.try_into().unwrap();
    let ev = node
        .raw()
        .service_builder(&name)
        .event()
        .max_notifiers(4)
        .max_listeners(4)
        .open_or_create()
        .unwrap();
    (
        ev.notifier_builder().create().unwrap(),
        ev.listener_builder().create().unwrap(),
    )
}

fn child(mode: &str, n: usize, sock: &str) {
    let _ = grip_io::rt::pin_to_cpus(&[1]);
    if mode.ends_with("event") || mode.ends_with("block") {
        let _ = grip_io::rt::set_fifo_priority(50);
    }
    let _ = grip_io::rt::lock_memory();
    let total = n + WARM;
    let mut lat: Vec<u64> = Vec::with_capacity(total);
    let mut last_seq: Option<u64> = None;
    let mut lost = 0u64;
    let mut record = |b: &AudioBlock, now: u64, lat: &mut Vec<u64>| {
        lat.push(now.saturating_sub(b.stamp_ns));
        if let Some(s) = last_seq {
            lost += b.seq - s - 1;
        }
        last_seq = Some(b.seq);
        assert_eq!(b.n_samples, 1024);
    };
    let stdout = std::io::stdout();
    if mode.starts_with("iox") {
        let node = IpcNode::create("bench-sub").unwrap();
        let sub = node
            .subscriber::<AudioBlock>(topics::AUDIO, SubscriberMode::Deep)
            .unwrap();
        let ports = mode.ends_with("event").then(|| event_ports(&node));
        writeln!(stdout.lock(), "ready").unwrap();
        while lat.len() < total {
            if let Some((_, l)) = &ports {
                l.timed_wait(|_| {}, Duration::from_millis(100)).unwrap();
            }
            while let Some(b) = sub.recv().unwrap() {
                let now = monotonic_now_ns();
                record(&b, now, &mut lat);
            }
        }
    } else {
        let _ = std::fs::remove_file(sock);
        let s = UnixDatagram::bind(sock).unwrap();
        let poll = mode.ends_with("poll");
        s.set_nonblocking(poll).unwrap();
        if !poll {
            s.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        }
        let mut buf = vec![0u8; SIZE + 16];
        writeln!(stdout.lock(), "ready").unwrap();
        while lat.len() < total {
            match s.recv(&mut buf) {
                Ok(k) => {
                    let now = monotonic_now_ns();
                    assert_eq!(k, SIZE);
                    let b = from_bytes(&buf[..SIZE]);
                    record(&b, now, &mut lat);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => panic!("recv: {e}"),
            }
        }
    }
    let mut v = lat[WARM..].to_vec();
    v.sort_unstable();
    let q = |p: f64| v[((p * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
    let mean = v.iter().sum::<u64>() as f64 / v.len() as f64;
    writeln!(
        stdout.lock(),
        "result {} {} {} {} {} {} {:.0} {}",
        v.len(),
        q(0.5),
        q(0.9),
        q(0.99),
        q(0.999),
        v[v.len() - 1],
        mean,
        lost
    )
    .unwrap();
}

fn parent_run(mode: &str, n: usize, period_ns: u64) -> String {
    let sock = std::env::temp_dir().join(format!("grip_bench_{}.sock", std::process::id()));
    let exe = std::env::current_exe().unwrap();
    let mut ch = Command::new(exe)
        .args(["child", mode, &n.to_string(), sock.to_str().unwrap()])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(ch.stdout.take().unwrap());
    let node = IpcNode::create("bench-pub").unwrap();
    let publisher = node.publisher::<AudioBlock>(topics::AUDIO).unwrap();
    let ports = mode.ends_with("event").then(|| event_ports(&node));
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    assert_eq!(line.trim(), "ready", "child: {line}");
    let uds = UnixDatagram::unbound().unwrap();
    let mut b = AudioBlock::zeroed();
    b.sample_rate = 44_100;
    b.n_samples = 1024;
    for (i, s) in b.samples[..1024].iter_mut().enumerate() {
        *s = (i as i16).wrapping_mul(31);
    }
    let clock = MonotonicClock;
    let mut next = clock.now_ns() + 10_000_000;
    for k in 0..(n + WARM) as u64 {
        clock.sleep_until_ns(next);
        next += period_ns;
        b.seq = k;
        b.stamp_ns = monotonic_now_ns();
        if mode.starts_with("iox") {
            publisher.publish(&b).unwrap();
            if let Some((nt, _)) = &ports {
                nt.notify().unwrap();
            }
        } else {
            uds.send_to(as_bytes(&b), &sock).unwrap();
        }
    }
    line.clear();
    out.read_line(&mut line).unwrap();
    ch.wait().unwrap();
    let _ = std::fs::remove_file(&sock);
    line
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("child") {
        child(&args[2], args[3].parse().unwrap(), &args[4]);
        return;
    }
    let n: usize = std::env::var("GRIP_BENCH_N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    let period_us: u64 = std::env::var("GRIP_BENCH_PERIOD_US")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1000);
    // SAFETY: set before any thread or iceoryx2 use; inherited by the child.
    unsafe {
        std::env::set_var(
            grip_io::ipc::INSTANCE_ENV,
            format!("bench_{}", std::process::id()),
        )
    };
    let _ = grip_io::rt::pin_to_cpus(&[0]);
    let _ = grip_io::rt::lock_memory();
    let (_dma, dma) = grip_io::rt::DmaLatencyGuard::hold();
    let fifo = grip_io::rt::set_fifo_priority(60);
    println!(
        "AudioBlock {SIZE} B (1024 valid samples), {n} blocks + {WARM} warm-up per mode, one every {period_us} us; publisher CPU 0 (SCHED_FIFO: {}), receiver CPU 1; cpu_dma_latency=0: {}",
        fifo.is_applied(),
        dma.is_applied()
    );
    println!("| mode | n | p50 µs | p90 µs | p99 µs | p99.9 µs | max µs | mean µs | lost |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let us = |s: &str| format!("{:.2}", s.parse::<f64>().unwrap() / 1000.0);
    for mode in MODES {
        let r = parent_run(mode, n, period_us * 1000);
        let f: Vec<&str> = r.split_whitespace().collect();
        assert_eq!(f.first(), Some(&"result"), "{mode}: {r}");
        println!(
            "| {mode} | {} | {} | {} | {} | {} | {} | {} | {} |",
            f[1],
            us(f[2]),
            us(f[3]),
            us(f[4]),
            us(f[5]),
            us(f[6]),
            us(f[7]),
            f[8]
        );
    }
}
