//! MCAP write rate of cycle records (JSON, lz4 / zstd single-thread / none),
//! 10 000 records per iteration into a temporary file, finish included.
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use grip_io::mcaplog::{Compression, McapWriter, McapWriterOptions};
use grip_msgs::{CycleRecord, topics};

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mut g = c.benchmark_group("mcap write CycleRecord");
    g.throughput(Throughput::Elements(10_000));
    g.sample_size(10);
    for comp in [Compression::None, Compression::Lz4, Compression::Zstd] {
        g.bench_function(format!("{comp:?}"), |b| {
            b.iter(|| {
                let path = dir.path().join("bench.mcap");
                let mut w = McapWriter::create(
                    &path,
                    McapWriterOptions {
                        compression: comp,
                        ..McapWriterOptions::default()
                    },
                )
                .unwrap();
                let mut r = CycleRecord::zeroed();
                for i in 0..10_000u64 {
                    r.seq = i;
                    r.stamp_ns = i * 1_000_000;
                    r.omega = 30.0 + i as f64 * 1e-3;
                    r.torque_cmd = 187.0 - i as f64 * 1e-2;
                    w.write(topics::CYCLE, &r).unwrap();
                }
                w.finish().unwrap();
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
