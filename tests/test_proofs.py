"""Proofs of inconsistency: contradictory logs are refuted, consistent ones never are.

A refutation (``Status.INCONSISTENT``) is a proof that no world fits the measurements,
so it must come exactly when the measurements contradict each other: an odometry loop
that cannot close onto a re-observed landmark, a pose prior that the odometry cannot
reach. Angles only matter modulo 2π: a heading prior given as the truth plus 2π is the
same prior and must not be refuted.
"""

from __future__ import annotations

import math

import pytest

from _exact import angle_inside, mpf
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.narrowing.propagation import Status, propagate

PI = math.pi
TWO_PI = 2 * math.pi
E_RANGE = 0.05
E_ANGLE = 0.05
E_TURN = 0.01
E_DIST = 0.1


def around(value: float, error: float) -> tuple[float, float]:
    return value - error, value + error


def corridor(
    second_range: float | None,
    second_bearing: float | None,
    first_range: float | None = 1.0,
    first_bearing: float | None = -PI / 2,
    theta0: tuple[float, float] = (0.0, 0.0),
    turn: tuple[float, float] = around(0.0, E_TURN),
    landmark_again: str = "L",
) -> KinematicGraph:
    """Pose 0 at the origin facing +x sees L; the robot drives 20 m straight; pose 1 sees
    ``landmark_again`` (by default "the same" L) at the given range and bearing."""
    g = KinematicGraph()
    g.add_pose_prior(0, (0.0, 0.0), (0.0, 0.0), theta0)
    g.add_observation(
        0,
        "L",
        range=None if first_range is None else around(first_range, E_RANGE),
        bearing=None if first_bearing is None else around(first_bearing, E_ANGLE),
    )
    g.add_odometry(0, 1, turn, around(20.0, E_DIST))
    g.add_observation(
        1,
        landmark_again,
        range=None if second_range is None else around(second_range, E_RANGE),
        bearing=None if second_bearing is None else around(second_bearing, E_ANGLE),
    )
    return g


# The truth of the consistent corridor: L = (0, -1), pose 1 = (20, 0, 0).
BACK_RANGE = math.hypot(20.0, 1.0)
BACK_BEARING = math.atan2(-1.0, -20.0)  # ≈ -π + 0.05


def test_loop_that_cannot_close_is_refuted():
    """L at 1 m on the right, 20 m straight ahead, "the same" L at 1 m on the right again."""
    result = propagate(corridor(1.0, -PI / 2))
    assert result.status is Status.INCONSISTENT
    assert result.is_empty


@pytest.mark.parametrize(
    ("second_range", "second_bearing", "first_range", "first_bearing"),
    [
        (1.0, None, 1.0, None),  # range-only: both within 1.05 m of L, 19.9 m apart
        (1.0, -PI / 2, 1.0, None),
        (None, -PI / 2, 1.0, -PI / 2),  # bearing-only second sighting: L would be at x ≈ 20
        (1.0, PI / 2, 1.0, -PI / 2),  # on the left the second time
        (1.0, -PI / 2 + TWO_PI, 1.0, -PI / 2 - TWO_PI),  # unwrapped: the same contradiction
    ],
)
def test_other_contradictory_sightings_are_refuted(
    second_range, second_bearing, first_range, first_bearing
):
    g = corridor(second_range, second_bearing, first_range, first_bearing)
    assert propagate(g).status is Status.INCONSISTENT


@pytest.mark.parametrize(
    ("second_range", "second_bearing", "landmark_again"),
    [
        (BACK_RANGE, BACK_BEARING, "L"),  # the true sighting of L from pose 1
        (BACK_RANGE, BACK_BEARING + TWO_PI, "L"),  # its bearing unwrapped
        (BACK_RANGE, BACK_BEARING - 3 * TWO_PI, "L"),
        (BACK_RANGE, None, "L"),  # range-only
        (None, BACK_BEARING, "L"),  # bearing-only
        (1.0, -PI / 2, "L2"),  # the contradictory sighting, of another landmark
    ],
)
def test_consistent_version_of_the_loop_is_not_refuted(
    second_range, second_bearing, landmark_again
):
    g = corridor(second_range, second_bearing, landmark_again=landmark_again)
    result = propagate(g)
    assert result.status is Status.CONSISTENT
    # and the truth is inside: L = (0, -1), pose 1 = (20, 0, heading ≡ 0)
    lm = g.landmark_index("L")
    assert result.lo[lm] <= 0.0 <= result.hi[lm]
    assert result.lo[lm + 1] <= -1.0 <= result.hi[lm + 1]
    p1 = g.pose_index(1)
    assert result.lo[p1] <= 20.0 <= result.hi[p1]
    assert result.lo[p1 + 1] <= 0.0 <= result.hi[p1 + 1]
    assert contains_angle(result.lo[p1 + 2], result.hi[p1 + 2], 0.0)
    # the loop closure made the landmark's box small
    assert result.hi[lm + 1] - result.lo[lm + 1] < 1.0


