//! The three sources through the acquisition loop, on a manual clock (wav,
//! synth) and a fake capture device (ALSA overruns, time stamps, sample
//! formats).

use std::collections::BTreeMap;
use std::sync::Arc;

use grip_audio_acq::alsa_src::{AlsaSource, CaptureDevice};
use grip_audio_acq::config::{AlsaSection, SynthSection, TruthLost};
use grip_audio_acq::format::{FormatSetting, SampleFormat};
use grip_audio_acq::synth::{NO_ROAD, SynthSource, TruthInput, TruthReadError};
use grip_audio_acq::wav::{WavSource, read_mono_i16};
use grip_audio_acq::{AcqLoop, AcqStatus, BlockSink, Read, Source, Step};
use grip_io::clock::{Clock, ManualClock, monotonic_now_ns};
use grip_io::ipc::IpcError;
use grip_msgs::{AudioBlock, GroundTruth, name_to_bytes};

mod common;

#[derive(Default)]
struct VecSink(Vec<AudioBlock>);
impl BlockSink for VecSink {
    fn send(&mut self, b: &AudioBlock) -> Result<(), IpcError> {
        self.0.push(*b);
        Ok(())
    }
}

const NS_PER_BLOCK_1024: f64 = 1024.0 * 1e9 / 44_100.0;

fn write_wav(path: &std::path::Path, rate: u32, channels: u16, frames: &[Vec<i16>]) {
    let spec = hound::WavSpec {
        channels,
        sample_rate: rate,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for f in frames {
        for &s in f {
            w.write_sample(s).unwrap();
        }
    }
    w.finalize().unwrap();
}

/// A 16-bit file's samples reach arte as they are in the file, full scale
/// included (arte's clipping rule counts |s| >= 32767: scaled by 32767
/// instead of 32768, a clipped file's 32767 arrived as 32766).
#[test]
fn a_16_bit_file_s_samples_arrive_unchanged_full_scale_included() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("full.wav");
    let values = [32767i16, -32768, 32766, -32767, 1, -1, 0, 12345, -23456];
    let frames: Vec<Vec<i16>> = values.iter().map(|&v| vec![v]).collect();
    write_wav(&p, 44_100, 1, &frames);
    let audio = read_mono_i16(&p, 44_100, None).unwrap();
    assert_eq!(audio.samples, values);
}

#[test]
fn wav_once_is_paced_stamped_and_ends_with_a_partial_block() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ramp.wav");
    let n = 5000;
    let frames: Vec<Vec<i16>> = (0..n).map(|i| vec![i as i16]).collect();
    write_wav(&p, 44_100, 1, &frames);
    let audio = read_mono_i16(&p, 44_100, None).unwrap();
    assert_eq!(audio.samples.len(), n);
    assert_eq!(audio.samples[4999], 4999);
    let clock = ManualClock::new(1_000_000_000);
    let src = WavSource::new(audio.samples, 44_100, false, clock.clone(), 200_000_000);
    let mut lp = AcqLoop::new(src, 1024, 0, Arc::new(AcqStatus::default()));
    let mut sink = VecSink::default();
    while lp.step(&mut sink).unwrap() == Step::Published {}
    let b = &sink.0;
    assert_eq!(b.len(), 5); // 4 full blocks + 904 samples
    for (k, blk) in b.iter().enumerate() {
        assert_eq!(blk.seq, k as u64);
        assert_eq!(blk.sample_rate, 44_100);
        let expect = 1_000_000_000 + (k as f64 * NS_PER_BLOCK_1024) as u64;
        assert!(blk.stamp_ns.abs_diff(expect) <= 1, "{k}");
        assert_eq!(blk.samples()[0], (k * 1024) as i16);
    }
    assert_eq!(b[4].n_samples, 5000 - 4096);
    assert_eq!(*b[4].samples().last().unwrap(), 4999);
    assert!(b[4].samples[904..].iter().all(|&s| s == 0));
    // the clock was advanced to the end of the last block: real-time pacing
    assert_eq!(
        clock.now_ns(),
        1_000_000_000 + (5000.0 * 1e9 / 44_100.0) as u64
    );
    assert_eq!(lp.step(&mut sink).unwrap(), Step::End);
}

