"""fleet summarize / fleet replay on a handful of generated logs (+ a
truncated and a garbage one): every log gets a row, the bad ones are named
with their reason, the fleet figures add up grip's own per-log figures, and
a replay with unchanged settings diverges nowhere."""

from __future__ import annotations

import contextlib
import io
import json
import math
import subprocess
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from grip_fleet import cli, tables
from grip_fleet.grip import expand_logs, find_grip, repo_root

from .conftest import GOOD


def run_cli(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, Any]:
    """Runs ``fleet ARGS --json``; returns the JSON summary line."""
    assert cli.main([*args, "--json"]) == 0
    out = capsys.readouterr().out
    return json.loads([ln for ln in out.splitlines() if ln.startswith("{")][-1])


def inspect_direct(grip_bin: str, path: Path) -> dict[str, Any]:
    """grip inspect --json, called here without Ray."""
    p = subprocess.run(
        [grip_bin, "--config-dir", str(repo_root() / "config"), "inspect", "--json", str(path)],
        check=True, capture_output=True, text=True,
    )
    return json.loads(p.stdout)


@pytest.fixture(scope="module")
def summarized(logs: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], Path, str]:
    """One ``fleet summarize DIR --out T.parquet --json`` for the tests
    below: its JSON summary, the table and what it printed."""
    out = tmp_path_factory.mktemp("summary") / "table.parquet"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli.main(["summarize", str(logs), "--out", str(out), "--json"]) == 0
    line = [ln for ln in buf.getvalue().splitlines() if ln.startswith("{")][-1]
    return json.loads(line), out, buf.getvalue()


@pytest.fixture(scope="module")
def summary(summarized: tuple[dict[str, Any], Path, str]) -> tuple[dict[str, Any], Path]:
    """The JSON summary and the table of ``summarized``."""
    s, out, _ = summarized
    return s, out


@pytest.fixture(scope="module")
def direct(logs: Path, grip_bin: str) -> list[dict[str, Any]]:
    """grip inspect --json on each good log, called here without Ray."""
    return [inspect_direct(grip_bin, p) for p in sorted(logs.glob("gen-*.mcap"))]


def test_summarize_gives_a_row_per_log_and_names_the_bad_ones(summary: tuple[dict[str, Any], Path]) -> None:
    s, out = summary
    assert s["rows"] == GOOD + 2
    assert sorted(s["bad"]) == ["garbage.mcap", "truncated.mcap"]
    df = pd.read_parquet(out)
    assert len(df) == GOOD + 2
    by = df.set_index("file")
    assert by.loc["garbage.mcap", "status"] == "unreadable"
    assert "not an MCAP file" in by.loc["garbage.mcap", "reason"]
    assert by.loc["truncated.mcap", "status"] == "incomplete"
    assert by.loc["truncated.mcap", "reason"]
    good = df[df["status"] == "ok"]
    assert len(good) == GOOD
    assert good["simulated"].all()
    assert set(good["controller"]) == {"mfc", "mtte"}
    assert (good["cycles"] > 2000).all()
    assert (good["deadline_misses_in_scenario"] == 0).all()
    assert (good["deadline_misses_whole_log"] == 0).all()
    # the scenario fully covered, the loop never in the safe state during it
    assert (good["scenario_window"] == "complete").all()
    assert (good["safe_state_entries_in_scenario"] == 0).all()
    assert good["arte_accuracy_whole_log"].between(0.5, 1.0).all()
    assert good["arte_accuracy"].between(0.5, 1.0).all()
    assert (good["distance_m"] > 5).all()
    for what in ("confusion", "speed_bands"):
        assert out.with_name(f"table.{what}.parquet").is_file()


def test_fleet_accuracy_is_the_mean_of_grip_inspects_per_log_figures(
    summary: tuple[dict[str, Any], Path], direct: list[dict[str, Any]]
) -> None:
    s, _ = summary
    accs = [o["arte_accuracy"] for o in direct]
    assert len(accs) == GOOD and all(a is not None for a in accs)
    assert math.isclose(s["accuracy"]["mean_of_logs"], sum(accs) / len(accs), rel_tol=0, abs_tol=1e-12)
    judged = sum(o["arte_judged"] for o in direct)
    correct = sum(o["arte_correct"] for o in direct)
    assert s["accuracy"]["judged"] == judged
    assert math.isclose(s["accuracy"]["pooled"], correct / judged, rel_tol=0, abs_tol=1e-12)


