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

from grip_fleet import cli
from grip_fleet.grip import expand_logs, repo_root

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
def summary(logs: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], Path]:
    """One ``fleet summarize DIR --out T.parquet --json`` for the tests below."""
    out = tmp_path_factory.mktemp("summary") / "table.parquet"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli.main(["summarize", str(logs), "--out", str(out), "--json"]) == 0
    line = [ln for ln in buf.getvalue().splitlines() if ln.startswith("{")][-1]
    return json.loads(line), out


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
