"""cuikslam.interop.gtsam: a log and a hypothesis as a GTSAM graph, optimised, checked.

The small world's intervals are centred on the truth, so a faithful graph has error 0 at the
truth and its optimum there: a factor read with a wrong sign, frame or unit would not.
"""

from __future__ import annotations

import doctest
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

gtsam = pytest.importorskip(
    "gtsam", reason="the GTSAM interop needs gtsam (pip install 'cuikslam[interop]')"
)

from _small_world import small_world  # noqa: E402
from cuikslam import check_estimate, check_truth, solve  # noqa: E402
from cuikslam.interop.estimate import landmark_key, pose_key  # noqa: E402
from cuikslam.interop.gtsam import factor_graph, move_factor  # noqa: E402
from cuikslam.log.records import Odometry, RelativePose  # noqa: E402
from cuikslam.results.solution import OUTLIER  # noqa: E402


@pytest.fixture(scope="module")
def solved():
    log, truth = small_world()
    return log, truth, solve(log)


def truth_values(truth, hypothesis) -> gtsam.Values:
    values = gtsam.Values()
    for p, xyt in zip(truth.pose_ids, truth.poses_xyt, strict=True):
        values.insert(pose_key(p), gtsam.Pose2(*xyt))
    for j, m in enumerate(hypothesis.landmark_ids):
        values.insert(landmark_key(j), gtsam.Point2(*truth.landmark_xy(m)))
    return values


def test_keys_are_gtsams_symbols() -> None:
    assert pose_key(7) == gtsam.symbol("x", 7)
    assert landmark_key(3) == gtsam.symbol("l", 3)


def test_graph_of_the_small_world_has_its_optimum_at_the_truth(solved) -> None:
    log, truth, solution = solved
    best = solution.best
    graph, values = factor_graph(log, best, initial="centres")
    # one factor per prior (pose, landmark), move (3 odometry, 1 relative) and observation
    assert graph.size() == 2 + 4 + len(log.observations)
    kinds = {type(graph.at(i)).__name__ for i in range(graph.size())}
    assert {"BearingFactor2D", "RangeFactor2D", "BearingRangeFactor2D"} <= kinds
    assert {"PriorFactorPose2", "PriorFactorPoint2", "BetweenFactorPose2"} <= kinds
    assert values.size() == len(best.pose_ids) + len(best.landmark_ids)
    assert graph.error(truth_values(truth, best)) < 1e-15
    assert graph.error(values) > 1e-3  # the box centres are not the optimum

    result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    assert graph.error(result) < 1e-12
    for p, xyt in zip(truth.pose_ids, truth.poses_xyt, strict=True):
        pose = result.atPose2(pose_key(p))
        assert np.allclose([pose.x(), pose.y(), pose.theta()], xyt, atol=1e-6)
    report = check_estimate(solution, result, tolerance=1e-9)
    assert report.ok, str(report)
    assert (report.poses_checked, report.landmarks_checked) == (4, 2)


def test_check_estimate_names_what_a_gtsam_estimate_puts_outside(solved) -> None:
    _, truth, solution = solved
    values = truth_values(truth, solution.best)
    j = solution.best.landmark_ids.index("B")
    box = solution.best.landmark("B")
    moved = float(box[0, 1]) + 0.25
    values.update(landmark_key(j), gtsam.Point2(moved, truth.landmark_xy("B")[1]))
    report = check_estimate(solution, values)
    assert report.landmarks_outside == ["B"] and report.poses_outside == []
    (outside,) = report.outside
    assert outside.coordinate == "x" and outside.excess == moved - float(box[0, 1])
    assert "landmark B x" in str(report)


def test_witness_initial_values_lie_in_the_boxes(solved) -> None:
    log, truth, solution = solved
    assert check_truth(solution.best, truth.pose_ids, truth.exact_poses()).ok
    _, values = factor_graph(log, solution.best, initial="witness")
    witness = solution.best.witness["poses_xyt"]
    assert values.atPose2(pose_key(2)).x() == witness[2, 0]
    # Pose2 keeps a heading as (cos, sin): it may come back a rounding error away
    assert check_estimate(solution, values, tolerance=1e-12).ok


