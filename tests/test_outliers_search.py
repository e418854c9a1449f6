"""Declared outliers with unknown correspondence: "outlier" as one more option of the search.

A world of the independent generator (:mod:`worlds`) gets k = 1 or 2 gross outliers: the
range interval of k observations moved far beyond the true range (a bearing-only one turned
by 3 rad). The log declares Q >= k outliers (in all, or per block of W poses), with or
without a ``sensor`` record and class priors. The *true hypothesis* is then the true
assignment with the injected observations that name no landmark taken as outliers (the
named ones keep their names: the q-relaxed intersection covers them). Whenever the search
is complete and reports every survivor, that hypothesis is among them and every box of it
holds the truth; and no survivor takes more outliers than declared. A hypothesis that takes
more observations as outliers (within the declaration) may survive too: it is a relaxation
of the true one, not checked here. ``python -m pytest -m slow tests/test_outliers_search.py``
checks 500 new, larger worlds.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from cuikslam.hypotheses import solve_unknown
from cuikslam.log import parse_log_lines
from cuikslam.results.association import rank_of, truth_verdict
from cuikslam.results.evaluate import evaluate
from cuikslam.results.measurement_check import check_log
from cuikslam.results.solution import OUTLIER, Hypothesis, Solution
from cuikslam.simulate.truth import GroundTruth
from test_cli import run
from test_guarantee import reported
from worlds import (
    SEARCH_LEVELS,
    World,
    correspondence,
    log_violations,
    search_level,
    truth_misses,
    worlds,
)

HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]
OUTLIER_WORLDS = {"poses": (3, 6), "landmarks": (2, 4), "max_observations": 8}
"""Small worlds: each observation has one option more, the trees grow quickly."""
BUDGET = {"max_nodes": 3_000}
GROSS = 40.0
"""How far beyond its true range an injected outlier's interval starts [m]."""


def _injected(world: World, which: list[int]) -> World:
    """``world`` with the range of observations ``which`` (record order) moved ``GROSS``
    beyond the upper bound, or for a bearing-only one its bearing turned by 3 rad (they
    are at most 0.2 rad wide): their intervals miss the truth."""
    records, k = [], 0
    for record in world.records:
        if record["type"] == "observation":
            if k in which and "range" in record:
                lo, hi = record["range"]
                record = {**record, "range": [hi + GROSS, hi + GROSS + (hi - lo)]}
            elif k in which:
                lo, hi = record["bearing"]
                record = {**record, "bearing": [lo + 3.0, hi + 3.0]}
            k += 1
        records.append(record)
    return replace(world, records=records, notes=[*world.notes, f"outliers injected: {which}"])


def _blocks(log_lines: list[str], window: int | None) -> list[int]:
    """Block of poses of each observation: poses in the order the log first mentions them,
    cut into blocks of ``window`` (all 0 without one)."""
    order: dict[int, int] = {}
    blocks = []
    for line in log_lines:
        r = json.loads(line)
        for key in ("pose", "from", "to"):
            if key in r and r["type"] != "landmark":
                order.setdefault(r[key], len(order))
        if r["type"] == "observation":
            blocks.append(0 if window is None else order[r["pose"]] // window)
    return blocks


def _true_hypothesis(solution: Solution, expected: list[str], named: set[str]) -> Hypothesis:
    target = correspondence(expected, named | {OUTLIER})
    found = [
        h for h in solution.hypotheses if correspondence(h.assignment, named | {OUTLIER}) == target
    ]
    assert found, f"the true hypothesis {expected} was refuted; {solution.messages}"
    return found[0]


def _misses(h: Hypothesis, world: World, named: set[str]) -> list[str]:
    """:func:`worlds.truth_misses` on the observations ``h`` does not take as outliers."""
    keep = [i for i, a in enumerate(h.assignment) if a != OUTLIER]
    truth = replace(world.truth, assignment=[world.truth.assignment[i] for i in keep])
    return truth_misses(replace(h, assignment=[h.assignment[i] for i in keep]), truth, named)


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(
    world=worlds(**OUTLIER_WORLDS),
    naming=st.sampled_from(["none", "none", "mixed"]),
    data=st.data(),
)
def test_declared_outliers_keep_the_true_hypothesis(world: World, naming: str, data) -> None:
    check_outliers(world, naming, data)


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**OUTLIER_WORLDS), data=st.data())
def test_declared_outliers_keep_the_true_hypothesis_at_lp(world: World, data) -> None:
    """The same with the ``lp`` level on every ambiguous node and on the survivors."""
    check_outliers(world, "none", data, "lp-during")


@pytest.mark.slow
@settings(max_examples=500, deadline=None, suppress_health_check=HEALTH)
@given(
    world=worlds(poses=(3, 8), landmarks=(2, 5), max_observations=12),
    naming=st.sampled_from(["none", "none", "mixed"]),
    data=st.data(),
)
def test_slow_declared_outliers(world: World, naming: str, data) -> None:
    check_outliers(world, naming, data)


