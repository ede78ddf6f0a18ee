//! The recorder's sustained write rate against what a drive produces.
//!
//! One "drive second" = 1000 `CycleRecord`s (1 kHz loop), 3200 `CanFrame`s
//! (tcs-loop logs WheelSpeeds + MotorStatus at 1 kHz, VehicleSpeed +
//! DriverDemand at 100 Hz received, TorqueCommand at 1 kHz sent), 1000
//! `GroundTruth`s (plant-sim, 1 kHz), 43 `AudioBlock`s (1024 samples at
//! 44.1 kHz) and 10 `RoadEstimate`s (0.1 s frames): 5253 messages. The
//! bench pushes 5 drive seconds through the recorder's own queue → writer
//! path (`Msg::write_to`, lz4 chunks, 1 s durable flushes, as configured in
//! `config/recorder.toml`) into a file and reports messages/s; the headroom
//! is that rate / 5253. It prints the file's bytes per drive second so
//! MB/s follows.
//!
//! Variant `write_5_drive_seconds_with_bus`: the same drive seconds plus
//! the bus log of a busy car bus, [`BUS_FPS`] foreign frames a second
//! (`recorder.toml` `bus = "foreign"`, channel `grip/can/bus`): 20 ids,
//! 11- and 29-bit, periods 5-100 ms, payloads like a car's (slowly moving
//! signals, a counter nibble, a checksum-like noisy byte). It prints what
//! the bus adds to the file per drive second and per hour.

use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use grip_io::mcaplog::{McapWriter, McapWriterOptions};
use grip_msgs::{
    AudioBlock, BusFrame, CanFrame, CycleRecord, GroundTruth, RoadEstimate, can_flags,
    name_to_bytes,
};
use grip_recorder::Msg;

const SECONDS: u64 = 5;

fn drive_second(sec: u64, out: &mut Vec<Msg>) {
    let t0 = sec * 1_000_000_000;
    let mut noise = 0x1234_5678u32 ^ sec as u32;
    let mut rnd = move || {
        noise ^= noise << 13;
        noise ^= noise >> 17;
        noise ^= noise << 5;
        noise
    };
    for k in 0..1000u64 {
        let t = t0 + k * 1_000_000;
        let mut c = CycleRecord::zeroed();
        c.seq = sec * 1000 + k;
        c.stamp_ns = t;
        c.wakeup_latency_ns = 12_000 + (rnd() % 20_000) as i64;
        c.compute_ns = 3000 + u64::from(rnd() % 2000);
        c.omega = 30.0 + k as f64 * 1e-3 + f64::from(rnd() % 1000) * 1e-6;
        c.v = 8.3 + k as f64 * 1e-3;
        c.v_valid = 1;
        c.torque = 250.0 + f64::from(rnd() % 500) * 0.1;
        c.demand = 300.0;
        c.torque_cmd = 260.0 + f64::from(rnd() % 500) * 0.1;
        c.internal = 0.1;
        c.mu_hat = 0.8;
        out.push(Msg::Cycle(c));
        for (id, every) in [
            (0x120u32, 1u64),
            (0x110, 1),
            (0x130, 10),
            (0x140, 10),
            (0x100, 1),
        ] {
            if k % every == 0 {
                let r = rnd().to_le_bytes();
                let mut f = CanFrame::new(id, &[r[0], (k & 15) as u8, r[1], r[2], r[3], 0, 0, 0]);
                f.stamp_ns = t + 100_000;
                f.direction = u8::from(id == 0x100);
                out.push(Msg::Can(f));
            }
        }
        let mut g = GroundTruth::zeroed();
        g.seq = sec * 1000 + k;
        g.stamp_ns = t;
        g.road_index = 0;
        g.road_name = name_to_bytes("asphalt");
        g.v = 8.3;
        g.omega = 30.0;
        g.lambda = 0.01 + f64::from(rnd() % 100) * 1e-4;
        g.torque = 280.0;
        g.x = k as f64 * 0.008;
        out.push(Msg::Truth(g));
        if k % 100 == 0 {
            let mut r = RoadEstimate::zeroed();
            r.seq = sec * 10 + k / 100;
            r.stamp_ns = t;
            r.class_index = 0;
            r.n_classes = 4;
            r.class_name = name_to_bytes("asphalt");
            r.probabilities[..4].copy_from_slice(&[0.9, 0.05, 0.03, 0.02]);
            r.confidence = 0.9;
            r.lambda_opt = 0.17;
            r.mu_peak = 1.17;
            r.alpha = 0.83;
            out.push(Msg::Road(r));
        }
    }
    for b in 0..43u64 {
        let mut a = AudioBlock::zeroed();
        a.seq = sec * 43 + b;
        a.stamp_ns = t0 + b * 23_219_955;
        a.sample_rate = 44_100;
        a.n_samples = 1024;
        for s in a.samples[..1024].iter_mut() {
            *s = (rnd() % 8000) as i16 - 4000;
        }
        out.push(Msg::Audio(Box::new(a)));
    }
}

/// Foreign frames a second on the busy car bus of the bus variant.
const BUS_FPS: u64 = 2000;

