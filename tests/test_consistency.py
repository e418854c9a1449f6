"""Soundness of every consistency level: random true worlds, random bounded errors, truth inside.

Also checks the linear relaxation itself: the true values of all variables satisfy every
row it builds, and its bounds from the LP never exclude the truth.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cuikslam.graph import KinematicGraph
from cuikslam.graph.encoding import OBSERVATION, ODOMETRY
from cuikslam.narrowing import propagate
from cuikslam.narrowing.consistency import LEVELS
from cuikslam.narrowing.relaxation import relax, tighten
from cuikslam.results.solution import check_truth
from cuikslam.simulate import simulate_paper, simulate_random_world
from cuikslam.solver import solve

worlds = st.fixed_dictionaries(
    {
        "seed": st.integers(0, 2**31 - 1),
        "n_poses": st.integers(3, 25),
        "n_landmarks": st.integers(1, 6),
        "range_only": st.sampled_from([0.0, 0.2]),
        "bearing_only": st.sampled_from([0.0, 0.2]),
    }
)


def _world(spec: dict):
    return simulate_random_world(
        seed=spec["seed"],
        n_poses=spec["n_poses"],
        n_landmarks=spec["n_landmarks"],
        size=(20.0, 15.0),
        range_only_fraction=spec["range_only"],
        bearing_only_fraction=spec["bearing_only"],
    )


@pytest.mark.parametrize("level", LEVELS)
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(spec=worlds)
def test_every_level_keeps_the_truth(level: str, spec: dict) -> None:
    log, truth = _world(spec)
    solution = solve(log, consistency=level, certify_limit=0)
    assert len(solution.hypotheses) == 1, solution.messages
    h = solution.best
    landmark_xy = dict(zip(truth.landmark_ids, truth.landmarks_xy, strict=True))
    report = check_truth(h, truth.pose_ids, truth.poses_xyt, landmark_xy)
    assert report.ok, report.misses[:5]


def _true_values(graph: KinematicGraph, log, truth) -> np.ndarray:
    """The exact value of every graph variable (measurements recomputed from the truth)."""
    values = np.full(graph.n_variables, np.nan)
    for pose, xyt in zip(truth.pose_ids, truth.poses_xyt, strict=True):
        values[graph.pose_index(pose) : graph.pose_index(pose) + 3] = xyt
    for lid, xy in zip(truth.landmark_ids, truth.landmarks_xy, strict=True):
        if lid in graph.landmark_ids:
            values[graph.landmark_index(lid) : graph.landmark_index(lid) + 2] = xy
    table = graph.factor_table()
    for row in table:
        xa, ya, ta, xb, yb, tb, ang, length = (int(v) for v in row[1:])
        dx, dy = values[xb] - values[xa], values[yb] - values[ya]
        values[length] = math.hypot(dx, dy)
        direction = math.atan2(dy, dx)
        if tb >= 0:  # odometry: the turn, and the heading equals the direction of travel
            values[ang] = values[tb] - values[ta]
        else:
            values[ang] = direction - values[ta]
    return values


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(spec=worlds)
def test_relaxation_rows_hold_at_the_truth(spec: dict) -> None:
    spec = {**spec, "range_only": 0.0, "bearing_only": 0.0}
    log, truth = _world(spec)
    graph = KinematicGraph.from_log(log)
    result = propagate(graph)
    values = _true_values(graph, log, truth)
    # put the true angles in the same 2 pi copy as the boxes
    lo, hi = result.lo, result.hi
    for v in range(len(values)):
        if not (lo[v] <= values[v] <= hi[v]):
            k = math.ceil((lo[v] - values[v]) / (2 * math.pi))
            values[v] += 2 * math.pi * k
    inside = (lo <= values) & (values <= hi)
    if not inside.all():
        return  # a non-angle variable, or an angle whose copy is ambiguous: skip this world
    relaxation = relax(graph.factor_table(), lo, hi)
    rows = relaxation.matrix @ relaxation.lift(values)
    slack = 1e-9 * (1 + np.abs(rows))
    assert np.all(relaxation.row_lo - slack <= rows)
    assert np.all(rows <= relaxation.row_hi + slack)
    targets = np.arange(graph.n_variables)
    new_lo, new_hi, feasible = tighten(graph.factor_table(), lo, hi, targets)
    assert feasible
    assert np.all(new_lo <= values + 1e-9) and np.all(values - 1e-9 <= new_hi)


@pytest.mark.parametrize("seed", range(3))
def test_lp_is_much_tighter_than_hull_on_the_paper(seed: int) -> None:
    log, truth = simulate_paper(seed=seed)
    hull = solve(log, consistency="hull", certify_limit=0).best
    lp = solve(log, consistency="lp", certify_limit=0).best
    w_hull = hull.poses[..., 1] - hull.poses[..., 0]
    w_lp = lp.poses[..., 1] - lp.poses[..., 0]
    assert np.all(w_lp <= w_hull + 1e-9)
    assert w_lp[:, :2].max() < 0.5 * w_hull[:, :2].max()
    assert check_truth(lp, truth.pose_ids, truth.poses_xyt).ok


_ODOMETRY_ROW = [ODOMETRY, 0, 1, 2, 3, 4, 5, 6, 7]
_OBSERVATION_ROW = [OBSERVATION, 0, 1, 2, 3, 4, -1, 5, 6]


@settings(max_examples=400, deadline=None)
@given(
    observation=st.booleans(),
    centre=st.floats(-1e4, 1e4),
    widths=st.lists(st.floats(0.0, 7.0), min_size=2, max_size=2),
    length=st.floats(0.0, 50.0),
    length_width=st.floats(0.0, 5.0),
    where=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
)
def test_every_relaxation_row_holds_at_every_point_of_the_box(
    observation: bool,
    centre: float,
    widths: list[float],
    length: float,
    length_width: float,
    where: list[float],
) -> None:
    """Any point of the box that satisfies the factor satisfies every row, lifted or not.

    Wide and far-off angle boxes exercise the Taylor, secant and arc rows where the
    curvature changes sign and where the rounding of large angles matters.
    """
    row = np.array([_OBSERVATION_ROW if observation else _ODOMETRY_ROW])
    n = 7 if observation else 8
    lo, hi = np.full(n, -100.0), np.full(n, 100.0)
    angles = [2, 5] if observation else [5]
    for var, w in zip(angles, widths, strict=False):
        lo[var], hi[var] = centre - w / 2, centre + w / 2
    lo[row[0, 8]], hi[row[0, 8]] = length, length + length_width
    values = np.zeros(n)
    for var, u in zip([*angles, row[0, 8]], where, strict=False):
        values[var] = lo[var] + u * (hi[var] - lo[var])
    phi = values[angles].sum()
    ell = values[row[0, 8]]
    values[3], values[4] = values[0] + ell * math.cos(phi), values[1] + ell * math.sin(phi)
    if not ((lo <= values) & (values <= hi)).all():
        return
    relaxation = relax(row, lo, hi)
    point = relaxation.lift(values)
    assert relaxation.matrix.shape[1] == n + 2
    rows = relaxation.matrix @ point
    slack = 1e-9 * (1.0 + abs(relaxation.matrix) @ np.abs(point))
    assert np.all(relaxation.row_lo - slack <= rows)
    assert np.all(rows <= relaxation.row_hi + slack)
    assert np.all(relaxation.col_lo <= point) and np.all(point <= relaxation.col_hi)


def test_lp_reports_progress_window_by_window() -> None:
    """A long lp solve tells the progress bar how far it is, ending at done == total."""
    log, _ = _world({"seed": 3, "n_poses": 25, "n_landmarks": 4, "range_only": 0.0,
                     "bearing_only": 0.0})  # fmt: skip
    calls: list[tuple[int, int]] = []
    solve(log, consistency="lp", certify_limit=0, progress=lambda d, t: calls.append((d, t)))
    assert len(calls) > 3, "no progress while the LP rounds ran"
    done = [d / t for d, t in calls]
    assert done == sorted(done)
    assert calls[-1][0] == calls[-1][1]
