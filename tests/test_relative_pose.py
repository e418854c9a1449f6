"""The ``relative_pose`` record: reading, writing, and its narrowing against turn-then-drive.

Soundness on random worlds with exact truth is in ``test_factor_soundness.py`` (its worlds
mix odometry and relative poses) and the comparison with codac in
``test_cross_check_codac.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from _exact import MP, mpf
from cuikslam.graph.encoding import RELATIVE
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.log import (
    InputFileError,
    RelativePose,
    parse_log_lines,
    read_log_file,
    write_log_file,
)
from cuikslam.narrowing.polytope import tighten
from cuikslam.narrowing.propagation import Status, propagate
from cuikslam.narrowing.relaxation import relax
from test_consistency import _assert_rows_hold, _inside
from test_factor_soundness import worlds as factor_worlds
from worlds import down, up

PRIOR = '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}'
MOVE = (
    '{"type": "relative_pose", "from": 0, "to": 1, "dx": [1, 1.1], "dy": [-0.1, 0.2],'
    ' "dtheta": [0.1, 0.2]}'
)


def test_round_trip(tmp_path):
    log = parse_log_lines([PRIOR, MOVE])
    (move,) = log.relative_poses
    assert move == RelativePose(0, 1, (1.0, 1.1), (-0.1, 0.2), (0.1, 0.2), line=2)
    assert log.pose_ids == [0, 1]
    path = tmp_path / "rel.jsonl"
    write_log_file(log, path)
    assert read_log_file(path).records == log.records


@pytest.mark.parametrize(
    ("line", "message"),
    [
        (MOVE.replace('"to": 1', '"to": 0'), "relative pose from pose 0 to itself"),
        (MOVE.replace('"from": 0', '"from": 5'), "relative pose from pose 5, which no prior"),
        (MOVE.replace(', "dtheta": [0.1, 0.2]', ""), 'missing field "dtheta"'),
        (MOVE.replace('"dy"', '"dz"'), 'unknown field "dz"'),
        (
            MOVE.replace("[1, 1.1]", "[1.1, 1]"),
            'field "dx" is the interval [1.1, 1.0] with lo > hi',
        ),
    ],
)
def test_bad_records_are_refused(line, message):
    with pytest.raises(InputFileError) as err:
        parse_log_lines([PRIOR, line], path="trip.jsonl")
    assert str(err.value).startswith("trip.jsonl:2: ")
    assert message in str(err.value)


def test_a_pose_reached_by_a_relative_pose_can_be_used():
    later = (
        '{"type": "relative_pose", "from": 1, "to": 2, "dx": [1, 1], "dy": [0, 0],'
        ' "dtheta": [0, 0]}'
    )
    assert parse_log_lines([PRIOR, MOVE, later]).pose_ids == [0, 1, 2]


def _chain(
    prior: tuple[float, float, float], moves: list[tuple[float, float]], relative: bool
) -> np.ndarray:
    """Pose boxes of a chain of exact (turn, distance) moves from a prior box centred at 0,
    logged as odometry or as relative poses (dx, dy rounded outward to a float box)."""
    graph = KinematicGraph()
    wx, wy, wt = prior
    graph.add_pose_prior(0, (-wx, wx), (-wy, wy), (-wt, wt))
    for i, (turn, distance) in enumerate(moves, start=1):
        if relative:
            dx = mpf(distance) * MP.cos(mpf(turn))
            dy = mpf(distance) * MP.sin(mpf(turn))
            dtheta = (turn, turn)
            graph.add_relative_pose(i - 1, i, (down(dx), up(dx)), (down(dy), up(dy)), dtheta)
        else:
            graph.add_odometry(i - 1, i, (turn, turn), (distance, distance))
    result = propagate(graph)
    assert result.status is Status.CONSISTENT
    return graph.pose_boxes(result.lo, result.hi)


@settings(max_examples=60, deadline=None)
@given(
    prior=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(0.0, 0.5)),
    moves=st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(0.1, 5.0)), min_size=1, max_size=8),
)
def test_as_tight_as_turn_then_drive(prior, moves):
    """A relative pose that is a turn then a drive narrows the poses as tightly as the
    odometry factor (up to the outward rounding of its dx, dy and the fixpoint's rtol)."""
    odometry = _chain(prior, moves, relative=False)
    relative = _chain(prior, moves, relative=True)
    w_odo = np.diff(odometry, axis=-1)[..., 0]
    w_rel = np.diff(relative, axis=-1)[..., 0]
    assert np.all(w_rel <= w_odo * 1.01 + 1e-9), (w_rel, w_odo)


def test_heading_recovered_from_two_known_positions():
    """Backward: known positions of both poses fix the heading of the first one."""
    graph = KinematicGraph()
    graph.add_pose_prior(0, (1.0, 1.0), (2.0, 2.0), (-4.0, 4.0))
    graph.add_pose_prior(1, (1.7, 1.7), (3.0, 3.0), (-4.0, 4.0))
    graph.add_relative_pose(0, 1, (0.99, 1.01), (0.69, 0.71), (0.09, 0.11))
    result = propagate(graph)
    assert result.status is Status.CONSISTENT
    t0 = graph.pose_boxes(result.lo, result.hi)[0, 2]
    truth = math.atan2(1.0, 0.7) - math.atan2(0.7, 1.0)
    assert t0[0] <= truth <= t0[1]
    assert t0[1] - t0[0] < 0.05


OFFSET_OBS = (
    '{"type": "observation", "pose": 0, "class": "post", "range": [2.0, 2.1],'
    ' "bearing": [0.1, 0.2], "landmark": "P0", "offset_x": [0.219, 0.219]}'
)


def test_observation_offset_round_trip(tmp_path):
    log = parse_log_lines([PRIOR, OFFSET_OBS])
    (obs,) = log.observations
    assert obs.offset == ((0.219, 0.219), (0.0, 0.0), (0.0, 0.0))
    write_log_file(log, tmp_path / "o.jsonl")
    assert read_log_file(tmp_path / "o.jsonl").records == log.records


@pytest.mark.parametrize("sensor_first", [True, False])
def test_offsets_and_negative_information_are_refused(sensor_first):
    sensor = '{"type": "sensor", "max_range": 8}'
    lines = [PRIOR, sensor, OFFSET_OBS] if sensor_first else [PRIOR, OFFSET_OBS, sensor]
    with pytest.raises(InputFileError, match="observation offsets cannot be combined"):
        parse_log_lines(lines, path="trip.jsonl")


def test_offset_observation_places_the_landmark_from_the_sensor():
    """A laser 0.219 m ahead of an exactly known pose: the landmark box is the sensor's
    range-bearing box around the laser, not around the robot centre."""
    log = parse_log_lines([PRIOR.replace('"theta": [0, 0]', '"theta": [0.5, 0.5]'), OFFSET_OBS])
    graph = KinematicGraph.from_log(log)
    result = propagate(graph)
    assert result.status is Status.CONSISTENT
    (box,) = graph.landmark_boxes(result.lo, result.hi)
    laser = np.array([0.219 * math.cos(0.5), 0.219 * math.sin(0.5)])
    corners = [
        laser + r * np.array([math.cos(0.5 + b), math.sin(0.5 + b)])
        for r in (2.0, 2.1)
        for b in (0.1, 0.2)
    ]
    lo, hi = np.min(corners, axis=0), np.max(corners, axis=0)
    assert np.all(box[:, 0] <= lo) and np.all(hi <= box[:, 1])
    # the hull of the annular sector is within a few mm of its corners' box
    assert np.all(box[:, 0] >= lo - 0.01) and np.all(box[:, 1] <= hi + 0.01)


@settings(max_examples=300, deadline=None)
@given(
    centre=st.floats(-1e3, 1e3),
    heading_width=st.floats(0.0, 7.0),
    u=st.tuples(st.floats(-5.0, 5.0), st.floats(0.0, 1.0)),
    v=st.tuples(st.floats(-5.0, 5.0), st.floats(0.0, 1.0)),
    where=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
)
def test_every_relative_relaxation_row_holds_at_every_point_of_the_box(
    centre, heading_width, u, v, where
):
    """Any point of the box on b - a = R(ta) (u, v) satisfies every row of the LP."""
    row = np.array([[RELATIVE, 0, 1, 2, 3, 4, -1, 5, 6]])
    lo, hi = np.full(7, -100.0), np.full(7, 100.0)
    lo[2], hi[2] = centre - heading_width / 2, centre + heading_width / 2
    lo[5], hi[5] = u[0], u[0] + u[1]
    lo[6], hi[6] = v[0], v[0] + v[1]
    values = np.zeros(7)
    for var, w in zip((2, 5, 6), where, strict=True):
        values[var] = lo[var] + w * (hi[var] - lo[var])
    exact = [mpf(x) for x in values]
    c, s = MP.cos(exact[2]), MP.sin(exact[2])
    exact[3] = exact[0] + exact[5] * c - exact[6] * s
    exact[4] = exact[1] + exact[5] * s + exact[6] * c
    assume(_inside(lo, hi, exact) == [])
    relaxation = relax(row, lo, hi)
    assert relaxation.matrix.shape[1] == 7 + 2  # cos and sin of ta
    _assert_rows_hold(relaxation, exact)


@settings(max_examples=100, deadline=None)
@given(data=st.data())
def test_lp_tightening_keeps_the_truth_of_relative_worlds(data):
    """The worlds of the soundness tests (odometry, relative poses, offset sensors):
    the polytope-hull narrowing after the fixpoint never loses the exact truth."""
    world = data.draw(factor_worlds(max_poses=5, max_landmarks=3))
    result = propagate(world.graph)
    assert result.status is Status.CONSISTENT
    targets = np.arange(world.graph.n_variables)
    tightened = tighten(world.graph.factor_table(), result.lo, result.hi, targets)
    assert tightened.status is Status.CONSISTENT, world.description
    assert world.lost(tightened.lo, tightened.hi) == [], world.description


def test_a_scan_per_sensor_offset_each_sees_distinct_landmarks():
    """Two sensors on one pose make two scans: the search lets both see P0 (one scan
    cannot see a landmark twice), from the sensor's pose, not the robot's centre."""
    from cuikslam.hypotheses import solve_unknown

    front = OFFSET_OBS.replace(', "landmark": "P0"', "")
    back = (
        front.replace('"offset_x": [0.219, 0.219]', '"offset_x": [-0.3, -0.3]')
        .replace('"range": [2.0, 2.1]', '"range": [2.5, 2.7]')
        .replace('"bearing": [0.1, 0.2]', '"bearing": [0.05, 0.2]')
    )  # what the front sensor sees, seen from 0.519 m further back
    log = parse_log_lines([PRIOR, front, front, back], path="o.jsonl")
    solution = solve_unknown(log, consistency="hull")
    assert solution.complete
    # the two front observations are one scan: two landmarks; the back one may be either
    partitions = {tuple(h.assignment) for h in solution.hypotheses}
    assert all(a[0] != a[1] for a in partitions)
    assert any(a[2] in (a[0], a[1]) for a in partitions)