def test_bearing_only_parallel_sightings_are_consistent():
    """Both sightings straight to the right, with ±0.05 rad: the rays meet ~200 m away."""
    g = corridor(None, -PI / 2, first_range=None, first_bearing=-PI / 2)
    result = propagate(g)
    assert result.status is Status.CONSISTENT
    lm = g.landmark_index("L")
    assert result.lo[lm + 1] <= -150.0  # far away, on the right


# ---------------------------------------------------------------- priors on a second pose


def two_poses(prior_x: tuple[float, float], prior_theta=(-PI, PI)) -> KinematicGraph:
    g = KinematicGraph()
    g.add_pose_prior(0, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    g.add_odometry(0, 1, around(0.0, E_TURN), around(20.0, E_DIST))
    g.add_pose_prior(1, prior_x, (-1.0, 1.0), prior_theta)
    return g


def test_prior_that_contradicts_the_odometry_is_refuted():
    assert propagate(two_poses((10.0, 11.0))).status is Status.INCONSISTENT
    assert propagate(two_poses((20.2, 25.0))).status is Status.INCONSISTENT
    # heading: the odometry says ≈ 0, the prior says ≈ π/2 (mod 2π)
    g = two_poses((19.0, 21.0), prior_theta=around(PI / 2 + TWO_PI, 0.1))
    assert propagate(g).status is Status.INCONSISTENT


def test_prior_that_agrees_with_the_odometry_is_not_refuted():
    result = propagate(two_poses((19.0, 21.0)))
    assert result.status is Status.CONSISTENT
    assert propagate(two_poses((19.95, 20.05))).status is Status.CONSISTENT


# ---------------------------------------------------------------- periodicity


def contains_angle(lo: float, hi: float, angle: float) -> bool:
    """``angle`` modulo 2π in [lo, hi + 1e-12]: the slack covers the priors given as float
    multiples of 2π, which differ from exact whole turns by up to 1e-12 (1000 turns)."""
    return angle_inside(lo, hi + 1e-12, mpf(angle))


@pytest.mark.parametrize("turns", [1, -1, 2, 1000])
def test_heading_prior_shifted_by_whole_turns_is_not_refuted(turns):
    """θ0 = 0 + 2πk is the same heading: the consistent corridor stays consistent."""
    shift = turns * TWO_PI
    for theta0 in [(shift, shift), around(shift, 0.01)]:
        g = corridor(BACK_RANGE, BACK_BEARING, theta0=theta0)
        result = propagate(g)
        assert result.status is Status.CONSISTENT, (turns, theta0)
        p1 = g.pose_index(1)
        assert result.lo[p1] <= 20.0 <= result.hi[p1]
        assert contains_angle(result.lo[p1 + 2], result.hi[p1 + 2], 0.0)
    # the same with the turn also measured one turn off, and a prior on pose 1's heading
    g = corridor(BACK_RANGE, BACK_BEARING, theta0=around(shift, 0.01), turn=around(-TWO_PI, 0.01))
    g.add_pose_prior(1, (-math.inf, math.inf), (-math.inf, math.inf), around(-TWO_PI, 0.02))
    assert propagate(g).status is Status.CONSISTENT


def test_heading_prior_shifted_by_half_a_turn_is_refuted():
    """θ0 = π (facing -x): pose 1 would be at x ≈ -20, where nothing fits."""
    g = corridor(BACK_RANGE, BACK_BEARING, theta0=around(PI, 0.01))
    g.add_pose_prior(1, (19.0, 21.0), (-1.0, 1.0), (-PI, PI))
    assert propagate(g).status is Status.INCONSISTENT
    # whereas θ0 = 2π with the same prior on pose 1 is fine
    g = corridor(BACK_RANGE, BACK_BEARING, theta0=around(TWO_PI, 0.01))
    g.add_pose_prior(1, (19.0, 21.0), (-1.0, 1.0), (-PI, PI))
    assert propagate(g).status is Status.CONSISTENT
