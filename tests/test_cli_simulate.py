"""`cuikslam simulate random` exposes every parameter of the random world."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

from cuikslam.log import read_log_file


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cuikslam.cli.main", *args], capture_output=True, text=True
    )


def test_dense_world_options_reach_the_simulator(tmp_path: Path) -> None:
    out = tmp_path / "dense.jsonl"
    done = _run(
        "simulate", "random", "--unknown", "--poses", "12", "--landmarks", "6", "--classes",
        "a,b", "--size", "30,20", "--step", "2,2", "--odometry-bounds", "0.02,0.05",
        "--observation-bounds", "0.04,0.03", "--max-range", "12", "-o", str(out),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    log = read_log_file(out)
    distances = [r.distance for r in log.odometry]
    assert all(math.isclose(hi - lo, 0.1, rel_tol=1e-9) for lo, hi in distances)
    turns = [r.turn for r in log.odometry]
    assert all(math.isclose(hi - lo, 0.04, rel_tol=1e-9) for lo, hi in turns)
    truth = json.loads(out.with_suffix(".truth.json").read_text())
    xy = [(v["x"], v["y"]) for v in truth["landmarks"].values()]
    assert all(0 <= x <= 30 and 0 <= y <= 20 for x, y in xy)


def test_a_malformed_pair_is_one_clear_line(tmp_path: Path) -> None:
    out = tmp_path / "x.jsonl"
    done = _run("simulate", "random", "--size", "3", "-o", str(out))
    assert done.returncode == 2
    assert done.stderr.strip() == "cuikslam: error: --size '3': expected two numbers A,B"
    assert not out.exists()
