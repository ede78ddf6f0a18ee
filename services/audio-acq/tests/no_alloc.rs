//! The per-block loop allocates nothing after start-up, for the wav and the
//! synth sources and for the ALSA source's read path and sample-format
//! conversion through a fake capture device (S32_LE, S24_3LE, S24_LE,
//! FLOAT_LE; no sound hardware here), into a test sink; into a real
//! iceoryx2 publisher it allocates exactly iceoryx2's one per published
//! sample.

use std::collections::BTreeMap;
use std::sync::Arc;

use grip_audio_acq::alsa_src::AlsaSource;
use grip_audio_acq::config::{AlsaSection, SynthNoise, SynthSection};
use grip_audio_acq::format::SampleFormat;
use grip_audio_acq::synth::{SynthSource, TruthInput, TruthReadError};
use grip_audio_acq::wav::WavSource;
use grip_audio_acq::{AcqLoop, AcqStatus, BlockSink, Source, Step};
use grip_io::clock::{Clock, ManualClock};
use grip_io::ipc::{IpcError, IpcNode, SubscriberMode};
use grip_msgs::{AudioBlock, GroundTruth, name_to_bytes, topics};

mod common;

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

/// This thread's allocations so far (other threads' are not counted).
fn allocs() -> usize {
    grip_testkit::thread_allocations() as usize
}

/// Sums samples (so the work is not optimised away), allocates nothing.
#[derive(Default)]
struct SumSink(i64, u64);
impl BlockSink for SumSink {
    fn send(&mut self, b: &AudioBlock) -> Result<(), IpcError> {
        self.0 += b.samples().iter().map(|&s| i64::from(s)).sum::<i64>();
        self.1 += 1;
        Ok(())
    }
}

/// Truth that changes road and speed every 50 polls.
struct Changing {
    n: u64,
    clock: ManualClock,
}
impl TruthInput for Changing {
    fn poll_latest(&mut self) -> Result<Option<GroundTruth>, TruthReadError> {
        self.n += 1;
        let roads = ["asphalt", "snow", "gravel_alias", "ice", "stone"];
        let r = roads[(self.n / 50) as usize % roads.len()];
        if (self.n / 200) % 2 == 1 {
            return Ok(None); // truth pauses (lost after the timeout)
        }
        Ok(Some(GroundTruth {
            seq: self.n,
            stamp_ns: self.clock.now_ns(),
            road_index: 0,
            mic_road_index: 0,
            road_name: name_to_bytes("under_the_wheel"),
            mic_road_name: name_to_bytes(r),
            v: 5.0 + (self.n % 7) as f64,
            omega: 0.0,
            lambda: 0.0,
            torque: 0.0,
            x: 0.0,
        }))
    }
}

fn drive<S: grip_audio_acq::Source>(
    lp: &mut AcqLoop<S>,
    sink: &mut impl BlockSink,
    warm: usize,
    n: usize,
) -> usize {
    for _ in 0..warm {
        assert_eq!(lp.step(sink).unwrap(), Step::Published);
    }
    let before = allocs();
    for _ in 0..n {
        assert_eq!(lp.step(sink).unwrap(), Step::Published);
    }
    allocs() - before
}

