//! The arte loop on synthetic audio of known roads (no processes): the
//! estimates are mostly right, switch after a road change within a stated
//! delay, carry consistent time spans and road parameters; lost blocks,
//! discontinuities and wrong sample rates are handled as documented.

mod common;

use std::sync::atomic::Ordering;

use common::*;
use grip_arte::stream::StreamConfig;
use grip_arte_svc::{ArteCounters, ArteError, ArteLoop, load_model, road_table};
use grip_io::clock::ManualClock;
use grip_msgs::{AudioBlock, RoadEstimate};

const T0: u64 = 5_000_000_000;
const CHANGE_S: f64 = 4.0;
/// Stated bound on the detection delay of an abrupt road change: 0.5 s
/// (measured: see the printed delays and services/README.md).
const MAX_DELAY_S: f64 = 0.5;

/// Feeds `first` then `second` (4 s each, 12 m/s, clean synthetic audio
/// of an unseen seed) through the loop; checks every estimate's fields and
/// returns (accuracy over frames wholly on one road outside the allowed
/// delay, detection delay of the change in s).
fn follow(
    model: &grip_arte::model::Model,
    first: &str,
    second: &str,
    speed: f64,
    seed: u64,
) -> (f64, f64) {
    let roads = roads_for(model);
    let k = model.classes().len();
    let clock = ManualClock::new(T0);
    let stats = ArteCounters::default();
    let mut sink = VecSink::default();
    let bl = blocks(
        seed,
        &[(first, speed, CHANGE_S), (second, speed, 4.0)],
        1024,
        T0,
    );
    let mut lp = ArteLoop::from_model(
        model,
        &StreamConfig::default(),
        roads.clone(),
        0.2,
        clock.clone(),
    )
    .unwrap();
    for b in &bl {
        clock.set_ns(b.stamp_ns + 23_219_955); // the block arrives after its last sample
        lp.on_block(b, &mut sink, &stats);
    }
    assert_eq!(stats.lost_blocks.load(Ordering::Relaxed), 0);
    assert_eq!(stats.resets.load(Ordering::Relaxed), 0);
    let est = &sink.0;
    // one estimate per hop (default 0.025 s, whole samples) after the first 0.1 s frame
    let n = bl.len() * 1024;
    let frame = (0.1 * f64::from(RATE)).round() as usize;
    let hop = (StreamConfig::default().hop_s * f64::from(RATE)).round() as usize;
    assert_eq!(est.len(), (n - frame) / hop + 1);
    let hop_ns = hop as f64 * 1e9 / f64::from(RATE);
    let change_ns = T0 + (CHANGE_S * 1e9) as u64;
    let mut right = 0;
    let mut judged = 0;
    let mut detect: Option<f64> = None;
    let mut hist = vec![[0usize; 2]; k];
    for (i, e) in est.iter().enumerate() {
        hist[e.class_index as usize][usize::from(e.frame_t1_ns > change_ns)] += 1;
        assert_eq!(e.seq, i as u64);
        assert_eq!(e.frame_t1_ns - e.frame_t0_ns, 100_000_000);
        assert!(
            e.stamp_ns >= e.frame_t1_ns,
            "published after the frame ends"
        );
        assert_eq!(e.n_classes as usize, k);
        let sum: f32 = e.probabilities[..k].iter().sum();
        assert!((sum - 1.0).abs() < 1e-4, "probabilities sum to {sum}");
        assert!(e.probabilities[k..].iter().all(|&p| p == 0.0));
        assert!((e.confidence - f64::from(e.probabilities[e.class_index as usize])).abs() < 1e-6);
        let name = e.class_name().unwrap();
        assert_eq!(name, model.classes()[e.class_index as usize]);
        let r = &roads[e.class_index as usize];
        assert_eq!(
            (e.lambda_opt, e.mu_peak, e.alpha),
            (r.lambda_opt, r.mu_peak, 1.0 - r.lambda_opt)
        );
        if i > 0 {
            // one hop of whole samples apart, to the nanosecond
            let step = e.frame_t1_ns - est[i - 1].frame_t1_ns;
            assert!(step.abs_diff(hop_ns.round() as u64) <= 1, "step {step} ns");
        }
        // frame entirely on one road, and (after a change) past the
        // allowed delay: must be that road
        let truth = if e.frame_t1_ns <= change_ns {
            Some(first)
        } else if e.frame_t0_ns >= change_ns + (MAX_DELAY_S * 1e9) as u64 {
            Some(second)
        } else {
            None
        };
        if let Some(t) = truth {
            judged += 1;
            right += usize::from(name == t);
        }
        if detect.is_none() && e.frame_t1_ns > change_ns && name == second {
            // holds for 0.3 s
            let holds = est[i..]
                .iter()
                .take_while(|f| f.frame_t1_ns <= e.frame_t1_ns + 300_000_000)
                .all(|f| f.class_name() == Some(second));
            if holds {
                detect = Some((e.frame_t1_ns - change_ns) as f64 / 1e9);
            }
        }
    }
    let acc = right as f64 / judged as f64;
    let delay = detect.unwrap_or(f64::INFINITY);
    println!(
        "{first} -> {second} at {speed} m/s: accuracy {acc:.3} over {judged} estimates, detection delay {delay:.3} s; estimates per class before/after: {:?}",
        model.classes().iter().zip(&hist).collect::<Vec<_>>()
    );
    (acc, delay)
}

