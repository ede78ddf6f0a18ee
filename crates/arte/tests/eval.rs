//! Cross-validation by recording and confusion-matrix scores.

use grip_arte::eval::{Confusion, EvalError, holdout_groups, stratified_group_kfold};
use proptest::prelude::*;
use std::collections::BTreeSet;

/// `recs[c]` recordings of class `c`, each with `frames` frames; returns (labels, groups).
fn layout(recs: &[usize], frames: &[usize]) -> (Vec<usize>, Vec<usize>) {
    let (mut labels, mut groups) = (Vec::new(), Vec::new());
    let mut g = 0;
    for (c, &n) in recs.iter().enumerate() {
        for r in 0..n {
            for _ in 0..frames[(g + r) % frames.len()] {
                labels.push(c);
                groups.push(g * 7 + 3); // arbitrary non-contiguous ids
            }
            g += 1;
        }
    }
    // Interleave so a recording's frames are not contiguous.
    let n = labels.len();
    let perm: Vec<usize> = (0..n).map(|i| (i * 7919) % n).collect();
    if n % 7919 != 0 {
        return (
            perm.iter().map(|&i| labels[i]).collect(),
            perm.iter().map(|&i| groups[i]).collect(),
        );
    }
    (labels, groups)
}

proptest! {
    #[test]
    fn no_recording_on_both_sides(
        recs in prop::collection::vec(5usize..12, 2..5),
        frames in prop::collection::vec(1usize..9, 1..6),
        k in 2usize..6,
        seed in any::<u64>(),
    ) {
        let (labels, groups) = layout(&recs, &frames);
        let folds = stratified_group_kfold(&labels, &groups, recs.len(), k, seed).unwrap();
        prop_assert_eq!(folds.len(), k);
        let mut tested = vec![0usize; labels.len()];
        for f in &folds {
            let tr: BTreeSet<usize> = f.train.iter().map(|&i| groups[i]).collect();
            let te: BTreeSet<usize> = f.test.iter().map(|&i| groups[i]).collect();
            prop_assert!(tr.is_disjoint(&te), "a recording is on both sides");
            prop_assert_eq!(f.train.len() + f.test.len(), labels.len());
            for &i in &f.test { tested[i] += 1; }
            // Stratified: every class is in every test fold (each has >= k recordings).
            let classes: BTreeSet<usize> = f.test.iter().map(|&i| labels[i]).collect();
            prop_assert_eq!(classes.len(), recs.len());
        }
        prop_assert!(tested.iter().all(|&t| t == 1), "every sample is tested exactly once");
    }

    #[test]
    fn holdout_keeps_recordings_whole(recs in prop::collection::vec(2usize..10, 2..5), seed in any::<u64>()) {
        let (labels, groups) = layout(&recs, &[3, 1, 4]);
        let (tr, va) = holdout_groups(&labels, &groups, recs.len(), 0.2, seed).unwrap();
        let a: BTreeSet<usize> = tr.iter().map(|&i| groups[i]).collect();
        let b: BTreeSet<usize> = va.iter().map(|&i| groups[i]).collect();
        prop_assert!(a.is_disjoint(&b));
        prop_assert_eq!(tr.len() + va.len(), labels.len());
        // Every class keeps training data and gives validation data.
        for c in 0..recs.len() {
            prop_assert!(tr.iter().any(|&i| labels[i] == c));
            prop_assert!(va.iter().any(|&i| labels[i] == c));
        }
    }
}

#[test]
fn split_errors_are_specific() {
    let (labels, groups) = layout(&[5, 3], &[2]);
    assert_eq!(
        stratified_group_kfold(&labels, &groups, 2, 4, 1),
        Err(EvalError::TooFewGroups {
            class: 1,
            have: 3,
            folds: 4
        })
    );
    assert_eq!(
        stratified_group_kfold(&labels, &groups, 2, 1, 1),
        Err(EvalError::FoldCount(1))
    );
    let err = stratified_group_kfold(&[0, 1], &[5, 5], 2, 2, 1).unwrap_err();
    assert_eq!(
        err,
        EvalError::MixedGroup {
            group: 5,
            a: 0,
            b: 1
        }
    );
    assert!(err.to_string().contains("recording 5"));
    assert!(stratified_group_kfold(&[0], &[1, 2], 2, 2, 1).is_err());
}

#[test]
fn split_is_deterministic_for_a_seed() {
    let (labels, groups) = layout(&[8, 8, 8], &[3, 5]);
    let a = stratified_group_kfold(&labels, &groups, 3, 4, 9).unwrap();
    let b = stratified_group_kfold(&labels, &groups, 3, 4, 9).unwrap();
    let c = stratified_group_kfold(&labels, &groups, 3, 4, 10).unwrap();
    assert_eq!(a, b);
    assert_ne!(a, c);
}

/// The paper's Table II, entered as (predicted, actual) counts.
fn table_ii() -> Confusion {
    let names = ["asphalt", "snow", "stone", "gravel"]
        .map(String::from)
        .to_vec();
    let rows = [[28, 0, 1, 1], [0, 26, 3, 4], [1, 3, 26, 2], [1, 1, 0, 23]];
    let mut m = Confusion::new(names);
    for (p, row) in rows.iter().enumerate() {
        for (a, &n) in row.iter().enumerate() {
            for _ in 0..n {
                m.add(p, a);
            }
        }
    }
    m
}

#[test]
fn confusion_reproduces_paper_table_ii_margins() {
    let m = table_ii();
    // The paper's false-positive column and false-negative row.
    assert_eq!(
        (0..4).map(|c| m.false_positives(c)).collect::<Vec<_>>(),
        [2, 7, 6, 2]
    );
    assert_eq!(
        (0..4).map(|c| m.false_negatives(c)).collect::<Vec<_>>(),
        [2, 4, 4, 7]
    );
    let s = m.metrics();
    assert_eq!(s.n, 120);
    assert!((s.accuracy - 103.0 / 120.0).abs() < 1e-12); // "around 85 %"
    assert!((s.recall[3] - 23.0 / 30.0).abs() < 1e-12);
    assert!((s.precision[1] - 26.0 / 33.0).abs() < 1e-12);
    let f1: f64 = (0..4)
        .map(|c| 2.0 * s.precision[c] * s.recall[c] / (s.precision[c] + s.recall[c]))
        .sum::<f64>()
        / 4.0;
    assert!((s.macro_f1 - f1).abs() < 1e-12);
    let text = m.to_string();
    assert!(
        text.contains("false pos") && text.contains("false neg"),
        "{text}"
    );
    assert!(
        m.to_markdown()
            .contains("| **asphalt** | **28** | 0 | 1 | 1 | 2 |"),
        "{}",
        m.to_markdown()
    );
    let mut twice = m.clone();
    twice.merge(&m);
    assert_eq!(twice.total(), 240);
    assert_eq!(twice.metrics().accuracy, s.accuracy);
}
