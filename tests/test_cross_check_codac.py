"""Cross-check of cuikslam's propagation against the same chaotic iteration with codac.

On random small worlds (known correspondence, every measured interval containing the
truth), cuikslam's fixpoint boxes must be no wider than those of the codac baseline
(``tests/reference/codac_propagation.py``, one ``CtcPolar`` per factor application), both
must contain the truth, and both must find the worlds consistent. On worlds with one
measurement moved far off, codac's proof of inconsistency must be matched by cuikslam.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip(
    "codac", reason="codac (pip install codac) is needed for the cross-check baseline"
)

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.narrowing.propagation import Status, propagate

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.reference.codac_propagation import codac_propagate  # noqa: E402

TWO_PI = 2.0 * math.pi
REL_SLACK = 0.01
"""cuikslam may be this fraction wider than codac (both stop at rtol, not at the exact hull)."""
ABS_SLACK = 1e-9
TRUTH_SLACK = 1e-9
"""The float truth satisfies the relations up to rounding."""


@dataclass
class World:
    graph: KinematicGraph
    poses: np.ndarray
    """Truth (n_poses, 3): x, y and an unwrapped heading consistent with the turns."""
    landmarks: np.ndarray
    """Truth (n_observed_landmarks, 2), in the graph's landmark order."""


def _noisy(rng: np.random.Generator, value: float, bound: float) -> tuple[float, float]:
    measured = value + rng.uniform(-bound, bound)
    return measured - bound, measured + bound


def random_world(seed: int, n_poses: int, n_landmarks: int, corrupt: bool = False) -> World:
    """A robot wandering among landmarks, observing those within 8 m (range and bearing).

    With ``corrupt``, one observation's range interval is moved 2 to 4 m off the truth.
    """
    rng = np.random.default_rng(seed)
    turn_b, dist_b = rng.uniform(0.002, 0.05), rng.uniform(0.005, 0.1)
    range_b, bearing_b = rng.uniform(0.005, 0.1), rng.uniform(0.002, 0.05)
    poses = np.zeros((n_poses, 3))
    poses[0] = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-math.pi, math.pi))
    turns = rng.uniform(-0.6, 0.6, n_poses)
    steps = rng.uniform(0.5, 2.0, n_poses)
    for i in range(1, n_poses):
        theta = poses[i - 1, 2] + turns[i]
        poses[i] = (
            poses[i - 1, 0] + steps[i] * math.cos(theta),
            poses[i - 1, 1] + steps[i] * math.sin(theta),
            theta,
        )
    anchors = poses[rng.integers(0, n_poses, n_landmarks), :2]
    landmarks = anchors + rng.uniform(-5.0, 5.0, (n_landmarks, 2))

    graph = KinematicGraph()
    x0, y0, t0 = (float(v) for v in poses[0])
    if rng.random() < 0.5:
        graph.add_pose_prior(0, (x0, x0), (y0, y0), (t0, t0))
    else:
        graph.add_pose_prior(0, _noisy(rng, x0, 0.1), _noisy(rng, y0, 0.1), _noisy(rng, t0, 0.05))
    observations: list[tuple[int, int]] = []
    for i in range(n_poses):
        if i > 0:
            turn = float(poses[i, 2] - poses[i - 1, 2])
            distance = float(math.hypot(*(poses[i, :2] - poses[i - 1, :2])))
            graph.add_odometry(i - 1, i, _noisy(rng, turn, turn_b), _noisy(rng, distance, dist_b))
        for m in range(n_landmarks):
            dx, dy = landmarks[m] - poses[i, :2]
            if math.hypot(dx, dy) <= 8.0:
                observations.append((i, m))
    bad = int(rng.integers(len(observations))) if corrupt and observations else -1
    for k, (i, m) in enumerate(observations):
        dx, dy = landmarks[m] - poses[i, :2]
        rho = math.hypot(dx, dy)
        bearing = math.remainder(math.atan2(dy, dx) - poses[i, 2], TWO_PI)
        rng_lo, rng_hi = _noisy(rng, rho, range_b)
        if k == bad:
            shift = rng.uniform(2.0, 4.0)
            shift = -shift if rng_lo > shift + 0.5 and rng.random() < 0.5 else shift
            rng_lo, rng_hi = rng_lo + shift, rng_hi + shift
        graph.add_observation(
            i, f"L{m}", range=(rng_lo, rng_hi), bearing=_noisy(rng, bearing, bearing_b)
        )
    observed = [int(name[1:]) for name in graph.landmark_ids]
    return World(graph, poses, landmarks[observed])