def test_new_landmark_ids_and_outliers_of_unknown_correspondence(solved) -> None:
    _, _, solution = solved
    unnamed, _ = small_world(named=False)
    best = solution.best
    rename = {"A": "A", "B": "+1"}
    assignment = [rename[m] for m in best.assignment]
    assignment[0] = OUTLIER  # the first reading taken as an outlier: no factor
    hypothesis = replace(
        best, assignment=assignment, landmark_ids=[rename[m] for m in best.landmark_ids]
    )
    graph, values = factor_graph(unnamed, hypothesis, initial="centres")
    assert graph.size() == 2 + 4 + len(unnamed.observations) - 1
    assert values.exists(landmark_key(hypothesis.landmark_ids.index("+1")))


def test_a_hypothesis_of_another_log_is_refused(solved) -> None:
    log, _, solution = solved
    shorter = replace(solution.best, assignment=solution.best.assignment[:-1])
    with pytest.raises(ValueError, match="assigns 7 observations"):
        factor_graph(log, shorter)


@pytest.mark.parametrize(
    "record, perturbed",
    [
        # turn 0.4 then 3 m; the truth turned 0.002 more and drove 0.01 less
        (Odometry(0, 1, (0.35, 0.45), (2.9, 3.1)), (0.402, 2.99)),
        (RelativePose(0, 1, (1.9, 2.1), (0.4, 0.6), (0.2, 0.4)), (2.01, 0.49, 0.302)),
    ],
)
def test_move_factor_whitens_small_errors_to_their_half_widths(record, perturbed) -> None:
    """A small error of the measured quantities costs (error / half-width)² / 2 (first order)."""
    factor = move_factor(record)
    values = gtsam.Values()
    values.insert(pose_key(0), gtsam.Pose2(1.0, -2.0, 0.7))
    if isinstance(record, Odometry):
        turn, distance = perturbed
        theta = 0.7 + turn
        end = (1.0 + distance * math.cos(theta), -2.0 + distance * math.sin(theta), theta)
        expected = ((turn - 0.4) / 0.05) ** 2 + ((distance - 3.0) / 0.1) ** 2
    else:
        dx, dy, dtheta = perturbed
        c, s = math.cos(0.7), math.sin(0.7)
        end = (1.0 + c * dx - s * dy, -2.0 + s * dx + c * dy, 0.7 + dtheta)
        expected = ((dx - 2.0) / 0.1) ** 2 + ((dy - 0.5) / 0.1) ** 2 + ((dtheta - 0.3) / 0.1) ** 2
    values.insert(pose_key(1), gtsam.Pose2(*end))
    assert factor.error(values) == pytest.approx(expected / 2, rel=2e-2)


def test_odometry_factor_charges_a_sideways_step_far_more_than_a_turn() -> None:
    """The model drives along its new heading: 10 cm sideways costs far more than reaching
    the same place by a turn within the interval (0.05 rad over 2 m)."""
    factor = move_factor(Odometry(0, 1, (-0.1, 0.1), (1.9, 2.1)))

    def error(end: tuple[float, float, float]) -> float:
        values = gtsam.Values()
        values.insert(pose_key(0), gtsam.Pose2(0.0, 0.0, 0.0))
        values.insert(pose_key(1), gtsam.Pose2(*end))
        return factor.error(values)

    turned = error((2 * math.cos(0.05), 2 * math.sin(0.05), 0.05))
    assert turned == pytest.approx(0.5 * (0.05 / 0.1) ** 2, rel=2e-2)
    assert error((2.0, 2 * math.sin(0.05), 0.0)) > 100 * turned


def test_readg2o_reads_the_g2o_export(solved, tmp_path) -> None:
    from cuikslam.interop.estimate import hypothesis_estimate
    from cuikslam.interop.g2o import write_g2o_file

    log, _, solution = solved
    path = tmp_path / "graph.g2o"
    write_g2o_file(log, hypothesis_estimate(solution.best), solution.best.assignment, path)
    graph, initial = gtsam.readG2o(str(path), False)
    assert initial.size() == 6  # 4 poses, 2 landmarks
    between = [graph.at(i) for i in range(graph.size())]
    assert sum(type(f).__name__ == "BetweenFactorPose2" for f in between) == 4


def test_the_examples_of_docs_interop_run() -> None:
    """Every ``>>>`` example of docs/interop.md (the seed's experiment, known and unknown
    correspondence: build, optimise, check) prints what the page says."""
    page = Path(__file__).resolve().parents[1] / "docs" / "interop.md"
    result = doctest.testfile(
        str(page), module_relative=False, optionflags=doctest.ELLIPSIS, verbose=False
    )
    assert result.attempted >= 15
    assert result.failed == 0
