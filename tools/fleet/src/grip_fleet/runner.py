"""One Ray task per log: local Ray in-process by default, a cluster when
``RAY_ADDRESS`` is set; progress on stderr; results in input order."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from typing import Any

import ray

from .grip import GripCall, inspect, replay


@ray.remote(num_cpus=1, max_retries=0)
def _inspect_task(call: GripCall, path: str) -> dict[str, Any]:
    return inspect(call, path)


@ray.remote(num_cpus=1, max_retries=0)
def _replay_task(call: GripCall, path: str, what_if: list[str]) -> dict[str, Any]:
    return replay(call, path, what_if)


#: Object store of a local Ray (the tasks only return JSON objects).
LOCAL_OBJECT_STORE_BYTES = 256 * 1024 * 1024


def start_ray(workers: int | None) -> str:
    """Connects to ``RAY_ADDRESS`` if set (``workers`` is then the cluster's
    business), else starts Ray in this process with ``workers`` CPUs (default:
    all). Returns a description for the report."""
    if ray.is_initialized():
        return "Ray already initialised"
    address = os.environ.get("RAY_ADDRESS")
    if address:
        ray.init(address=address, log_to_driver=False)
        cpus = ray.cluster_resources().get("CPU", 0)  # type: ignore[no-untyped-call]
        return f"Ray cluster at {address} ({cpus:.0f} CPUs)"
    n = workers or os.cpu_count() or 1
    # a small object store: the tasks return small JSON objects
    ray.init(num_cpus=n, include_dashboard=False, log_to_driver=False, object_store_memory=LOCAL_OBJECT_STORE_BYTES)
    return f"local Ray, {n} worker(s)"


class Progress:
    """``label: done/total (bad) elapsed`` on stderr, redrawn in place on a
    terminal, a line every 10 % otherwise."""

    def __init__(self, total: int, label: str) -> None:
        self.total, self.label = total, label
        self.done = self.bad = 0
        self.t0 = time.monotonic()
        self.tty = sys.stderr.isatty()
        self.last_tenth = -1

    def step(self, bad: bool) -> None:
        self.done += 1
        self.bad += int(bad)
        tenth = self.done * 10 // max(self.total, 1)
        line = (
            f"{self.label}: {self.done}/{self.total} logs, {self.bad} bad, "
            f"{time.monotonic() - self.t0:.1f} s"
        )
        if self.tty:
            print("\r" + line, end="" if self.done < self.total else "\n", file=sys.stderr, flush=True)
        elif tenth != self.last_tenth:
            self.last_tenth = tenth
            print(line, file=sys.stderr, flush=True)

    def elapsed(self) -> float:
        return time.monotonic() - self.t0


def run_tasks(
    submit: Callable[[str], Any], paths: list[str], label: str, is_bad: Callable[[dict[str, Any]], bool]
) -> tuple[list[dict[str, Any]], float]:
    """Submits one task per path, collects the objects as they finish (with
    progress), returns them in the order of ``paths`` and the wall time, s."""
    prog = Progress(len(paths), label)
    refs = [submit(p) for p in paths]
    index = {r: i for i, r in enumerate(refs)}
    out: list[dict[str, Any] | None] = [None] * len(paths)
    pending = list(refs)
    while pending:
        ready, pending = ray.wait(pending, num_returns=1)
        for r in ready:
            i = index[r]
            try:
                obj: dict[str, Any] = ray.get(r)
            except Exception as e:  # a task that died: reported like a bad log
                obj = {"file": os.path.basename(paths[i]), "path": paths[i], "status": "error",
                       "reason": f"task failed: {e}"}
            out[i] = obj
            prog.step(is_bad(obj))
    return [o for o in out if o is not None], prog.elapsed()


def inspect_all(call: GripCall, paths: list[str]) -> tuple[list[dict[str, Any]], float]:
    """``grip inspect --json`` on every log, one Ray task each."""
    return run_tasks(
        lambda p: _inspect_task.remote(call, p), paths, "summarize", lambda o: o.get("status") != "ok"
    )


def replay_all(call: GripCall, paths: list[str], what_if: list[str]) -> tuple[list[dict[str, Any]], float]:
    """``grip replay --json`` on every log, one Ray task each."""
    return run_tasks(
        lambda p: _replay_task.remote(call, p, what_if), paths, "replay", lambda o: o.get("status") != "replayed"
    )
