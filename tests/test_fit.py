"""The least-squares fit that ranks equally parsimonious hypotheses
(:mod:`cuikslam.witness.fit`): it follows the readings, is written and read back,
and a spent budget leaves the order to box size and says so."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cuikslam.budget import Budget
from cuikslam.errors import InputFileError
from cuikslam.hypotheses import solve_unknown
from cuikslam.log.reader import parse_log_lines
from cuikslam.outliers import log_without_observations
from cuikslam.results.io import read_result_file, write_result_file
from cuikslam.results.solution import OUTLIER, PROVEN, Hypothesis
from cuikslam.solver import solve
from cuikslam.witness import HypothesisModel, fit_hypotheses
from cuikslam.witness.fit import fit_cost

# two surveyed doors 0.3 m apart, 2 m ahead of a robot at the origin; one door reading
# whose intervals hold both
MAP = [
    '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
    '{"type": "landmark", "id": "A", "class": "door", "x": [1.99, 2.01], "y": [-0.01, 0.01]}',
    '{"type": "landmark", "id": "B", "class": "door", "x": [1.99, 2.01], "y": [0.29, 0.31]}',
    '{"type": "class", "class": "door", "at_most": 2}',
]


def _reading(bearing_centre: float) -> str:
    lo, hi = bearing_centre - 0.2, bearing_centre + 0.2
    return (
        '{"type": "observation", "pose": 0, "class": "door", "range": [1.9, 2.2], '
        f'"bearing": [{lo!r}, {hi!r}]}}'
    )


@pytest.mark.parametrize(("centre", "best"), [(0.0, "A"), (math.atan2(0.3, 2.0), "B")])
def test_the_door_the_reading_points_at_ranks_first(centre: float, best: str) -> None:
    log = parse_log_lines([*MAP, _reading(centre)])
    solution = solve(log, certify_limit=0, work_budget=None)
    assert sorted(h.assignment[0] for h in solution.hypotheses) == ["A", "B"]
    first, second = solution.hypotheses
    assert first.assignment == [best]
    assert first.fit < second.fit
    assert solution.statistics["fitted_hypotheses"] == 2


def test_fit_is_the_least_squares_cost_in_half_widths() -> None:
    """From the reading's centre (range 2.05 m, bearing 0), door A (range 2, bearing 0)
    is 0.05 m off in range (half-width 0.15 m); A may move ``d`` along x within its prior
    (half-width 0.01 m), so the cost is the minimum over d of ((0.05 - d) / 0.15)^2 +
    (d / 0.01)^2 = 0.05^2 / (0.15^2 + 0.01^2)."""
    log = parse_log_lines([*MAP, _reading(0.0)])
    solution = solve(log, certify_limit=0, work_budget=None)
    [h] = [h for h in solution.hypotheses if h.assignment == ["A"]]
    cost, params = fit_cost(HypothesisModel(log, h.assignment), h)
    assert params is not None
    assert cost == pytest.approx(0.05**2 / (0.15**2 + 0.01**2), rel=1e-6)


def test_a_spent_budget_leaves_the_order_to_box_size_and_says_so() -> None:
    log = parse_log_lines([*MAP, _reading(0.0)])
    solution = solve(log, certify_limit=0, work_budget=None)
    for h in solution.hypotheses:
        h.fit = math.nan
    solution.messages.clear()
    assert fit_hypotheses(log, solution, deadline=Budget.start(work=0.0)) == 0
    assert all(math.isnan(h.fit) for h in solution.hypotheses)
    assert solution.messages == [
        "the least-squares fit that ranks equally parsimonious hypotheses was computed for 0 "
        "of 2 (budget); the others rank after them, by box size"
    ]


def _hypothesis(status: str = "", fit: float = math.nan, size: float = 1.0) -> Hypothesis:
    return Hypothesis(
        assignment=["A"],
        pose_ids=[0],
        poses=np.array([[[0.0, size], [0.0, 0.0], [0.0, 0.0]]]),
        landmark_ids=["A"],
        landmark_classes=["door"],
        landmarks=np.zeros((1, 2, 2)),
        status=status or "not refuted",
        fit=fit,
    )


def test_rank_key_puts_proof_before_fit_and_fit_before_box_size() -> None:
    proven_poor_fit = _hypothesis(PROVEN, fit=9.0, size=5.0)
    good_fit = _hypothesis(fit=1.0, size=3.0)
    unfitted_small = _hypothesis(size=0.5)
    poor_fit_small = _hypothesis(fit=2.0, size=1.0)
    shuffled = [unfitted_small, poor_fit_small, good_fit, proven_poor_fit]
    ranked = sorted(shuffled, key=lambda h: h.rank_key)
    assert ranked == [proven_poor_fit, good_fit, poor_fit_small, unfitted_small]


def test_fit_is_written_and_read_back(tmp_path) -> None:
    log = parse_log_lines([*MAP, _reading(0.0)])
    solution = solve(log, certify_limit=0, work_budget=None)
    path = tmp_path / "result.json"
    write_result_file(solution, path)
    again = read_result_file(path)
    assert [h.fit for h in again.hypotheses] == [h.fit for h in solution.hypotheses]
    doc = json.loads(path.read_text())
    doc["hypotheses"][1]["fit"] = "small"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputFileError, match="hypothesis 2 fit is 'small'"):
        read_result_file(path)


def test_an_outlier_is_fitted_as_if_its_reading_were_not_in_the_log() -> None:
    lines = [*MAP, _reading(0.0), _reading(0.0).replace('"pose": 0', '"pose": 0, "landmark": "B"')]
    log = parse_log_lines(lines)
    solution = solve(log, certify_limit=0, work_budget=None)
    h = solution.hypotheses[0]
    taken = Hypothesis(**{**h.__dict__, "assignment": [OUTLIER, "B"], "fit": math.nan})
    solution.hypotheses = [taken]
    fit_hypotheses(log, solution)
    reduced = log_without_observations(log, {0})
    alone, _ = fit_cost(HypothesisModel(reduced, ["B"]), taken)
    assert math.isfinite(taken.fit)
    assert taken.fit == alone


# a robot known to 0.3 m, two doors 0.4 m apart: a reading of door A from the prior's
# centre; door B, 0.4 m to the left, fits it only if the robot stood 0.2-0.3 m left of the
# centre, so that hypothesis has the narrower pose box (y in [0.2, 0.3] against [-0.2, 0.2])
# and the search, which keeps the smallest boxes, reports it first
NEAR_CONTRADICTION = [
    '{"type": "prior", "pose": 0, "x": [-0.3, 0.3], "y": [-0.3, 0.3], "theta": [0, 0]}',
    '{"type": "landmark", "id": "A", "class": "door", "x": [1.99, 2.01], "y": [-0.01, 0.01]}',
    '{"type": "landmark", "id": "B", "class": "door", "x": [1.99, 2.01], "y": [0.39, 0.41]}',
    '{"type": "class", "class": "door", "at_most": 2}',
    _reading(0.0),
]


def test_the_best_fitting_survivor_is_reported_even_beyond_max_hypotheses() -> None:
    """One hypothesis reported of two: the search keeps door B (smaller boxes), the fit
    reports door A in its place, with the boxes a known-correspondence solve gives it,
    and says so."""
    log = parse_log_lines(NEAR_CONTRADICTION)
    search = solve_unknown(log, max_hypotheses=1)
    assert [h.assignment for h in search.hypotheses] == [["B"]]
    assert search.unreported == [["A"]]
    solution = solve(log, certify_limit=0, work_budget=None, max_hypotheses=1)
    [h] = solution.hypotheses
    assert h.assignment == ["A"]
    assert solution.statistics["promoted_hypotheses"] == 1
    assert solution.unreported == []  # used, not carried in the result
    assert any("reported in their place" in m for m in solution.messages)
    labelled = parse_log_lines(
        [*NEAR_CONTRADICTION[:-1], _reading(0.0)[:-1] + ', "landmark": "A"}']
    )
    [alone] = solve(labelled, certify_limit=0, work_budget=None, consistency="hull").hypotheses
    assert np.array_equal(h.poses, alone.poses)
    assert np.array_equal(h.landmarks, alone.landmarks)
    both = solve(log, certify_limit=0, work_budget=None, max_hypotheses=2).hypotheses
    assert [b.assignment for b in both] == [["A"], ["B"]]
    assert h.fit == pytest.approx(both[0].fit, rel=1e-6)
    assert both[0].fit < both[1].fit


def test_the_stronger_level_follows_the_ranking() -> None:
    """The search ranks its report (``rank``, the fit in ``solve``) before the stronger
    level: with room for one narrowing, the hypothesis the ranking puts first gets it,
    whichever has the smaller boxes."""
    log = parse_log_lines(NEAR_CONTRADICTION)
    for rank, first in [(None, "B"), (lambda report: report.hypotheses.reverse(), "A")]:
        solution = solve_unknown(
            log, max_hypotheses=2, consistency="lp", strengthen_limit=1, rank=rank
        )
        levels = {h.assignment[0]: h.consistency for h in solution.hypotheses}
        assert levels == {first: "lp", ({"A", "B"} - {first}).pop(): "hull"}
        assert solution.consistency == "hull"


def test_a_promoted_survivor_gets_the_stronger_level_from_its_labelled_log() -> None:
    """The survivor the fit reports in place of the search's choice has no node of the
    search: the stronger level narrows its labelled log, to the boxes a known-correspondence
    solve of that log gives at the same level."""
    log = parse_log_lines(NEAR_CONTRADICTION)
    solution = solve(log, certify_limit=0, work_budget=None, max_hypotheses=1, consistency="lp")
    [h] = solution.hypotheses
    assert h.assignment == ["A"] and solution.statistics["promoted_hypotheses"] == 1
    assert h.consistency == "lp" == solution.consistency
    labelled = parse_log_lines(
        [*NEAR_CONTRADICTION[:-1], _reading(0.0)[:-1] + ', "landmark": "A"}']
    )
    [alone] = solve(labelled, certify_limit=0, work_budget=None, consistency="lp").hypotheses
    assert np.array_equal(h.poses, alone.poses)
    assert np.array_equal(h.landmarks, alone.landmarks)


def test_the_report_is_narrowed_on_labelled_logs_unless_there_is_negative_information(
    monkeypatch,
) -> None:
    """Without a sensor record a hypothesis' labelled log holds the constraints of its node
    in the search, so the stronger level runs there; with one, on the node, whose UNSEEN
    factors the labelled log lacks."""
    from cuikslam.hypotheses.explorer import Explorer

    on_nodes = []
    narrow = Explorer.strengthen_node
    monkeypatch.setattr(
        Explorer, "strengthen_node", lambda self, *a: on_nodes.append(1) or narrow(self, *a)
    )
    sensor = '{"type": "sensor", "max_range": 1.0}'  # the doors are out of range
    for lines, nodes in [(NEAR_CONTRADICTION, 0), ([sensor, *NEAR_CONTRADICTION], 2)]:
        on_nodes.clear()
        solution = solve_unknown(parse_log_lines(lines), max_hypotheses=2, consistency="lp")
        assert [h.consistency for h in solution.hypotheses] == ["lp", "lp"]
        assert len(on_nodes) == nodes


def test_a_declared_outlier_among_named_readings_never_becomes_a_hard_constraint() -> None:
    """A log that declares outliers: its named readings may be outliers too, which a
    labelled log would make hard constraints. So no survivor is reported in place of
    another with a labelled log's boxes, and the stronger level runs on the search's
    nodes: the tree's box holds its truth although its one reading is 1 m off."""
    tree = (
        '{"type": "observation", "pose": 0, "landmark": "T", "class": "tree", '
        '"range": [4.0, 4.1], "bearing": [1.5, 1.6]}'
    )  # the tree stands at (0, 3): 3 m away, not 4
    lines = [*NEAR_CONTRADICTION, tree, '{"type": "outliers", "at_most": 1}']
    for options in [{"max_hypotheses": 1}, {"max_hypotheses": 2}]:
        solution = solve(
            parse_log_lines(lines), certify_limit=0, work_budget=None, consistency="lp",
            **options,
        )  # fmt: skip
        assert solution.hypotheses
        assert solution.statistics.get("promoted_hypotheses", 0) == 0
        for h in solution.hypotheses:
            (x, y) = h.landmarks[h.landmark_ids.index("T")]
            assert x[0] <= 0.0 <= x[1] and y[0] <= 3.0 <= y[1]


