"""Witnesses of logs with ``relative_pose`` records and sensor offsets.

Random small worlds written here, with their truth exact: poses, landmarks and offsets are
floats, every measured interval is computed from them at 1300 bits and rounded outward
(then widened by a random error), so every interval holds the truth. Relative poses run
forward and backward along the chain (a prior on the source first) and close loops (the
heading shifted by a random 2 pi k); observations are made from the robot, from a point
offset (a laser ahead of the centre) or from an interval offset (a reading between
keyframes), one landmark possibly seen from two offsets of one pose.

Properties: the truth's parameters verify; the witness search finds a verified point; a
log made provably impossible (one interval moved off the truth until the known-correspondence
solve refutes it) never gets a verified point, neither from the search nor at the truth.
The real-data check runs on Lost in the Woods when the recording is there (``CUIKSLAM_DATA``).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, replace
from pathlib import Path

import mpmath
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from _exact import MP, TWO_PI, mpf
from cuikslam.cli.main import main
from cuikslam.datasets import data_dir
from cuikslam.log import read_log_file
from cuikslam.log.records import (
    LandmarkPrior,
    Log,
    Observation,
    PosePrior,
    Record,
    RelativePose,
    SensorModel,
)
from cuikslam.results.solution import PROVEN
from cuikslam.solver import solve
from cuikslam.witness import HypothesisModel, find_witness, verify_witness
from cuikslam.witness.verify import verified_box
from worlds import down, up

MPPose = tuple[mpmath.mpf, mpmath.mpf, mpmath.mpf]


def compose(a: MPPose, b: MPPose) -> MPPose:
    """``a ⊕ b``: the pose ``b`` given in the frame of ``a``, in the world frame (exact)."""
    c, s = MP.cos(a[2]), MP.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def between(a: MPPose, b: MPPose) -> MPPose:
    """The pose ``b`` in the frame of ``a`` (exact)."""
    c, s = MP.cos(a[2]), MP.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return (c * dx + s * dy, -s * dx + c * dy, b[2] - a[2])


def around(rng: random.Random, v: mpmath.mpf, error: float) -> tuple[float, float]:
    """An interval of floats holding ``v``, about ``error`` on each side (asymmetric)."""
    return (
        down(v - mpf(error * rng.uniform(0.3, 1.0))),
        up(v + mpf(error * rng.uniform(0.3, 1.0))),
    )


def float_pose(p: tuple[float, float, float]) -> MPPose:
    return (mpf(p[0]), mpf(p[1]), mpf(p[2]))


@dataclass
class MotionWorld:
    """A random log with its exact truth."""

    log: Log
    assignment: list[str]
    poses: dict[int, tuple[float, float, float]]
    landmarks: dict[str, tuple[float, float]]
    offsets: dict[tuple, tuple[float, float, float]]
    """(pose, offset intervals) -> the true offset."""
    kinds: set[str]


def motion_world(seed: int, n_poses: int = 5, error: float = 0.05) -> MotionWorld:
    """A chain of ``n_poses`` poses joined by relative poses, observed landmarks, closures."""
    rng = random.Random(seed)
    poses = {0: (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-4, 4))}
    for k in range(1, n_poses):
        x, y, t = poses[k - 1]
        step = rng.uniform(0.5, 2.0)
        t2 = t + rng.uniform(-0.8, 0.8)
        poses[k] = (x + step * math.cos(t), y + step * math.sin(t), t2)
    landmarks = {
        f"L{j}": (rng.uniform(-8, 8), rng.uniform(-8, 8)) for j in range(rng.randint(1, 3))
    }
    truth = {k: float_pose(p) for k, p in poses.items()}
    kinds: set[str] = set()
    records: list[Record] = []
    assignment: list[str] = []
    scans: set[tuple] = set()
    offsets: dict[tuple, tuple[float, float, float]] = {}

    def prior(k: int, width: float) -> PosePrior:
        x, y, t = truth[k]
        return PosePrior(k, around(rng, x, width), around(rng, y, width), around(rng, t, width))

    def relative(a: int, b: int, width: float) -> RelativePose:
        d = between(truth[a], truth[b])
        shift = TWO_PI * rng.choice([-1, 0, 0, 1])
        return RelativePose(
            a, b, around(rng, d[0], width), around(rng, d[1], width),
            around(rng, d[2] + shift, width),
        )  # fmt: skip

    def observe(k: int) -> None:
        mount = (0.219, 0.0, 0.0)
        for lid, (lx, ly) in landmarks.items():
            for _ in range(rng.choice([0, 1, 1, 2])):
                kind = rng.choice(["none", "point", "interval"])
                if kind == "none":
                    offset, sensor = None, truth[k]
                elif kind == "point":
                    offset = tuple((v, v) for v in mount)
                    offsets[(k, offset)] = mount
                    sensor = compose(truth[k], float_pose(mount))
                else:
                    o = (rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3), rng.uniform(-0.4, 0.4))
                    offset = tuple(around(rng, mpf(v), 0.02) for v in o)
                    offsets[(k, offset)] = o
                    sensor = compose(truth[k], float_pose(o))
                if (k, offset, lid) in scans:
                    continue  # one scan (pose and offset) sees a landmark once
                scans.add((k, offset, lid))
                dx, dy = mpf(lx) - sensor[0], mpf(ly) - sensor[1]
                bearing = MP.atan2(dy, dx) - sensor[2] + TWO_PI * rng.choice([-1, 0, 1])
                kinds.add(kind)
                records.append(
                    Observation(
                        k,
                        "post",
                        around(rng, MP.sqrt(dx * dx + dy * dy), error),
                        around(rng, bearing, error),
                        lid,
                        offset=offset,
                    )
                )
                assignment.append(lid)

    records.append(prior(0, 0.01))
    observe(0)
    for k in range(1, n_poses):
        if rng.random() < 0.3:  # backward: the record runs from the new pose to the old one
            records.append(prior(k, 1.0))
            records.append(relative(k, k - 1, error))
            kinds.add("backward")
        else:
            records.append(relative(k - 1, k, error))
        observe(k)
        if k >= 2 and rng.random() < 0.5:  # a loop closure between placed poses
            records.append(relative(rng.randrange(k - 1), k, 3 * error))
            kinds.add("closure")
    if rng.random() < 0.3:
        lid, (lx, ly) = next(iter(landmarks.items()))
        records.append(
            LandmarkPrior(lid, "post", around(rng, mpf(lx), 0.5), around(rng, mpf(ly), 0.5))
        )
    return MotionWorld(Log(records=records), assignment, poses, landmarks, offsets, kinds)


def _true_params(world: MotionWorld) -> np.ndarray:
    model = HypothesisModel(world.log, world.assignment)
    assert model.problems == []
    p = model.params_from_world(world.poses, world.landmarks, clip=False)
    for step in model.steps:
        if step.child >= model.n_poses:  # a sensor: its true offset
            i, offset = model.sensor_frames[step.child - model.n_poses]
            p[list(step.params)] = world.offsets[(model.pose_ids[i], offset)]
    return p


def test_the_model_takes_relative_poses_and_offsets() -> None:
    world = motion_world(3, n_poses=6)
    model = HypothesisModel(world.log, world.assignment)
    assert model.problems == []
    n_relative = len(world.log.relative_poses)
    tree = [s for s in model.steps if s.child < model.n_poses]
    assert len(tree) == model.n_poses - 1
    assert len(model.loop_source) == n_relative - len(tree)
    assert model.n_frames - model.n_poses == len(
        {(o.pose, o.offset) for o in world.log.observations if o.offset is not None}
    )


@pytest.mark.parametrize("seed", range(6))
def test_jacobian_matches_finite_differences(seed: int) -> None:
    world = motion_world(seed, n_poses=6)
    model = HypothesisModel(world.log, world.assignment)
    p = _true_params(world) + np.random.default_rng(seed).normal(0, 0.01, model.n_params)
    _, J = model.evaluate(p, jacobian=True)
    assert J is not None
    h = 1e-6
    for k in range(model.n_params):
        e = np.zeros(model.n_params)
        e[k] = h
        fd = (model.evaluate(p + e)[0] - model.evaluate(p - e)[0]) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-4, atol=1e-5, err_msg=model.param_names[k])


def test_the_truth_verifies_and_a_moved_point_does_not() -> None:
    for seed in range(10):
        world = motion_world(seed)
        p = _true_params(world)
        assert verify_witness(world.log, world.assignment, p), seed
        q = p.copy()
        q[-1] += 5.0  # a landmark moved far from its sightings
        assert not verify_witness(world.log, world.assignment, q), seed


_FAST = settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
_MANY = settings(max_examples=1000, deadline=None, suppress_health_check=list(HealthCheck))


def _found(seed: int, n_poses: int) -> None:
    world = motion_world(seed, n_poses)
    assert verify_witness(world.log, world.assignment, _true_params(world))
    point = find_witness(world.log, world.assignment, seed=seed)
    assert point is not None
    assert verify_witness(world.log, world.assignment, point)


@_FAST
@given(seed=st.integers(0, 2**32 - 1), n_poses=st.integers(2, 6))
def test_true_hypotheses_get_a_verified_witness(seed: int, n_poses: int) -> None:
    _found(seed, n_poses)


@pytest.mark.slow
@_MANY
@given(seed=st.integers(0, 2**32 - 1), n_poses=st.integers(2, 10))
def test_true_hypotheses_get_a_verified_witness_many(seed: int, n_poses: int) -> None:
    _found(seed, n_poses)


def test_offsets_with_a_sensor_record_get_no_witness() -> None:
    """The format refuses a sensor record with offsets (its negative information is the
    robot's): a log built in Python with both is never proven."""
    world = motion_world(3)
    assert any(o.offset is not None for o in world.log.observations)
    log = Log(records=[*world.log.records, SensorModel(max_range=100.0)])
    model = HypothesisModel(log, world.assignment)
    assert model.problems == ["observation offsets with a sensor record"]
    assert not verify_witness(log, world.assignment, _true_params(world))


def _moved(world: MotionWorld, rng: random.Random) -> Log:
    """The log with one relative-pose or observation interval moved off the truth."""
    records = list(world.log.records)
    k = rng.choice([i for i, r in enumerate(records) if isinstance(r, (RelativePose, Observation))])
    r = records[k]
    by = rng.choice([-1, 1]) * rng.uniform(0.5, 3.0)

    def shift(b: tuple[float, float], amount: float) -> tuple[float, float]:
        return (b[0] + amount, b[1] + amount)

    if isinstance(r, RelativePose):
        field = rng.choice(["dx", "dy", "dtheta"])
        records[k] = replace(r, **{field: shift(getattr(r, field), by)})
    elif r.range is not None:
        records[k] = replace(r, range=shift(r.range, abs(by)))
    return Log(records=records)


def _never_verified(seed: int, n_poses: int) -> None:
    world = motion_world(seed, n_poses, error=0.02)
    log = _moved(world, random.Random(seed))
    assume(solve(log, work_budget=None).refuted)  # provably impossible
    model = HypothesisModel(log, world.assignment)
    assert verified_box(model, _true_params(world)) is None
    point = find_witness(log, world.assignment, seed=seed)
    assert point is None or not verify_witness(log, world.assignment, point)


@_FAST
@given(seed=st.integers(0, 2**32 - 1), n_poses=st.integers(2, 6))
def test_impossible_hypotheses_never_verify(seed: int, n_poses: int) -> None:
    _never_verified(seed, n_poses)


@pytest.mark.slow
@_MANY
@given(seed=st.integers(0, 2**32 - 1), n_poses=st.integers(2, 10))
def test_impossible_hypotheses_never_verify_many(seed: int, n_poses: int) -> None:
    _never_verified(seed, n_poses)


def test_the_worlds_hold_every_kind() -> None:
    kinds: set[str] = set()
    for seed in range(20):
        kinds |= motion_world(seed).kinds
    assert kinds == {"none", "point", "interval", "backward", "closure"}


# --- real data -------------------------------------------------------------------------


def _recording(*parts: str) -> Path:
    folder = data_dir()
    path = folder.joinpath(*parts) if folder else None
    if path is None or not path.exists():
        pytest.skip(f"{'/'.join(parts)} not found: set CUIKSLAM_DATA to the folder holding it")
    return path


def test_lost_in_the_woods_window_is_proven_consistent(tmp_path: Path) -> None:
    """300 samples of the real run (relative poses, readings from the laser 0.219 m ahead):
    the known correspondence gets a verified witness (about 1 s of search on an idle
    machine, within the solve's default budget; no clock here, so that a loaded machine
    cannot fail the test)."""
    mat = _recording("lost-in-the-woods", "dataset2.mat")
    bounds, out = tmp_path / "bounds.json", tmp_path / "k.jsonl"
    assert main(["calibrate", "lost-in-the-woods", str(mat), "-o", str(bounds)]) == 0
    window = ["--start", "3000", "--steps", "300", "--keyframe-observations", "--known"]
    args = ["import", "lost-in-the-woods", str(mat), "--bounds", str(bounds), *window]
    assert main([*args, "-o", str(out)]) == 0
    log = read_log_file(out)
    assert log.relative_poses and all(o.offset is not None for o in log.observations)
    assert HypothesisModel(log, [str(o.landmark) for o in log.observations]).problems == []
    solution = solve(log, work_budget=None)  # no clock: the search's work limit only
    assert [h.status for h in solution.hypotheses] == [PROVEN]


@pytest.mark.slow
def test_mrclam_window_gets_a_verified_witness(tmp_path: Path) -> None:
    """Robot 1 of MRCLAM 6, 440-500 s (97 poses, beyond the solver's witness cap): the
    witness search on the known correspondence finds a verified point."""
    folder = _recording("mrclam-6")
    bounds, out = tmp_path / "r1.bounds.json", tmp_path / "r1.jsonl"
    common = [str(folder), "--robot", "1"]
    assert main(["calibrate", "mrclam", *common, "--duration", "440", "-o", str(bounds)]) == 0
    window = ["--start", "440", "--duration", "60", "--bounds", str(bounds)]
    assert main(["import", "mrclam", *common, *window, "-o", str(out)]) == 0
    log = read_log_file(out)
    assignment = [str(o.landmark) for o in log.observations]
    best = solve(log).best
    point = find_witness(log, assignment, best.poses, best.landmarks)
    assert point is not None and verify_witness(log, assignment, point)


def test_only_parameters_with_room_are_optimised() -> None:
    """A laser mount written a few ulps wide is held at its midpoint; an offset interval,
    a relative pose and an unbounded landmark coordinate are optimised."""
    mount = ((0.21901626684334177, 0.219016266843342), (-5e-324, 5e-324), (0.0, 0.0))
    wide = ((0.1, 0.2), (-0.01, 0.01), (-0.05, 0.05))
    records: list[Record] = [
        PosePrior(0, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)),
        RelativePose(0, 1, (0.9, 1.1), (-0.1, 0.1), (-0.1, 0.1)),
        Observation(1, "post", (2.0, 2.2), (0.4, 0.6), "P", offset=mount),
        Observation(1, "post", (2.0, 2.3), (0.3, 0.7), "P", offset=wide),
    ]
    model = HypothesisModel(Log(records=records), ["P", "P"])
    free = dict(zip(model.param_names, model.free, strict=True))
    assert [name for name, f in free.items() if not f] == [
        "pose 0 x", "pose 0 y", "pose 0 t", "offset 1 #0 dx", "offset 1 #0 dy",
        "offset 1 #0 dtheta",
    ]  # fmt: skip
    assert free["landmark P x"] and free["dx 0->1"] and free["offset 1 #1 dtheta"]
    point = find_witness(Log(records=records), ["P", "P"])
    assert point is not None and verify_witness(Log(records=records), ["P", "P"], point)
