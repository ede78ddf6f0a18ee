//! The streaming estimator, the feature extractor, a real model's predictor
//! and the streaming synthesiser allocate nothing after construction.

use grip_arte::calib::{Calibration, StreamCalibration};
use grip_arte::eval::Samples;
use grip_arte::features::{FeatureConfig, FeatureExtractor, FeatureSet, SpeedNorm};
use grip_arte::mlp::LmConfig;
use grip_arte::model::{ClassifierSpec, Predictor, fit};
use grip_arte::stream::{StreamConfig, StreamEstimator};
use grip_arte::synth::{NoiseConfig, RoadAudioSynth, SynthConfig};

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

/// This thread's allocations so far. Everything measured runs on the test's
/// thread; the harness's main thread may allocate meanwhile and must not
/// count (a process-wide count failed CI that way).
fn allocs() -> usize {
    grip_testkit::thread_allocations() as usize
}

#[test]
fn hot_paths_allocate_nothing() {
    let synth_cfg = SynthConfig {
        sample_rate: 44_100,
        noise: Some(NoiseConfig {
            rain: true,
            car: true,
            snr_db: 10.0,
        }),
    };
    let mut synth = RoadAudioSynth::new(&synth_cfg, 1).unwrap();
    let norm = Some(SpeedNorm {
        ref_kmh: 20.0,
        exponent: 0.25,
    });
    for (set, speed_norm, fixed_bands) in [
        (FeatureSet::Paper20, None, false),
        (FeatureSet::Paper7, None, false),
        (FeatureSet::Rich, None, false),
        (FeatureSet::Rich, norm, false),
        (FeatureSet::Rich, norm, true),
    ] {
        let fcfg = FeatureConfig {
            speed_norm,
            fixed_bands,
            ..FeatureConfig::new(44_100, set)
        };
        // A real (tiny) model, trained on synthetic frames of two roads.
        let mut ex = FeatureExtractor::new(&fcfg).unwrap();
        let mut train = Samples::new(ex.dim());
        let mut buf = vec![0f32; 4410];
        let mut row = vec![0.0; ex.dim()];
        for i in 0..40 {
            let road = i % 2 * 2;
            synth.fill(road, 8.0, &mut buf);
            ex.extract(&buf, &mut row).unwrap();
            train.push(&row, i % 2, i / 4);
        }
        let classes = vec!["asphalt".to_string(), "snow".to_string()];
        let spec = ClassifierSpec::Mlp {
            lm: LmConfig {
                epochs: 5,
                ..Default::default()
            },
            val_fraction: 0.0,
        };
        let (model, _) = fit(&classes, &fcfg, &spec, &train).unwrap();
        // Without and with a confidence calibration (a model file v1 and v2).
        let isotonic = StreamCalibration {
            map: Calibration::Isotonic {
                x: (0..40).map(|i| 0.3 + 0.0175 * f64::from(i)).collect(),
                y: (0..40).map(|i| 0.2 + 0.02 * f64::from(i)).collect(),
            },
            stream: StreamConfig::default(),
            notes: vec![],
            files: vec![],
        };
        for cal in [None, Some(isotonic)] {
            let calibrated = cal.is_some();
            let model = model.clone().with_calibration(cal).unwrap();
            let mut est =
                StreamEstimator::new(Predictor::new(model), &fcfg, &StreamConfig::default())
                    .unwrap();

            let mut block = vec![0f32; 1024];
            let mut out = vec![0.0; ex.dim()];
            // Warm up (first decision, first road change).
            synth.fill(0, 8.0, &mut block);
            est.push(&block, |_| {});
            let before = allocs();
            let mut n = 0;
            let mut seen = 0u64;
            let mut top = 0.0f64;
            for i in 0..200 {
                let road = if i < 100 { 0 } else { 3 };
                let v = 5.0 + i as f64 * 0.02;
                synth.fill(road, v, &mut block);
                // The speed changes every block, over a range wide enough to
                // rebuild the speed-normalised filter banks at every extreme.
                let speed = [0.1, v, 70.0, 2.0 + 0.3 * i as f64][i % 4];
                est.set_speed(Some(speed));
                ex.set_speed(Some(speed));
                n += est.push(&block, |d| {
                    seen = d.seq;
                    top = top.max(d.confidence);
                });
                ex.extract(&block, &mut out).unwrap();
            }
            let after = allocs();
            assert!(n > 80, "{n} decisions");
            assert!(seen > 80);
            // The calibration was applied: its values end at 0.98.
            assert_eq!(calibrated, top <= 0.98 + 1e-12, "highest confidence {top}");
            assert_eq!(
                after - before,
                0,
                "{set:?} (speed norm {speed_norm:?}, fixed bands {fixed_bands}, calibrated {calibrated}): {} allocations in the hot loop",
                after - before
            );
        }
    }
}
