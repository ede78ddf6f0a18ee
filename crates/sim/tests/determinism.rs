//! Same seed -> bit-identical output (whatever the thread count); different
//! seeds -> different output; the CSV headers carry the required columns.

mod common;

use grip_sim::report::{summary_header, write_summary_csv};
use grip_sim::{Job, RoadEstimator, RunResult, Trace, Variant, run_batch};

fn batch(seeds: &[u64], threads: usize) -> Vec<RunResult> {
    let (setup, est) = common::reference();
    let jobs = Job::grid(&Variant::ALL, seeds, false);
    let make =
        move || -> Result<Box<dyn RoadEstimator>, grip_sim::SimError> { Ok(Box::new(est.clone())) };
    run_batch(&setup, &jobs, threads, &make, &|_| {}).unwrap()
}

fn csv(results: &[RunResult]) -> String {
    let mut out = Vec::new();
    write_summary_csv(&mut out, results).unwrap();
    String::from_utf8(out).unwrap()
}

#[test]
fn same_seed_gives_a_bit_identical_summary() {
    let a = csv(&batch(&[7, 8], 1));
    let b = csv(&batch(&[7, 8], 2));
    let c = csv(&batch(&[7, 8], 2));
    assert_eq!(a, b, "thread count changed the output");
    assert_eq!(b, c, "same seeds, different output");
    assert_eq!(a.lines().count(), 1 + 2 * Variant::ALL.len());
}

#[test]
fn different_seeds_differ() {
    let a = batch(&[1], 2);
    let b = batch(&[2], 2);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.variant, y.variant);
        assert_ne!(
            x.metrics, y.metrics,
            "{}: seeds 1 and 2 gave identical metrics",
            x.variant
        );
    }
}

#[test]
fn csv_headers_have_the_required_columns() {
    let h = summary_header();
    let cols: Vec<&str> = h.split(',').collect();
    for need in [
        "variant",
        "seed",
        "slip_deviation",
        "max_torque",
        "torque_effort",
        "mean_accel",
        "distance",
        "energy",
        "kinetic_energy_gain",
        "arte_accuracy",
    ] {
        assert!(cols.contains(&need), "summary.csv lacks `{need}`: {h}");
    }
    // The older columns keep their positions; the command's come last.
    assert_eq!(
        h,
        "variant,seed,slip_deviation,max_torque,torque_effort,mean_accel,distance,energy,\
         kinetic_energy_gain,final_speed_kmh,arte_accuracy,arte_usage,arte_frames,duration,\
         samples,rejected,non_finite_cycles,cmd_tv_per_s,cmd_hf_rms,cmd_hf_share"
    );
    let results = batch(&[3], 1);
    let text = csv(&results);
    assert_eq!(text.lines().next(), Some(h.as_str()));
    for line in text.lines().skip(1) {
        assert_eq!(line.split(',').count(), cols.len(), "{line}");
    }
    let t: Vec<&str> = Trace::CSV_HEADER.split(',').collect();
    for need in [
        "t",
        "v",
        "omega",
        "r_omega",
        "lambda",
        "torque",
        "torque_cmd",
        "demand",
        "mu",
        "mu_hat",
        "internal",
        "true_road",
        "est_road",
        "used_arte",
    ] {
        assert!(t.contains(&need), "trace CSV lacks `{need}`");
    }
}
