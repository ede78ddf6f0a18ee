//! What a retention sweep costs the writing thread when it deletes
//! nothing (the steady state, paid every 10 s while recording): listing
//! `out_dir`, `lstat` of each log, `statvfs`, the plan. The directory holds
//! 1000 logs (about 25 days of an hour's driving a day in one-hour logs, or
//! a year of short drives) and 100 foreign files; the budget and the floor
//! both hold, so nothing is deleted. Deleting is the kernel's `unlink`,
//! measured on its own (`services/recorder/README.md`, "Retention").

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use grip_recorder::retention::{Limits, Retention};

fn sweep(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temporary directory");
    for i in 0..1000u32 {
        let boot = if i < 990 { "aaaaaaaa" } else { "bbbbbbbb" };
        let f = std::fs::File::create(dir.path().join(format!(
            "grip-{}-{boot}-{}.mcap",
            1_700_000_000 + i,
            300 + i
        )))
        .expect("log file");
        f.set_len(1 << 20).expect("length");
    }
    for i in 0..100u32 {
        std::fs::write(dir.path().join(format!("notes-{i}.txt")), b"x").expect("foreign file");
    }
    let cur = dir.path().join("grip-1800000000-bbbbbbbb-9999.mcap");
    std::fs::write(&cur, b"").expect("current log");
    let mut r = Retention::new(
        dir.path(),
        &cur,
        Limits {
            max_total: 2000 << 20,
            min_free: 1 << 20,
        },
    );
    c.bench_function("sweep 1000 logs + 100 foreign, nothing deleted", |b| {
        b.iter(|| {
            let s = r.sweep();
            assert!(s.deleted.is_empty());
            s.took
        });
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().measurement_time(Duration::from_secs(5));
    targets = sweep
}
criterion_main!(benches);
