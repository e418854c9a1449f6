"""The joined walk (:mod:`cuikslam.hypotheses.joined`): lanes that agree on their future
are walked once; the truth is never cut, its boxes hold it, and the envelope holds it at
every budget cut with joined nodes pending. Joins are forced on small worlds by joining
lanes as soon as a scan starts, agreed on nothing (``JOIN_AGREE = 0``: soundness does not
rest on their agreement, which only makes joining pay)."""

from __future__ import annotations

from unittest.mock import patch

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings

import cuikslam.hypotheses.joined as joined
from cuikslam.hypotheses import _shared, search, solve_unknown
from cuikslam.simulate import simulate_random_world
from test_envelope import envelope_misses
from test_search_progress import associations, check_reports
from test_shared_graph import _fingerprint
from worlds import SEARCHED, World, true_index, truth_misses, worlds

HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]
NODE_CUTS = (1, 2, 3, 5, 8, 13, 21)


def _solve(log, **options):
    with patch.object(joined, "JOIN_AGREE", 0):
        return solve_unknown(log, consistency="hull", max_hypotheses=10_000, **options)


def check_truth(world: World, naming: str, joins: int = 0) -> None:
    """The truth survives a search that may join (that joins ``joins`` times at least: a
    world that does not is assumed away), its boxes hold it, and so does the envelope."""
    log = world.log(naming)
    note("\n".join(world.lines(naming)))
    solution = _solve(log, max_nodes=5_000)
    assume(solution.complete and solution.statistics["joins"] >= joins)
    named = world.named_ids(naming)
    index = true_index(solution, world.truth, named)
    assert index >= 0, solution.messages
    assert truth_misses(solution.hypotheses[index], world.truth, named) == []
    assert envelope_misses(solution, world.truth) == []


def check_cuts(world: World, joins: int = 0) -> None:
    """The envelope holds the truth at every node budget of a search that may join (as
    :func:`check_truth`)."""
    log = world.log("none")
    note("\n".join(world.lines("none")))
    assume(_solve(log, max_nodes=5_000).statistics["joins"] >= joins)
    for cut in NODE_CUTS:
        solution = _solve(log, max_nodes=cut)
        assert envelope_misses(solution, world.truth) == [], (cut, solution.messages)


@pytest.mark.parametrize("naming", ["none", "mixed"])
@settings(max_examples=4, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_a_joined_search_keeps_the_truth_and_its_boxes_hold_it(world: World, naming: str) -> None:
    check_truth(world, naming)


@settings(max_examples=3, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_the_envelope_holds_the_truth_at_every_cut_of_a_joined_search(world: World) -> None:
    check_cuts(world)


@pytest.mark.slow
@pytest.mark.parametrize("naming", ["none", "mixed"])
@settings(max_examples=60, deadline=None, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_a_joined_search_keeps_the_truth_many(world: World, naming: str) -> None:
    check_truth(world, naming, joins=1)


@pytest.mark.slow
@settings(max_examples=40, deadline=None, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_the_envelope_holds_the_truth_at_every_cut_of_a_joined_search_many(world: World) -> None:
    check_cuts(world, joins=1)


JOINING = [(2, 20, 8), (8, 30, 10), (10, 20, 8), (10, 40, 12), (11, 20, 8)]
"""Worlds (seed, poses, landmarks) of ``simulate random`` (12 x 8 m, 4 m range) whose
search joins lanes when forced to."""


@pytest.mark.parametrize(("seed", "poses", "landmarks"), JOINING)
def test_a_joined_search_finds_the_survivors_of_the_plain_one(
    seed: int, poses: int, landmarks: int
) -> None:
    """Every survivor of the depth-first search is a survivor of the joined one, with the
    same assignment."""
    log, _ = simulate_random_world(
        seed=seed, n_poses=poses, n_landmarks=landmarks, unknown=True, size=(12.0, 8.0),
        max_range=4.0,
    )  # fmt: skip
    with patch.object(joined, "JOIN_MAX_LANES", 1):  # no look-ahead: depth first
        plain = solve_unknown(log, consistency="hull", max_hypotheses=10_000)
    both = _solve(log)
    assert plain.complete and both.complete
    assert plain.statistics["joins"] == 0 < both.statistics["joins"]
    assert {tuple(h.assignment) for h in plain.hypotheses} <= {
        tuple(h.assignment) for h in both.hypotheses
    }


@pytest.mark.parametrize(("seed", "poses", "landmarks"), JOINING)
def test_what_a_joined_search_reports_decided_every_survivor_agrees_on(
    seed: int, poses: int, landmarks: int
) -> None:
    """Reported after every expansion, with joined nodes pending: a decided reading stays
    decided, every survivor associates it alike, and the upper bound holds their number."""
    log, _ = simulate_random_world(
        seed=seed, n_poses=poses, n_landmarks=landmarks, unknown=True, size=(12.0, 8.0),
        max_range=4.0,
    )  # fmt: skip
    reports: list = []
    with patch.object(search, "REPORT_EVERY", 1):
        solution = _solve(log, progress=lambda done, total, status: reports.append(status))
    assert solution.complete and solution.statistics["joins"] > 0
    rows = [associations(h.assignment, set()) for h in solution.hypotheses]
    searched = [r for r in reports if r.stage != "dive"]
    assert searched[-1].stage == "done"
    check_reports(searched, rows, solution.statistics["survivors"], truth=rows[0])


@pytest.mark.parametrize(("seed", "poses", "landmarks"), JOINING)
def test_a_joined_box_holds_every_lanes_box(seed: int, poses: int, landmarks: int) -> None:
    """Every variable's bounds in the joined node hold the lane's, in every lane (found by
    a review: a landmark only some lanes hold was hulled over those, but every lane bounds
    its slot, where its reading puts what it sees, and the true lane's value fell out)."""
    log, _ = simulate_random_world(
        seed=seed, n_poses=poses, n_landmarks=landmarks, unknown=True, size=(12.0, 8.0),
        max_range=4.0,
    )  # fmt: skip
    checked: list[int] = []
    real = joined.join

    def join(explorer, nodes):
        node = real(explorer, nodes)
        lo, hi = explorer.graph.materialize(node.overlay)
        for lane in nodes:
            lane_lo, lane_hi = explorer.graph.materialize(lane.overlay)
            assert np.all(lo <= lane_lo) and np.all(lane_hi <= hi)
            checked.append(len(lo))
        return node

    with patch.object(joined, "join", join):
        assert _solve(log).complete
    assert checked


def test_maintenance_with_joined_nodes_pending_changes_no_result() -> None:
    """The shared graph's housekeeping re-expresses the joined nodes and their lanes: the
    same hypotheses, boxes bit for bit, as without it."""
    log, _ = simulate_random_world(
        seed=2, n_poses=20, n_landmarks=8, unknown=True, size=(12.0, 8.0), max_range=4.0
    )
    with patch.object(_shared, "MIN_MAINTENANCE_LOAD", 10**12):
        never = _solve(log)
    calls: list[int] = []
    maintain = _shared.SharedGraph.maintain

    def counted(graph, overlays):
        calls.append(len(overlays))
        return maintain(graph, overlays)

    with (
        patch.object(_shared, "MIN_MAINTENANCE_LOAD", 4),
        patch.object(search, "MAINTAIN_EVERY", 4),
        patch.object(_shared.SharedGraph, "maintain", counted),
    ):
        often = _solve(log)
    assert never.statistics["joins"] > 0 and len(calls) >= 3
    assert _fingerprint(never) == _fingerprint(often)
