//! `grip inspect --json`: one JSON object per drive log, everything a fleet
//! table needs, computed by the same summary `grip inspect` prints
//! ([`grip_drive::summary::summarize`]): run metadata, the scenario window
//! and how much of the scenario it covers, metrics, what the loop measured
//! (`measured`: from the cycle records, for every log), ARTE accuracy (per
//! road, per speed band, the confusion counts; during the scenario, and
//! over the whole log as `_whole_log`), road-change detection delays,
//! deadline misses, wake-up latency and safe-state entries (over the whole
//! log, and during the scenario as `_in_scenario`), E2E faults, the
//! inverter's command timeouts and its episodes (`inverter`: fault,
//! derating, command timeout, not ready; FaultCodes). Counts are given as
//! counts (judged, correct) so that a fleet can add them up without
//! re-implementing any of this; NaN and missing figures are `null`.

use std::path::Path;

use grip_drive::{DriveLog, summary};
use grip_msgs::E2eFaults;
use serde_json::{Value, json};

/// A finite number, else `null`.
fn num(x: f64) -> Value {
    if x.is_finite() { json!(x) } else { Value::Null }
}

fn faults(f: &E2eFaults) -> Value {
    json!({
        "crc": f.crc,
        "counter_repeated": f.counter_repeated,
        "counter_skipped": f.counter_skipped,
        "length": f.length,
        "unknown_id": f.unknown_id,
        "timeout": f.timeout,
        "total": f.total(),
    })
}

/// `inverter`: the inverter's episodes and FaultCodes from its
/// `MotorStatus` frames ([`summary::inverter()`]); times on its `origin`.
fn inverter_json(inv: &summary::Inverter) -> Value {
    let episode = |e: &summary::inverter::Episode| {
        json!({
            "start_s": num(e.start_s),
            "end_s": e.end_s.map(num),
            "duration_s": num(e.duration_s),
            "frames": e.frames,
            "at_first_frame": e.at_first_frame,
            "place": e.place.map(|p| p.as_str()),
            "fault_codes": e.codes,
            "safe_cycles": e.safe.map(|s| s.safe),
            "cycles": e.safe.map(|s| s.cycles),
            "safe_before": e.safe.map(|s| s.safe_before),
        })
    };
    let mut o = serde_json::Map::new();
    o.insert("motor_status_frames".into(), json!(inv.frames));
    o.insert("rejected_frames".into(), json!(inv.rejected));
    o.insert(
        "origin".into(),
        json!(if inv.from_scenario_start {
            "scenario_start"
        } else {
            "first_message"
        }),
    );
    o.insert(
        "span_s".into(),
        json!(inv.span_s.map(|(a, b)| [num(a), num(b)])),
    );
    o.insert("frames_in_scenario".into(), json!(inv.frames_in_scenario));
    o.insert("clean".into(), json!(inv.clean()));
    for f in &inv.flags {
        o.insert(
            f.flag.as_str().into(),
            json!({
                "episodes": f.count,
                "entered": f.entered,
                "time_s": num(f.time_s),
                "episodes_in_scenario": f.in_scenario.map(|(n, _)| n),
                "time_in_scenario_s": f.in_scenario.map(|(_, t)| num(t)),
                "before_scenario": f.in_scenario.map(|_| f.places[0]),
                "after_scenario": f.in_scenario.map(|_| f.places[2]),
                "safe_throughout": (f.flag == summary::inverter::Flag::Fault).then_some(f.safe_throughout),
                // the loop's cycle records in the fault episodes and, of
                // them, those in its safe state (every episode, listed or not)
                "loop_cycles": (f.flag == summary::inverter::Flag::Fault).then_some(f.loop_cycles.0),
                "loop_cycles_safe": (f.flag == summary::inverter::Flag::Fault).then_some(f.loop_cycles.1),
                "loop_cycles_in_scenario": (f.flag == summary::inverter::Flag::Fault)
                    .then_some(f.loop_cycles_in_scenario.map(|c| c.0))
                    .flatten(),
                "loop_cycles_safe_in_scenario": (f.flag == summary::inverter::Flag::Fault)
                    .then_some(f.loop_cycles_in_scenario.map(|c| c.1))
                    .flatten(),
                "listed": f.listed.iter().map(episode).collect::<Vec<_>>(),
            }),
        );
    }
    o.insert(
        "fault_codes".into(),
        inv.codes
            .iter()
            .map(|c| json!({"code": c.code, "first_s": num(c.first_s), "frames": c.frames}))
            .collect::<Vec<_>>()
            .into(),
    );
    Value::Object(o)
}