def _angle_inside(lo: np.ndarray, hi: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Whether angle + 2 pi k lies in [lo, hi] for some k (cuikslam's headings are periodic)."""
    with np.errstate(invalid="ignore"):
        shifted = lo + np.mod(angle - lo, TWO_PI)
        return (
            (hi - lo >= TWO_PI)
            | (shifted <= hi + TRUTH_SLACK)
            | (shifted - TWO_PI >= lo - TRUTH_SLACK)
        )


def _assert_truth_inside(world: World, lo: np.ndarray, hi: np.ndarray, who: str) -> None:
    pb = world.graph.pose_boxes(lo, hi)
    lb = world.graph.landmark_boxes(lo, hi)
    xy = world.poses[:, :2]
    assert np.all(pb[:, :2, 0] <= xy + TRUTH_SLACK), f"{who}: a pose x/y box misses the truth"
    assert np.all(xy - TRUTH_SLACK <= pb[:, :2, 1]), f"{who}: a pose x/y box misses the truth"
    heading_ok = _angle_inside(pb[:, 2, 0], pb[:, 2, 1], world.poses[:, 2])
    assert np.all(heading_ok), (
        f"{who}: heading boxes miss the truth at {np.flatnonzero(~heading_ok)}"
    )
    assert np.all(lb[..., 0] <= world.landmarks + TRUTH_SLACK), f"{who}: a landmark box misses"
    assert np.all(world.landmarks - TRUTH_SLACK <= lb[..., 1]), f"{who}: a landmark box misses"


def _widths(world: World, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Widths of every pose and landmark coordinate; headings capped at 2 pi (any angle)."""
    pw = np.diff(world.graph.pose_boxes(lo, hi), axis=-1)[..., 0]
    pw[:, 2] = np.minimum(pw[:, 2], TWO_PI)
    lw = np.diff(world.graph.landmark_boxes(lo, hi), axis=-1)[..., 0]
    return np.concatenate([pw.ravel(), lw.ravel()])


SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(
    seed=st.integers(0, 2**32 - 1),
    n_poses=st.integers(5, 30),
    n_landmarks=st.integers(2, 6),
)
def test_cuikslam_no_wider_than_codac(seed: int, n_poses: int, n_landmarks: int) -> None:
    world = random_world(seed, n_poses, n_landmarks)
    ours = propagate(world.graph)
    lo_c, hi_c, consistent_c, _ = codac_propagate(world.graph)

    assert consistent_c, "codac proved a world with its truth inside inconsistent"
    assert ours.status is Status.CONSISTENT, (
        "cuikslam proved a world with its truth inside inconsistent"
    )
    _assert_truth_inside(world, lo_c, hi_c, "codac")
    _assert_truth_inside(world, ours.lo, ours.hi, "cuikslam")

    w_ours = _widths(world, ours.lo, ours.hi)
    w_codac = _widths(world, lo_c, hi_c)
    wider = ~(w_ours <= w_codac * (1.0 + REL_SLACK) + ABS_SLACK)
    assert not wider.any(), (
        f"cuikslam wider than codac at coordinates {np.flatnonzero(wider)}: "
        f"{w_ours[wider]} vs {w_codac[wider]}"
    )


@SETTINGS
@given(
    seed=st.integers(0, 2**32 - 1),
    n_poses=st.integers(5, 30),
    n_landmarks=st.integers(2, 6),
)
def test_codac_inconsistency_is_found_by_cuikslam(
    seed: int, n_poses: int, n_landmarks: int
) -> None:
    world = random_world(seed, n_poses, n_landmarks, corrupt=True)
    ours = propagate(world.graph)
    _, _, consistent_c, _ = codac_propagate(world.graph)
    if not consistent_c:
        assert ours.status is Status.INCONSISTENT, "codac proved inconsistency, cuikslam did not"