def check_outliers(world: World, naming: str, data: st.DataObject, level: str = "hull") -> None:
    """Inject up to 2 gross outliers, declare at least as many (in all, or per block of 1
    to 3 poses): the declaration is honoured, and a complete search keeps the true
    hypothesis with the truth in its boxes."""
    n = world.n_observations
    assume(n > 0)
    which = data.draw(st.lists(st.integers(0, n - 1), unique=True, min_size=1, max_size=min(2, n)))
    window = data.draw(st.sampled_from([None, None, 1, 2, 3]))
    if data.draw(st.booleans()):
        world = world.with_class_priors(1.0, data.draw(st.sampled_from([0.0, 0.3])), 0)
    world = _injected(world, which)
    lines = world.lines(naming)
    blocks = _blocks(lines, window)
    most = max([sum(blocks[i] == b for i in which) for b in set(blocks)], default=0)
    allowed = data.draw(st.integers(most if window else len(which), 2))
    declared = {"type": "outliers", "at_most": allowed}
    if window is not None:
        declared["window"] = window
    lines = [json.dumps(declared), *lines]
    with reported(world, naming):
        log = parse_log_lines(lines)
        bad = log_violations(log, world.truth)  # the injected ranges, and nothing else
        assert len(bad) == len(which), bad
        named = world.named_ids(naming)
        unnamed = [k for k, o in enumerate(log.observations) if o.landmark is None]
        expected = [
            OUTLIER if i in which and i in unnamed else a
            for i, a in enumerate(world.truth.assignment)
        ]
        options = {**SEARCH_LEVELS[level], "max_hypotheses": 100_000, **BUDGET}
        if level == "lp-during":
            options["strengthen_limit"] = 10_000  # and lp on every survivor
        with search_level(level):
            solution = solve_unknown(log, **options)
        for h in solution.hypotheses:  # the declaration is honoured
            outliers = h.outliers
            assert set(outliers) <= set(unnamed)
            if window is None:
                assert len(outliers) <= allowed, h.assignment
            else:
                assert all(sum(blocks[i] == b for i in outliers) <= allowed for b in blocks)
        survivors = solution.statistics["survivors"]
        assume(solution.complete and survivors <= len(solution.hypotheses))
        h = _true_hypothesis(solution, expected, named)
        assert _misses(h, world, named) == []
        event(f"{len(which)} injected, {expected.count(OUTLIER)} decided as outliers")
        event(f"window {window}, sensor {world.sensor is not None}")


def _two_poses(declaration: str | None) -> list[str]:
    """One landmark (a class of at most one): seen at 2 m from pose 0, then from pose 1,
    1 m further, an observation whose range says 7 m (truly 1 m): a gross outlier."""
    lines = [
        '{"type": "class", "class": "post", "at_most": 1}',
        '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
        '{"type": "observation", "pose": 0, "class": "post", "range": [1.95, 2.05], '
        '"bearing": [-0.05, 0.05]}',
        '{"type": "odometry", "from": 0, "to": 1, "turn": [-0.01, 0.01], "distance": [1, 1.02]}',
        '{"type": "observation", "pose": 1, "class": "post", "range": [7, 7.1], '
        '"bearing": [-0.05, 0.05]}',
    ]
    return lines if declaration is None else [declaration, *lines]


def test_without_the_outlier_option_the_log_is_refuted() -> None:
    """The same log: undeclared, every hypothesis is refuted (the true association misses
    the range, a second post breaks the class); declared, the outlier option keeps the true
    hypothesis, and its boxes hold the true poses and post."""
    plain = solve_unknown(parse_log_lines(_two_poses(None)), consistency="hull")
    assert plain.complete and plain.refuted
    declared = parse_log_lines(_two_poses('{"type": "outliers", "at_most": 1}'))
    solution = solve_unknown(declared, consistency="hull")
    assignments = sorted(h.assignment for h in solution.hypotheses)
    assert solution.complete and assignments == [["+1", OUTLIER], [OUTLIER, "+1"]]
    [h] = [h for h in solution.hypotheses if h.outliers == [1]]  # the true one
    (x, y), pose1 = h.landmark("+1"), h.pose(1)
    assert x[0] <= 2 <= x[1] and y[0] <= 0 <= y[1]
    assert pose1[0, 0] <= 1 <= pose1[0, 1] and pose1[1, 0] <= 0 <= pose1[1, 1]
    assert solution.statistics["outlier_options"] >= 1


