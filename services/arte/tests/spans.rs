//! Property: whatever the block size, every estimate's frame span is where
//! the stream puts it — t1 = first block's stamp + (frame + k·hop)/fs —
//! when the blocks' stamps are contiguous; the loop's seq is contiguous and
//! class tables are applied. A toy classifier stands in for a model.

mod common;
use common::{Toy, VecSink};
use grip_arte::features::{FeatureConfig, FeatureSet};
use grip_arte::stream::StreamConfig;
use grip_arte_svc::{ArteCounters, ArteLoop, ClassKnowledge};
use grip_io::clock::ManualClock;
use grip_msgs::{AudioBlock, name_to_bytes};
use proptest::prelude::*;

fn road(name: &str, l: f64) -> ClassKnowledge {
    ClassKnowledge {
        name: name_to_bytes(name),
        lambda_opt: l,
        mu_peak: 1.0,
        alpha: 1.0 - l,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn spans_follow_the_block_stamps(block in 1usize..=4096, t0 in 1u64..1_000_000_000_000, rate_sel in 0usize..2) {
        let rate = [44_100u32, 16_000][rate_sel];
        let fcfg = FeatureConfig::new(rate, FeatureSet::Rich);
        let roads = vec![road("a", 0.1), road("b", 0.2), road("c", 0.3)];
        let mut lp = ArteLoop::new(
            Toy {
                dim: fcfg.dim(),
                probs: &[0.2, 0.7, 0.1],
            },
            &fcfg,
            &StreamConfig::default(),
            roads,
            0.2,
            ManualClock::new(0),
        ).unwrap();
        let stats = ArteCounters::default();
        let mut sink = VecSink::default();
        let total = rate as usize / 2; // 0.5 s
        let mut sent = 0usize;
        let mut k = 0u64;
        while sent < total {
            let n = block.min(total - sent);
            let mut b = AudioBlock::zeroed();
            b.seq = k;
            b.sample_rate = rate;
            b.n_samples = n as u32;
            b.stamp_ns = t0 + (u128::from(sent as u64) * 1_000_000_000 / u128::from(rate)) as u64;
            for (i, s) in b.samples[..n].iter_mut().enumerate() {
                // never near silence: a one-sample block of |s| < 4 is
                // silent audio to the loop (-80 dBFS), which publishes a
                // no-road estimate and restarts the frame instead
                let v = ((((sent + i) * 7919) % 1000) + 100) as i16;
                *s = if (sent + i).is_multiple_of(2) { v } else { -v };
            }
            lp.on_block(&b, &mut sink, &stats);
            sent += n;
            k += 1;
        }
        let frame = (0.1 * f64::from(rate)).round() as u64;
        let hop = (StreamConfig::default().hop_s * f64::from(rate)).round() as u64;
        let expect_n = ((total as u64 - frame) / hop + 1) as usize;
        prop_assert_eq!(sink.0.len(), expect_n);
        for (i, e) in sink.0.iter().enumerate() {
            let end = frame + i as u64 * hop;
            let t1 = t0 + (u128::from(end) * 1_000_000_000 / u128::from(rate)) as u64;
            // one ns of rounding from the per-block stamps
            prop_assert!(e.frame_t1_ns.abs_diff(t1) <= 1, "estimate {}: {} vs {}", i, e.frame_t1_ns, t1);
            prop_assert_eq!(e.frame_t1_ns - e.frame_t0_ns, (u128::from(frame) * 1_000_000_000 / u128::from(rate)) as u64);
            prop_assert_eq!(e.seq, i as u64);
            prop_assert_eq!(e.class_index, 1);
            prop_assert_eq!(e.class_name(), Some("b"));
            prop_assert_eq!((e.lambda_opt, e.alpha), (0.2, 0.8));
        }
        prop_assert_eq!(stats.lost_blocks.load(std::sync::atomic::Ordering::Relaxed), 0);
        prop_assert_eq!(stats.resets.load(std::sync::atomic::Ordering::Relaxed), 0);
    }
}