#[test]
fn wav_looped_wraps_and_stereo_48k_is_mixed_and_resampled() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("tone.wav");
    // 1 s of a 1 kHz tone at 48 kHz, left = right = tone, plus opposite DC
    // offsets (mixdown must cancel them)
    let frames: Vec<Vec<i16>> = (0..48_000)
        .map(|i| {
            let s =
                (8000.0 * (2.0 * std::f64::consts::PI * 1000.0 * i as f64 / 48_000.0).sin()) as i16;
            vec![s + 1000, s - 1000]
        })
        .collect();
    write_wav(&p, 48_000, 2, &frames);
    let a = read_mono_i16(&p, 44_100, None).unwrap();
    assert_eq!((a.file_rate, a.file_channels), (48_000, 2));
    assert_eq!(a.samples.len(), 44_100);
    // frequency by zero crossings in the middle: 1 kHz at 44.1 kHz
    let mid = &a.samples[10_000..30_000];
    let zc = mid.windows(2).filter(|w| (w[0] < 0) != (w[1] < 0)).count();
    let f = zc as f64 / 2.0 / (mid.len() as f64 / 44_100.0);
    assert!((f - 1000.0).abs() < 5.0, "{f} Hz");
    let mean: f64 = mid.iter().map(|&s| f64::from(s)).sum::<f64>() / mid.len() as f64;
    assert!(mean.abs() < 50.0, "DC {mean}");
    // `[wav] channel`: one channel, as the ALSA source publishes its
    // `[alsa] channel`: the right one keeps its -1000 offset; a channel the
    // file lacks is an error naming the file
    let right = read_mono_i16(&p, 44_100, Some(1)).unwrap();
    let mean_r: f64 = right.samples[10_000..30_000]
        .iter()
        .map(|&s| f64::from(s))
        .sum::<f64>()
        / 20_000.0;
    assert!(
        (mean_r + 1000.0).abs() < 50.0,
        "right channel's DC {mean_r}"
    );
    let e = read_mono_i16(&p, 44_100, Some(2)).unwrap_err().to_string();
    assert!(
        e.contains(&p.display().to_string()) && e.contains('2'),
        "{e}"
    );
    // looped: 100 blocks of 1024 from a 44100-sample file continue seamlessly
    let src = WavSource::new(
        a.samples.clone(),
        44_100,
        true,
        ManualClock::new(0),
        200_000_000,
    );
    let mut lp = AcqLoop::new(src, 1024, 0, Arc::new(AcqStatus::default()));
    let mut sink = VecSink::default();
    for _ in 0..100 {
        assert_eq!(lp.step(&mut sink).unwrap(), Step::Published);
    }
    let all: Vec<i16> = sink.0.iter().flat_map(|b| b.samples().to_vec()).collect();
    assert_eq!(all.len(), 102_400);
    for (i, &s) in all.iter().enumerate() {
        assert_eq!(s, a.samples[i % 44_100], "sample {i}");
    }
}

#[test]
fn wav_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("missing.wav");
    let e = read_mono_i16(&p, 44_100, None).unwrap_err().to_string();
    assert!(
        e.contains("missing.wav") && e.contains("cannot open"),
        "{e}"
    );
    let p = dir.path().join("text.wav");
    std::fs::write(&p, b"RIFF not really").unwrap();
    let e = read_mono_i16(&p, 44_100, None).unwrap_err().to_string();
    assert!(e.contains("text.wav") && e.contains("WAV"), "{e}");
}