def test_solve_lists_the_outliers_of_each_hypothesis(tmp_path: Path) -> None:
    """Either sighting may be the outlier: both hypotheses are listed, with line and pose."""
    (tmp_path / "trip.jsonl").write_text(
        "\n".join(_two_poses('{"type": "outliers", "at_most": 1}')) + "\n", encoding="utf-8"
    )
    result = run("solve", "trip.jsonl", "--consistency", "hull", "--json", "r.json", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "hypothesis 1 takes 1 observation(s) as outliers: line 6 (pose 1)" in result.stdout
    assert "1 landmarks, 1 outliers" in result.stdout
    doc = json.loads((tmp_path / "r.json").read_text(encoding="utf-8"))
    assert doc["hypotheses"][0]["assignment"] == ["+1", "outlier"]
    assert "hypothesis 2 takes 1 observation(s) as outliers: line 4 (pose 0)" in result.stdout
    assert doc["outliers"]["hypotheses"] == [
        [{"observation": 1, "line": 6, "pose": 1}],
        [{"observation": 0, "line": 4, "pose": 0}],
    ]
    assert doc["correspondence"]["outliers"] == {"every_survivor": [], "some_survivors": [0, 1]}


def _h(*assignment: str) -> Hypothesis:
    empty = np.zeros((0, 3, 2))
    return Hypothesis(list(assignment), [], empty, [], [], np.zeros((0, 2, 2)))


def test_the_true_hypothesis_takes_exactly_the_true_outliers() -> None:
    """Truth files carry no outlier marks: the true hypothesis agrees with the truth on the
    other observations and takes as outliers exactly those that miss their interval
    (``outside``); failing that, the first whose outliers include them."""
    truth = ["L0", "L1", "L0"]
    plain, exact, more = _h("N1", "N2", "N1"), _h("N1", OUTLIER, "N1"), _h(OUTLIER, OUTLIER, "N1")
    assert rank_of([plain, exact, more], truth) == 1
    assert rank_of([plain, more, exact], truth, outside=[1]) == 3
    assert rank_of([plain, more], truth, outside=[1]) == 2
    assert rank_of([plain, _h(OUTLIER, "N1", "N2")], truth, outside=[1]) is None
    assert rank_of([_h("N1", OUTLIER, "N2")], truth, outside=[1]) is None  # 0 and 2 differ


def test_truth_check_and_evaluate_take_the_true_outliers() -> None:
    """The two-pose log and its truth (post at (2, 0), poses at x = 0 and 1): the true
    hypothesis takes the sighting that misses its range (7 m, truly 1 m) as an outlier."""
    log = parse_log_lines(_two_poses('{"type": "outliers", "at_most": 1}'))
    truth = GroundTruth(
        poses_xyt=np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]),
        pose_ids=[0, 1],
        landmarks_xy=np.array([[2.0, 0.0]]),
        landmark_ids=["P"],
        landmark_classes=["post"],
        assignment=["P", "P"],
    )
    outside = check_log(log, truth).outside_observations
    assert outside == [1]
    solution = solve_unknown(log, consistency="hull")
    verdict = truth_verdict(solution, truth, outside=outside)
    assert verdict.ok and "survived" in verdict.lines[0], verdict.lines
    ev = evaluate(solution, truth, outside=outside)
    assert solution.hypotheses[ev.true_rank - 1].outliers == [1]


def test_no_witness_proves_a_hypothesis_with_more_outliers_than_declared() -> None:
    """At most 1 outlier per pose; the named sighting of A from pose 0 is proven an outlier
    (3 m too far). A hypothesis that also takes the other pose-0 sighting as an outlier has
    2 at pose 0: no world meets the declaration, so none may be proven consistent (it was,
    by a witness that left out both); the next one, which keeps to it, is tried instead."""
    from cuikslam.outliers import check_declaration
    from cuikslam.solver import solve

    log = parse_log_lines(
        [
            '{"type": "outliers", "at_most": 1, "window": 1}',
            '{"type": "class", "class": "c", "at_most": 1}',
            '{"type": "landmark", "id": "A", "class": "a", "x": [4.99, 5.01], "y": [-0.01, 0.01]}',
            '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
            '{"type": "observation", "pose": 0, "class": "a", "landmark": "A", '
            '"range": [8, 8.1], "bearing": [-0.01, 0.01]}',
            '{"type": "observation", "pose": 0, "class": "c", "range": [3.5, 4.5], '
            '"bearing": [1.4, 1.75]}',
            '{"type": "odometry", "from": 0, "to": 1, "turn": [0, 0], "distance": [2, 2]}',
            '{"type": "observation", "pose": 1, "class": "c", "range": [3, 3.001], '
            '"bearing": [-1.0, -0.999]}',
        ],
        path="window.jsonl",
    )
    solution = solve(log, work_budget=2e7)
    proven_outliers = [p["observation"] for p in solution.outliers["proven"]]
    assert proven_outliers == [0]
    too_many = [h for h in solution.hypotheses if h.outliers == [1]]
    assert len(too_many) == 1  # the hypothesis that breaks the declaration is reported
    assert too_many[0].status != "proven consistent"
    for h in solution.hypotheses:
        if h.status == "proven consistent":
            assert check_declaration(log, sorted(set(proven_outliers) | set(h.outliers)))[0]
    # the best-ranked hypothesis that keeps to the declaration (the true one, which takes
    # the pose-1 sighting as its outlier) is the one certified, and ranks first once proven
    assert solution.best.outliers == [2] and solution.best.status == "proven consistent"
