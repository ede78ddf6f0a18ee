//! `grip sim --arte acoustic`'s note on the speeds the model was trained
//! at: how much of the audio the acoustic chain heard was slower or faster
//! than the model's training recordings (`grip_arte::speeds`), where its
//! estimates and their calibrated confidence are extrapolation.
//!
//! From the time each ARTE run's [`crate::InLoopProbe`] heard at each
//! speed ([`crate::InLoopStats::heard_speed_s`], bins of
//! [`crate::probe::SPEED_BIN_KMH`], the pre-roll included), over every ARTE
//! run. A bin that straddles an end of the training range counts as
//! inside it, so a run that stays inside gets no note; the speeds named
//! are the bins' lower edges (to 0.1 km/h). A note only: it changes no run.

use grip_arte::model::Model;
use grip_arte::speeds::{NOT_RECORDED, SpeedCheck};

use crate::probe::SPEED_BIN_KMH;
use crate::sim::RunResult;

/// The report's note (one line, without `Note: `) on the speeds the
/// acoustic chain heard against `model`'s training speeds: the share
/// below and above them, or that the model does not record them. None
/// when every ARTE run of `results` stayed inside them (or no run has a
/// record of what it heard: no ARTE variant).
pub fn training_speeds_note(model: &Model, results: &[RunResult]) -> Option<String> {
    let runs: Vec<_> = results.iter().filter_map(|r| r.inloop.as_ref()).collect();
    if runs.is_empty() {
        return None;
    }
    let Some(range) = model.training_speeds().range() else {
        return Some(format!(
            "the ARTE model's {NOT_RECORDED} (a model file from before grip train wrote them): the speeds the acoustic chain heard are not checked against them"
        ));
    };
    let mut c = SpeedCheck::new(range);
    for s in &runs {
        for &(b, t) in &s.heard_speed_s {
            let (lo, hi) = (b as f64 * SPEED_BIN_KMH, (b + 1) as f64 * SPEED_BIN_KMH);
            // a bin wholly below the range counts there at its lower edge
            // (standing still reads 0.0, [3.9, 4.0) reads 3.9), one wholly
            // above at its lower edge too (its centre if that edge is the
            // range's end); one across an end counts inside
            let kmh = if hi <= range.min_kmh || lo > range.max_kmh {
                lo
            } else if lo >= range.max_kmh {
                0.5 * (lo + hi)
            } else {
                (0.5 * (lo + hi)).clamp(range.min_kmh, range.max_kmh)
            };
            c.add(kmh, t);
        }
    }
    let notes = c.notes(
        "the audio the acoustic chain heard",
        &format!(
            "over {} ARTE run{}, pre-roll included",
            runs.len(),
            if runs.len() == 1 { "" } else { "s" }
        ),
    );
    (!notes.is_empty()).then(|| notes.join("; "))
}

/// [`training_speeds_note`] as a line of `grip sim`'s report (`Note: ...`
/// and a newline), or nothing: without a model (`--arte` other than
/// `acoustic`) or with every ARTE run inside its training speeds.
pub fn report_note(model: Option<&Model>, results: &[RunResult]) -> String {
    model
        .and_then(|m| training_speeds_note(m, results))
        .map_or_else(String::new, |n| format!("Note: {n}\n"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::probe::InLoopStats;
    use grip_arte::speeds::SpeedRange;

    fn model(speeds: Option<SpeedRange>) -> Model {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../config/models/paper.model");
        let mut m = Model::from_bytes(&std::fs::read(p).unwrap()).unwrap();
        m.meta.notes.clear();
        m.meta.speeds = speeds;
        m
    }

    fn run(heard: Vec<(usize, f64)>) -> RunResult {
        RunResult {
            variant: crate::Variant::ALL[0],
            seed: 1,
            metrics: Default::default(),
            arte: Default::default(),
            final_state: Default::default(),
            farthest_x: 0.0,
            non_finite_cycles: 0,
            trace: None,
            inloop: Some(InLoopStats {
                heard_speed_s: heard,
                ..Default::default()
            }),
        }
    }

    #[test]
    fn speeds_outside_the_training_range_are_noted() {
        let m = model(SpeedRange::new(4.0, 30.0));
        // one run: 1 s at 3.5 km/h, 6 s at 20, 3 s at 40-45; another 10 s
        // at 20
        let a = run(vec![(35, 1.0), (200, 6.0), (400, 2.0), (450, 1.0)]);
        let b = run(vec![(200, 10.0)]);
        let n = training_speeds_note(&m, &[a, b.clone()]).unwrap();
        assert_eq!(
            n,
            "5 % of the audio the acoustic chain heard (1.0 of 20.0 s, over 2 ARTE runs, pre-roll included) at 3.5 km/h, below the model's training speeds (4.0-30.0 km/h): its estimates there are extrapolation; \
             15 % of the audio the acoustic chain heard (3.0 of 20.0 s, over 2 ARTE runs, pre-roll included) at 40.0-45.0 km/h, above the model's training speeds (4.0-30.0 km/h): its estimates there are extrapolation"
        );
        // inside, to the range's ends (bin 299 holds 30.0 km/h: 30 / 0.1
        // is just below 300 in floating point): no note
        let edge = run(vec![(40, 1.0), (200, 1.0), (299, 1.0)]);
        assert_eq!(training_speeds_note(&m, &[b.clone(), edge]), None);
        // no ARTE run: nothing to say
        let mut no_arte = b.clone();
        no_arte.inloop = None;
        assert_eq!(training_speeds_note(&m, &[no_arte]), None);
        // a model without its training speeds says so
        let n = training_speeds_note(&model(None), std::slice::from_ref(&b)).unwrap();
        assert!(n.contains("training speeds not recorded"), "{n}");
        // the report's line: only with a model, only when there is a note
        assert_eq!(report_note(None, std::slice::from_ref(&b)), "");
        assert_eq!(report_note(Some(&m), std::slice::from_ref(&b)), "");
        let r = report_note(Some(&m), &[run(vec![(450, 1.0)])]);
        assert!(
            r.starts_with("Note: 100 % of the audio") && r.ends_with("extrapolation\n"),
            "{r}"
        );
    }
}