def test_a_survivor_is_discarded_by_its_partition_whatever_its_new_landmarks_are_named() -> None:
    """A promoted survivor refuted by the stronger level leaves the tally: it is found by
    its partition, whatever its new landmark is named (``+1`` in the search, ``+9`` here)."""
    from cuikslam.hypotheses.explorer import Explorer
    from cuikslam.hypotheses.problem import build_problem
    from cuikslam.hypotheses.tally import Tally

    log = parse_log_lines([*NEAR_CONTRADICTION, _reading(0.0)])
    tally = Tally(Explorer(build_problem(log), 1e-3, "hull", None, True), None)
    tally.assignments = [["A", "+1"], ["+1", "A"], ["A", "B"]]
    tally.discard_assignment(["+9", "A"])
    assert tally.kept() == [["A", "+1"], ["A", "B"]]


def test_a_landmark_the_robot_would_have_seen_raises_the_fit() -> None:
    """A new landmark placed at the reading fits it as well as door A does, but then A,
    1 m inside the sensor's range, was not seen: with the sensor record the fit pays that
    violation (A cannot leave the range without breaking its 0.01 m prior); without the
    record the new landmark costs no more than A."""
    sensor = '{"type": "sensor", "max_range": 3.0}'
    log = parse_log_lines([MAP[0], MAP[1], sensor, _reading(0.0)])
    seen, _ = fit_cost(HypothesisModel(log, ["A"]), None)
    new, _ = fit_cost(HypothesisModel(log, ["N"]), None)
    blind, _ = fit_cost(HypothesisModel(log, ["N"], use_sensor=False), None)
    assert blind <= seen + 1e-9
    assert new > seen + 1.0


