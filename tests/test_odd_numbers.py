"""Odd numbers are valid input: signed zeros, subnormals, huge and tiny magnitudes, zero-width
intervals, angles of a million radians. No traceback anywhere, a well-formed result, and
the truth inside every box whenever the log was built from a true world.

The worlds are made of floats (pose 0, every turn and distance, every landmark), so their
priors and odometry can be written as exact ``[v, v]`` intervals. Poses are computed
from them in 1300-bit arithmetic (:mod:`_exact`); each range and bearing interval is
rounded outward around its exact value (zero-width when that value is a float), so the
exact truth is inside every measured interval.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mpmath
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from _exact import angle_inside
from cuikslam.log import Log, parse_log_lines
from cuikslam.narrowing.consistency import BUDGET_SUFFIX, LEVELS
from cuikslam.results.association import partition
from cuikslam.results.io import solution_to_json
from cuikslam.results.solution import NOT_REFUTED, PROVEN, Hypothesis, Solution
from cuikslam.solver import solve

REPRO = Path(__file__).parent / "data" / "repro"
SCALES = (1.0, 1e-300, 1e-310, 5e-324, 1e150, 1e300)
"""Length units of a world: normal, tiny, subnormal, the smallest subnormal, huge."""
REPORTED_LEVELS = {*LEVELS, *(level + BUDGET_SUFFIX for level in LEVELS)}
TEST_BUDGET = 1.0
"""Seconds per solve in these tests (the budget only ever leaves boxes wider)."""
MP = mpmath.MPContext()
MP.prec = 2400
"""Exact enough for 1e300 + 5e-324 (2070 bits), and for the products and sums of a few
odometry steps on top of that."""


def mpf(x: float) -> mpmath.mpf:
    """A float, exactly."""
    return MP.mpf(float(x))


# --- exact reference values and outward rounding ------------------------------------------


def _down(v: Any) -> float:
    """The largest float <= the exact value ``v``."""
    f = float(v)
    if math.isinf(f) or mpf(f) > v:
        f = math.nextafter(f, -math.inf)
    return f


def _up(v: Any) -> float:
    """The smallest float >= the exact value ``v``."""
    f = float(v)
    if math.isinf(f) or mpf(f) < v:
        f = math.nextafter(f, math.inf)
    return f


def _zero(sign_lo: bool, sign_hi: bool) -> list[float]:
    return [-0.0 if sign_lo else 0.0, -0.0 if sign_hi else 0.0]


# --- worlds --------------------------------------------------------------------------------


@dataclass
class OddWorld:
    """A true world (floats where they are free, exact values where they are derived)."""

    lines: list[str]
    poses: list[tuple[Any, Any, Any]]
    landmarks: dict[str, tuple[float, float]]
    observation_landmark: list[str]
    known: bool
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def log(self) -> Log:
        return parse_log_lines(self.lines)


def _odd(draw: st.DrawFn, scale: float, base: list[float]) -> float:
    """A length: one of ``base`` (zeros of both signs included) or ``scale`` times a
    small number, rounded to a float."""
    return draw(
        st.one_of(
            st.sampled_from(base),
            st.floats(-10.0, 10.0).map(lambda u: float(scale * u)),
        )
    )


def _interval(draw: st.DrawFn, v: Any, scale: float) -> list[float]:
    """An interval around the exact value ``v``: exact ``[v, v]`` (signed zeros for 0) when
    ``v`` is a float, else one ulp wide, or widened by a random relative or absolute margin."""
    kind = draw(st.sampled_from(["tight", "tight", "relative", "absolute"]))
    lo, hi = _down(v), _up(v)
    if lo == hi == 0.0:
        lo, hi = _zero(draw(st.booleans()), draw(st.booleans()))
    if kind == "relative":
        m = abs(float(v)) * draw(st.sampled_from([1e-15, 1e-6, 1e-2]))
        lo, hi = _down(mpf(lo) - mpf(m)), _up(mpf(hi) + mpf(m))
    elif kind == "absolute":
        m = scale * draw(st.sampled_from([1e-9, 1e-3, 0.5]))
        lo, hi = _down(mpf(lo) - mpf(m)), _up(mpf(hi) + mpf(m))
    return [lo, hi]


@st.composite
def odd_worlds(draw: st.DrawFn, known: bool | None = None) -> OddWorld:
    """A small world of odd numbers and its log (known or unknown correspondence)."""
    scale = draw(st.sampled_from(SCALES))
    x0 = _odd(draw, scale, [0.0, -0.0, 5e-324, -1e-310, 1e300])
    y0 = _odd(draw, scale, [0.0, -0.0, 5e-324, 1e-308])
    t0 = draw(st.sampled_from([0.0, -0.0, math.pi, -math.pi, 1e6, -1e6, 0.3]))
    n_poses = draw(st.integers(1, 4))
    known = draw(st.booleans()) if known is None else known
    lines = [json.dumps({"type": "prior", "pose": 0, "x": [x0, x0], "y": [y0, y0],
                         "theta": [t0, t0]})]  # fmt: skip
    poses = [(mpf(x0), mpf(y0), mpf(t0))]
    for i in range(1, n_poses):
        turn = draw(st.sampled_from([0.0, -0.0, 1e6, -2.5, math.pi, 1.0e-300]))
        distance = draw(
            st.one_of(
                st.sampled_from([0.0, -0.0, 5e-324]),
                st.floats(0.0, 5.0).map(lambda u: float(scale * u)),
            )
        )
        x, y, t = poses[-1]
        heading = t + mpf(turn)
        poses.append((x + mpf(distance) * MP.cos(heading), y + mpf(distance) * MP.sin(heading),
                      heading))  # fmt: skip
        odometry = {"type": "odometry", "from": i - 1, "to": i, "turn": [turn, turn]}
        lines.append(json.dumps({**odometry, "distance": [distance, distance]}))
    n_landmarks = draw(st.integers(1, 3))
    landmarks = {}
    for k in range(n_landmarks):
        near = draw(st.sampled_from(range(n_poses)))
        lx = float(poses[near][0]) + _odd(draw, scale, [0.0, -0.0, 5e-324])
        ly = float(poses[near][1]) + _odd(draw, scale, [0.0, 1e-310])
        assume(math.isfinite(lx) and math.isfinite(ly))
        landmarks[f"L{k}"] = (lx, ly)
    for name, (lx, ly) in landmarks.items():
        if draw(st.integers(0, 3)) == 0:
            lines.append(json.dumps({"type": "landmark", "id": name, "class": "c",
                                     "x": _interval(draw, mpf(lx), scale),
                                     "y": _interval(draw, mpf(ly), scale)}))  # fmt: skip
    observed: list[str] = []
    for i in range(n_poses):
        for name in draw(st.lists(st.sampled_from(sorted(landmarks)), max_size=2, unique=True)):
            x, y, t = poses[i]
            dx, dy = mpf(landmarks[name][0]) - x, mpf(landmarks[name][1]) - y
            rng = MP.sqrt(dx * dx + dy * dy)
            record: dict[str, Any] = {"type": "observation", "pose": i, "class": "c"}
            kind = draw(st.sampled_from(["both", "range", "bearing"]))
            if rng == 0:
                kind = "range"  # no bearing to a landmark under the robot
            if kind in ("both", "range"):
                record["range"] = [max(v, 0.0) for v in _interval(draw, rng, scale)]
            if kind in ("both", "bearing"):
                record["bearing"] = _interval(draw, MP.atan2(dy, dx) - t, scale)
            if known or draw(st.booleans()):
                record["landmark"] = name
            lines.append(json.dumps(record))
            observed.append(name)
    return OddWorld(lines, poses, landmarks, observed, known)


# --- checks --------------------------------------------------------------------------------


def _misses(h: Hypothesis, world: OddWorld) -> list[str]:
    """Boxes of ``h`` (the true hypothesis) that miss the exact truth."""
    misses = []
    for k, pid in enumerate(h.pose_ids):
        x, y, t = world.poses[pid]
        box = h.poses[k]
        if not (box[0, 0] <= x <= box[0, 1] and box[1, 0] <= y <= box[1, 1]):
            misses.append(f"pose {pid} ({x}, {y}) not in {box[:2].tolist()}")
        if not angle_inside(float(box[2, 0]), float(box[2, 1]), t):
            misses.append(f"pose {pid} theta {t} not in {box[2].tolist()}")
    names = dict(zip(h.assignment, world.observation_landmark, strict=True))
    for k, lid in enumerate(h.landmark_ids):
        true_name = names.get(lid, lid)
        if true_name not in world.landmarks:
            continue
        lx, ly = world.landmarks[true_name]
        box = h.landmarks[k]
        if not (box[0, 0] <= lx <= box[0, 1] and box[1, 0] <= ly <= box[1, 1]):
            misses.append(f"landmark {lid} ({lx}, {ly}) not in {box.tolist()}")
    return misses


def assert_well_formed(solution: Solution) -> None:
    """Boxes without NaN and with lo <= hi, known statuses and levels, strict JSON."""
    json.dumps(solution_to_json(solution), allow_nan=False)
    assert solution.consistency in REPORTED_LEVELS, solution.consistency
    for h in solution.hypotheses:
        for boxes in (h.poses, h.landmarks):
            assert not np.isnan(boxes).any()
            assert np.all(boxes[..., 0] <= boxes[..., 1])
        assert h.status in (PROVEN, NOT_REFUTED)
        assert h.consistency in REPORTED_LEVELS, h.consistency
        if h.status == PROVEN:
            assert h.witness is not None
            assert all(np.isfinite(v).all() for v in h.witness.values())


def assert_truth_kept(solution: Solution, world: OddWorld) -> None:
    """The log is consistent: never refuted, and the true partition's boxes hold the truth."""
    assert not solution.refuted, solution.messages
    log = world.log
    named = {p.landmark for p in log.landmark_priors} | {
        str(o.landmark) for o in log.observations if o.landmark is not None
    }
    truth = partition(world.observation_landmark, named)
    found = [h for h in solution.hypotheses if partition(h.assignment, named) == truth]
    if not found:
        assert not solution.complete, "the true partition was discarded"
        return
    misses = _misses(found[0], world)
    assert not misses, misses[:5]


