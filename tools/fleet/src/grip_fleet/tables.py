"""Tables from grip's JSON objects. Nothing here recomputes a figure of a
drive: per-drive columns are copied from ``grip inspect --json`` /
``grip replay --json``, and fleet tables add up the counts those carry."""

from __future__ import annotations

import json
import math
from typing import Any

import pandas as pd

METRICS = [
    "slip_deviation",
    "max_torque_nm",
    "torque_effort_nm",
    "mean_accel_ms2",
    "distance_m",
    "energy_j",
]


#: What the loop measured (``grip inspect --json``'s ``measured``: from the
#: cycle records, never ground truth; the only slip and traction figures a
#: log from the car has), as ``measured_<key>`` columns.
MEASURED = [
    "mean_abs_slip",
    "p95_abs_slip",
    "max_abs_slip",
    "share_above_0_1",
    "share_above_0_2",
    "mean_accel_ms2",
    "mean_cmd_nm",
    "mean_demand_nm",
    "cmd_over_demand",
    "withheld_nms",
    "cmd_tv_per_s",
]


def _f(x: Any) -> float:
    return float("nan") if x is None else float(x)


def drive_rows(objs: list[dict[str, Any]]) -> pd.DataFrame:
    """One row per log (bad ones too, with their status and reason). The
    loop's figures come twice: during the scenario (``_in_scenario``, what
    to ask "which drives missed deadlines or entered the safe state") and
    over the whole log (``_whole_log``: start-up and the stop included; a
    ``grip drive`` log's stop enters the safe state once, when plant-sim has
    ended). ARTE's are the scenario's, its whole-log accuracy labelled
    ``_whole_log``. ``measured_*`` and ``spin_events`` are what the loop
    measured (over ``measured_window``: the scenario window, else the time
    the driver demanded torque); ``control_lost`` is grip's control
    statement (``None`` without a scenario window); ``inverter_*`` count the
    inverter's fault and derating episodes (``inverter``'s
    ``episodes_in_scenario`` and ``episodes``; ``None`` without
    ``MotorStatus`` frames), as ``grip inspect DIR``'s CSV does."""
    roads = sorted({r for o in objs for r in (o.get("arte_per_road") or {})})
    rows = []
    for o in objs:
        m = o.get("metrics") or {}
        meas = o.get("measured") or {}
        e2e = o.get("e2e_faults") or {}
        e2e_in = o.get("e2e_faults_in_scenario") or {}
        inv = o.get("inverter") or {}
        row: dict[str, Any] = {
            "file": o.get("file"),
            "path": o.get("path"),
            "status": o.get("status"),
            "reason": o.get("reason"),
            "simulated": bool(o.get("simulated", False)),
            "scenario": o.get("scenario"),
            "controller": o.get("controller"),
            "arte": o.get("arte"),
            "seed": o.get("seed"),
            "revision": o.get("revision"),
            "version": o.get("version"),
            "cycles": o.get("cycles"),
            "scenario_window": o.get("scenario_window"),
            "scenario_duration_s": _f(o.get("scenario_duration_s")),
            "scenario_s": _f(o.get("scenario_s")),
            "speed_kmh_start": _f(o.get("speed_kmh_start")),
            "speed_kmh_end": _f(o.get("speed_kmh_end")),
        }
        for k in METRICS:
            row[k] = _f(m.get(k))
        row["measured_window"] = meas.get("window")
        row["measured_time_s"] = _f(meas.get("time_s"))
        for k in MEASURED:
            row[f"measured_{k}"] = _f(meas.get(k))
        row["spin_events"] = meas.get("spin_events")
        row["control_lost"] = o.get("control_lost")
        row["control_out_at_end_s"] = _f(o.get("control_out_at_end_s"))
        row.update(
            {
                "arte_estimates": o.get("arte_estimates"),
                "arte_judged": o.get("arte_judged"),
                "arte_correct": o.get("arte_correct"),
                "arte_accuracy": _f(o.get("arte_accuracy")),
                "arte_judged_whole_log": o.get("arte_judged_whole_log"),
                "arte_correct_whole_log": o.get("arte_correct_whole_log"),
                "arte_accuracy_whole_log": _f(o.get("arte_accuracy_whole_log")),
                "changes_detected": o.get("changes_detected"),
                "changes_missed": o.get("changes_missed"),
                "mean_delay_s": _f(o.get("mean_delay_s")),
                "max_delay_s": _f(o.get("max_delay_s")),
                "deadline_misses_in_scenario": o.get("deadline_misses_in_scenario"),
                "wakeup_p99_ns_in_scenario": o.get("wakeup_p99_ns_in_scenario"),
                "wakeup_max_ns_in_scenario": o.get("wakeup_max_ns_in_scenario"),
                "safe_state_entries_in_scenario": o.get("safe_state_entries_in_scenario"),
                "safe_cycles_in_scenario": o.get("safe_cycles_in_scenario"),
                "deadline_misses_whole_log": o.get("deadline_misses"),
                "wakeup_max_ns_whole_log": o.get("wakeup_max_ns"),
                "safe_state_entries_whole_log": o.get("safe_state_entries"),
                "e2e_faults": e2e.get("total"),
                "e2e_faults_in_scenario": e2e_in.get("total"),
                "command_timeouts": o.get("command_timeouts"),
                "inverter_faults_in_scenario": (inv.get("fault") or {}).get("episodes_in_scenario"),
                "inverter_faults_whole_log": (inv.get("fault") or {}).get("episodes"),
                "inverter_derating_in_scenario": (inv.get("derating") or {}).get("episodes_in_scenario"),
                "inverter_derating_whole_log": (inv.get("derating") or {}).get("episodes"),
                "road_changes": json.dumps(o.get("road_changes")) if "road_changes" in o else None,
            }
        )
        per_road = o.get("arte_per_road") or {}
        for r in roads:
            pr = per_road.get(r) or {}
            row[f"arte_judged_{r}"] = pr.get("judged", 0) if o.get("status") in ("ok", "incomplete", "damaged") else None
            row[f"arte_correct_{r}"] = pr.get("correct", 0) if o.get("status") in ("ok", "incomplete", "damaged") else None
        rows.append(row)
    df = pd.DataFrame(rows)
    for c in df.columns:
        if c.startswith(("arte_judged", "arte_correct", "cycles", "deadline", "wakeup_", "safe_", "e2e", "command_", "changes_", "arte_estimates", "spin_events", "inverter_")):
            df[c] = df[c].astype("Int64")
    if "control_lost" in df:
        df["control_lost"] = df["control_lost"].astype("boolean")
    return df


