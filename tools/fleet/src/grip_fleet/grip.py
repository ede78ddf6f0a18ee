"""Finding the logs and the ``grip`` binary, and calling it on one log."""

from __future__ import annotations

import glob
import json
import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: How long one grip call on one log may take before it is reported as bad, s.
DEFAULT_TIMEOUT_S = 600.0


def repo_root() -> Path:
    """The grip repository this package lives in (tools/fleet/src/grip_fleet/..)."""
    return Path(__file__).resolve().parents[4]


def absolute(path: str) -> str:
    """``path`` made absolute against this process's working directory
    (symbolic links kept): a Ray worker need not share the driver's working
    directory (a cluster's never does), so every path a task is given is
    absolute. A bare command name (no ``/``) is left for ``PATH``."""
    return os.path.abspath(path) if os.sep in path else path


def find_grip(explicit: str | None = None) -> str:
    """The grip binary: ``explicit``, else ``$GRIP_BIN``, else the
    repository's ``target/release/grip`` or ``target/debug/grip`` (the newer),
    else ``grip`` on ``PATH``; a path is made absolute ([`absolute`])."""
    if explicit:
        return absolute(explicit)
    env = os.environ.get("GRIP_BIN")
    if env:
        return absolute(env)
    built = [
        p
        for p in (
            repo_root() / "target" / "release" / "grip",
            repo_root() / "target" / "debug" / "grip",
        )
        if p.is_file()
    ]
    if built:
        return str(max(built, key=lambda p: p.stat().st_mtime))
    found = shutil.which("grip")
    if found:
        return found
    raise FileNotFoundError(
        "no grip binary: build it (cargo build -p grip), pass --grip PATH or set GRIP_BIN"
    )


def expand_logs(specs: list[str]) -> list[str]:
    """Each spec is a directory (its ``*.mcap`` files), a glob, or a file;
    returns the logs as absolute paths (a Ray worker need not share this
    process's working directory), sorted, without duplicates. A spec that
    matches nothing is an error naming it."""
    out: list[str] = []
    for spec in specs:
        p = Path(spec)
        if p.is_dir():
            found = sorted(str(x) for x in p.glob("*.mcap") if x.is_file())
        elif p.is_file():
            found = [str(p)]
        else:
            found = sorted(x for x in glob.glob(spec, recursive=True) if Path(x).is_file())
        if not found:
            raise FileNotFoundError(f"{spec}: no .mcap files (not a directory, file or matching glob)")
        out.extend(os.path.abspath(x) for x in found)
    seen: set[str] = set()
    unique = []
    for x in out:
        if x not in seen:
            seen.add(x)
            unique.append(x)
    return unique


@dataclass(frozen=True)
class GripCall:
    """How to run grip on a log (everything a Ray task needs; picklable)."""

    grip: str
    config_dir: str | None = None
    timeout_s: float = DEFAULT_TIMEOUT_S


def _error(path: str, status: str, reason: str) -> dict[str, Any]:
    return {"file": Path(path).name, "path": path, "status": status, "reason": reason}


def run_json(call: GripCall, args: list[str], path: str) -> dict[str, Any]:
    """Runs ``grip [--config-dir D] ARGS... PATH`` and returns the JSON
    object it prints (one line). A crash, a timeout or output that is not one
    JSON object gives ``status = "error"`` with the reason: a bad log never
    stops the job."""
    cmd = [call.grip]
    if call.config_dir:
        cmd += ["--config-dir", call.config_dir]
    cmd += [*args, path]
    try:
        p = subprocess.run(
            cmd,
            capture_output=True,
            text=True,
            timeout=call.timeout_s,
            env={**os.environ, "RUST_LOG": os.environ.get("RUST_LOG", "error")},
        )
    except subprocess.TimeoutExpired:
        return _error(path, "error", f"grip {' '.join(args)} took longer than {call.timeout_s:.0f} s")
    except OSError as e:
        return _error(path, "error", f"cannot run {call.grip}: {e}")
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
    if len(lines) == 1:
        try:
            obj = json.loads(lines[0])
        except json.JSONDecodeError as e:
            return _error(path, "error", f"grip printed invalid JSON: {e}")
        if isinstance(obj, dict):
            return obj
    tail = (p.stderr.strip().splitlines() or ["(no message)"])[-1]
    return _error(path, "error", f"grip {' '.join(args)} exited with status {p.returncode}: {tail}")


def inspect(call: GripCall, path: str) -> dict[str, Any]:
    """``grip inspect --json PATH``."""
    return run_json(call, ["inspect", "--json"], path)


def replay(call: GripCall, path: str, what_if: list[str]) -> dict[str, Any]:
    """``grip replay --json [what-if options] PATH``."""
    return run_json(call, ["replay", "--json", *what_if], path)