/// The status and reason of a loaded log (as `grip inspect DIR` gives them).
fn status(log: &DriveLog) -> (&'static str, Option<String>) {
    if let Some(t) = &log.report.truncated {
        ("incomplete", Some(t.clone()))
    } else if log.report.bad > 0 {
        (
            "damaged",
            Some(format!(
                "{} messages did not decode (first: {})",
                log.report.bad,
                log.report.first_error.as_deref().unwrap_or("?")
            )),
        )
    } else {
        ("ok", None)
    }
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// The JSON object of the log at `path` (an unreadable file gives an object
/// with `status = "unreadable"` and the reason).
pub fn log_json(path: &Path, config_dir: &Path) -> Value {
    let log = match DriveLog::load(path) {
        Ok(l) => l,
        Err(e) => {
            return json!({
                "file": file_name(path),
                "path": path.display().to_string(),
                "status": "unreadable",
                "reason": e.full(),
            });
        }
    };
    let (vehicle, from, warnings) = grip_drive::vehicle_for(&log, config_dir);
    let roads = log.road_catalogue(config_dir);
    let s = summary::summarize_with_roads(&log, &vehicle, &from, &roads);
    summary_json(path, &log, &s, &warnings)
}

/// `measured`: what the loop measured (its cycle records; not ground
/// truth), [`summary::measured()`].
fn measured_json(m: &summary::Measured) -> Value {
    use summary::measured as ms;
    let spins: Vec<Value> = m
        .spins
        .iter()
        .map(|e| {
            // cut: still spinning at the window's end (it lasted at least
            // length_s)
            json!({"start_s": num(e.start_s), "length_s": num(e.length_s),
                   "peak": num(e.peak), "peak_s": num(e.peak_s), "cut": e.cut})
        })
        .collect();
    let per_belief: Vec<Value> = m
        .per_belief
        .iter()
        .map(|b| {
            json!({"road": b.road, "index": b.index, "time_s": num(b.time_s),
                   "slip_s": num(b.slip_s), "mean_abs_slip": num(b.mean_abs_slip),
                   "max_slip": num(b.max_slip), "mean_cmd_nm": num(b.mean_cmd)})
        })
        .collect();
    json!({
        "window": m.window.as_str(),
        "origin": if m.window == ms::MeasuredWindow::Scenario { "scenario_start" } else { "first_message" },
        "span_s": m.span_s.map(|(a, b)| [num(a), num(b)]),
        "stretches": m.stretches,
        "demand_min_nm": ms::DEMAND_MIN_NM,
        "cycles": m.cycles,
        "time_s": num(m.time_s),
        "no_valid_v_cycles": m.no_valid_v,
        "below_min_speed_cycles": m.slow,
        "safe_state_cycles": m.safe,
        "min_speed_mps": ms::MIN_SPEED_MPS,
        "slip_cycles": m.slip_cycles,
        "slip_s": num(m.slip_s),
        "r_m": num(m.r),
        "v_eps_mps": num(m.v_eps),
        "mean_abs_slip": num(m.mean_abs_slip),
        "p95_abs_slip": num(m.p95_abs_slip),
        "max_abs_slip": num(m.max_abs_slip),
        "max_abs_slip_s": num(m.max_abs_slip_s),
        "share_above_0_1": num(m.share_above[0]),
        "share_above_0_2": num(m.share_above[1]),
        "spin_lambda": ms::SPIN_LAMBDA,
        "spin_min_s": ms::SPIN_MIN_S,
        "spin_bridge_s": ms::SPIN_BRIDGE_S,
        "spin_events": m.spins.len(),
        "spins": spins,
        "mean_accel_ms2": num(m.mean_accel),
        "dv_mps": num(m.dv),
        "accel_s": num(m.accel_s),
        "mean_cmd_nm": num(m.mean_cmd),
        "mean_demand_nm": num(m.mean_demand),
        "cmd_over_demand": num(m.delivered),
        "withheld_nms": num(m.withheld_nms),
        "mean_torque_nm": num(m.mean_torque),
        "cmd_tv_per_s": num(m.cmd_tv_per_s),
        "cmd_hf_rms_nm": num(m.cmd_hf_rms),
        "cmd_hf_share": num(m.cmd_hf_share),
        // where the command figures start (the first cycle with the
        // driver's demand), s on the window's origin
        "cmd_from_s": m.cmd_from_s.map(num),
        "mean_withheld_nm": num(m.mean_withheld),
        "per_belief": per_belief,
    })
}

/// A `preview` entry: the driven wheel reaching a road that carries less
/// ([`summary::PreviewEvent`]; times s from the scenario start, N m, m).
/// `training_speeds`: the drive's speeds against the speeds arte's model
/// was trained at ([`summary::speeds::DriveSpeeds`]); `null` when the log
/// names no model. `known` false: the model's speeds are unknown (why in
/// `unknown_because`); `below`/`above` `null`: none of the drive there.
fn training_speeds_json(d: &summary::speeds::DriveSpeeds) -> Value {
    use grip_arte::speeds::TrainingSpeeds;
    use summary::speeds::ModelSpeeds;
    let (range, from, unknown) = match &d.model {
        ModelSpeeds::NotAttached(n) => {
            (None, None, Some(format!("{n} is not attached to the log")))
        }
        ModelSpeeds::Unreadable(n, why) => (None, None, Some(format!("{n} does not load: {why}"))),
        ModelSpeeds::Model(TrainingSpeeds::Recorded(r)) => (Some(*r), Some("model"), None),
        ModelSpeeds::Model(TrainingSpeeds::FromNote(r)) => (Some(*r), Some("note"), None),
        ModelSpeeds::Model(TrainingSpeeds::NotRecorded) => {
            (None, None, Some(grip_arte::speeds::NOT_RECORDED.to_owned()))
        }
    };
    let outside = |o: Option<grip_arte::speeds::Outside>| {
        o.map_or(Value::Null, |o| {
            json!({"time_s": num(o.time_s), "min_kmh": num(o.min_kmh), "max_kmh": num(o.max_kmh)})
        })
    };
    json!({
        "known": range.is_some(),
        "unknown_because": unknown,
        "min_kmh": range.map(|r| num(r.min_kmh)),
        "max_kmh": range.map(|r| num(r.max_kmh)),
        "range_from": from,
        "window": d.what.0,
        "speed": d.what.1,
        "checked_s": d.check.map(|c| num(c.total_s)),
        "below": d.check.map_or(Value::Null, |c| outside(c.below)),
        "above": d.check.map_or(Value::Null, |c| outside(c.above)),
        "notes": d.lines(),
    })
}

fn preview_json(e: &summary::PreviewEvent) -> Value {
    json!({
        "t_s": num(e.t),
        "x_m": num(e.x),
        "from": e.from,
        "to": e.to,
        "limit_nm": num(e.limit),
        // how long and how far before arrival the command was at or
        // below the limit; null: it was not at arrival
        "ahead_s": e.ahead.map(|a| num(a.0)),
        "ahead_m": e.ahead.map(|a| num(a.1)),
        "ahead_since_start": e.ahead_since_start,
        "cmd_at_arrival_nm": num(e.cmd_at_arrival),
        "torque_at_arrival_nm": num(e.torque_at_arrival),
        "max_slip_after": num(e.max_slip_after),
    })
}

/// A `releases` entry: the driven wheel reaching a road that carries more
/// ([`summary::ReleaseEvent`]).
fn release_json(e: &summary::ReleaseEvent) -> Value {
    use summary::Release;
    let (after, s, m) = match e.after {
        Release::NotNeeded => ("not_needed", None, None),
        Release::AlreadyAbove => ("already_above", None, None),
        Release::After(s, m) => ("after", Some(s), Some(m)),
        Release::Held(s) => ("held", Some(s), None),
    };
    json!({
        "t_s": num(e.t),
        "x_m": num(e.x),
        "from": e.from,
        "to": e.to,
        "old_limit_nm": num(e.old_limit),
        "demand_at_arrival_nm": num(e.demand_at_arrival),
        "cmd_at_arrival_nm": num(e.cmd_at_arrival),
        // not_needed | already_above | after (release_s, release_m after
        // arrival) | held (release_s: held this long, to the next change
        // or the window's end)
        "release": after,
        "release_s": s.map(num),
        "release_m": m.map(num),
        "withheld_nms_0_2s": num(e.withheld_nms),
    })
}

/// The summary's run entry `k` (`grip.run`'s, or a replay's own).
fn run_value(s: &summary::Summary, k: &str) -> Option<String> {
    s.run.iter().find(|(kk, _)| kk == k).map(|(_, v)| v.clone())
}

/// The JSON object of a loaded log and its summary.
pub fn summary_json(
    path: &Path,
    log: &DriveLog,
    s: &summary::Summary,
    vehicle_warnings: &[String],
) -> Value {
    let (st, reason) = status(log);
    let get = |k: &str| log.run.get(k).cloned();
    let a = &s.arte;
    let per_road: serde_json::Map<String, Value> = a
        .per_road
        .iter()
        .map(|(road, (n, c))| {
            (
                road.clone(),
                json!({"judged": n, "correct": c,
                       "accuracy": num(*c as f64 / (*n).max(1) as f64),
                       // a road without a sound of its own (its alias, or
                       // noise only); null otherwise
                       "sound_note": s.audio.as_ref().and_then(|au| au.road_note(road))}),
            )
        })
        .collect();
    let confusion: Vec<Value> = a
        .confusion
        .iter()
        .map(|((t, e), n)| json!({"truth": t, "estimate": e, "count": n}))
        .collect();
    let bands: Vec<Value> = a
        .per_speed_band
        .iter()
        .map(|(b, (n, c))| {
            json!({
                "band_kmh_lo": f64::from(*b) * summary::SPEED_BAND_KMH,
                "band_kmh_hi": f64::from(*b + 1) * summary::SPEED_BAND_KMH,
                "judged": n,
                "correct": c,
            })
        })
        .collect();
    let changes: Vec<Value> = a
        .changes
        .iter()
        .map(|c| {
            json!({"t_s": num(c.t), "from": c.from, "to": c.to,
                        "delay_s": c.delay.map_or(Value::Null, num),
                        // the first estimate of the new road the loop's
                        // confidence gate passes (`arte_min_confidence`)
                        "gated_delay_s": c.gated_delay.map_or(Value::Null, num)})
        })
        .collect();
    let delays: Vec<f64> = a.changes.iter().filter_map(|c| c.delay).collect();
    let mean_delay = if delays.is_empty() {
        Value::Null
    } else {
        num(delays.iter().sum::<f64>() / delays.len() as f64)
    };
    let max_delay = if delays.is_empty() {
        Value::Null
    } else {
        num(delays.iter().copied().fold(0.0, f64::max))
    };
    let metrics = s.metrics.as_ref().map_or(Value::Null, |m| {
        json!({
            "slip_deviation": num(m.slip_deviation),
            "max_torque_nm": num(m.max_torque),
            "torque_effort_nm": num(m.torque_effort),
            "mean_accel_ms2": num(m.mean_accel),
            "distance_m": num(m.distance),
            "energy_j": num(m.energy),
            "kinetic_energy_gain_j": num(m.kinetic_energy_gain),
            "duration_s": num(m.duration),
            "cmd_tv_per_s": num(m.cmd_tv_per_s),
        })
    });
    // where the ground-truth block's command figures start, s from the
    // scenario start
    let cmd_from_s = s.cmd_from_s.map(num);
    let mut warnings: Vec<String> = vehicle_warnings.to_vec();
    warnings.extend(s.warnings.iter().cloned());
    let in_scn = s.timing.in_scenario.as_ref();
    json!({
        "file": file_name(path),
        "path": path.display().to_string(),
        "status": st,
        "reason": reason,
        "run": log.run,
        "simulated": get("source").as_deref() == Some("generated"),
        "scenario": get("scenario"),
        // a replay's own (`grip.run` is its source's)
        "controller": run_value(s, "controller"),
        "arte": run_value(s, "arte"),
        "seed": get("seed"),
        "revision": get("git_revision"),
        "version": get("version"),
        "vehicle": s.vehicle,
        "vehicle_sha256": s.vehicle_sha256,
        // the microphone's lead ahead of the driven wheel, m, of the vehicle
        // the summary used (the preview's; `grip inspect DIR`'s `mic_lead_m`)
        "mic_lead_m": num(s.vehicle_params.mic_lead_m),
        "scenario_sha256": s.scenario_sha256,
        "roads_from": s.roads_from,
        "model": s.model.as_ref().map(|m| m.name.clone()),
        "model_sha256": s.model.as_ref().and_then(|m| m.sha256.clone()),
        "model_from": s.model.as_ref().map(|m| m.from.clone()),
        // audio-acq's [audio] source (`synth`: the plant's roads; `wav`:
        // a file, graded against the plant's roads all the same)
        "audio_source": s.audio.as_ref().map(|a| a.source.clone()),
        "audio_wav": s.audio.as_ref().and_then(|a| a.wav.clone()),
        "replay": s.replay.as_ref().map_or(Value::Null, |r| json!({
            "source": r.source,
            "mode": r.mode,
            "configuration": r.configuration,
            "changes": r.changes,
            // what its tcs-loop ran with (null: a replay log from before
            // they were recorded)
            "min_confidence": r.min_confidence.map(num),
            "vehicle": r.vehicle,
            "vehicle_set": r.vehicle_set,
            "vehicle_sha256": r.vehicle_sha256,
        })),
        "cycles": s.timing.cycles,
        "scenario_window": s.window_status.as_str(),
        "scenario_duration_s": s.scenario_duration_s.map_or(Value::Null, num),
        "scenario_s": s.window.map_or(Value::Null, |(a, b)| num(b - a)),
        "speed_kmh_start": s.speed_kmh.map_or(Value::Null, |v| num(v.0)),
        "speed_kmh_end": s.speed_kmh.map_or(Value::Null, |v| num(v.1)),
        "metrics": metrics,
        // the largest true |λ| in the scenario window and when, s from the
        // scenario start
        "max_slip": s.max_slip.map(|m| num(m.0)),
        "max_slip_s": s.max_slip.map(|m| num(m.1)),
        // torques and energies are one driven wheel's; the car's are
        // n_driven times them
        "n_driven": num(s.vehicle_params.n_driven),
        "preview": s.preview.as_ref().map(|p| p.iter().map(preview_json).collect::<Vec<_>>()),
        "releases": s.releases.as_ref().map(|r| r.iter().map(release_json).collect::<Vec<_>>()),
        "cmd_from_s": cmd_from_s,
        "measured": measured_json(&s.measured),
        "arte_estimates": a.estimates,
        "arte_judged": a.judged,
        "arte_correct": a.correct,
        "arte_accuracy": num(a.accuracy()),
        "arte_judged_whole_log": a.log_judged,
        "arte_correct_whole_log": a.log_correct,
        "arte_accuracy_whole_log": num(a.accuracy_whole_log()),
        "arte_used_cycles": a.used_cycles,
        "arte_active_cycles": a.active_cycles,
        // of those, cycles whose command road knowledge's torque cap held
        // below the driver's demand (gate passed or not)
        "arte_capped_cycles": a.capped_cycles,
        // the window of those two: the scenario's, else (a log without
        // ground truth) the measured section's demand window
        "arte_used_window": if a.used_in_demand_window { "demand" } else { "scenario" },
        "arte_per_road": per_road,
        "confusion": confusion,
        "speed_band_kmh": summary::SPEED_BAND_KMH,
        "speed_bands": bands,
        "road_changes": changes,
        "arte_min_confidence": num(a.min_confidence.0),
        // whether the log gave it (its controllers.toml, or a replay's
        // record; else the default)
        "arte_min_confidence_from_log": a.min_confidence.1,
        // where from: log (its controllers.toml), replay (the gate the
        // replay's tcs-loop ran), replay_changed (the source's, which an
        // older replay log's changes touched), default, unknown (a
        // controllers.toml whose [arte] does not read)
        "arte_min_confidence_from": a.gate_from.as_str(),
        "training_speeds": s.training_speeds.as_ref().map_or(Value::Null, training_speeds_json),
        "changes_detected": delays.len(),
        "changes_missed": a.changes.len() - delays.len(),
        "mean_delay_s": mean_delay,
        "max_delay_s": max_delay,
        "deadline_misses": s.timing.deadline_misses,
        "deadline_misses_in_scenario": in_scn.map(|w| w.deadline_misses),
        "wakeup_p99_ns": s.timing.wakeup.p99,
        "wakeup_max_ns": s.timing.wakeup.max,
        "wakeup_p99_ns_in_scenario": in_scn.map(|w| w.wakeup.p99),
        "wakeup_max_ns_in_scenario": in_scn.map(|w| w.wakeup.max),
        "safe_cycles": s.timing.safe_cycles,
        "safe_cycles_in_scenario": s.safe_cycles_in_window,
        "safe_state_entries": s.timing.safe_entries,
        "safe_state_entries_in_scenario": in_scn.map(|w| w.safe_entries),
        "control_lost": s.control.as_ref().map(|c| c.lost()),
        "control_out_at_end_since_s": s.control.as_ref().and_then(|c| c.end_out).map(|e| e.0),
        "control_out_at_end_s": s.control.as_ref().and_then(|c| c.end_out).map(|e| e.1),
        "control": s.control.as_ref().map(|c| c.line()),
        "e2e_faults": faults(&s.can.faults),
        "e2e_faults_in_scenario": s.can.faults_in_window.as_ref().map_or(Value::Null, faults),
        "e2e_rejected_frames": s.can.rejected,
        // the inverter's CmdTimeout going from clear to set (not the state
        // it came up in), in its frames the E2E check accepted
        "command_timeouts": s
            .inverter
            .flag(summary::inverter::Flag::CmdTimeout)
            .map_or(0, |f| f.entered),
        "inverter": inverter_json(&s.inverter),
        "bad_messages": log.report.bad,
        "warnings": warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::export::test_log;

    fn config_dir() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
    }

    /// The JSON object of `log` as `grip inspect --json` makes it.
    fn json_of(log: &DriveLog) -> Value {
        let (vehicle, from, warnings) = grip_drive::vehicle_for(log, &config_dir());
        let roads = log.road_catalogue(&config_dir());
        let s = summary::summarize_with_roads(log, &vehicle, &from, &roads);
        summary_json(&log.path, log, &s, &warnings)
    }

    /// [`test_log::drive`] as `grip drive --vehicle .../front-mic.toml`
    /// records it: the file attached as `drive/vehicle.toml`.
    fn front_mic_drive() -> DriveLog {
        let mut log = test_log::drive();
        log.attachments.insert(
            grip_drive::plan::VEHICLE_ATTACHMENT.into(),
            std::fs::read(config_dir().join("vehicles/front-mic.toml")).unwrap(),
        );
        log
    }

    /// `mic_lead_m`: the microphone's lead of the vehicle the summary used
    /// (the log's attached vehicle file), beside `vehicle` and
    /// `vehicle_sha256`; `grip inspect DIR`'s CSV had it, `--json` not.
    #[test]
    fn the_microphones_lead_is_beside_the_vehicle() {
        let j = json_of(&front_mic_drive());
        assert_eq!(j["mic_lead_m"], 2.77, "{}", j["vehicle"]);
        assert!(
            j["vehicle"]
                .as_str()
                .unwrap()
                .contains("attached to the log as drive/vehicle.toml"),
            "{}",
            j["vehicle"]
        );
        // a log that carries no vehicle: the configuration directory's
        // vehicle.toml, the microphone at the driven wheel
        let mut bare = test_log::drive();
        bare.run.remove("vehicle");
        assert_eq!(json_of(&bare)["mic_lead_m"], 0.0);
    }

    /// `training_speeds`: the model's training speeds and the drive's time
    /// outside them, as the report's ARTE section notes them; why not,
    /// when the log does not carry the model.
    #[test]
    fn the_training_speeds_are_in_the_object() {
        let mut log = front_mic_drive();
        log.attachments.insert(
            "arte-svc.toml".into(),
            b"model = \"models/m.model\"\n".to_vec(),
        );
        let j = json_of(&log);
        let t = &j["training_speeds"];
        assert_eq!(t["known"], false, "{t}");
        assert!(
            t["unknown_because"]
                .as_str()
                .unwrap()
                .contains("models/m.model is not attached"),
            "{t}"
        );
        assert_eq!(t["notes"].as_array().unwrap().len(), 1, "{t}");
        assert!(t["below"].is_null() && t["above"].is_null(), "{t}");
        // the paper model (its training speeds, 4.0-29.8 km/h, in its notes)
        log.attachments.insert(
            "models/m.model".into(),
            std::fs::read(config_dir().join("models/paper.model")).unwrap(),
        );
        let j = json_of(&log);
        let t = &j["training_speeds"];
        assert_eq!(t["known"], true, "{t}");
        assert!(t["unknown_because"].is_null(), "{t}");
        assert_eq!(t["range_from"], "note", "{t}");
        assert_eq!(
            (t["min_kmh"].as_f64(), t["max_kmh"].as_f64()),
            (Some(4.0), Some(29.8))
        );
        let checked = t["checked_s"].as_f64().unwrap();
        assert!(checked > 0.0, "{t}");
        // the summary's own figures, field by field
        let (vehicle, from, _) = grip_drive::vehicle_for(&log, &config_dir());
        let roads = log.road_catalogue(&config_dir());
        let s = summary::summarize_with_roads(&log, &vehicle, &from, &roads);
        let sp = s.training_speeds.unwrap();
        let c = sp.check.unwrap();
        assert_eq!(checked, c.total_s);
        for (k, o) in [("below", c.below), ("above", c.above)] {
            match o {
                None => assert!(t[k].is_null(), "{t}"),
                Some(o) => assert_eq!(t[k]["time_s"].as_f64(), Some(o.time_s), "{t}"),
            }
        }
        let notes: Vec<String> = serde_json::from_value(t["notes"].clone()).unwrap();
        assert_eq!(notes, sp.lines());
        assert_eq!(t["window"], sp.what.0.as_str());
        // a log that names no model: null
        log.attachments.remove("arte-svc.toml");
        log.attachments.remove("models/m.model");
        let j = json_of(&log);
        assert!(j["training_speeds"].is_null(), "{}", j["training_speeds"]);
    }

    /// Every field of the object (and of `measured`, its spins and
    /// `replay`) is named in `tools/grip/README.md`'s list of them, "grip
    /// inspect --json".
    #[test]
    fn the_readme_names_every_field() {
        let readme =
            std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md"))
                .unwrap();
        let start = readme
            .find("## `grip inspect --json`, `grip replay --json`")
            .expect("the README's --json section");
        let end = start
            + readme[start..]
                .find("`grip replay --json LOG|DIR")
                .expect("its replay paragraph");
        let list = &readme[start..end];
        let mut log = front_mic_drive();
        log.metadata.insert(
            "grip.replay".into(),
            [("source", "a.mcap"), ("mode", "open loop")]
                .into_iter()
                .map(|(k, v)| (k.into(), v.into()))
                .collect(),
        );
        let j = json_of(&log);
        let keys = |v: &Value| -> Vec<String> {
            v.as_object()
                .unwrap_or_else(|| panic!("{v}"))
                .keys()
                .cloned()
                .collect()
        };
        let mut all = keys(&j);
        all.extend(keys(&j["measured"]));
        all.extend(keys(&j["replay"]));
        // the training speeds' fields, of one made up (the drive names no
        // model)
        all.extend(keys(&training_speeds_json(&summary::speeds::DriveSpeeds {
            model: summary::speeds::ModelSpeeds::NotAttached("m.model".into()),
            what: ("the scenario window".into(), "ground-truth speed".into()),
            check: None,
        })));
        // a spin's fields, of one made up if the drive has none
        let mut m = summary::Measured::default();
        m.spins.push(summary::measured::SpinEvent::default());
        let spin = &measured_json(&m)["spins"][0];
        all.extend(keys(spin));
        let missing: Vec<String> = all
            .into_iter()
            .filter(|k| !list.contains(&format!("`{k}`")))
            .collect();
        assert!(
            missing.is_empty(),
            "tools/grip/README.md, \"grip inspect --json\": not in its list of fields: {missing:?}"
        );
    }
}