// One test function only, so no other test thread allocates meanwhile.
#[test]
fn acquisition_loop_allocates_nothing() {
    // --- wav, looped, 4096-sample blocks over a 10 000-sample file
    let samples: Vec<i16> = (0..10_000).map(|i| (i % 1000) as i16).collect();
    let src = WavSource::new(samples, 44_100, true, ManualClock::new(0), 200_000_000);
    let mut lp = AcqLoop::new(src, 4096, 0, Arc::new(AcqStatus::default()));
    let mut sink = SumSink::default();
    let a = drive(&mut lp, &mut sink, 5, 2000);
    assert_eq!(a, 0, "wav source: {a} allocations in 2000 blocks");

    // --- synth with noise, following changing truth (incl. unknown roads,
    // aliases and truth loss)
    let clock = ManualClock::new(0);
    let cfg = SynthSection {
        noise: Some(SynthNoise {
            rain: true,
            car: true,
            snr_db: 10.0,
        }),
        aliases: BTreeMap::from([("gravel_alias".to_string(), "gravel".to_string())]),
        ..SynthSection::default()
    };
    let truth = Changing {
        n: 0,
        clock: clock.clone(),
    };
    let src = SynthSource::new(&cfg, 44_100, 1024, truth, clock, 200_000_000).unwrap();
    let mut lp = AcqLoop::new(src, 1024, 0, Arc::new(AcqStatus::default()));
    let mut sink = SumSink::default();
    let a = drive(&mut lp, &mut sink, 5, 2000);
    assert_eq!(a, 0, "synth source: {a} allocations in 2000 blocks");
    assert!(lp.source().stats().unknown_road > 0);
    assert!(sink.0 != 0);

    // --- ALSA's read path (wait, raw read, conversion of one channel to
    // S16) through a fake device, in every format other than S16_LE
    for format in [
        SampleFormat::S32Le,
        SampleFormat::S24_3Le,
        SampleFormat::S24Le,
        SampleFormat::FloatLe,
    ] {
        let dev = common::FormatFake {
            format,
            channels: 2,
            chunk: 300,
            next: 0,
        };
        let mut cfg = AlsaSection::with_device("fake");
        cfg.channels = 2;
        cfg.channel = 1;
        let src = AlsaSource::new(dev, &cfg, 44_100, 1024);
        let mut lp = AcqLoop::new(src, 1024, 1, Arc::new(AcqStatus::default()));
        let mut sink = SumSink::default();
        let a = drive(&mut lp, &mut sink, 5, 300);
        assert_eq!(a, 0, "ALSA source, {format}: {a} allocations in 300 blocks");
        assert_eq!(sink.1, 305);
        assert_eq!(lp.source().device().next, 305 * 1024);
        assert!(sink.0 != 0);
    }

    // --- into a real iceoryx2 publisher, read back by a deep subscriber
    // SAFETY: single test function; set before any iceoryx2 use.
    unsafe {
        std::env::set_var(
            grip_io::ipc::INSTANCE_ENV,
            format!("acq_noalloc_{}", std::process::id()),
        )
    };
    let node = IpcNode::create("audio-acq-test").unwrap();
    let mut publisher = node.publisher::<AudioBlock>(topics::AUDIO).unwrap();
    let sub = node
        .subscriber::<AudioBlock>(topics::AUDIO, SubscriberMode::Deep)
        .unwrap();
    let samples: Vec<i16> = (0..5000).map(|i| i as i16).collect();
    let src = WavSource::new(samples, 44_100, true, ManualClock::new(0), 200_000_000);
    let mut lp = AcqLoop::new(src, 1024, 0, Arc::new(AcqStatus::default()));
    for _ in 0..10 {
        lp.step(&mut publisher).unwrap();
        while sub.recv().unwrap().is_some() {}
    }
    let before = allocs();
    let mut got = 0u64;
    let mut last_seq = 0;
    let mut in_pub = 0;
    for _ in 0..1000 {
        let b0 = allocs();
        lp.step(&mut publisher).unwrap();
        in_pub += allocs() - b0;
        while let Some(b) = sub.recv().unwrap() {
            got += 1;
            last_seq = b.seq;
        }
    }
    let a = allocs() - before;
    assert_eq!(got, 1000);
    assert_eq!(last_seq, 1009);
    // iceoryx2 0.10's `loan_uninit` allocates one 48-byte Arc per loaned
    // sample (crates/io/README.md, "Allocation on the hot path"); pinned at
    // exactly one per block so anything grip adds fails here. Receiving
    // allocates nothing.
    assert_eq!(in_pub, 1000, "publish: {in_pub} allocations in 1000 blocks");
    assert_eq!(
        a,
        in_pub,
        "receive: {} allocations in 1000 blocks",
        a - in_pub
    );
}
