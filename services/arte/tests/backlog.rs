//! A backlog of audio (arte stopped for 2 s, or starved of CPU) never turns
//! into estimates of old audio published as new: the live entry
//! [`ArteLoop::on_live_block`] drops blocks whose audio ended more than
//! `input.max_lag_s` before the loop took them, counts them, and starts a
//! fresh frame at the next block in time. Without the bound the same feed
//! publishes estimates of audio two seconds old (the test's own check that
//! it can fail). Allocation-free like the rest of the loop.

mod common;
use std::sync::atomic::Ordering;

use common::{Toy, VecSink};
use grip_arte::features::{FeatureConfig, FeatureSet};
use grip_arte::stream::StreamConfig;
use grip_arte_svc::{ArteCounters, ArteLoop, ClassKnowledge, DEFAULT_MAX_LAG_S};
use grip_io::clock::ManualClock;
use grip_msgs::{AudioBlock, RoadEstimate, name_to_bytes};

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

const RATE: u32 = 44_100;
const BLOCK: usize = 441; // 10 ms
const BLOCK_NS: u64 = 10_000_000;
const T0: u64 = 5_000_000_000;

fn block(k: u64) -> AudioBlock {
    let mut b = AudioBlock::zeroed();
    b.seq = k;
    b.sample_rate = RATE;
    b.n_samples = BLOCK as u32;
    b.stamp_ns = T0 + k * BLOCK_NS;
    for (i, s) in b.samples[..BLOCK].iter_mut().enumerate() {
        *s = (((k as usize * BLOCK + i) * 7919) % 2000) as i16 - 1000;
    }
    b
}

fn new_loop(clock: &ManualClock, max_lag_s: f64) -> ArteLoop<Toy, ManualClock> {
    let fcfg = FeatureConfig::new(RATE, FeatureSet::Rich);
    let road = |name: &str| ClassKnowledge {
        name: name_to_bytes(name),
        lambda_opt: 0.1,
        mu_peak: 1.0,
        alpha: 0.9,
    };
    ArteLoop::new(
        Toy {
            dim: fcfg.dim(),
            probs: &[0.1, 0.9],
        },
        &fcfg,
        &StreamConfig::default(),
        vec![road("a"), road("b")],
        0.2,
        clock.clone(),
    )
    .unwrap()
    .with_max_lag(max_lag_s)
}

/// 1 s of audio taken live (5 ms after each block ends), then the process
/// stopped for 2 s: the 2 s of blocks that piled up are taken at once when
/// it resumes, then 1 s live again. Returns the estimates, the counters and
/// the time each block was taken.
fn run(max_lag_s: f64) -> (Vec<RoadEstimate>, ArteCounters, Vec<u64>, usize) {
    let clock = ManualClock::new(0);
    let mut lp = new_loop(&clock, max_lag_s);
    let stats = ArteCounters::default();
    let mut sink = VecSink(Vec::with_capacity(1000));
    let live = |k: u64| T0 + (k + 1) * BLOCK_NS + 5_000_000;
    let resume = live(300); // the 2 s stop ends
    let mut taken = Vec::with_capacity(400);
    // warm-up: the estimator's buffers, the sink's reserve
    let mut allocs = 0;
    for k in 0..400u64 {
        let now = if (100..300).contains(&k) {
            resume
        } else {
            live(k)
        };
        clock.set_ns(now);
        taken.push(now);
        let before = grip_testkit::thread_allocations();
        lp.on_live_block(&block(k), now, &mut sink, &stats);
        if k >= 20 {
            allocs += (grip_testkit::thread_allocations() - before) as usize;
        }
    }
    (sink.0, stats, taken, allocs)
}

