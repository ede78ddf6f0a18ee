//! Encode + E2E check + decode of one inverter frame.
use criterion::{Criterion, criterion_group, criterion_main};
use grip_io::can::protocol::*;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let mut tx = E2eSender::<MotorStatus>::new();
    let mut rx = ProtocolRx::for_tcs();
    let m = MotorStatus {
        ready: true,
        torque_actual: 187.3,
        motor_speed: 31.4,
        ..MotorStatus::default()
    };
    let mut t = 0u64;
    c.bench_function("encode+e2e+decode MotorStatus", |b| {
        b.iter(|| {
            t += 1_000_000;
            let f = tx.encode(black_box(&m), t);
            black_box(rx.receive(black_box(&f), t).ok())
        })
    });
    c.bench_function("crc8 j1850 (9 bytes)", |b| {
        let d = [1u8, 2, 3, 4, 5, 6, 7, 8, 9];
        b.iter(|| crc8_j1850(black_box(&d)))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