def test_fit_residuals_jacobian_matches_finite_differences() -> None:
    """The sensor rows' derivatives (a violated pair: door A unseen in range) agree with
    central differences, so the least squares descends the cost it reports."""
    sensor = '{"type": "sensor", "max_range": 3.0}'
    log = parse_log_lines([MAP[0], MAP[1], sensor, _reading(0.0)])
    model = HypothesisModel(log, ["N"])
    p = model.initial_params() + 0.01
    r, J = model.fit_residuals(p, jacobian=True)
    assert J is not None and r[-1] > 0  # the sensor row is violated
    h = 1e-6
    for k in range(len(p)):
        step = np.zeros_like(p)
        step[k] = h
        numeric = (model.fit_residuals(p + step)[0] - model.fit_residuals(p - step)[0]) / (2 * h)
        np.testing.assert_allclose(J[:, k], numeric, rtol=1e-5, atol=1e-6)


def test_the_iterative_fit_spends_each_product_with_the_jacobian() -> None:
    """Above ``LSMR_ABOVE`` parameters the fit's steps are iterative: each product by the
    Jacobian spends its entries' work (a 1,000-pose log took 20 ms a product, uncounted:
    a solve ran 1,883 s on a budget sized for 600), and a spent budget stops a step."""
    from cuikslam.budget import COSTS, OutOfTime
    from cuikslam.witness._dense import LSMR_ABOVE, dense_least_squares, tr_solver_for

    n = LSMR_ABOVE + 20
    rng = np.random.default_rng(0)
    J = rng.normal(size=(2 * n, n))
    target = rng.normal(size=2 * n)

    def residuals(z: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray]:
        return J @ z - target, J

    spent: list[float] = []
    bounds = (np.full(n, -np.inf), np.full(n, np.inf))
    columns = np.ones(n, dtype=bool)
    solver = tr_solver_for(n)
    assert solver == "lsmr"
    z = dense_least_squares(
        residuals, np.zeros(n), lambda: None, 5, columns, bounds, solver, spend=spent.append
    )
    per_product = COSTS["product_entry"] * J.size  # a product by k vectors: k of them
    assert len(spent) >= 4 and all((s / per_product).is_integer() for s in spent)
    assert np.sum((J @ z - target) ** 2) < np.sum(target**2)

    def refuse(units: float) -> None:
        raise OutOfTime

    with pytest.raises(OutOfTime):
        dense_least_squares(
            residuals, np.zeros(n), lambda: None, 5, columns, bounds, solver, spend=refuse
        )