/// One second of a busy car bus's foreign traffic ([`BUS_FPS`] frames):
/// (id, extended, period ms) chosen so that the rates add up to 2000/s.
fn bus_second(sec: u64, out: &mut Vec<Msg>) {
    // 1000/5*4 + 1000/10*8 + 1000/20*4 + 1000/100*4 = 800+800+200+40 = 1840,
    // + 4 ids at 1000/25 = 160: 2000 frames/s
    let ids: [(u32, bool, u64); 24] = [
        (0x0A0, false, 5),
        (0x0A8, false, 5),
        (0x1F0, false, 5),
        (0x0C4_F100, true, 5),
        (0x130 + 0x200, false, 10),
        (0x340, false, 10),
        (0x348, false, 10),
        (0x3E9, false, 10),
        (0x18F0_0400, true, 10),
        (0x18FE_F100, true, 10),
        (0x0CF0_0300, true, 10),
        (0x260, false, 10),
        (0x4F0, false, 20),
        (0x4F8, false, 20),
        (0x18FE_E000, true, 20),
        (0x18FE_EE00, true, 20),
        (0x5A0, false, 100),
        (0x5A8, false, 100),
        (0x18FE_CA00, true, 100),
        (0x7DF, false, 100),
        (0x2A0, false, 25),
        (0x2A8, false, 25),
        (0x18FF_0010, true, 25),
        (0x18FF_0020, true, 25),
    ];
    let t0 = sec * 1_000_000_000;
    let mut noise = 0x9E37_79B9u32 ^ sec as u32;
    for ms in 0..1000u64 {
        for (k, &(id, ext, period)) in ids.iter().enumerate() {
            if ms % period != 0 {
                continue;
            }
            noise ^= noise << 13;
            noise ^= noise >> 17;
            noise ^= noise << 5;
            let n = (sec * 1000 + ms) / period;
            let slow = ((n / 8) as u16).wrapping_mul(k as u16 + 1).to_le_bytes();
            let mut data = [slow[0], slow[1], 0x40, k as u8, 0, 0x7D, (n & 15) as u8, 0];
            data[4] = (noise & 0x0F) as u8;
            data[7] = (noise >> 8) as u8;
            out.push(Msg::Bus(BusFrame {
                stamp_ns: t0 + ms * 1_000_000 + k as u64 * 13_000,
                id,
                dlc: 8,
                bus: 0,
                flags: if ext { can_flags::EXTENDED } else { 0 },
                _reserved: 0,
                data,
            }));
        }
    }
}

fn write_all(msgs: &[Msg], dir: &std::path::Path) -> u64 {
    let path = dir.join("bench.mcap");
    let mut w = McapWriter::create(&path, McapWriterOptions::default()).unwrap();
    for m in msgs {
        m.write_to(&mut w).unwrap();
    }
    w.finish().unwrap();
    std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0)
}

fn bench(c: &mut Criterion) {
    let mut msgs = Vec::new();
    for s in 0..SECONDS {
        drive_second(s, &mut msgs);
    }
    let dir = tempfile::tempdir().unwrap();
    let t = Instant::now();
    let bytes = write_all(&msgs, dir.path());
    let el = t.elapsed();
    eprintln!(
        "write_rate: {} messages per drive second, {} bytes per drive second in the file (lz4), one pass: {:.0} msg/s, {:.1} MB/s of file, {:.0}x real time",
        msgs.len() as u64 / SECONDS,
        bytes / SECONDS,
        msgs.len() as f64 / el.as_secs_f64(),
        bytes as f64 / el.as_secs_f64() / 1e6,
        SECONDS as f64 / el.as_secs_f64()
    );
    let mut g = c.benchmark_group("recorder");
    g.throughput(Throughput::Elements(msgs.len() as u64));
    g.measurement_time(Duration::from_secs(8));
    g.sample_size(10);
    g.bench_function("write_5_drive_seconds", |b| {
        b.iter(|| write_all(&msgs, dir.path()))
    });
    g.finish();

    // the same drive seconds with a busy car bus's foreign frames, each
    // second's bus frames after its drive messages (the order the
    // recorder's queue sees them in does not change the bytes much)
    let mut with_bus = Vec::new();
    let mut bus_msgs = 0u64;
    for s in 0..SECONDS {
        drive_second(s, &mut with_bus);
        let before = with_bus.len();
        bus_second(s, &mut with_bus);
        bus_msgs += (with_bus.len() - before) as u64;
    }
    assert_eq!(bus_msgs, BUS_FPS * SECONDS, "the bus variant's frame rate");
    let t = Instant::now();
    let bytes_bus = write_all(&with_bus, dir.path());
    let el = t.elapsed();
    let added = bytes_bus.saturating_sub(bytes) / SECONDS;
    eprintln!(
        "write_rate with bus: {} messages per drive second ({} bus frames), {} bytes per drive second in the file (lz4): the bus adds {added} bytes/s = {:.2} GB per hour ({:.1} bytes per frame); one pass: {:.0} msg/s, {:.0}x real time",
        with_bus.len() as u64 / SECONDS,
        BUS_FPS,
        bytes_bus / SECONDS,
        added as f64 * 3600.0 / 1e9,
        added as f64 / BUS_FPS as f64,
        with_bus.len() as f64 / el.as_secs_f64(),
        SECONDS as f64 / el.as_secs_f64()
    );
    let mut g = c.benchmark_group("recorder");
    g.throughput(Throughput::Elements(with_bus.len() as u64));
    g.measurement_time(Duration::from_secs(8));
    g.sample_size(10);
    g.bench_function("write_5_drive_seconds_with_bus", |b| {
        b.iter(|| write_all(&with_bus, dir.path()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