# --- tests ---------------------------------------------------------------------------------

ODD = settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))


@pytest.mark.parametrize("level", LEVELS)
@ODD
@given(world=odd_worlds())
def test_odd_numbers_never_crash_and_keep_the_truth(level: str, world: OddWorld) -> None:
    solution = solve(world.log, consistency=level, time_budget=TEST_BUDGET)
    assert_well_formed(solution)
    assert_truth_kept(solution, world)


@pytest.mark.slow
@pytest.mark.parametrize("level", LEVELS)
@settings(max_examples=400, deadline=None, suppress_health_check=list(HealthCheck))
@given(world=odd_worlds())
def test_odd_numbers_many(level: str, world: OddWorld) -> None:
    solution = solve(world.log, consistency=level, time_budget=TEST_BUDGET)
    assert_well_formed(solution)
    assert_truth_kept(solution, world)


def test_the_repro_logs_of_odd_numbers_solve() -> None:
    """``[0.0, -0.0]`` intervals and subnormal magnitudes crashed the witness search."""
    for name in ("signed-zero-crash.jsonl", "subnormal-crash.jsonl"):
        log = parse_log_lines((REPRO / name).read_text().splitlines())
        for level in LEVELS:
            solution = solve(log, consistency=level, time_budget=TEST_BUDGET)
            assert_well_formed(solution)
            assert len(solution.hypotheses) == 1, (name, solution.messages)


