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
    // the same message of a protocol read from a DBC (tests/data/own-bus.dbc:
    // MotorStatus there is Motorola, MotorSpeed in rpm), not installed: the
    // spec is passed, so the two rows compare layouts, not the lookup
    let (path, names) = (
        grip_testkit::own_bus::dbc_path(),
        grip_testkit::own_bus::names(),
    );
    let own: &'static Protocol = Box::leak(Box::new(Protocol::load_dbc(&path, &names).unwrap()));
    for (label, p) in [
        ("built-in (Intel)", Protocol::builtin()),
        ("own-bus.dbc (Motorola)", own),
    ] {
        let spec: &'static MessageSpec = p.spec(MsgKind::MotorStatus);
        let mut rx = E2eReceiver::new(spec);
        let mut k = 0u8;
        c.bench_function(
            &format!("encode_in+check+decode_as MotorStatus, {label}"),
            |b| {
                b.iter(|| {
                    t += 1_000_000;
                    k = k.wrapping_add(1);
                    let f = encode_in(spec, black_box(&m), k, t);
                    let _ = rx.check(black_box(&f), t);
                    black_box(InverterMsg::decode_as(spec, &f.data))
                })
            },
        );
    }
    c.bench_function("crc8 j1850 (9 bytes)", |b| {
        let d = [1u8, 2, 3, 4, 5, 6, 7, 8, 9];
        b.iter(|| crc8_j1850(black_box(&d)))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
