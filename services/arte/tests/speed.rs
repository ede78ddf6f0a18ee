//! The vehicle speed handed to the estimator (no processes; a manual
//! clock; a toy classifier stands in for a model, so nothing here depends
//! on what the speed does to the features): the newest record with
//! `v_valid = 1` is used while at most `speed_timeout` old, else none;
//! invalid, non-finite and older records change nothing; every processed
//! block is counted with or without a speed.

mod common;
use common::Toy;
use std::sync::atomic::Ordering;

use grip_arte::features::{FeatureConfig, FeatureSet, SpeedNorm};
use grip_arte::stream::StreamConfig;
use grip_arte_svc::{ArteCounters, ArteLoop, ClassKnowledge, EstimateSink};
use grip_io::clock::{Clock, ManualClock};
use grip_io::ipc::IpcError;
use grip_msgs::{AudioBlock, CycleRecord, RoadEstimate, name_to_bytes};

const RATE: u32 = 16_000;
const BLOCK: usize = 512; // 32 ms
const T0: u64 = 10_000_000_000;
const MS: u64 = 1_000_000;

#[derive(Default)]
struct Count(u64);
impl EstimateSink for Count {
    fn send(&mut self, _e: &RoadEstimate) -> Result<(), IpcError> {
        self.0 += 1;
        Ok(())
    }
}

fn road(name: &str) -> ClassKnowledge {
    ClassKnowledge {
        name: name_to_bytes(name),
        lambda_opt: 0.1,
        mu_peak: 1.0,
        alpha: 0.9,
    }
}

fn new_loop(fcfg: &FeatureConfig, clock: &ManualClock) -> ArteLoop<Toy, ManualClock> {
    ArteLoop::new(
        Toy {
            dim: fcfg.dim(),
            probs: &[0.3, 0.7],
        },
        fcfg,
        &StreamConfig::default(),
        vec![road("a"), road("b")],
        0.2,
        clock.clone(),
    )
    .unwrap()
}

/// Contiguous blocks of a little noise; block k starts at T0 + k·32 ms.
struct Blocks(u64);
impl Blocks {
    fn next(&mut self) -> AudioBlock {
        let mut b = AudioBlock::zeroed();
        b.seq = self.0;
        b.sample_rate = RATE;
        b.n_samples = BLOCK as u32;
        b.stamp_ns = T0 + self.0 * 32 * MS;
        for (i, s) in b.samples[..BLOCK].iter_mut().enumerate() {
            *s = (((self.0 as usize * BLOCK + i) * 7919) % 2000) as i16 - 1000;
        }
        self.0 += 1;
        b
    }
}

fn record(v: f64, valid: bool, stamp_ns: u64) -> CycleRecord {
    let mut r = CycleRecord::zeroed();
    r.stamp_ns = stamp_ns;
    r.v = v;
    r.v_valid = u8::from(valid);
    r
}

fn counts(s: &ArteCounters) -> (u64, u64) {
    (
        s.blocks_with_speed.load(Ordering::Relaxed),
        s.blocks_without_speed.load(Ordering::Relaxed),
    )
}

