"""``fleet summarize`` and ``fleet replay`` (see tools/fleet/README.md)."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

import pandas as pd

from . import runner, tables
from .grip import GripCall, expand_logs, find_grip


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("logs", nargs="+", help="directories of .mcap logs, globs, or files")
    p.add_argument("--grip", help="the grip binary (default: $GRIP_BIN, the repository's build, or PATH)")
    p.add_argument("--config-dir", help="grip --config-dir (the road catalogue for inspect; a replay's whole configuration)")
    p.add_argument("--workers", type=int, help="local Ray: worker processes (default: all CPUs); ignored with RAY_ADDRESS")
    p.add_argument("--timeout-s", type=float, default=600.0, help="longest grip call per log before it is reported as bad")
    p.add_argument("--out", type=Path, help="write the per-drive table here (Parquet)")
    p.add_argument("--json", action="store_true", help="also print the result summary as one JSON object on stdout")


def _write(df: pd.DataFrame, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    df.to_parquet(path, index=False)
    print(f"wrote {path} ({len(df)} rows)", file=sys.stderr)


def _sibling(out: Path, what: str) -> Path:
    return out.with_name(f"{out.stem}.{what}.parquet")


def _bad_lines(objs: list[dict[str, Any]], ok: str) -> list[str]:
    return [f"  {o.get('file')}: {o.get('status')}: {o.get('reason')}" for o in objs if o.get("status") != ok]


def _events(n: int) -> str:
    return f"{n} event" + ("" if n == 1 else "s")


def summarize(a: argparse.Namespace) -> int:
    paths = expand_logs(a.logs)
    call = GripCall(find_grip(a.grip), a.config_dir and os.path.abspath(a.config_dir), a.timeout_s)
    how = runner.start_ray(a.workers)
    objs, wall = runner.inspect_all(call, paths)
    df = tables.drive_rows(objs)
    conf = tables.confusion(objs)
    bands = tables.speed_bands(objs)
    acc = tables.accuracy_summary(objs)
    loop = tables.loop_summary(objs)
    bad = _bad_lines(objs, "ok")
    pd.set_option("display.width", 200)
    print(f"fleet summarize: {len(df)} rows from {len(paths)} logs ({how}), {wall:.1f} s, {len(paths) / wall:.2f} logs/s")
    print(f"bad logs: {len(bad)}" + ("".join("\n" + b for b in bad) if bad else ""))
    print(
        f"ARTE accuracy over {int(acc['logs'])} good logs: mean of the per-log figures {acc['mean_of_logs']:.4f}, "
        f"pooled {acc['pooled']:.4f} ({int(acc['judged'])} judged estimates)"
    )
    lost = loop["control_lost"]
    named = ", ".join(lost[:10]) + (f" and {len(lost) - 10} more" if len(lost) > 10 else "")
    print(f"good logs with control lost and not regained: {len(lost)}" + (f": {named}" if lost else ""))
    most = loop["most_spin_events"]
    print(
        f"good logs with spin events (measured by the loop): {loop['logs_with_spin_events']}"
        + (f", {_events(loop['spin_events'])}; most: {most['file']} ({_events(most['spin_events'])})" if most else "")
    )
    if not conf.empty:
        print("\nper-road confusion (rows: true road at the microphone; share of that road's judged estimates):")
        print(conf.pivot(index="truth", columns="estimate", values="share_of_truth").fillna(0).round(3).to_string())
    if not bands.empty:
        print("\nARTE accuracy per speed band:")
        print(bands.to_string(index=False))
    if a.out:
        _write(df, a.out)
        _write(conf, _sibling(a.out, "confusion"))
        _write(bands, _sibling(a.out, "speed_bands"))
    if a.json:
        print(json.dumps({"rows": len(df), "bad": [o.get("file") for o in objs if o.get("status") != "ok"],
                          "accuracy": acc, "loop": loop, "wall_s": wall, "logs_per_s": len(paths) / wall}))
    return 0


def replay(a: argparse.Namespace) -> int:
    paths = expand_logs(a.logs)
    call = GripCall(find_grip(a.grip), a.config_dir and os.path.abspath(a.config_dir), a.timeout_s)
    what_if: list[str] = []
    if a.controller:
        what_if += ["--controller", a.controller]
    if a.arte:
        what_if += ["--arte", a.arte]
    if a.model:
        what_if += ["--model", str(Path(a.model).resolve())]
    if a.vehicle:
        what_if += ["--vehicle", str(Path(a.vehicle).resolve())]
    for s in a.set or []:
        what_if += ["--set", s]
    if a.closed_loop:
        what_if.append("--closed-loop")
    how = runner.start_ray(a.workers)
    objs, wall = runner.replay_all(call, paths, what_if)
    df = tables.replay_rows(objs)
    replayed = df[df["status"] == "replayed"]
    divergent = replayed[replayed["identical"] != True]  # noqa: E712 (a column of bools)
    bad = _bad_lines(objs, "replayed")
    pd.set_option("display.width", 220)
    print(f"fleet replay {' '.join(what_if) or '(unchanged settings)'}: {len(paths)} logs ({how}), {wall:.1f} s, {len(paths) / wall:.2f} logs/s")
    print(f"replayed {len(replayed)}, divergent {len(divergent)}, not replayed {len(bad)}" + ("".join("\n" + b for b in bad) if bad else ""))
    cols = ["file", "identical", "differing_messages"] + [
        f"{w}_{k}" for k in ("mean_torque_cmd_nm", "arte_accuracy", "slip_deviation") for w in ("old", "new")
    ]
    if not replayed.empty:
        print("\nper drive, old (logged) vs new (replayed):")
        print(replayed[[c for c in cols if c in replayed]].to_string(index=False))
        num = [c for c in replayed.columns if c.startswith(("old_", "new_", "delta_"))]
        print("\nfleet mean:")
        print(replayed[num].mean().to_frame("mean").T.to_string(index=False))
        top = tables.most_divergent(df, a.top)
        if not top.empty and len(divergent):
            print(f"\nthe {min(a.top, len(divergent))} drives that diverge most:")
            print(top[["file", "differing_messages", "delta_mean_torque_cmd_nm", "first_divergence"]].head(len(divergent)).to_string(index=False))
    if a.out:
        _write(df, a.out)
    if a.json:
        print(json.dumps({"logs": len(paths), "replayed": len(replayed), "divergent": len(divergent),
                          "bad": [o.get("file") for o in objs if o.get("status") != "replayed"],
                          "wall_s": wall, "logs_per_s": len(paths) / wall}))
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="fleet", description=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("summarize", help="one row per drive (grip inspect --json per log, as Ray tasks)")
    _common(s)
    r = sub.add_parser("replay", help="grip replay --json per log, as Ray tasks: old vs new per drive")
    _common(r)
    r.add_argument("--controller", choices=["mfc", "src", "mtte"], help="what if: this controller")
    r.add_argument("--arte", choices=["on", "off"], help="what if: ARTE on or off in the controller")
    r.add_argument("--model", help="what if: this ARTE model file")
    r.add_argument("--vehicle", help="what if: this vehicle TOML for tcs-loop")
    r.add_argument("--set", action="append", metavar="[FILE:]SECTION.KEY=VALUE", help="what if: one parameter (repeatable)")
    r.add_argument("--closed-loop", action="store_true", help="re-simulate the plant with the new controller (grip replay --closed-loop)")
    r.add_argument("--top", type=int, default=5, help="how many of the most divergent drives to list")
    a = ap.parse_args(argv)
    try:
        return summarize(a) if a.cmd == "summarize" else replay(a)
    except FileNotFoundError as e:
        print(f"fleet: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