#[test]
fn estimates_follow_a_road_change() {
    let model = train_model(6);
    for (first, second) in [("asphalt", "snow"), ("stone", "gravel")] {
        let (acc, delay) = follow(&model, first, second, 12.0, 999);
        assert!(acc >= 0.9, "{first} -> {second}: accuracy {acc}");
        assert!(delay <= MAX_DELAY_S, "{first} -> {second}: delay {delay} s");
    }
}

/// The shipped `config/models/default.model` (trained by `grip train`,
/// not by this test) through the same loop: every estimate's fields are
/// checked inside `follow`; its accuracy is printed, not asserted, because
/// it is the classifier's property, not the service's. Measured
/// 2026-11-22 with the model of that day (Rich + fixed bands, speed
/// exponent 0.1), seeds 1-12 (this test runs 1 and 5): asphalt -> snow
/// 1.000 on all, stone -> gravel 1.000 on 9 of 12 (0.94, 0.84, 0.68 on
/// seeds 6, 7, 9), delays 0.03-0.10 s. (An earlier default, trained on
/// 10-30 km/h only, called seed 5's asphalt at 6 m/s "snow" in every frame;
/// `services/README.md`, "audio-acq / arte".)
#[test]
fn shipped_default_model_runs_in_the_loop() {
    let model = load_model(&config_dir().join("models/default.model")).unwrap();
    assert_eq!(model.feature_config().sample_rate, RATE);
    for seed in [1, 5] {
        for (first, second) in [("asphalt", "snow"), ("stone", "gravel")] {
            let (acc, delay) = follow(&model, first, second, 6.0, seed);
            println!(
                "shipped model, seed {seed}: {first} -> {second}: accuracy {acc:.3}, delay {delay:.3} s"
            );
        }
    }
}

#[test]
fn gaps_discontinuities_and_wrong_rates() {
    let model = train_model(2);
    let roads = roads_for(&model);
    let clock = ManualClock::new(T0);
    let mut lp =
        ArteLoop::from_model(&model, &StreamConfig::default(), roads, 0.2, clock.clone()).unwrap();
    let stats = ArteCounters::default();
    let mut sink = VecSink::default();
    let bl = blocks(7, &[("asphalt", 10.0, 2.0)], 1024, T0);
    // drop blocks 10 and 11 (lost in transport): counted, no restart (46 ms gap)
    for b in bl.iter().take(40).filter(|b| b.seq != 10 && b.seq != 11) {
        lp.on_block(b, &mut sink, &stats);
    }
    assert_eq!(stats.lost_blocks.load(Ordering::Relaxed), 2);
    assert_eq!(stats.resets.load(Ordering::Relaxed), 0);
    // the spans stay anchored to the block stamps across the gap
    let last = sink.0.last().unwrap();
    let b39_end = bl[39].stamp_ns + (1024u64 * 1_000_000_000 / u64::from(RATE));
    assert!(last.frame_t1_ns <= b39_end && b39_end - last.frame_t1_ns < 50_000_000);
    // a block 1 s later (audio-acq restarted its timeline): restart
    let mut late = bl[40];
    late.stamp_ns += 1_000_000_000;
    let n_before = sink.0.len();
    lp.on_block(&late, &mut sink, &stats);
    assert_eq!(stats.resets.load(Ordering::Relaxed), 1);
    assert_eq!(sink.0.len(), n_before, "no decision right after a restart");
    // after the restart the first decision comes once a full frame (0.1 s) is in
    for (k, b) in bl[41..46].iter().enumerate() {
        let mut b = *b;
        b.stamp_ns += 1_000_000_000;
        lp.on_block(&b, &mut sink, &stats);
        let expect_first = (k + 2) * 1024 >= 4410;
        assert_eq!(sink.0.len() > n_before, expect_first, "block {k}");
    }
    let first_after = &sink.0[n_before];
    assert_eq!(
        first_after.frame_t0_ns, late.stamp_ns,
        "frame starts at the restart block"
    );
    // a sequence number going backwards (publisher restarted) also restarts
    let mut again = bl[0];
    again.stamp_ns = late.stamp_ns + 6 * 23_219_955;
    lp.on_block(&again, &mut sink, &stats);
    assert_eq!(stats.resets.load(Ordering::Relaxed), 2);
    // a block at another sample rate is refused and counted
    let n = sink.0.len();
    let mut wrong = bl[1];
    wrong.sample_rate = 48_000;
    for _ in 0..10 {
        lp.on_block(&wrong, &mut sink, &stats);
    }
    assert_eq!(stats.rate_mismatch.load(Ordering::Relaxed), 10);
    assert_eq!(stats.bad_rate.load(Ordering::Relaxed), 48_000);
    assert_eq!(sink.0.len(), n);
}

