"""The simulators: their logs must contain the truth they return, and match the paper."""

from __future__ import annotations

import inspect
import json
import math
from dataclasses import fields, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _exact import angle_inside, mpf
from cuikslam.errors import InputFileError
from cuikslam.log.reader import parse_log_lines
from cuikslam.log.records import Bounds, Log
from cuikslam.log.writer import log_to_lines
from cuikslam.simulate import (
    GroundTruth,
    WorldSpec,
    paper,
    paper_survivors,
    paper_table1,
    read_truth_file,
    simulate_paper,
    simulate_random_world,
    write_truth_file,
)

# The checks below recompute the true values along another floating-point path than the
# simulators, so they may differ from the simulated ones in the last bits.
TOL = 1e-9

DIAGONAL_RANGE = math.sqrt(325 - 150 * math.sqrt(2))
"""From a diagonal pose, e.g. pose 2 at (15 + 5√2, 15 − 5√2), to L1 (15, 0) or L2 (30, 15)."""


def wrapped(angle: float) -> float:
    """``angle`` in (−π, π]."""
    a = math.remainder(angle, 2 * math.pi)
    return math.pi if a == -math.pi else a


def contains(bounds: Bounds, value: float) -> bool:
    lo, hi = bounds
    return lo <= hi and lo - TOL <= value <= hi + TOL


def contains_angle(bounds: Bounds, angle: float) -> bool:
    """Whether ``angle + 2πk`` lies in ``bounds`` (widened by TOL) for some integer ``k``."""
    lo, hi = bounds
    return lo <= hi and angle_inside(lo - TOL, hi + TOL, mpf(angle))


def assert_log_contains_truth(log: Log, truth: GroundTruth) -> None:
    """Every measured interval of ``log`` contains the value recomputed from ``truth``."""
    prior = log.priors[0]
    x, y, t = truth.pose_xyt(prior.pose)
    assert prior.x == (x, x) and prior.y == (y, y) and prior.theta == (t, t)
    assert len(truth.assignment) == len(log.observations)
    for record in log.odometry:
        x0, y0, t0 = truth.pose_xyt(record.source)
        x1, y1, t1 = truth.pose_xyt(record.target)
        distance = math.hypot(x1 - x0, y1 - y0)
        assert contains_angle(record.turn, wrapped(t1 - t0)), record
        assert contains(record.distance, distance), record
        # Turn then drive: the drive goes along the new heading.
        assert x1 - x0 == pytest.approx(distance * math.cos(t1), abs=TOL)
        assert y1 - y0 == pytest.approx(distance * math.sin(t1), abs=TOL)
    for record, landmark in zip(log.observations, truth.assignment, strict=True):
        x, y, t = truth.pose_xyt(record.pose)
        lx, ly = truth.landmark_xy(landmark)
        assert record.landmark in (None, landmark)
        assert record.landmark_class == truth.landmark_class(landmark)
        assert record.range is not None or record.bearing is not None
        if record.range is not None:
            assert contains(record.range, math.hypot(lx - x, ly - y)), record
        if record.bearing is not None:
            assert contains_angle(record.bearing, wrapped(math.atan2(ly - y, lx - x) - t)), record


def test_contains_angle_works_modulo_two_pi() -> None:
    assert contains_angle((3.0, 3.5), -math.pi + 0.1)
    assert contains_angle((-7.0, -6.0), 0.0)
    assert not contains_angle((0.1, 0.2), 0.3)


# --- the paper's experiment --------------------------------------------------------------


@pytest.mark.parametrize("seed", range(40))
@pytest.mark.parametrize("unknown", [False, True])
def test_paper_log_contains_truth(seed: int, unknown: bool) -> None:
    log, truth = simulate_paper(seed, unknown=unknown)
    assert_log_contains_truth(log, truth)
    back = parse_log_lines(log_to_lines(log))
    assert [replace(r, line=0) for r in back.records] == log.records


