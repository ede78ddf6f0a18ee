"""A handful of logs for the tests: four that ``grip generate`` writes (two
controllers, noisy audio), one cut in half, one that is not MCAP; and one
local Ray for the whole session."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
import ray

from grip_fleet.grip import find_grip, repo_root
from grip_fleet.runner import start_ray

GOOD = 4


@pytest.fixture(scope="session")
def grip_bin() -> str:
    return find_grip(os.environ.get("GRIP_BIN"))


@pytest.fixture(scope="session")
def logs(tmp_path_factory: pytest.TempPathFactory, grip_bin: str) -> Path:
    d = tmp_path_factory.mktemp("fleet")
    subprocess.run(
        [grip_bin, "--config-dir", str(repo_root() / "config"), "generate", "--out", str(d),
         "--count", str(GOOD), "--seed0", "21", "--controllers", "mfc,mtte", "--snr-db", "10:20",
         "--hold-s", "0.3", "--jobs", "2"],
        check=True,
        capture_output=True,
    )
    good = sorted(d.glob("gen-*.mcap"))
    assert len(good) == GOOD
    data = good[0].read_bytes()
    (d / "truncated.mcap").write_bytes(data[: len(data) // 2])
    (d / "garbage.mcap").write_bytes(b"this is not an MCAP file\n" * 40)
    return d


@pytest.fixture(scope="session", autouse=True)
def local_ray() -> Iterator[None]:
    start_ray(2)
    yield
    ray.shutdown()
