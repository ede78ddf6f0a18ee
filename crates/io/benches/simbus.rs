//! SimBus publish-to-receive within one process (two participants, one
//! thread: send on A, try_recv on B), and a typed CycleRecord publish+latest.
use criterion::{Criterion, criterion_group, criterion_main};
use grip_io::can::{CanBus, SimBus};
use grip_io::ipc::{IpcNode, SubscriberMode};
use grip_msgs::{CanFrame, CycleRecord};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let node = IpcNode::create("bench-simbus").unwrap();
    let name = format!("bench_{}", std::process::id());
    let mut a = SimBus::open(&node, &name, 0).unwrap();
    let mut b = SimBus::open(&node, &name, 0).unwrap();
    let f = CanFrame::new(0x110, &[1, 2, 3, 4, 5, 6, 7, 8]);
    c.bench_function("simbus send+recv (in-process)", |bn| {
        bn.iter(|| {
            a.send(black_box(&f)).unwrap();
            black_box(b.try_recv().unwrap())
        })
    });
    let topic = format!("grip/bench/cycle_{}", std::process::id());
    let p = node.publisher::<CycleRecord>(&topic).unwrap();
    let s = node
        .subscriber::<CycleRecord>(&topic, SubscriberMode::Latest)
        .unwrap();
    let r = CycleRecord::zeroed();
    c.bench_function("CycleRecord publish+latest (in-process)", |bn| {
        bn.iter(|| {
            p.publish(black_box(&r)).unwrap();
            black_box(s.latest().unwrap())
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