#[test]
fn a_backlog_is_dropped_not_classified() {
    let max_lag_ns = (DEFAULT_MAX_LAG_S * 1e9) as u64;
    let (est, stats, taken, allocs) = run(DEFAULT_MAX_LAG_S);
    assert_eq!(allocs, 0, "{allocs} allocations after warm-up");
    // the blocks whose audio ended more than max_lag before they were taken
    let stale = (0..400u64)
        .filter(|&k| taken[k as usize] > T0 + (k + 1) * BLOCK_NS + max_lag_ns)
        .count() as u64;
    assert!(stale > 100, "only {stale} stale blocks in the feed");
    assert_eq!(stats.stale_blocks.load(Ordering::Relaxed), stale);
    assert_eq!(stats.blocks.load(Ordering::Relaxed), 400);
    // taken, not lost; no discontinuity either
    assert_eq!(stats.lost_blocks.load(Ordering::Relaxed), 0);
    assert_eq!(stats.resets.load(Ordering::Relaxed), 0);
    let worst = stats.max_stale_lag_ns.load(Ordering::Relaxed);
    assert!(
        worst > 1_900_000_000 && worst <= 2_010_000_000,
        "largest lag of a dropped block {worst} ns"
    );
    // no estimate of audio older than max_lag when it was published
    for e in &est {
        let lag = e.stamp_ns - e.frame_t1_ns;
        assert!(
            lag <= max_lag_ns,
            "estimate {} of audio ending {} ms before it was published",
            e.seq,
            lag / 1_000_000
        );
    }
    // the estimates after the stop come from a fresh frame of fresh audio
    let first_fresh = (0..400u64)
        .find(|&k| k >= 100 && taken[k as usize] <= T0 + (k + 1) * BLOCK_NS + max_lag_ns)
        .unwrap();
    let after: Vec<_> = est.iter().filter(|e| e.stamp_ns >= taken[100]).collect();
    assert!(!after.is_empty(), "no estimate after the stop");
    assert!(
        after
            .iter()
            .all(|e| e.frame_t0_ns >= T0 + first_fresh * BLOCK_NS),
        "an estimate after the stop has a frame reaching back before the first fresh block"
    );
    // live again: an estimate per hop, as before the stop
    let before_stop = est.iter().filter(|e| e.stamp_ns < taken[100]).count();
    let last_live = est.iter().filter(|e| e.stamp_ns > taken[299]).count();
    assert!(
        before_stop >= 30 && last_live >= 30,
        "{before_stop} estimates before the stop, {last_live} after it"
    );
    // the sequence of estimates stays contiguous
    for (i, e) in est.iter().enumerate() {
        assert_eq!(e.seq, i as u64);
    }
}

#[test]
fn without_the_bound_the_backlog_is_published_as_new() {
    // the same feed with max_lag 60 s: estimates of 2-s-old audio go out
    let (est, stats, _, _) = run(60.0);
    assert_eq!(stats.stale_blocks.load(Ordering::Relaxed), 0);
    let worst = est
        .iter()
        .map(|e| e.stamp_ns - e.frame_t1_ns)
        .max()
        .unwrap();
    assert!(
        worst > 1_500_000_000,
        "the unbounded loop's oldest estimate lagged only {worst} ns"
    );
}

#[test]
fn an_estimate_ready_too_late_is_not_published() {
    // the block is taken in time, but the process is stopped for 2 s before
    // its estimates go out (the clock the loop stamps with has moved on)
    let clock = ManualClock::new(0);
    let mut lp = new_loop(&clock, DEFAULT_MAX_LAG_S);
    let stats = ArteCounters::default();
    let mut sink = VecSink(Vec::with_capacity(100));
    let live = |k: u64| T0 + (k + 1) * BLOCK_NS + 5_000_000;
    for k in 0..30u64 {
        clock.set_ns(live(k));
        lp.on_live_block(&block(k), live(k), &mut sink, &stats);
    }
    let n0 = sink.0.len();
    assert!(n0 > 0, "no estimate from 0.3 s of audio");
    // taken at live(30), published 2 s later: not published, counted
    let mut late = 0;
    for k in 30..33u64 {
        clock.set_ns(live(k) + 2_000_000_000);
        late += lp.on_live_block(&block(k), live(k), &mut sink, &stats);
    }
    assert_eq!(late, 0);
    assert_eq!(sink.0.len(), n0);
    let dropped = stats.stale_estimates.load(Ordering::Relaxed);
    assert!(dropped >= 1, "{dropped} estimates counted as too late");
    assert_eq!(stats.stale_blocks.load(Ordering::Relaxed), 0);
    // on time again (the audio from after the stop; the clock never goes
    // back): published, seq contiguous
    for k in 240..260u64 {
        clock.set_ns(live(k));
        lp.on_live_block(&block(k), live(k), &mut sink, &stats);
    }
    assert!(sink.0.len() > n0);
    for (i, e) in sink.0.iter().enumerate() {
        assert_eq!(e.seq, i as u64);
    }
    // on_block (replays, generated drives) publishes whatever the clock says
    let clock = ManualClock::new(0);
    let mut lp = new_loop(&clock, DEFAULT_MAX_LAG_S);
    let mut sink = VecSink(Vec::with_capacity(100));
    for k in 0..30u64 {
        clock.set_ns(live(k) + 2_000_000_000);
        lp.on_block(&block(k), &mut sink, &stats);
    }
    assert!(!sink.0.is_empty());
}