def test_confusion_and_speed_bands_add_up_to_the_judged_estimates(
    summary: tuple[dict[str, Any], Path], direct: list[dict[str, Any]]
) -> None:
    _, out = summary
    judged = sum(o["arte_judged"] for o in direct)
    conf = pd.read_parquet(out.with_name("table.confusion.parquet"))
    bands = pd.read_parquet(out.with_name("table.speed_bands.parquet"))
    assert conf["count"].sum() == judged
    assert bands["judged"].sum() == judged
    for _, share in conf.groupby("truth")["share_of_truth"]:
        assert math.isclose(share.sum(), 1.0)


MEASURED_COLUMNS = {
    "measured_mean_abs_slip": "mean_abs_slip",
    "measured_p95_abs_slip": "p95_abs_slip",
    "measured_max_abs_slip": "max_abs_slip",
    "measured_share_above_0_1": "share_above_0_1",
    "measured_share_above_0_2": "share_above_0_2",
    "measured_mean_accel_ms2": "mean_accel_ms2",
    "measured_mean_cmd_nm": "mean_cmd_nm",
    "measured_mean_demand_nm": "mean_demand_nm",
    "measured_cmd_over_demand": "cmd_over_demand",
    "measured_withheld_nms": "withheld_nms",
    "measured_cmd_tv_per_s": "cmd_tv_per_s",
    "measured_time_s": "time_s",
}


def test_the_table_has_what_the_loop_measured_and_control_lost_as_grip_gives_them(
    summarized: tuple[dict[str, Any], Path, str], direct: list[dict[str, Any]]
) -> None:
    s, out, text = summarized
    df = pd.read_parquet(out)
    assert str(df["spin_events"].dtype) == "Int64"
    assert str(df["control_lost"].dtype) == "boolean"
    for c in ("inverter_faults_in_scenario", "inverter_faults_whole_log", "inverter_derating_in_scenario", "inverter_derating_whole_log"):
        assert str(df[c].dtype) == "Int64", c
    for c in [*MEASURED_COLUMNS, "control_out_at_end_s"]:
        assert df[c].dtype == "float64", c
    by = df.set_index("file")
    for o in direct:
        row = by.loc[o["file"]]
        m = o["measured"]
        for col, key in MEASURED_COLUMNS.items():
            assert m[key] is not None, key
            assert row[col] == m[key], (o["file"], col)  # copied, not recomputed
        assert row["measured_window"] == m["window"] == "scenario"
        assert row["spin_events"] == m["spin_events"]
        assert row["control_lost"] == o["control_lost"]
        assert o["control_lost"] is False  # generated drives stay in control
        assert math.isnan(row["control_out_at_end_s"])
        inv = o["inverter"]
        for flag, col in (("fault", "inverter_faults"), ("derating", "inverter_derating")):
            assert row[f"{col}_in_scenario"] == inv[flag]["episodes_in_scenario"], (o["file"], col)
            assert row[f"{col}_whole_log"] == inv[flag]["episodes"], (o["file"], col)
        # the generated inverter faults at start-up only (before the window)
        assert row["inverter_faults_in_scenario"] == 0 and row["inverter_faults_whole_log"] >= 1, o["file"]
    # a log grip could not read: every one of them missing
    g = by.loc["garbage.mcap"]
    assert pd.isna(g["control_lost"]) and pd.isna(g["spin_events"]) and pd.isna(g["measured_window"])
    assert pd.isna(g["inverter_faults_whole_log"]) and pd.isna(g["inverter_faults_in_scenario"])
    assert all(math.isnan(g[c]) for c in MEASURED_COLUMNS)
    # the summary lines add up grip's per-log figures
    spins = {o["file"]: o["measured"]["spin_events"] for o in direct}
    with_spins = sorted((f for f, n in spins.items() if n > 0), key=lambda f: (-spins[f], f))
    assert s["loop"]["control_lost"] == []
    assert s["loop"]["logs_with_spin_events"] == len(with_spins)
    assert s["loop"]["spin_events"] == sum(spins.values())
    assert "good logs with control lost and not regained: 0\n" in text
    if with_spins:
        most = with_spins[0]
        assert s["loop"]["most_spin_events"] == {"file": most, "spin_events": spins[most]}
        n, k = sum(spins.values()), spins[most]
        assert (
            f"good logs with spin events (measured by the loop): {len(with_spins)}, "
            f"{n} event{'' if n == 1 else 's'}; most: {most} ({k} event{'' if k == 1 else 's'})"
        ) in text


