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

import mpmath
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

# hypothesis and mpmath first: importing codac switches the process to rounding upward,
# and hypothesis checks its float constants when imported (run alone, this file failed)
from _exact import MP, angle_inside, mpf
from _exact import TWO_PI as TWO_PI_MP
from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.narrowing.propagation import Status, propagate

pytest.importorskip(
    "codac", reason="codac (pip install codac) is needed for the cross-check baseline"
)
ensure_round_to_nearest()

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.reference.codac_propagation import codac_propagate  # noqa: E402

TWO_PI = 2.0 * math.pi
REL_SLACK = 0.01
"""cuikslam may be this fraction wider than codac (both stop at rtol, not at the exact hull)."""
ABS_SLACK = 1e-9


@dataclass
class World:
    graph: KinematicGraph
    poses: list[tuple[mpmath.mpf, mpmath.mpf, mpmath.mpf]]
    """Exact truth (1300 bits): x, y and an unwrapped heading, the sum of the turns."""
    landmarks: list[tuple[mpmath.mpf, mpmath.mpf]]
    """Exact truth, in the graph's landmark order."""


def _down(v: mpmath.mpf) -> float:
    f = float(v)
    return float(np.nextafter(f, -math.inf)) if mpf(f) > v else f


def _up(v: mpmath.mpf) -> float:
    f = float(v)
    return float(np.nextafter(f, math.inf)) if mpf(f) < v else f


def _noisy(rng: np.random.Generator, value: mpmath.mpf, bound: float) -> tuple[float, float]:
    """A reading of the exact ``value`` off by at most ``bound``, ± bound, rounded outward:
    the interval holds ``value`` exactly."""
    measured = value + mpf(rng.uniform(-bound, bound))
    return _down(measured - mpf(bound)), _up(measured + mpf(bound))


def random_world(
    seed: int, n_poses: int, n_landmarks: int, corrupt: bool = False, relative: bool = False
) -> World:
    """A robot wandering among landmarks, observing those within 8 m (range and bearing).

    With ``corrupt``, one observation's range interval is moved 2 to 4 m off the truth.
    With ``relative``, each move is logged as a relative pose (dx, dy, dtheta) instead of
    a turn and a distance, and half the observations come from a sensor mounted off the
    robot's centre (``offset``).
    """
    rng = np.random.default_rng(seed)
    turn_b, dist_b = rng.uniform(0.002, 0.05), rng.uniform(0.005, 0.1)
    range_b, bearing_b = rng.uniform(0.005, 0.1), rng.uniform(0.002, 0.05)
    x0, y0, t0 = rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-math.pi, math.pi)
    poses = [(mpf(x0), mpf(y0), mpf(t0))]
    turns = rng.uniform(-0.6, 0.6, n_poses)
    steps = rng.uniform(0.5, 2.0, n_poses)
    for i in range(1, n_poses):  # exactly: the truth satisfies every relation, no slack
        x, y, theta = poses[i - 1]
        theta = theta + mpf(turns[i])
        step = mpf(steps[i])
        poses.append((x + step * MP.cos(theta), y + step * MP.sin(theta), theta))
    anchors = rng.integers(0, n_poses, n_landmarks)
    landmarks = [
        (float(poses[a][0]) + rng.uniform(-5.0, 5.0), float(poses[a][1]) + rng.uniform(-5.0, 5.0))
        for a in anchors
    ]
    exact_landmarks = [(mpf(x), mpf(y)) for x, y in landmarks]

    graph = KinematicGraph()
    if rng.random() < 0.5:
        graph.add_pose_prior(0, (x0, x0), (y0, y0), (t0, t0))
    else:
        x, y, t = poses[0]
        graph.add_pose_prior(0, _noisy(rng, x, 0.1), _noisy(rng, y, 0.1), _noisy(rng, t, 0.05))
    observations: list[tuple[int, int]] = []
    for i in range(n_poses):
        if i > 0:
            turn, distance = mpf(turns[i]), mpf(steps[i])
            if relative:
                graph.add_relative_pose(
                    i - 1,
                    i,
                    _noisy(rng, distance * MP.cos(turn), dist_b),
                    _noisy(rng, distance * MP.sin(turn), dist_b),
                    _noisy(rng, turn, turn_b),
                )
            else:
                graph.add_odometry(
                    i - 1, i, _noisy(rng, turn, turn_b), _noisy(rng, distance, dist_b)
                )
        for m in range(n_landmarks):
            x, y, _ = poses[i]
            if MP.hypot(exact_landmarks[m][0] - x, exact_landmarks[m][1] - y) <= 8.0:
                observations.append((i, m))
    bad = int(rng.integers(len(observations))) if corrupt and observations else -1
    for k, (i, m) in enumerate(observations):
        x, y, theta = poses[i]
        offset = None
        if relative and rng.random() < 0.5:
            # a sensor mounted off the centre: (ox, oy) ahead and left, turned by ot
            ox, oy, ot = (mpf(v) for v in rng.uniform([-0.3, -0.3, -0.5], [0.3, 0.3, 0.5]))
            offset = tuple(_noisy(rng, v, 0.01) for v in (ox, oy, ot))
            x = x + ox * MP.cos(theta) - oy * MP.sin(theta)
            y = y + ox * MP.sin(theta) + oy * MP.cos(theta)
            theta = theta + ot
        dx, dy = exact_landmarks[m][0] - x, exact_landmarks[m][1] - y
        rho = MP.hypot(dx, dy)
        bearing = MP.atan2(dy, dx) - theta
        bearing -= TWO_PI_MP * MP.nint(bearing / TWO_PI_MP)
        rng_lo, rng_hi = _noisy(rng, rho, range_b)
        if k == bad:
            shift = rng.uniform(2.0, 4.0)
            shift = -shift if rng_lo > shift + 0.5 and rng.random() < 0.5 else shift
            rng_lo, rng_hi = rng_lo + shift, rng_hi + shift
        graph.add_observation(
            i,
            f"L{m}",
            range=(rng_lo, rng_hi),
            bearing=_noisy(rng, bearing, bearing_b),
            offset=offset,
        )
    observed = [int(name[1:]) for name in graph.landmark_ids]
    return World(graph, poses, [exact_landmarks[m] for m in observed])