def _cli(log: Path, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "COLUMNS": "220", "NO_COLOR": "1"}
    return subprocess.run(
        [sys.executable, "-m", "cuikslam.cli.main", "solve", str(log), "--json",
         str(tmp_path / f"{log.stem}.json"), "--time-budget", str(TEST_BUDGET)],
        capture_output=True, text=True, timeout=300, env=env, check=False,
    )  # fmt: skip


def test_cli_on_odd_logs(tmp_path: Path) -> None:
    """The command exits 0 or 1 without a traceback, and writes a strict-JSON result."""
    logs = [REPRO / "signed-zero-crash.jsonl", REPRO / "subnormal-crash.jsonl"]
    for name, record in (
        ("huge", {"type": "prior", "pose": 0, "x": [1e300, 1e300], "y": [-1e300, -1e300],
                  "theta": [1e6, 1e6]}),
        ("tiny", {"type": "prior", "pose": 0, "x": [5e-324, 5e-324], "y": [-0.0, 0.0],
                  "theta": [-0.0, -0.0]}),
    ):  # fmt: skip
        path = tmp_path / f"{name}.jsonl"
        x = record["x"][0]
        lines = [
            record,
            {"type": "odometry", "from": 0, "to": 1, "turn": [-0.0, 0.0], "distance": [x, x]},
            {"type": "observation", "pose": 1, "class": "c", "range": [abs(x), 2 * abs(x)]},
        ]
        path.write_text("".join(json.dumps(r) + "\n" for r in lines))
        logs.append(path)
    for log in logs:
        result = _cli(log, tmp_path)
        assert "Traceback" not in result.stderr, result.stderr
        assert result.returncode in (0, 1), (log.name, result.returncode, result.stderr)
        doc = json.loads((tmp_path / f"{log.stem}.json").read_text())
        assert doc["hypotheses"], (log.name, doc["messages"])


def test_a_subnormal_range_straight_ahead_is_not_refuted() -> None:
    """Pose 3 sits at (0, 1e-300) after three null moves; L0 lies exactly
    1.00000046334765e-310 m ahead of it along +y (bearing pi/2 from heading 0), inside
    its prior box. Every interval holds the exact truth, so the log must not be refuted.

    It was, at hull and lp: the offset xL - xP came out [0.0, -0.0] and atan2 read the
    sign of that zero (atan2(0, -0) = pi). The log is also kept in ``data/found``."""
    lines = [
        '{"type": "prior", "pose": 0, "x": [0.0, 0.0], "y": [1e-300, 1e-300], "theta": [0.0, 0.0]}',
        *(
            f'{{"type": "odometry", "from": {i}, "to": {i + 1}, "turn": [0.0, 0.0], '
            '"distance": [0.0, 0.0]}'
            for i in range(3)
        ),
        '{"type": "landmark", "id": "L0", "class": "c", "x": [0.0, -0.0], '
        '"y": [9.999990000999999e-301, 1.0000010001000002e-300]}',
        '{"type": "observation", "pose": 3, "class": "c", '
        '"range": [1.00000046334765e-310, 1.00000046334765e-310], '
        '"bearing": [1.5707963267948966, 1.5707963267948968], "landmark": "L0"}',
    ]
    y0, r = MP.mpf(1e-300), MP.mpf(1.00000046334765e-310)
    assert 9.999990000999999e-301 <= y0 + r <= 1.0000010001000002e-300  # the truth fits
    assert MP.mpf(1.5707963267948966) <= MP.pi / 2 <= MP.mpf(1.5707963267948968)
    solution = solve(parse_log_lines(lines), consistency="hull", time_budget=TEST_BUDGET)
    assert not solution.refuted, solution.messages