/// Truth from a script: (time from which it is published, road, speed);
/// publishes a new sample on every poll while the clock is inside an entry
/// with `Some` road, nothing for `None`.
struct ScriptedTruth {
    clock: ManualClock,
    script: Vec<(u64, Option<&'static str>, f64)>,
}

impl TruthInput for ScriptedTruth {
    fn poll_latest(&mut self) -> Result<Option<GroundTruth>, TruthReadError> {
        let now = self.clock.now_ns();
        let e = self.script.iter().rev().find(|e| e.0 <= now);
        Ok(e.and_then(|&(_, road, v)| {
            road.map(|r| GroundTruth {
                seq: 0,
                stamp_ns: now,
                road_index: 0,
                mic_road_index: 0,
                // the wheel is on another road: the synth renders the
                // road at the microphone
                road_name: name_to_bytes("under_the_wheel"),
                mic_road_name: name_to_bytes(r),
                v,
                omega: v / 0.3,
                lambda: 0.0,
                torque: 0.0,
                x: 0.0,
            })
        }))
    }
}

fn rms(b: &AudioBlock) -> f64 {
    let s = b.samples();
    (s.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / s.len() as f64).sqrt()
}

fn synth_run(on_lost: TruthLost) -> (Vec<AudioBlock>, Vec<(usize, f64)>, Vec<bool>) {
    let clock = ManualClock::new(0);
    let s = 1_000_000_000u64;
    let truth = ScriptedTruth {
        clock: clock.clone(),
        script: vec![
            (0, None, 0.0),                        // 0-0.5 s: nothing yet
            (s / 2, Some("asphalt"), 10.0),        // 0.5-1.5 s: asphalt
            (3 * s / 2, Some("asphalt_mf"), 10.0), // alias of asphalt
            (2 * s, Some("snow"), 15.0),           // 2-3 s: snow
            (3 * s, None, 0.0),                    // 3 s on: truth lost
        ],
    };
    let cfg = SynthSection {
        on_truth_lost: on_lost,
        aliases: BTreeMap::from([("asphalt_mf".to_string(), "asphalt".to_string())]),
        ..SynthSection::default()
    };
    let src = SynthSource::new(&cfg, 44_100, 1024, truth, clock.clone(), 200_000_000).unwrap();
    let mut lp = AcqLoop::new(src, 1024, 0, Arc::new(AcqStatus::default()));
    let mut sink = VecSink::default();
    let mut cur = Vec::new();
    let mut lost = Vec::new();
    for _ in 0..(4.5 * 44_100.0 / 1024.0) as usize {
        assert_eq!(lp.step(&mut sink).unwrap(), Step::Published);
        cur.push(lp.source().current());
        lost.push(lp.source().stats().truth_lost);
    }
    (sink.0, cur, lost)
}

#[test]
fn synth_follows_truth_and_documents_loss() {
    let at = |t: f64| (t * 44_100.0 / 1024.0) as usize;
    let (blocks, cur, lost) = synth_run(TruthLost::Hold);
    // before any truth: silence, reported lost
    assert!(blocks[..at(0.45)].iter().all(|b| rms(b) == 0.0));
    assert!(lost[..at(0.45)].iter().all(|&l| l));
    // asphalt, then the alias, then snow at 15 m/s
    let asphalt = grip_arte::synth::road_index("asphalt").unwrap();
    let snow = grip_arte::synth::road_index("snow").unwrap();
    assert!(cur[at(0.6)..at(1.9)].iter().all(|&c| c == (asphalt, 10.0)));
    assert!(cur[at(2.1)..at(2.9)].iter().all(|&c| c == (snow, 15.0)));
    assert!(blocks[at(0.6)..at(2.9)].iter().all(|b| rms(b) > 10.0));
    assert!(!lost[at(0.6)..at(2.9)].iter().any(|&l| l));
    // truth stops at 3 s; lost after the 0.5 s timeout; hold keeps sound
    assert!(!lost[at(3.3)]);
    assert!(lost[at(3.6)..].iter().all(|&l| l));
    assert!(blocks[at(3.6)..].iter().all(|b| rms(b) > 10.0));
    assert_eq!(cur[at(4.4)], (snow, 15.0));
    // silence mode: zeros once lost
    let (blocks, _, lost) = synth_run(TruthLost::Silence);
    assert!(blocks[at(2.1)..at(2.9)].iter().all(|b| rms(b) > 10.0));
    assert!(lost[at(3.6)..].iter().all(|&l| l));
    assert!(blocks[at(3.6)..].iter().all(|b| rms(b) == 0.0));
    // stamps contiguous on the sample clock
    for w in blocks.windows(2) {
        let d = w[1].stamp_ns - w[0].stamp_ns;
        assert!((d as f64 - NS_PER_BLOCK_1024).abs() <= 1.0);
    }
}

#[test]
fn synth_unknown_road_is_vehicle_noise_and_counted() {
    let clock = ManualClock::new(0);
    let truth = ScriptedTruth {
        clock: clock.clone(),
        script: vec![(0, Some("ice"), 10.0)],
    };
    let src = SynthSource::new(
        &SynthSection::default(),
        44_100,
        1024,
        truth,
        clock,
        200_000_000,
    )
    .unwrap();
    let status = Arc::new(AcqStatus::default());
    let mut lp = AcqLoop::new(src, 1024, 0, status.clone());
    let mut sink = VecSink::default();
    for _ in 0..20 {
        lp.step(&mut sink).unwrap();
    }
    assert_eq!(lp.source().current().0, NO_ROAD);
    assert_eq!(lp.source().stats().unknown_road, 20);
    // the road's name reaches the status the helper thread warns from
    // (its warning said "a road" without naming it)
    assert_eq!(
        grip_msgs::name_from_bytes(&status.unknown_name()),
        Some("ice")
    );
}

/// Ground truth that cannot be read: every failed read is counted in the
/// status the helper thread warns from (it was counted in the source only,
/// and reached no log line).
#[test]
fn synth_truth_read_errors_reach_the_status() {
    struct Broken;
    impl TruthInput for Broken {
        fn poll_latest(&mut self) -> Result<Option<GroundTruth>, TruthReadError> {
            Err(TruthReadError)
        }
    }
    let clock = ManualClock::new(0);
    let src = SynthSource::new(
        &SynthSection::default(),
        44_100,
        1024,
        Broken,
        clock,
        200_000_000,
    )
    .unwrap();
    let status = Arc::new(AcqStatus::default());
    let mut lp = AcqLoop::new(src, 1024, 0, Arc::clone(&status));
    let mut sink = VecSink::default();
    for _ in 0..7 {
        lp.step(&mut sink).unwrap();
    }
    assert_eq!(lp.source().stats().truth_errors, 7);
    assert_eq!(
        status
            .truth_errors
            .load(std::sync::atomic::Ordering::Relaxed),
        7
    );
}

/// A fake capture device: a ramp of samples (2 channels: ramp and −ramp),
/// with scripted overruns and time stamps.
struct FakePcm {
    next: i64,
    xrun_at_reads: Vec<usize>,
    reads: usize,
    recovers: usize,
    chunk: usize,
    timing: Option<(u64, i64)>,
}

impl CaptureDevice for FakePcm {
    fn format(&self) -> SampleFormat {
        SampleFormat::S16Le
    }
    fn wait(&mut self, _timeout_ms: u32) -> Result<bool, alsa::Error> {
        Ok(true)
    }
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, alsa::Error> {
        self.reads += 1;
        if self.xrun_at_reads.contains(&self.reads) {
            self.next += 5000; // audio lost during the overrun
            return Err(alsa::Error::new("snd_pcm_readi", libc::EPIPE));
        }
        let frames = (buf.len() / 4).min(self.chunk);
        for f in buf.chunks_exact_mut(4).take(frames) {
            let v = (self.next % 30_000) as i16;
            f[..2].copy_from_slice(&v.to_le_bytes());
            f[2..].copy_from_slice(&(-v).to_le_bytes());
            self.next += 1;
        }
        Ok(frames)
    }
    fn recover(&mut self, e: alsa::Error) -> Result<(), alsa::Error> {
        assert_eq!(e.errno(), libc::EPIPE);
        self.recovers += 1;
        Ok(())
    }
    fn timing(&mut self) -> Option<(u64, i64)> {
        self.timing
    }
}

fn alsa_cfg(channel: u32) -> AlsaSection {
    AlsaSection {
        device: "fake".into(),
        channels: 2,
        channel,
        period_frames: 256,
        buffer_frames: 2048,
        wait_timeout_ms: 10,
        format: FormatSetting::Auto,
        resample: false,
    }
}

#[test]
fn alsa_overruns_are_recovered_counted_and_the_partial_block_dropped() {
    let dev = FakePcm {
        next: 0,
        xrun_at_reads: vec![6],
        reads: 0,
        recovers: 0,
        chunk: 300,
        timing: None,
    };
    let src = AlsaSource::new(dev, &alsa_cfg(1), 44_100, 1024);
    let status = Arc::new(AcqStatus::default());
    let mut lp = AcqLoop::new(src, 1024, 1, Arc::clone(&status));
    let mut sink = VecSink::default();
    for _ in 0..4 {
        assert_eq!(lp.step(&mut sink).unwrap(), Step::Published);
    }
    let b = &sink.0;
    // block 0: reads 1-4 (1200 frames, 1024 used... reads are clipped to
    // the block) -> samples 0..1023 of channel 1 = -ramp
    assert_eq!(b[0].samples()[0], 0);
    assert_eq!(b[0].samples()[1], -1);
    assert_eq!(b[0].channel, 1);
    assert_eq!(b[0].xruns, 0);
    // the overrun hit during block 1: its partial samples are dropped, the
    // block restarts after the lost audio, and every later block reports it
    assert_eq!(lp.source().device().recovers, 1);
    assert_eq!(b[1].xruns, 1);
    assert_eq!(b[3].xruns, 1);
    assert_eq!(status.xruns.load(std::sync::atomic::Ordering::Relaxed), 1);
    let first = -i64::from(b[1].samples()[0]);
    assert!(
        first > 1024 + 5000,
        "block 1 starts after the lost audio: {first}"
    );
    for w in b[1].samples().windows(2) {
        assert_eq!(
            i64::from(w[0]) - i64::from(w[1]),
            1,
            "block 1 is contiguous"
        );
    }
    assert_eq!(
        b.iter().map(|b| b.seq).collect::<Vec<_>>(),
        vec![0, 1, 2, 3]
    );
    // no driver time stamp: capture time minus the block duration
    assert_eq!(lp.source().stamp_fallbacks(), 4);
    let now = monotonic_now_ns();
    assert!(now - b[3].stamp_ns < 1_000_000_000 && now > b[3].stamp_ns);
}

#[test]
fn alsa_stamp_is_driver_time_minus_delay_and_block() {
    let ts = monotonic_now_ns();
    let dev = FakePcm {
        next: 0,
        xrun_at_reads: vec![],
        reads: 0,
        recovers: 0,
        chunk: 4096,
        timing: Some((ts, 441)), // 10 ms queued behind the block
    };
    let mut src = AlsaSource::new(dev, &alsa_cfg(0), 44_100, 1024);
    let mut out = [0i16; 1024];
    match src.read(&mut out).unwrap() {
        Read::Block { n, stamp_ns } => {
            assert_eq!(n, 1024);
            let expect = ts - 10_000_000 - (1024.0 * 1e9 / 44_100.0) as u64;
            assert!(stamp_ns.abs_diff(expect) <= 1, "{stamp_ns} vs {expect}");
        }
        r => panic!("{r:?}"),
    }
    assert_eq!(src.stamp_fallbacks(), 0);
    assert_eq!(out[5], 5);
}

#[test]
fn alsa_every_sample_format_is_converted_to_s16_through_the_source() {
    // 3 channels, channel 2 published, reads of 300 frames (blocks span
    // reads); 70 blocks of 1024 cover every S16 value of the ramp, both
    // extremes included, with low bits and padding that must be dropped
    for format in SampleFormat::PREFERENCE {
        let dev = common::FormatFake {
            format,
            channels: 3,
            chunk: 300,
            next: 0,
        };
        let cfg = AlsaSection {
            channels: 3,
            channel: 2,
            ..alsa_cfg(0)
        };
        let mut src = AlsaSource::new(dev, &cfg, 48_000, 1024);
        let mut out = [0i16; 1024];
        let mut i = 0u64;
        let (mut min, mut max) = (0i16, 0i16);
        for _ in 0..70 {
            match src.read(&mut out).unwrap() {
                Read::Block { n, .. } => assert_eq!(n, 1024),
                r => panic!("{r:?}"),
            }
            for &s in &out {
                assert_eq!(s, common::expected(i, 2), "{format}: frame {i}");
                min = min.min(s);
                max = max.max(s);
                i += 1;
            }
        }
        assert_eq!((min, max), (i16::MIN, i16::MAX), "{format}");
    }
}