#[test]
fn fresh_valid_records_give_the_speed_stale_or_absent_give_none() {
    let fcfg = FeatureConfig::new(RATE, FeatureSet::Rich);
    let clock = ManualClock::new(T0);
    let mut lp = new_loop(&fcfg, &clock);
    let stats = ArteCounters::default();
    let mut sink = Count::default();
    let mut bl = Blocks(0);
    // no record yet
    assert_eq!(lp.current_speed(), None);
    lp.on_block(&bl.next(), &mut sink, &stats);
    assert_eq!(counts(&stats), (0, 1));
    assert_eq!(stats.speed_in_use(), None);

    // a valid record stamped now: used
    lp.on_cycle(&record(12.5, true, T0), &stats);
    lp.on_block(&bl.next(), &mut sink, &stats);
    assert_eq!(counts(&stats), (1, 1));
    assert_eq!(stats.speed_in_use(), Some(12.5));

    // age exactly the default timeout (0.2 s): still fresh; 1 ns more: stale
    clock.set_ns(T0 + 200 * MS);
    assert_eq!(lp.current_speed(), Some(12.5));
    lp.on_block(&bl.next(), &mut sink, &stats);
    assert_eq!(counts(&stats), (2, 1));
    clock.set_ns(T0 + 200 * MS + 1);
    assert_eq!(lp.current_speed(), None);
    lp.on_block(&bl.next(), &mut sink, &stats);
    assert_eq!(counts(&stats), (2, 2));
    assert_eq!(stats.speed_in_use(), None);

    // newer records that are not valid speeds do not revive or replace it
    let now = T0 + 300 * MS;
    clock.set_ns(now);
    lp.on_cycle(&record(f64::NAN, false, now), &stats);
    lp.on_cycle(&record(30.0, false, now), &stats);
    lp.on_cycle(&record(f64::NAN, true, now), &stats);
    lp.on_cycle(&record(f64::INFINITY, true, now), &stats);
    assert_eq!(lp.current_speed(), None);
    lp.on_block(&bl.next(), &mut sink, &stats);
    assert_eq!(counts(&stats), (2, 3));
    assert_eq!(stats.cycle_records.load(Ordering::Relaxed), 5);
    assert_eq!(stats.bad_speeds.load(Ordering::Relaxed), 2);

    // reversing: the magnitude
    lp.on_cycle(&record(-3.0, true, now), &stats);
    lp.on_block(&bl.next(), &mut sink, &stats);
    assert_eq!(stats.speed_in_use(), Some(3.0));

    // an older record (arriving late) does not replace a newer one; an
    // equal stamp does (the later of two records of one cycle wins)
    lp.on_cycle(&record(9.0, true, now - 10 * MS), &stats);
    assert_eq!(lp.current_speed(), Some(3.0));
    lp.on_cycle(&record(4.0, true, now), &stats);
    assert_eq!(lp.current_speed(), Some(4.0));

    // a stamp further in the future than the timeout is not trusted
    lp.on_cycle(&record(7.0, true, now + 250 * MS), &stats);
    assert_eq!(lp.current_speed(), None);
    clock.set_ns(now + 100 * MS);
    assert_eq!(lp.current_speed(), Some(7.0));

    // a refused block (wrong rate) is counted neither way
    let before = counts(&stats);
    let mut wrong = bl.next();
    wrong.sample_rate = 48_000;
    lp.on_block(&wrong, &mut sink, &stats);
    assert_eq!(counts(&stats), before);
    assert_eq!(stats.rate_mismatch.load(Ordering::Relaxed), 1);
    // every processed block is counted once, estimates flow regardless
    let n = 40;
    for _ in 0..n {
        lp.on_block(&bl.next(), &mut sink, &stats);
    }
    let (w, wo) = counts(&stats);
    assert_eq!(w + wo, stats.blocks.load(Ordering::Relaxed) - 1);
    assert_eq!(w, before.0 + n);
    assert!(sink.0 > 0);
}

/// One record stamped far in the future (a corrupt clock, a restarted
/// tcs-loop on another time base) is not trusted, and it does not lock out
/// the records after it: a kept record that is no longer fresh is replaced
/// by the next valid one, whatever its stamp.
#[test]
fn a_far_future_record_does_not_lock_out_later_ones() {
    let fcfg = FeatureConfig::new(RATE, FeatureSet::Rich);
    let clock = ManualClock::new(T0);
    let mut lp = new_loop(&fcfg, &clock);
    let stats = ArteCounters::default();
    let mut sink = Count::default();
    let mut bl = Blocks(0);
    for future in [T0 + 3_600_000_000_000, u64::MAX] {
        lp.on_cycle(&record(10.0, true, future), &stats);
        assert_eq!(lp.current_speed(), None, "{future}");
        // the next record, stamped now
        lp.on_cycle(&record(12.0, true, clock.now_ns()), &stats);
        assert_eq!(lp.current_speed(), Some(12.0), "{future}");
        lp.on_block(&bl.next(), &mut sink, &stats);
        assert_eq!(stats.speed_in_use(), Some(12.0));
        // and the ones after it, as before
        clock.set_ns(clock.now_ns() + MS);
        lp.on_cycle(&record(12.5, true, clock.now_ns()), &stats);
        assert_eq!(lp.current_speed(), Some(12.5));
        // an older record still does not replace a fresh newer one
        lp.on_cycle(&record(9.0, true, clock.now_ns() - MS), &stats);
        assert_eq!(lp.current_speed(), Some(12.5));
        clock.set_ns(clock.now_ns() + 10 * MS);
    }
}