/// arte stopped for 4 s while audio-acq goes on publishing: the
/// subscriber's queue keeps the newest 64 blocks, the older ones are
/// overwritten and never reach the loop. When it resumes, the first blocks
/// it takes are stale (dropped, not lost), and the blocks that never
/// reached it are lost: counted, although the block after the gap was
/// dropped as stale. (The fail-safe trial's arte, stopped for 4 s, took 425
/// of 537 blocks, dropped 43 as stale and reported `lost_blocks=0`: the
/// stale path moved the expected sequence number on without counting.)
#[test]
fn blocks_that_never_arrived_are_lost_even_when_the_next_one_is_stale() {
    const QUEUE: u64 = 64;
    let max_lag_ns = (DEFAULT_MAX_LAG_S * 1e9) as u64;
    let clock = ManualClock::new(0);
    let mut lp = new_loop(&clock, DEFAULT_MAX_LAG_S);
    let stats = ArteCounters::default();
    let mut sink = VecSink(Vec::with_capacity(1000));
    let live = |k: u64| T0 + (k + 1) * BLOCK_NS + 5_000_000;
    // 1 s live, stopped while blocks 100..500 are published (4 s), 1 s live
    let resume = live(499);
    let (mut taken, mut stale) = (0u64, 0u64);
    let mut first_after_stop = None;
    for k in 0..600u64 {
        let now = match k {
            // overwritten in the subscriber's queue
            100..500 if k < 500 - QUEUE => continue,
            100..500 => resume,
            _ => live(k),
        };
        clock.set_ns(now);
        let is_stale = now > T0 + (k + 1) * BLOCK_NS + max_lag_ns;
        if k >= 100 && first_after_stop.is_none() {
            first_after_stop = Some(is_stale);
        }
        stale += u64::from(is_stale);
        lp.on_live_block(&block(k), now, &mut sink, &stats);
        taken += 1;
    }
    assert_eq!(
        first_after_stop,
        Some(true),
        "the feed must resume with a stale block"
    );
    assert_eq!(taken, 100 + QUEUE + 100);
    assert_eq!(stats.blocks.load(Ordering::Relaxed), taken);
    assert_eq!(stats.stale_blocks.load(Ordering::Relaxed), stale);
    assert!(stale > 0 && stale < QUEUE, "{stale} stale blocks");
    // published = taken + lost
    let lost = stats.lost_blocks.load(Ordering::Relaxed);
    assert_eq!(lost, 500 - QUEUE - 100, "lost_blocks");
    assert_eq!(taken + lost, 600);
    // the dropped block re-anchored the time line: no restart
    assert_eq!(stats.resets.load(Ordering::Relaxed), 0);
    // estimates flowed again after the stop, seq contiguous
    assert!(sink.0.iter().any(|e| e.stamp_ns > resume));
    for (i, e) in sink.0.iter().enumerate() {
        assert_eq!(e.seq, i as u64);
    }
}

/// A gap is counted whatever the block after it: one refused for its
/// sample rate (taken, not lost) counts the blocks skipped before it, and
/// the blocks after it are no gap.
#[test]
fn a_gap_before_a_refused_block_is_counted() {
    let clock = ManualClock::new(0);
    let mut lp = new_loop(&clock, DEFAULT_MAX_LAG_S);
    let stats = ArteCounters::default();
    let mut sink = VecSink(Vec::with_capacity(100));
    let live = |k: u64| T0 + (k + 1) * BLOCK_NS + 5_000_000;
    for k in (0..10u64).chain(15..30) {
        clock.set_ns(live(k));
        let mut b = block(k);
        if k == 15 {
            b.sample_rate = 48_000;
        }
        lp.on_live_block(&b, live(k), &mut sink, &stats);
    }
    assert_eq!(stats.rate_mismatch.load(Ordering::Relaxed), 1);
    assert_eq!(stats.lost_blocks.load(Ordering::Relaxed), 5);
    assert_eq!(stats.blocks.load(Ordering::Relaxed), 25);
    // the same through on_block (replays)
    let mut lp = new_loop(&clock, DEFAULT_MAX_LAG_S);
    let stats = ArteCounters::default();
    for k in (0..10u64).chain(12..14) {
        let mut b = block(k);
        if k == 12 {
            b.sample_rate = 16_000;
        }
        lp.on_block(&b, &mut sink, &stats);
    }
    assert_eq!(stats.lost_blocks.load(Ordering::Relaxed), 2);
}