def _assert_truth_inside(world: World, lo: np.ndarray, hi: np.ndarray, who: str) -> None:
    """Every box holds the exact truth (headings modulo 2π): no slack."""
    pb = world.graph.pose_boxes(lo, hi)
    lb = world.graph.landmark_boxes(lo, hi)
    for i, (x, y, theta) in enumerate(world.poses):
        for name, v, (low, high) in (("x", x, pb[i, 0]), ("y", y, pb[i, 1])):
            assert mpf(low) <= v <= mpf(high), f"{who}: pose {i} {name} misses the truth"
        assert angle_inside(float(pb[i, 2, 0]), float(pb[i, 2, 1]), theta), (
            f"{who}: pose {i} heading misses the truth"
        )
    for j, xy in enumerate(world.landmarks):
        for name, v, (low, high) in zip("xy", xy, lb[j], strict=True):
            assert mpf(low) <= v <= mpf(high), f"{who}: landmark {j} {name} misses the truth"


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


@SETTINGS
@given(
    seed=st.integers(0, 2**32 - 1),
    n_poses=st.integers(5, 30),
    n_landmarks=st.integers(2, 6),
)
def test_relative_poses_no_wider_than_codac(seed: int, n_poses: int, n_landmarks: int) -> None:
    """The same check on worlds whose moves are relative poses (RELATIVE and ROTATION)."""
    world = random_world(seed, n_poses, n_landmarks, relative=True)
    ours = propagate(world.graph)
    lo_c, hi_c, consistent_c, _ = codac_propagate(world.graph)
    assert consistent_c, "codac proved a world with its truth inside inconsistent"
    assert ours.status is Status.CONSISTENT
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
def test_relative_codac_inconsistency_is_found_by_cuikslam(
    seed: int, n_poses: int, n_landmarks: int
) -> None:
    world = random_world(seed, n_poses, n_landmarks, corrupt=True, relative=True)
    ours = propagate(world.graph)
    _, _, consistent_c, _ = codac_propagate(world.graph)
    if not consistent_c:
        assert ours.status is Status.INCONSISTENT, "codac proved inconsistency, cuikslam did not"