def test_paper_geometry() -> None:
    log, truth = simulate_paper()
    assert truth.pose_ids == list(range(1, 10)) == log.pose_ids
    np.testing.assert_array_equal(truth.pose_xyt(9)[:2], truth.pose_xyt(1)[:2])
    np.testing.assert_array_equal(truth.pose_xyt(1), [15.0, 5.0, -math.pi / 8])
    radii = np.hypot(*(truth.poses_xyt[:, :2] - paper.CENTRE_XY).T)
    np.testing.assert_allclose(radii, paper.RADIUS)
    assert truth.pose_xyt(9)[2] == pytest.approx(-math.pi / 8 + 2 * math.pi)
    assert np.all((truth.poses_xyt[:, :2] > 0) & (truth.poses_xyt[:, :2] < paper.ROOM_SIZE))
    chord = 2 * paper.RADIUS * math.sin(math.pi / 8)
    for record in log.odometry:
        assert record.target == record.source + 1
        assert record.turn[0] < math.pi / 4 < record.turn[1]
        assert record.distance[0] < chord < record.distance[1]
    prior = log.priors[0]
    assert (prior.pose, prior.x, prior.y) == (1, (15.0, 15.0), (5.0, 5.0))
    assert prior.theta == (-math.pi / 8, -math.pi / 8)


def test_paper_sightings() -> None:
    log, truth = simulate_paper()
    seen: dict[int, list[str]] = {}
    for record in log.observations:
        seen.setdefault(record.pose, []).append(record.landmark)
    assert seen == {
        1: ["L1"],
        2: ["L1", "L2"],
        3: ["L2"],
        4: ["L2", "L3"],
        5: ["L3"],
        6: ["L3", "L4"],
        7: ["L4"],
        8: ["L1", "L4"],
        9: ["L1"],
    }
    assert truth.assignment == [record.landmark for record in log.observations]
    for record in log.observations:
        expected = 5.0 if record.pose % 2 else DIAGONAL_RANGE
        assert record.range[0] < expected < record.range[1]


def test_paper_diagonal_poses_see_exact_ties() -> None:
    truth = simulate_paper()[1]
    for pose in (2, 4, 6, 8):
        distances = np.hypot(*(truth.landmarks_xy - truth.pose_xyt(pose)[:2]).T)
        near = np.sort(distances)[:2]
        assert near[1] - near[0] < 1e-9
        assert near[0] == pytest.approx(DIAGONAL_RANGE)


def test_paper_bounds() -> None:
    log = simulate_paper(3)[0]
    for record in log.odometry:
        assert record.turn[1] - record.turn[0] == pytest.approx(2 * math.radians(5))
        assert record.distance[1] - record.distance[0] == pytest.approx(0.5)
    for record in log.observations:
        assert record.range[1] - record.range[0] == pytest.approx(0.05)
        assert record.bearing[1] - record.bearing[0] == pytest.approx(2 * math.radians(0.5))


def test_paper_unknown_drops_ids_keeps_classes_and_measurements() -> None:
    known, truth = simulate_paper(7)
    unknown, truth_unknown = simulate_paper(7, unknown=True)
    assert unknown.has_unknown_correspondence and not known.has_unknown_correspondence
    assert truth_unknown.assignment == truth.assignment
    for a, b in zip(known.observations, unknown.observations, strict=True):
        assert b.landmark is None
        assert (a.pose, a.landmark_class, a.range, a.bearing) == (
            b.pose,
            b.landmark_class,
            b.range,
            b.bearing,
        )
    assert known.odometry == unknown.odometry


def test_paper_seed_decides_errors() -> None:
    assert simulate_paper(1)[0].records == simulate_paper(1)[0].records
    assert simulate_paper(1)[0].records != simulate_paper(2)[0].records


def test_paper_table1_loads() -> None:
    rows = paper_table1()
    assert len(rows) == 13
    assert [r[0] for r in rows] == [f"r {k}" for k in range(1, 10)] + [
        f"l {k}" for k in range(1, 5)
    ]
    for description, x, y, theta in rows:
        assert x[0] <= x[1] and y[0] <= y[1]
        assert (theta is None) == description.startswith("l")
        if theta is not None:
            assert theta[0] <= theta[1]
    assert rows[0][3] == (1.963495, 1.963496)
    assert rows[-1][1] == (-6.799463, 11.729289)