#[test]
fn speed_timeout_is_configurable() {
    let fcfg = FeatureConfig::new(RATE, FeatureSet::Rich);
    let clock = ManualClock::new(T0);
    let mut lp = new_loop(&fcfg, &clock).with_speed_timeout(1.0);
    let stats = ArteCounters::default();
    lp.on_cycle(&record(20.0, true, T0), &stats);
    clock.set_ns(T0 + 999 * MS);
    assert_eq!(lp.current_speed(), Some(20.0));
    clock.set_ns(T0 + 1001 * MS);
    assert_eq!(lp.current_speed(), None);
}

#[test]
fn speed_is_applied_across_estimator_restarts() {
    // a stamp jump restarts the estimator; the block is still counted with
    // the speed (it is set after the restart)
    let fcfg = FeatureConfig::new(RATE, FeatureSet::Rich);
    let clock = ManualClock::new(T0);
    let mut lp = new_loop(&fcfg, &clock);
    let stats = ArteCounters::default();
    let mut sink = Count::default();
    let mut bl = Blocks(0);
    lp.on_cycle(&record(15.0, true, T0), &stats);
    for _ in 0..5 {
        lp.on_block(&bl.next(), &mut sink, &stats);
    }
    let mut late = bl.next();
    late.stamp_ns += 5_000_000_000;
    lp.on_block(&late, &mut sink, &stats);
    assert_eq!(stats.resets.load(Ordering::Relaxed), 1);
    assert_eq!(counts(&stats), (6, 0));
    assert_eq!(stats.speed_in_use(), Some(15.0));
}

#[test]
fn speed_normalised_follows_the_feature_config() {
    let clock = ManualClock::new(T0);
    let plain = FeatureConfig::new(RATE, FeatureSet::Rich);
    assert!(!new_loop(&plain, &clock).speed_normalised());
    let norm = FeatureConfig {
        speed_norm: Some(SpeedNorm {
            ref_kmh: 50.0,
            exponent: 0.25,
        }),
        ..plain
    };
    let mut lp = new_loop(&norm, &clock);
    assert!(lp.speed_normalised());
    // a speed-normalised loop runs with and without a speed
    let stats = ArteCounters::default();
    let mut sink = Count::default();
    let mut bl = Blocks(0);
    for k in 0..20 {
        if k == 10 {
            lp.on_cycle(&record(25.0, true, T0), &stats);
        }
        lp.on_block(&bl.next(), &mut sink, &stats);
    }
    assert_eq!(counts(&stats), (10, 10));
    assert!(sink.0 > 0);
}

/// Keeps every estimate.
#[derive(Default)]
struct Keep(Vec<RoadEstimate>);
impl EstimateSink for Keep {
    fn send(&mut self, e: &RoadEstimate) -> Result<(), IpcError> {
        self.0.push(*e);
        Ok(())
    }
}

/// Each estimate carries tcs-loop's odometer at its frame's start and end:
/// the newest fresh record's odometer moved on at its speed to the frame's
/// times; NaN without a fresh record.
#[test]
fn estimates_carry_the_odometer_of_their_frame() {
    let fcfg = FeatureConfig::new(RATE, FeatureSet::Rich);
    let clock = ManualClock::new(T0);
    let mut lp = new_loop(&fcfg, &clock);
    let stats = ArteCounters::default();
    let mut sink = Keep::default();
    let mut bl = Blocks(0);
    // no record: NaN
    while sink.0.is_empty() {
        lp.on_block(&bl.next(), &mut sink, &stats);
    }
    assert!(sink.0.iter().all(|e| e.x_from.is_nan() && e.x_to.is_nan()));
    // a record at 40 m, 5 m/s, stamped at the next block's start
    let mut rec = record(5.0, true, 0);
    rec.odometer = 40.0;
    let n0 = sink.0.len();
    let b = bl.next();
    rec.stamp_ns = b.stamp_ns;
    clock.set_ns(b.stamp_ns);
    lp.on_cycle(&rec, &stats);
    lp.on_block(&b, &mut sink, &stats);
    while sink.0.len() == n0 {
        let b = bl.next();
        clock.set_ns(b.stamp_ns);
        lp.on_block(&b, &mut sink, &stats);
    }
    let e = sink.0[n0];
    let at = |t: u64| 40.0 + 5.0 * (t as f64 - rec.stamp_ns as f64) * 1e-9;
    assert!((e.x_to - at(e.frame_t1_ns)).abs() < 1e-9, "{e:?}");
    assert!((e.x_from - at(e.frame_t0_ns)).abs() < 1e-9, "{e:?}");
    assert!(e.x_to > e.x_from && e.x_to - e.x_from < 5.0, "{e:?}");
}
