//! The arte loop allocates nothing per block after warm-up (blocks from the
//! synthesiser, a model trained here, vehicle speeds from cycle records
//! that come and go stale); into a real iceoryx2 publisher, with the cycle
//! records over a real iceoryx2 topic, it allocates exactly iceoryx2's one
//! per published sample (estimates and the test's cycle records).

mod common;

use std::sync::atomic::Ordering;

use common::*;
use grip_arte::stream::StreamConfig;
use grip_arte_svc::{ArteCounters, ArteLoop, EstimateSink};
use grip_io::clock::ManualClock;
use grip_io::ipc::{IpcError, IpcNode, SubscriberMode};
use grip_msgs::{CycleRecord, RoadEstimate, topics};

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

/// This thread's allocations so far. Everything measured runs on the test's
/// thread; the harness's main thread may allocate meanwhile and must not
/// count (a process-wide count failed CI that way).
fn allocs() -> usize {
    grip_testkit::thread_allocations() as usize
}

#[derive(Default)]
struct CountSink(u64, f64);
impl EstimateSink for CountSink {
    fn send(&mut self, e: &RoadEstimate) -> Result<(), IpcError> {
        self.0 += 1;
        self.1 += e.confidence;
        Ok(())
    }
}

#[test]
fn arte_loop_allocates_nothing_per_block() {
    let model = train_model(1);
    let roads = roads_for(&model);
    // road changes, a lost block, a discontinuity and a wrong-rate block
    // inside the measured stretch
    let mut bl = blocks(
        5,
        &[
            ("asphalt", 10.0, 2.0),
            ("snow", 12.0, 2.0),
            ("stone", 8.0, 2.0),
        ],
        1024,
        1_000_000_000,
    );
    bl.remove(100);
    bl[150].stamp_ns += 500_000_000;
    for b in &mut bl[151..] {
        b.stamp_ns += 500_000_000;
    }
    bl[200].sample_rate = 48_000;
    let clock = ManualClock::new(0);
    let mut lp = ArteLoop::from_model(
        &model,
        &StreamConfig::default(),
        roads.clone(),
        0.2,
        clock.clone(),
    )
    .unwrap();
    let stats = ArteCounters::default();
    let mut sink = CountSink::default();
    // the clock follows the blocks; a valid cycle record for the first 20
    // of every 40 blocks (then it goes stale after 0.2 s), an invalid one
    // otherwise
    let feed = |lp: &mut ArteLoop<_, ManualClock>, k: usize, b: &grip_msgs::AudioBlock| {
        clock.set_ns(b.stamp_ns);
        lp.on_cycle(&cycle(k, b.stamp_ns, k % 40 < 20), &stats);
    };
    for (k, b) in bl[..10].iter().enumerate() {
        feed(&mut lp, k, b);
        lp.on_block(b, &mut sink, &stats);
    }
    let before = allocs();
    for (k, b) in bl.iter().enumerate().skip(10) {
        feed(&mut lp, k, b);
        lp.on_block(b, &mut sink, &stats);
    }
    let a = allocs() - before;
    assert_eq!(a, 0, "{a} allocations in {} blocks", bl.len() - 10);
    assert!(sink.0 > 100);
    assert_eq!(stats.lost_blocks.load(Ordering::Relaxed), 1);
    assert_eq!(stats.resets.load(Ordering::Relaxed), 1);
    assert_eq!(stats.rate_mismatch.load(Ordering::Relaxed), 1);
    // both speed paths ran
    let with = stats.blocks_with_speed.load(Ordering::Relaxed);
    let without = stats.blocks_without_speed.load(Ordering::Relaxed);
    assert!(with > 100 && without > 30, "{with} with, {without} without");
    assert_eq!(with + without, bl.len() as u64 - 1);

    // into iceoryx2
    // SAFETY: single test function; set before any iceoryx2 use.
    unsafe {
        std::env::set_var(
            grip_io::ipc::INSTANCE_ENV,
            format!("arte_noalloc_{}", std::process::id()),
        )
    };
    let node = IpcNode::create("arte-test").unwrap();
    let mut publisher = node.publisher::<RoadEstimate>(topics::ROAD).unwrap();
    let sub = node
        .subscriber::<RoadEstimate>(topics::ROAD, SubscriberMode::Deep)
        .unwrap();
    // the service's cycle subscription (latest value) and a stand-in tcs-loop
    let cycles = node
        .subscriber::<CycleRecord>(topics::CYCLE, SubscriberMode::Latest)
        .unwrap();
    let tcs = node.publisher::<CycleRecord>(topics::CYCLE).unwrap();
    let stats = ArteCounters::default();
    // (a manual clock never goes back: a new one for this timeline)
    let clock = ManualClock::new(0);
    let mut lp =
        ArteLoop::from_model(&model, &StreamConfig::default(), roads, 0.2, clock.clone()).unwrap();
    let bl = blocks(6, &[("gravel", 10.0, 3.0)], 1024, 1_000_000_000);
    // per block: 0, 1 or 2 cycle records (valid for the first 20 of every
    // 40 blocks, then invalid; none every third block), the drain, the block
    let mut step = |k: usize, b: &grip_msgs::AudioBlock, lp: &mut ArteLoop<_, ManualClock>| {
        clock.set_ns(b.stamp_ns);
        for j in 0..(k % 3) {
            tcs.publish(&cycle(k * 2 + j, b.stamp_ns, k % 40 < 20))
                .unwrap();
        }
        lp.poll_cycles(&cycles, &stats);
        let n = lp.on_block(b, &mut publisher, &stats);
        let mut got = 0;
        while sub.recv().unwrap().is_some() {
            got += 1;
        }
        (n, got, k % 3)
    };
    let mut records = 0;
    for (k, b) in bl[..10].iter().enumerate() {
        records += step(k, b, &mut lp).2;
    }
    let before = allocs();
    let mut sent = 0;
    let mut got = 0;
    let mut published = 0;
    for (k, b) in bl.iter().enumerate().skip(10) {
        let (n, g, r) = step(k, b, &mut lp);
        sent += n;
        got += g;
        published += r;
    }
    let a = allocs() - before;
    records += published;
    assert!(sent > 40);
    assert_eq!(got, sent);
    assert!(published > 80, "{published} cycle records");
    let with = stats.blocks_with_speed.load(Ordering::Relaxed);
    let without = stats.blocks_without_speed.load(Ordering::Relaxed);
    assert!(with > 50 && without > 20, "{with} with, {without} without");
    // the latest-value subscriber hands over at most one record per drain
    assert!(stats.cycle_records.load(Ordering::Relaxed) < records as u64);
    // iceoryx2 0.10's loan allocates one Arc per published sample
    // (crates/io/README.md, "Allocation on the hot path"): the estimates
    // and the test's cycle records; receiving and the loop add nothing.
    assert_eq!(
        a,
        sent + published,
        "{a} allocations for {sent} published estimates and {published} cycle records"
    );
}

/// A cycle record stamped `stamp_ns` at 10 m/s plus a little, valid or not.
fn cycle(k: usize, stamp_ns: u64, valid: bool) -> CycleRecord {
    let mut r = CycleRecord::zeroed();
    r.seq = k as u64;
    r.stamp_ns = stamp_ns;
    r.v = if valid {
        10.0 + k as f64 * 1e-3
    } else {
        f64::NAN
    };
    r.v_valid = u8::from(valid);
    r
}