def test_paper_table1_boxes_contain_our_truth_positions() -> None:
    truth = simulate_paper()[1]
    ids = [f"r {k}" for k in truth.pose_ids] + [f"l {k[1:]}" for k in truth.landmark_ids]
    xy = np.vstack((truth.poses_xyt[:, :2], truth.landmarks_xy))
    for (description, x, y, _), (px, py), name in zip(paper_table1(), xy, ids, strict=True):
        assert description == name
        assert x[0] - 1e-6 <= px <= x[1] + 1e-6 and y[0] - 1e-6 <= py <= y[1] + 1e-6, name
    # The paper's θ is clockwise from +y and unwrapped: θ_paper = π/2 − θ_ours.
    for (_, _, _, theta), (_, _, t) in zip(paper_table1(), truth.poses_xyt, strict=False):
        assert theta[0] - 1e-6 <= math.pi / 2 - t <= theta[1] + 1e-6


def test_paper_survivors() -> None:
    facts = paper_survivors()
    assert facts["hypotheses"] == 5
    assert facts["distinct_up_to_labels"] == facts["hypotheses"] - facts["label_swapped_pairs"]


# --- random worlds ------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_poses=st.integers(1, 40),
    n_landmarks=st.integers(1, 15),
    max_range=st.floats(0.5, 20.0),
    fov=st.floats(0.1, 2 * math.pi),
    loop=st.booleans(),
    unknown=st.booleans(),
)
def test_random_world_log_contains_truth(
    seed: int,
    n_poses: int,
    n_landmarks: int,
    max_range: float,
    fov: float,
    loop: bool,
    unknown: bool,
) -> None:
    log, truth = simulate_random_world(
        seed,
        n_poses=n_poses,
        n_landmarks=n_landmarks,
        max_range=max_range,
        fov=fov,
        loop=loop,
        unknown=unknown,
    )
    assert_log_contains_truth(log, truth)
    assert log.observations, "every log has an observation"
    assert truth.pose_ids == list(range(n_poses))
    assert truth.landmark_ids == [f"L{j}" for j in range(n_landmarks)]
    assert all(o.landmark is None for o in log.observations) == unknown
    size = np.array([40.0, 30.0])
    assert np.all((truth.poses_xyt[:, :2] > 0) & (truth.poses_xyt[:, :2] < size))
    assert np.all((truth.landmarks_xy >= 0) & (truth.landmarks_xy <= size))
    for record, landmark in zip(log.observations, truth.assignment, strict=True):
        x, y, t = truth.pose_xyt(record.pose)
        lx, ly = truth.landmark_xy(landmark)
        assert math.hypot(lx - x, ly - y) <= max_range
        assert abs(wrapped(math.atan2(ly - y, lx - x) - t)) <= fov / 2 + TOL
    parse_log_lines(log_to_lines(log))


@pytest.mark.parametrize("seed", range(20))
def test_random_world_defaults(seed: int) -> None:
    log, truth = simulate_random_world(seed)
    assert_log_contains_truth(log, truth)
    assert len(log.odometry) == 49
    assert truth.landmark_classes == ["door", "corridor", "post"] * 3 + ["door"]
    for record in log.odometry:
        assert record.turn[1] - record.turn[0] == pytest.approx(0.1)
        assert record.distance[1] - record.distance[0] == pytest.approx(0.2)
    # The default loop comes back near its start, so early landmarks are seen again.
    assert np.hypot(*(truth.poses_xyt[-1, :2] - truth.poses_xyt[0, :2])) < 2.0
    seen: dict[int, set[str]] = {0: set(), 49: set()}
    for record, landmark in zip(log.observations, truth.assignment, strict=True):
        seen.setdefault(record.pose, set()).add(landmark)
    assert seen[0] & seen[49] or not seen[0]


@pytest.mark.parametrize("seed", range(20))
def test_random_world_range_and_bearing_only(seed: int) -> None:
    log, truth = simulate_random_world(seed, range_only_fraction=0.3, bearing_only_fraction=0.2)
    assert_log_contains_truth(log, truth)
    n = len(log.observations)
    range_only = sum(o.bearing is None for o in log.observations)
    bearing_only = sum(o.range is None for o in log.observations)
    assert (range_only, bearing_only) == (round(0.3 * n), round(0.2 * n))


