"""cuikslam.check_estimate: an estimate's values against the boxes, exactly (no GTSAM needed)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuikslam import Hypothesis, Solution, check_estimate
from cuikslam.interop.estimate import PointEstimate, hypothesis_estimate


def hypothesis(theta: tuple[float, float] = (6.0, 6.5), status: str = "not refuted") -> Hypothesis:
    """Pose 0 exact at the origin, pose 1 in a box; landmark L1 in a box."""
    poses = np.array([[[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], [[0.9, 1.1], [-0.1, 0.1], theta]])
    return Hypothesis(
        ["L1"], [0, 1], poses, ["L1"], ["door"], np.array([[[4.0, 6.0], [-1.0, 1.0]]]), status
    )


INSIDE = {0: (0.0, 0.0, 0.0), 1: (1.0, 0.0, 6.2), "L1": (5.0, 0.0)}


def test_values_inside_every_box_are_ok() -> None:
    report = check_estimate(Solution([hypothesis()]), INSIDE)
    assert report.ok and report.outside == []
    assert (report.poses_checked, report.landmarks_checked) == (2, 1)
    assert "every value inside its box" in str(report)


@pytest.mark.parametrize("bound", [0.9, 1.1])
def test_a_value_on_a_bound_is_inside_and_the_next_float_is_not(bound: float) -> None:
    solution = Solution([hypothesis()])
    assert check_estimate(solution, {**INSIDE, 1: (bound, 0.0, 6.2)}).ok
    beyond = math.nextafter(bound, bound + (1 if bound > 1 else -1))
    report = check_estimate(solution, {**INSIDE, 1: (beyond, 0.0, 6.2)})
    (outside,) = report.outside
    assert (outside.kind, outside.id, outside.coordinate) == ("pose", 1, "x")
    assert outside.excess == abs(beyond - bound) > 0


@pytest.mark.parametrize("k", [-3, -1, 0, 1, 5])
def test_headings_are_compared_modulo_two_pi(k: int) -> None:
    solution = Solution([hypothesis()])
    assert check_estimate(solution, {**INSIDE, 1: (1.0, 0.0, 6.2 + 2 * math.pi * k)}).ok
    report = check_estimate(solution, {**INSIDE, 1: (1.0, 0.0, 0.3 + 2 * math.pi * k)})
    (outside,) = report.outside
    assert outside.coordinate == "theta"
    # [6.0, 6.5] is [-0.283, 0.217] modulo 2π: 0.3 lies 0.083 beyond its upper end
    assert outside.excess == pytest.approx(0.3 - (6.5 - 2 * math.pi), abs=1e-9)


def test_an_exact_heading_one_float_away_is_outside_unless_a_tolerance_allows() -> None:
    solution = Solution([hypothesis()])
    near = {**INSIDE, 0: (0.0, 0.0, 5e-17)}
    (outside,) = check_estimate(solution, near).outside
    assert outside.excess > 0
    assert check_estimate(solution, near, tolerance=1e-12).ok
    report = check_estimate(solution, {**INSIDE, 0: (1e-9, 0.0, 0.0)}, tolerance=1e-12)
    assert report.poses_outside == [0]


def test_landmarks_missing_values_and_nan_are_reported() -> None:
    solution = Solution([hypothesis()])
    report = check_estimate(solution, {1: (1.0, 0.0, math.nan), "L1": (7.0, 0.0)})
    assert report.poses_missing == [0]
    assert report.poses_outside == [1] and math.isnan(report.outside[0].excess)
    assert report.landmarks_outside == ["L1"] and report.outside[1].excess == 1.0
    assert "not in the estimate: 1 pose" in str(report)


def test_the_hypothesis_is_chosen_by_index_or_given() -> None:
    wide = hypothesis(theta=(-4.0, 4.0), status="proven consistent")
    solution = Solution([wide, hypothesis()])
    odd = {**INSIDE, 1: (1.0, 0.0, 1.0)}
    assert check_estimate(solution, odd).ok  # the best: any heading in [-4, 4]
    second = check_estimate(solution, odd, hypothesis=1)
    assert second.rank == 2 and second.poses_outside == [1]
    assert check_estimate(solution, odd, hypothesis=solution.hypotheses[1]).rank == 2
    assert str(second).startswith("hypothesis 2 (not refuted)")
    with pytest.raises(ValueError, match="no hypothesis 2"):
        check_estimate(solution, odd, hypothesis=2)
    with pytest.raises(ValueError, match="tolerance"):
        check_estimate(solution, odd, tolerance=-1.0)
    with pytest.raises(TypeError, match=r"gtsam\.Values"):
        check_estimate(solution, [1.0, 2.0])


def test_a_point_estimate_of_the_boxes_is_inside_them() -> None:
    h = hypothesis()
    h.witness = {"poses_xyt": np.array([[0.0, 0.0, 0.0], [1.05, 0.0, np.nan]]),
                 "landmarks_xy": np.array([[4.5, 0.5]])}  # fmt: skip
    point = hypothesis_estimate(h)
    assert point.source == "witness, box centres where it has no value"
    assert point.poses_xyt[1].tolist() == [1.05, 0.0, 6.25]
    assert isinstance(point, PointEstimate)
    assert check_estimate(Solution([h]), point).ok
    assert hypothesis_estimate(h, "centres").poses_xyt[1].tolist() == [1.0, 0.0, 6.25]
    with pytest.raises(ValueError, match="no witness"):
        hypothesis_estimate(hypothesis(), "witness")