#[test]
fn model_and_class_errors_name_the_file_and_class() {
    let dir = tempfile::tempdir().unwrap();
    // missing
    let p = dir.path().join("none.model");
    let e = load_model(&p).unwrap_err().to_string();
    assert!(e.contains("none.model") && e.contains("cannot read"), "{e}");
    // corrupt: a flipped byte in the payload
    let model = train_model(2);
    let mut bytes = model.to_bytes().unwrap();
    let n = bytes.len();
    bytes[n - 10] ^= 0x01;
    let p = dir.path().join("corrupt.model");
    std::fs::write(&p, &bytes).unwrap();
    let e = load_model(&p).unwrap_err();
    assert!(matches!(e, ArteError::Model { .. }));
    let e = e.to_string();
    assert!(
        e.contains("corrupt.model") && e.contains("checksum mismatch"),
        "{e}"
    );
    // not a model
    let p = dir.path().join("text.model");
    std::fs::write(&p, b"hello\nworld").unwrap();
    let e = load_model(&p).unwrap_err();
    // the reason said in the message and not also returned as the source
    // (`grip replay` prints the chain: it said the reason twice)
    let mut said = e.to_string();
    let mut cause = std::error::Error::source(&e);
    while let Some(c) = cause {
        said = format!("{said}: {c}");
        cause = c.source();
    }
    assert_eq!(said.matches("not a grip ARTE model").count(), 1, "{said}");
    let e = e.to_string();
    assert!(
        e.contains("text.model") && e.contains("not a grip ARTE model"),
        "{e}"
    );
    // a class the catalogue does not have
    let roads = grip_config::load_roads(config_dir().join("roads.toml")).unwrap();
    let classes = vec!["asphalt".to_string(), "lava".to_string()];
    let rule = grip_tcs::RoadTable::new(&roads, &Default::default()).unwrap();
    let e = road_table(
        &classes,
        &roads,
        &rule,
        std::path::Path::new("m.model"),
        std::path::Path::new("roads.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("m.model") && e.contains("`lava`") && e.contains("roads.toml"),
        "{e}"
    );
    // a valid model round-trips through the file and loads
    let p = dir.path().join("good.model");
    std::fs::write(&p, model.to_bytes().unwrap()).unwrap();
    let m = load_model(&p).unwrap();
    assert_eq!(m.classes(), model.classes());
}

/// The shipped model's confidence calibration was fitted at hop 0.025 s
/// with the HMM (0.9, 0.01): an `arte-svc.toml` with other `[stream]`
/// settings is refused at start-up, naming the file, the field(s), the
/// model and the remedy; `prepare_with_clock` (a replay's or a generated
/// drive's start-up) loads it, the mismatch kept for its caller to refuse
/// or say.
#[test]
fn stream_settings_the_calibration_was_not_fitted_for_are_refused() {
    use grip_arte_svc::{Options, prepare, prepare_with_clock};
    let model = config_dir().join("models/default.model");
    let dir = tempfile::tempdir().unwrap();
    let opts = |name: &str, stream: &str| {
        let f = dir.path().join(name);
        std::fs::write(
            &f,
            format!(
                "model = {:?}\n[stream]\n{stream}\n",
                model.display().to_string()
            ),
        )
        .unwrap();
        Options {
            config: grip_io::service::ConfigArgs {
                config_dir: config_dir(),
                config: Some(f),
            },
            model: None,
            run_for: None,
        }
    };
    let hmm = "smoothing = { hmm = { stay = 0.9, floor = 0.01 } }";
    // as fitted: starts
    prepare(&opts("fitted.toml", &format!("hop_s = 0.025\n{hmm}"))).unwrap();
    let cases = [
        (
            "hop.toml",
            format!("hop_s = 0.05\n{hmm}"),
            vec![
                "field `stream.hop_s` = 0.05:",
                "--calib-hop 0.05 --calib-stay 0.9 --calib-floor 0.01",
            ],
        ),
        (
            "none.toml",
            "hop_s = 0.025\nsmoothing = \"none\"".to_owned(),
            vec![
                "field `stream.smoothing` = \"none\":",
                "--calib-hop 0.025 --calib-stay 0`",
            ],
        ),
        (
            "both.toml",
            "hop_s = 0.1\nsmoothing = { hmm = { stay = 0.8, floor = 0.01 } }".to_owned(),
            vec![
                "fields `stream.hop_s` = 0.1, `stream.smoothing` = { hmm = { stay = 0.8, floor = 0.01 } }:",
            ],
        ),
    ];
    for (name, stream, says) in cases {
        let e = prepare(&opts(name, &stream)).unwrap_err();
        assert!(matches!(e, ArteError::CalibrationMismatch { .. }), "{e}");
        let m = e.to_string();
        let file = dir.path().join(name);
        assert!(m.starts_with(&format!("{}: ", file.display())), "{m}");
        for s in says.iter().chain(&[
            model.display().to_string().as_str(),
            "was fitted at [stream] hop_s = 0.025, smoothing = { hmm = { stay = 0.9, floor = 0.01 } }",
            "grip calibrate --model",
            "or set [stream] back to the settings it was fitted at",
        ]) {
            assert!(m.contains(s), "{name}: no {s:?} in: {m}");
        }
        // what-ifs run, the mismatch kept for the caller
        let p = prepare_with_clock(&opts(name, &stream), ManualClock::new(T0)).unwrap();
        assert_eq!(p.calibration_mismatch.unwrap().to_string(), m);
    }
}

fn toy_road(name: &str) -> grip_arte_svc::ClassKnowledge {
    grip_arte_svc::ClassKnowledge {
        name: grip_msgs::name_to_bytes(name),
        lambda_opt: 0.1,
        mu_peak: 1.0,
        alpha: 0.9,
    }
}

/// An arte loop over asphalt and snow whose classifier always says `probs`.
fn toy_loop(
    f: &grip_arte::features::FeatureConfig,
    probs: &'static [f64],
    stream: &StreamConfig,
    clock: &ManualClock,
) -> ArteLoop<Toy, ManualClock> {
    ArteLoop::new(
        Toy {
            dim: f.dim(),
            probs,
        },
        f,
        stream,
        vec![toy_road("asphalt"), toy_road("snow")],
        0.2,
        clock.clone(),
    )
    .unwrap()
}

/// Contiguous blocks of `n` samples of a little noise from `T0`.
fn noise_blocks(count: usize, n: usize) -> Vec<AudioBlock> {
    (0..count)
        .map(|k| {
            let mut b = AudioBlock::zeroed();
            b.seq = k as u64;
            b.sample_rate = RATE;
            b.n_samples = n as u32;
            b.stamp_ns = T0 + (k * n) as u64 * 1_000_000_000 / u64::from(RATE);
            for (i, s) in b.samples[..n].iter_mut().enumerate() {
                *s = (((k * n + i) * 7919) % 2000) as i16 - 1000;
            }
            b
        })
        .collect()
}

/// A block stamped far in the future (up to u64::MAX) that reports a new
/// capture overrun: no overflow, and the overrun hold it starts ends at
/// most `xrun_hold_ns` after the blocks that follow on the right time base
/// (before, it held every later block for good: no estimate ever again).
#[test]
fn a_far_future_block_neither_overflows_nor_holds_for_good() {
    for future in [T0 + 3_600_000_000_000, u64::MAX - 1_000, u64::MAX] {
        let f =
            grip_arte::features::FeatureConfig::new(RATE, grip_arte::features::FeatureSet::Rich);
        let clock = ManualClock::new(T0);
        let mut lp = toy_loop(&f, &[0.3, 0.7], &StreamConfig::default(), &clock);
        let stats = ArteCounters::default();
        let mut sink = VecSink::default();
        let mut bl = noise_blocks(130, 1024); // 3 s
        bl[20].stamp_ns = future;
        for b in &mut bl[20..] {
            b.xruns = 1;
        }
        let mut good_after = 0;
        for (k, b) in bl.iter().enumerate() {
            let from = sink.0.len();
            lp.on_block(b, &mut sink, &stats);
            if k > 20 {
                good_after += sink.0[from..]
                    .iter()
                    .filter(|e| e.class_index != grip_msgs::NO_CLASS)
                    .count();
            }
        }
        // the block itself and at most 0.5 s of the ones after it
        let held = stats.xrun_blocks.load(Ordering::Relaxed);
        assert!((2..=24).contains(&held), "{future}: {held} blocks held");
        // estimates again after the hold: 2.5 s of blocks after it, 0.5 s
        // held, a frame to fill, then one per 25 ms (76)
        assert!(
            good_after >= 70,
            "{future}: {good_after} estimates after it"
        );
    }
}

/// A classifier that gives NaN, without smoothing: what is published is
/// a finite confidence (the estimator reads the frame as uniform), never NaN.
#[test]
fn a_nan_classifier_output_publishes_a_finite_confidence() {
    let f = grip_arte::features::FeatureConfig::new(RATE, grip_arte::features::FeatureSet::Rich);
    let clock = ManualClock::new(T0);
    let none = StreamConfig {
        smoothing: grip_arte::stream::Smoothing::None,
        ..StreamConfig::default()
    };
    let mut lp = toy_loop(&f, &[f64::NAN, f64::NAN], &none, &clock);
    let stats = ArteCounters::default();
    let mut sink = VecSink::default();
    for b in noise_blocks(40, 1024) {
        lp.on_block(&b, &mut sink, &stats);
    }
    assert!(!sink.0.is_empty());
    for e in &sink.0 {
        assert_eq!(e.confidence, 0.5, "{e:?}");
        assert!(e.probabilities[..2].iter().all(|p| p.is_finite()), "{e:?}");
    }
}

/// The microphone's faults (`AudioQuality`): silent, clipped and
/// overrun blocks are not classified. Each gives one estimate with
/// `NO_CLASS` and confidence 0 (counted per kind); the estimator restarts,
/// so the first real decision after the fault is a full frame of good audio
/// later. Also printed: what the shipped model says of silence and of
/// clipped audio without the gate (the reason for it).
#[test]
fn silence_clipping_and_overruns_give_no_road() {
    use grip_arte_svc::AudioQuality;
    let model = load_model(&config_dir().join("models/default.model")).unwrap();
    let roads = roads_for(&model);
    let clock = ManualClock::new(T0);
    let new_loop = |q: AudioQuality| {
        ArteLoop::from_model(
            &model,
            &StreamConfig::default(),
            roads.clone(),
            0.2,
            clock.clone(),
        )
        .unwrap()
        .with_quality(q)
    };
    let bl = blocks(7, &[("asphalt", 10.0, 3.0)], 1024, T0);
    let block_ns = 1024u64 * 1_000_000_000 / u64::from(RATE);
    // blocks 0..43: clean; 43..53 silent; 53..63 clean; 63..73 clipped;
    // (amplified 1000x) 73..83 clean; block 83 reports an overrun, 84..129 clean
    let faulty: Vec<AudioBlock> = bl
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let mut b = *b;
            match i {
                43..53 => b.samples.fill(0),
                63..73 => {
                    for s in &mut b.samples {
                        *s = (i32::from(*s) * 1000).clamp(-32768, 32767) as i16;
                    }
                }
                _ => {}
            }
            b.xruns = u32::from(i >= 83);
            b
        })
        .collect();

    // without the gate: what the model makes of the faulty audio
    let off = AudioQuality {
        silence_rms: 0.0,
        clip_share: 1.0,
        xrun_hold_ns: 0,
    };
    let mut lp = new_loop(off);
    let stats = ArteCounters::default();
    let mut sink = VecSink::default();
    for b in &faulty {
        lp.on_block(b, &mut sink, &stats);
    }
    let span = |a: usize, b: usize| (bl[a].stamp_ns, bl[b].stamp_ns);
    let conf_in = |es: &[RoadEstimate], (t0, t1): (u64, u64)| -> Vec<(String, f64)> {
        es.iter()
            .filter(|e| e.frame_t0_ns >= t0 && e.frame_t1_ns <= t1)
            .map(|e| (e.class_name().unwrap_or("-").to_owned(), e.confidence))
            .collect()
    };
    for (what, w) in [("silence", span(43, 53)), ("clipping", span(63, 73))] {
        let c = conf_in(&sink.0, w);
        let top = c.iter().map(|x| x.1).fold(0.0, f64::max);
        println!(
            "without the gate, {what}: {} estimates, classes {:?}, highest confidence {top:.3}",
            c.len(),
            c.iter()
                .map(|x| x.0.as_str())
                .collect::<std::collections::BTreeSet<_>>()
        );
    }
    assert_eq!(stats.silent_blocks.load(Ordering::Relaxed), 0);

    // with the shipped gate
    let mut lp = new_loop(AudioQuality::default());
    let stats = ArteCounters::default();
    let mut sink = VecSink::default();
    let mut per_block = Vec::new();
    for b in &faulty {
        clock.set_ns(b.stamp_ns + block_ns);
        let from = sink.0.len();
        lp.on_block(b, &mut sink, &stats);
        per_block.push(sink.0[from..].to_vec());
    }
    let load = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
    assert_eq!(load(&stats.silent_blocks), 10);
    assert_eq!(load(&stats.clipped_blocks), 10);
    // the overrun block and the clean ones within 0.5 s after it
    let held = (0.5e9 / block_ns as f64).ceil() as u64;
    assert_eq!(load(&stats.xrun_blocks), held);
    for (i, es) in per_block.iter().enumerate() {
        let bad =
            (43..53).contains(&i) || (63..73).contains(&i) || (83..83 + held as usize).contains(&i);
        if bad {
            assert_eq!(es.len(), 1, "block {i}: one estimate per unusable block");
            let e = &es[0];
            assert_eq!(e.class_index, grip_msgs::NO_CLASS, "block {i}");
            assert_eq!(e.confidence, 0.0, "block {i}");
            assert!(e.lambda_opt.is_nan() && e.mu_peak.is_nan(), "block {i}");
            let end = faulty[i].stamp_ns + block_ns;
            assert!(
                e.frame_t1_ns.abs_diff(end) <= 1,
                "block {i}: span ends with the block"
            );
        } else {
            assert!(
                es.iter().all(|e| e.class_index != grip_msgs::NO_CLASS),
                "block {i}: a good block gave a no-road estimate"
            );
        }
    }
    // after each fault the first decision needs a full frame of good audio
    for first_good in [53usize, 73, 83 + held as usize] {
        let frame_blocks = 4410usize.div_ceil(1024);
        for (k, es) in per_block[first_good..first_good + frame_blocks]
            .iter()
            .enumerate()
        {
            assert_eq!(
                !es.is_empty(),
                k + 1 == frame_blocks,
                "block {}: a decision before a full frame of good audio",
                first_good + k
            );
        }
    }
    // and the decisions after the faults are of the road again
    let after: Vec<&RoadEstimate> = per_block[110..].iter().flatten().collect();
    assert!(!after.is_empty());
    let right = after
        .iter()
        .filter(|e| e.class_name() == Some("asphalt"))
        .count();
    println!(
        "after the faults: {right}/{} estimates asphalt",
        after.len()
    );
}

/// Start-up knows (and `run` logs, in "arte starting") the speeds the
/// model was trained at: for the shipped model, from its training note.
#[test]
fn start_up_knows_the_models_training_speeds() {
    use grip_arte_svc::{Options, prepare};
    let p = prepare(&Options {
        config: grip_io::service::ConfigArgs {
            config_dir: config_dir(),
            config: None,
        },
        model: None,
        run_for: None,
    })
    .unwrap();
    assert_eq!(
        p.training_speeds.describe(),
        "4.0-29.8 km/h (from the model's training notes)"
    );
}
