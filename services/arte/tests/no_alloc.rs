//! The arte loop allocates nothing per block after warm-up (blocks from the
//! synthesiser, a model trained here); into a real iceoryx2 publisher it
//! allocates exactly iceoryx2's one per published estimate.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use common::*;
use grip_arte::stream::StreamConfig;
use grip_arte_svc::{ArteLoop, ArteStats, EstimateSink};
use grip_io::clock::ManualClock;
use grip_io::ipc::{IpcError, IpcNode, SubscriberMode};
use grip_msgs::{RoadEstimate, topics};

struct Counting;
static ALLOCS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static A: Counting = Counting;

fn allocs() -> usize {
    ALLOCS.load(Ordering::SeqCst)
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

// One test function only, so no other test thread allocates meanwhile.
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
    let stats = ArteStats::default();
    let mut sink = CountSink::default();
    for b in &bl[..10] {
        lp.on_block(b, &mut sink, &stats);
    }
    let before = allocs();
    for b in &bl[10..] {
        lp.on_block(b, &mut sink, &stats);
    }
    let a = allocs() - before;
    assert_eq!(a, 0, "{a} allocations in {} blocks", bl.len() - 10);
    assert!(sink.0 > 100);
    assert_eq!(stats.lost_blocks.load(Ordering::Relaxed), 1);
    assert_eq!(stats.resets.load(Ordering::Relaxed), 1);
    assert_eq!(stats.rate_mismatch.load(Ordering::Relaxed), 1);

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
    let mut lp = ArteLoop::from_model(&model, &StreamConfig::default(), roads, 0.2, clock).unwrap();
    let bl = blocks(6, &[("gravel", 10.0, 3.0)], 1024, 1_000_000_000);
    for b in &bl[..10] {
        lp.on_block(b, &mut publisher, &stats);
        while sub.recv().unwrap().is_some() {}
    }
    let before = allocs();
    let mut sent = 0;
    let mut got = 0;
    for b in &bl[10..] {
        sent += lp.on_block(b, &mut publisher, &stats);
        while sub.recv().unwrap().is_some() {
            got += 1;
        }
    }
    let a = allocs() - before;
    assert!(sent > 40);
    assert_eq!(got, sent);
    // iceoryx2 0.10's loan allocates one Arc per published sample
    // (crates/io/README.md, "Allocation on the hot path").
    assert_eq!(a, sent, "{a} allocations for {sent} published estimates");
}
