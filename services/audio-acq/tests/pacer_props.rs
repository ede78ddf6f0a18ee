//! Property: the real-time pacer stamps blocks back to back on the sample
//! clock (stamp[k+1] − stamp[k] = duration of block k, within 1 ns of
//! rounding) unless the caller fell more than the slack behind, in which
//! case it counts a resync and the stamp only moves forward; it never
//! releases a block before its last sample is due.

use grip_audio_acq::source::Pacer;
use grip_io::clock::{Clock, ManualClock};
use proptest::prelude::*;

proptest! {
    #[test]
    fn pacer_stamps_are_contiguous_or_counted(
        rate in prop::sample::select(vec![8_000u32, 16_000, 44_100, 48_000, 192_000]),
        steps in prop::collection::vec((1usize..=4096, 0u64..400_000_000), 1..200),
    ) {
        let clock = ManualClock::new(5_000_000_000);
        let slack = 200_000_000;
        let mut p = Pacer::new(clock.clone(), rate, slack);
        let dur = |n: usize| n as f64 * 1e9 / f64::from(rate);
        let mut prev: Option<(u64, usize)> = None;
        for (n, delay) in steps {
            let resyncs = p.resyncs();
            let stamp = p.wait_block(n);
            let now = clock.now_ns();
            // released no earlier than the block's end
            prop_assert!(now as f64 + 1.0 >= stamp as f64 + dur(n));
            if let Some((ps, pn)) = prev {
                prop_assert!(stamp > ps);
                if p.resyncs() == resyncs {
                    let d = (stamp - ps) as f64 - dur(pn);
                    prop_assert!(d.abs() <= 2.0, "gap {} ns without a resync", d);
                } else {
                    prop_assert!((stamp - ps) as f64 > dur(pn));
                }
            }
            prev = Some((stamp, n));
            clock.advance_ns(delay); // the caller's work / a stall
        }
    }
}