def test_control_lost_and_spin_events_are_counted_over_the_good_logs_from_grips_objects() -> None:
    """The fleet's lines on grip-shaped objects (the fields of ``grip
    inspect --json``): a lost drive, one in control, one without a scenario
    window, and a truncated log that lost control (not counted: only good
    logs count)."""
    objs: list[dict[str, Any]] = [
        {"file": "a.mcap", "status": "ok", "control_lost": True, "control_out_at_end_s": 1.48,
         "measured": {"window": "scenario", "spin_events": 2, "mean_abs_slip": 0.05}},
        {"file": "b.mcap", "status": "ok", "control_lost": False, "control_out_at_end_s": None,
         "measured": {"window": "scenario", "spin_events": 5, "mean_abs_slip": 0.07}},
        {"file": "car.mcap", "status": "ok", "control_lost": None, "control_out_at_end_s": None,
         "measured": {"window": "demand", "spin_events": 0, "mean_abs_slip": None}},
        {"file": "cut.mcap", "status": "incomplete", "reason": "cut", "control_lost": True,
         "measured": {"window": "scenario", "spin_events": 9}},
        {"file": "text.mcap", "status": "unreadable", "reason": "not MCAP"},
    ]
    loop = tables.loop_summary(objs)
    assert loop == {
        "control_lost": ["a.mcap"],
        "logs_with_spin_events": 2,
        "spin_events": 7,
        "most_spin_events": {"file": "b.mcap", "spin_events": 5},
    }
    df = tables.drive_rows(objs).set_index("file")
    assert df["control_lost"].tolist()[:2] == [True, False]
    assert pd.isna(df.loc["car.mcap", "control_lost"]) and pd.isna(df.loc["text.mcap", "control_lost"])
    assert df.loc["a.mcap", "control_out_at_end_s"] == 1.48
    assert df["spin_events"].tolist()[:4] == [2, 5, 0, 9]
    assert pd.isna(df.loc["text.mcap", "spin_events"])
    assert df.loc["b.mcap", "measured_mean_abs_slip"] == 0.07
    assert math.isnan(df.loc["car.mcap", "measured_mean_abs_slip"])
    assert df.loc["car.mcap", "measured_window"] == "demand"


def test_replay_with_unchanged_settings_has_no_divergent_drive(
    logs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "replay.parquet"
    s = run_cli(capsys, "replay", str(logs), "--out", str(out))
    assert s["replayed"] == GOOD
    assert s["divergent"] == 0
    assert sorted(s["bad"]) == ["garbage.mcap", "truncated.mcap"]
    df = pd.read_parquet(out)
    assert len(df) == GOOD + 2
    ok = df[df["status"] == "replayed"]
    assert ok["identical"].all()
    assert (ok["differing_messages"] == 0).all()
    assert (ok["delta_mean_torque_cmd_nm"] == 0).all()
    bad = df[df["status"] != "replayed"].set_index("file")
    assert "incomplete" in bad.loc["truncated.mcap", "reason"]


def test_replay_with_another_controller_gives_old_and_new_per_drive(
    logs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "src.parquet"
    s = run_cli(capsys, "replay", str(logs / "gen-*.mcap"), "--controller", "src", "--out", str(out))
    assert s["replayed"] == GOOD and s["bad"] == []
    assert s["divergent"] == GOOD  # none of these drives ran SRC
    df = pd.read_parquet(out)
    assert (df["controller"] == "src").all()
    assert (df["differing_messages"] > 0).all()
    assert df["old_mean_torque_cmd_nm"].notna().all() and df["new_mean_torque_cmd_nm"].notna().all()
    assert (df["delta_mean_torque_cmd_nm"] != 0).any()


def test_a_spec_that_matches_nothing_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["summarize", str(tmp_path / "nothing-*.mcap")]) == 2
    assert "nothing-*.mcap" in capsys.readouterr().err
    with pytest.raises(FileNotFoundError):
        expand_logs([str(tmp_path)])


def test_paths_a_task_gets_are_absolute(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Relative specs (a directory, a glob, a file) give absolute log paths,
    and a relative --grip path is made absolute: a Ray worker need not share
    the driver's working directory (a cluster's never does)."""
    (tmp_path / "logs").mkdir()
    for n in ("a.mcap", "b.mcap"):
        (tmp_path / "logs" / n).write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    for spec in ("logs", "logs/*.mcap", "./logs/a.mcap"):
        got = expand_logs([spec])
        assert got and all(Path(p).is_absolute() and Path(p).is_file() for p in got), (spec, got)
    assert expand_logs(["logs", "./logs/a.mcap"]) == [str(tmp_path / "logs" / "a.mcap"), str(tmp_path / "logs" / "b.mcap")]
    assert find_grip("bin/grip") == str(tmp_path / "bin" / "grip")
    assert find_grip("grip") == "grip"