def good(objs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The complete, undamaged logs: the ones fleet aggregates count."""
    return [o for o in objs if o.get("status") == "ok"]


def confusion(objs: list[dict[str, Any]]) -> pd.DataFrame:
    """Per (true road, estimated road): estimates over the good logs, and the
    share of that true road's judged estimates."""
    counts: dict[tuple[str, str], int] = {}
    for o in good(objs):
        for c in o.get("confusion") or []:
            k = (c["truth"], c["estimate"])
            counts[k] = counts.get(k, 0) + int(c["count"])
    df = pd.DataFrame(
        [{"truth": t, "estimate": e, "count": n} for (t, e), n in sorted(counts.items())],
        columns=["truth", "estimate", "count"],
    )
    if not df.empty:
        df["share_of_truth"] = df["count"] / df.groupby("truth")["count"].transform("sum")
    return df


def speed_bands(objs: list[dict[str, Any]]) -> pd.DataFrame:
    """ARTE accuracy per speed band (of the truth at each judged frame),
    pooled over the good logs."""
    acc: dict[tuple[float, float], list[int]] = {}
    for o in good(objs):
        for b in o.get("speed_bands") or []:
            k = (float(b["band_kmh_lo"]), float(b["band_kmh_hi"]))
            a = acc.setdefault(k, [0, 0])
            a[0] += int(b["judged"])
            a[1] += int(b["correct"])
    df = pd.DataFrame(
        [{"band_kmh_lo": lo, "band_kmh_hi": hi, "judged": n, "correct": c} for (lo, hi), (n, c) in sorted(acc.items())],
        columns=["band_kmh_lo", "band_kmh_hi", "judged", "correct"],
    )
    if not df.empty:
        df["accuracy"] = df["correct"] / df["judged"]
    return df


def accuracy_summary(objs: list[dict[str, Any]]) -> dict[str, float]:
    """Fleet ARTE accuracy: the mean of the per-log figures (each log's
    ``arte_accuracy`` from grip inspect, logs without a judged estimate left
    out) and the pooled figure (all correct / all judged)."""
    per_log = [float(o["arte_accuracy"]) for o in good(objs) if o.get("arte_accuracy") is not None]
    judged = sum(int(o.get("arte_judged") or 0) for o in good(objs))
    correct = sum(int(o.get("arte_correct") or 0) for o in good(objs))
    return {
        "mean_of_logs": sum(per_log) / len(per_log) if per_log else math.nan,
        "logs": float(len(per_log)),
        "pooled": correct / judged if judged else math.nan,
        "judged": float(judged),
    }


def loop_summary(objs: list[dict[str, Any]]) -> dict[str, Any]:
    """Over the good logs, from grip's per-log figures: the logs whose
    control was lost and not regained (``control_lost``), and the logs with
    spin events (the loop's ``measured.spin_events``), the one with the
    most first."""
    ok = good(objs)
    lost = sorted(str(o.get("file")) for o in ok if o.get("control_lost") is True)
    spins = sorted(
        ((str(o.get("file")), int((o.get("measured") or {}).get("spin_events") or 0)) for o in ok),
        key=lambda fs: (-fs[1], fs[0]),
    )
    with_spins = [(f, n) for f, n in spins if n > 0]
    return {
        "control_lost": lost,
        "logs_with_spin_events": len(with_spins),
        "spin_events": sum(n for _, n in with_spins),
        "most_spin_events": {"file": with_spins[0][0], "spin_events": with_spins[0][1]} if with_spins else None,
    }


FIGURES = [
    "mean_torque_cmd_nm",
    "max_torque_cmd_nm",
    "mean_torque_cut_nm",
    "arte_used_pct",
    "safe_cycles",
    "arte_accuracy",
]


def replay_rows(objs: list[dict[str, Any]]) -> pd.DataFrame:
    """One row per log: identical or not, the first divergence, and each
    figure old, new and new - old (plant metrics too in closed loop)."""
    rows = []
    for o in objs:
        row: dict[str, Any] = {
            "file": o.get("file"),
            "path": o.get("path"),
            "status": o.get("status"),
            "reason": o.get("reason"),
            "mode": o.get("mode"),
            "controller": o.get("controller"),
            "arte": o.get("arte"),
            "identical": o.get("identical"),
            "differing_messages": o.get("differing_messages"),
            "first_divergence": o.get("first_divergence"),
        }
        old, new = o.get("old") or {}, o.get("new") or {}
        names = list(FIGURES)
        if o.get("plant_metrics_replayed"):
            names += METRICS
        for k in FIGURES + METRICS:
            if k in METRICS:
                a, b = (old.get("metrics") or {}).get(k), (new.get("metrics") or {}).get(k)
                if k not in names:
                    b = None
            else:
                a, b = old.get(k), new.get(k)
            row[f"old_{k}"] = _f(a)
            row[f"new_{k}"] = _f(b)
            row[f"delta_{k}"] = _f(b) - _f(a)
        rows.append(row)
    df = pd.DataFrame(rows)
    if "differing_messages" in df:
        df["differing_messages"] = df["differing_messages"].astype("Int64")
    return df


def most_divergent(df: pd.DataFrame, n: int) -> pd.DataFrame:
    """The ``n`` replayed drives whose outputs differ most: most differing
    messages, then the largest change of the mean torque command."""
    ok = df[df["status"] == "replayed"].copy()
    if ok.empty:
        return ok
    ok["abs_delta_torque"] = ok["delta_mean_torque_cmd_nm"].abs()
    ok = ok.sort_values(["differing_messages", "abs_delta_torque"], ascending=False)
    return ok.head(n)
