//! `Predictor::predict_proba` allocates nothing (counting global allocator,
//! this thread's allocations: the harness's main thread may allocate meanwhile).

use grip_arte::eval::Samples;
use grip_arte::features::{FeatureConfig, FeatureSet};
use grip_arte::mlp::LmConfig;
use grip_arte::model::{ClassifierSpec, fit};
use grip_arte::svm::{Kernel, SvmConfig};

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

#[test]
fn predict_proba_allocates_nothing() {
    let classes: Vec<String> = ["a", "b", "c"].map(String::from).to_vec();
    let mut s = Samples::new(7);
    for i in 0..90 {
        let c = i % 3;
        let row: Vec<f64> = (0..7)
            .map(|d| if d == c { 2.0 } else { 0.0 } + ((i * 31 + d * 7) % 11) as f64 * 0.1)
            .collect();
        s.push(&row, c, i % 15);
    }
    let cfg = FeatureConfig::new(44_100, FeatureSet::Paper7);
    let specs = [
        ClassifierSpec::Mlp {
            lm: LmConfig {
                epochs: 20,
                ..Default::default()
            },
            val_fraction: 0.0,
        },
        ClassifierSpec::Svm {
            cfg: SvmConfig {
                kernel: Kernel::Rbf { gamma: 0.2 },
                prob_folds: 0,
                ..Default::default()
            },
            max_per_class: 100,
        },
    ];
    for spec in specs {
        let (model, _) = fit(&classes, &cfg, &spec, &s).unwrap();
        let mut p = model.predictor();
        let mut out = [0.0; 3];
        let before = grip_testkit::thread_allocations();
        let mut sum = 0;
        for i in 0..s.len() {
            sum += p.predict_proba(s.row(i), &mut out).unwrap();
        }
        let after = grip_testkit::thread_allocations();
        assert_eq!(
            after - before,
            0,
            "{} allocations in {} predictions",
            after - before,
            s.len()
        );
        assert!(sum > 0);
    }
}