def test_random_world_is_deterministic_and_seeded() -> None:
    a, truth_a = simulate_random_world(5)
    b, truth_b = simulate_random_world(5)
    assert a.records == b.records
    np.testing.assert_array_equal(truth_a.poses_xyt, truth_b.poses_xyt)
    assert simulate_random_world(6)[0].records != a.records


def test_random_world_forces_an_observation() -> None:
    for seed in range(10):
        log, truth = simulate_random_world(seed, n_poses=2, n_landmarks=1, max_range=0.3)
        assert log.observations
        assert_log_contains_truth(log, truth)


def test_random_world_defaults_match_world_spec() -> None:
    parameters = inspect.signature(simulate_random_world).parameters
    for field in fields(WorldSpec):
        assert parameters[field.name].default == field.default, field.name
    assert set(parameters) == {"seed"} | {field.name for field in fields(WorldSpec)}


@pytest.mark.parametrize(
    "change",
    [
        {"n_poses": 0},
        {"n_landmarks": 0},
        {"classes": ()},
        {"fov": 0.0},
        {"max_range": -1.0},
        {"step_length": (2.0, 1.0)},
        {"range_only_fraction": 0.7, "bearing_only_fraction": 0.6},
    ],
)
def test_world_spec_rejects_nonsense(change: dict) -> None:
    with pytest.raises(ValueError, match="WorldSpec"):
        WorldSpec(**change)


# --- truth files --------------------------------------------------------------------------


@pytest.mark.parametrize("make", [lambda: simulate_paper(2), lambda: simulate_random_world(2)])
def test_truth_round_trip(tmp_path, make) -> None:
    truth = make()[1]
    path = tmp_path / "truth.json"
    write_truth_file(truth, path)
    back = read_truth_file(path)
    np.testing.assert_array_equal(back.poses_xyt, truth.poses_xyt)
    np.testing.assert_array_equal(back.landmarks_xy, truth.landmarks_xy)
    assert back.pose_ids == truth.pose_ids
    assert back.landmark_ids == truth.landmark_ids
    assert back.landmark_classes == truth.landmark_classes
    assert back.assignment == truth.assignment
    doc = json.loads(path.read_text())
    assert set(doc) == {"poses", "landmarks", "assignment"}
    assert doc["poses"][str(truth.pose_ids[0])] == list(truth.poses_xyt[0])
    first = truth.landmark_ids[0]
    assert doc["landmarks"][first]["class"] == truth.landmark_classes[0]


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("{", "not valid JSON"),
        ("[]", "JSON object"),
        ('{"poses": {}, "landmarks": {}}', "assignment"),
        ('{"poses": {"a": [0, 0, 0]}, "landmarks": {}, "assignment": []}', "not an integer"),
        ('{"poses": {"1": [0, 0]}, "landmarks": {}, "assignment": []}', "x, y, theta"),
        ('{"poses": {"1": [0, 0, "x"]}, "landmarks": {}, "assignment": []}', "finite"),
        ('{"poses": {"1": [0, 0, true]}, "landmarks": {}, "assignment": []}', "finite"),
        ('{"poses": {"1": [0,0,0], "01": [0,0,0]}, "landmarks": {}, "assignment": []}', "twice"),
        ('{"poses": {}, "landmarks": {"L0": {"x": 1, "y": 2}}, "assignment": []}', "class"),
        (
            '{"poses": {}, "landmarks": {"L0": {"class": 3, "x": 1, "y": 2}}, "assignment": []}',
            "class",
        ),
        ('{"poses": {}, "landmarks": {}, "assignment": ["L9"]}', "not a landmark id"),
        ('{"poses": {}, "landmarks": {}, "assignment": [[1]]}', "not a landmark id"),
    ],
)
def test_malformed_truth_file(tmp_path, text: str, problem: str) -> None:
    path = tmp_path / "truth.json"
    path.write_text(text)
    with pytest.raises(InputFileError, match=problem) as caught:
        read_truth_file(path)
    assert caught.value.path == str(path)


def test_missing_truth_file(tmp_path) -> None:
    with pytest.raises(InputFileError, match="cannot read"):
        read_truth_file(tmp_path / "absent.json")
