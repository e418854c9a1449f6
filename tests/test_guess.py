"""The guess decides a scan at a time and adds nothing that is not proven.

Random true worlds from the independent generator (:mod:`worlds`). The guess
(:mod:`cuikslam.hypotheses.guess`) narrows with a coarser tolerance and skips checks the
search makes, so the properties are: where it follows the true correspondence its boxes
hold the truth (exactly, headings mod 2π); with it, a complete search finds the same
survivors as without it, and its proven hypothesis is one of them; under budget cuts the
survivors reported are survivors of the complete search.
"""

from __future__ import annotations

import itertools
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings

from _repeats import once_per_log
from cuikslam.budget import SCHEDULE, Budget
from cuikslam.hypotheses import _shared, search
from cuikslam.hypotheses import guess as guess_module
from cuikslam.hypotheses.dive import dive
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.guess import first_guess, scans
from cuikslam.hypotheses.problem import build_problem
from cuikslam.hypotheses.search import explore, solve_unknown
from cuikslam.hypotheses.survivors import hypothesis_of
from cuikslam.hypotheses.tree import SearchLimit
from cuikslam.outcome.solution import PROVEN, Solution
from cuikslam.results.association import rank_of
from cuikslam.simulate import simulate_random_world
from cuikslam.witness import certify
from worlds import SEARCHED, SMALL, World, correspondence, true_index, truth_misses, worlds

HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]
WORK_CUTS = (3e3, 3e4, 3e5)
PROOF_WORK = 1e6
NODES = {"max_nodes": 4_000}
"""Node expansions of a search before it stops (incomplete: then the world is skipped);
a few of the slow run's worlds would search for hours."""


def _prove(log):
    """The solver's ``prove``: the witness search on one hypothesis, on a budget (it would
    try long to prove a guess that is wrong)."""
    return lambda h, stage: certify(
        log, Solution([h]), deadline=SCHEDULE.share(Budget.start(work=PROOF_WORK), stage)
    )


@once_per_log
def check_guess(world: World, naming: str) -> None:
    log = world.log(naming)
    note("\n".join(world.lines(naming)))
    named = world.named_ids(naming)
    explorer = Explorer(build_problem(log), 1e-3, "hull", 0, True)
    root = explorer.root()
    assume(root is not None)
    guessed = first_guess(explorer, root, SearchLimit(max_nodes=10_000))
    if guessed.leaf is not None:
        assert guessed.leaf.depth == len(explorer.problem.decisions)
        h = hypothesis_of(explorer, guessed.leaf)
        if true_index(Solution([h]), world.truth, named) == 0:
            assert truth_misses(h, world.truth, named) == []
    everything: list[list[str]] = []
    plain = solve_unknown(log, consistency="hull", on_survivor=everything.append, **NODES)
    assume(plain.complete)
    survivors = {correspondence(a, named) for a in everything}
    found: list[list[str]] = []
    proving = solve_unknown(
        log, consistency="hull", on_survivor=found.append, prove=_prove(log), **NODES
    )
    assume(proving.complete)
    assert {correspondence(a, named) for a in found} == survivors
    proven = [h for h in proving.hypotheses if h.status == PROVEN]
    assert all(correspondence(h.assignment, named) in survivors for h in proven)
    if proving.statistics["guess_proven"]:
        assert proving.statistics["dive_nodes"] == 0 and proven
    for work in WORK_CUTS:
        cut = solve_unknown(log, consistency="hull", deadline=Budget.start(work=work),
                            prove=_prove(log))  # fmt: skip
        assert {correspondence(h.assignment, named) for h in cut.hypotheses} <= survivors


@pytest.mark.parametrize("naming", ["none", "mixed"])
@settings(max_examples=6, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_the_guess_holds_the_truth_and_adds_only_survivors(world: World, naming: str) -> None:
    check_guess(world, naming)


@pytest.mark.slow
@pytest.mark.parametrize("naming", ["none", "mixed"])
@settings(max_examples=200, deadline=None, suppress_health_check=HEALTH)
@given(world=worlds(**SMALL))
def test_the_guess_holds_the_truth_and_adds_only_survivors_many(world: World, naming: str) -> None:
    check_guess(world, naming)


def _sparse(n_poses: int, seed: int = 42):
    return simulate_random_world(
        seed=seed, n_poses=n_poses, n_landmarks=15, size=(30.0, 20.0), max_range=6.0,
        unknown=True,
    )  # fmt: skip


def test_scans_cover_the_decisions_in_order() -> None:
    log, _ = _sparse(30)
    explorer = Explorer(build_problem(log), 1e-3, "hull", 0, True)
    ranges = scans(explorer)
    decisions = explorer.problem.decisions
    assert ranges[0][0] == 0 and ranges[-1][1] == len(decisions)
    assert all(a[1] == b[0] for a, b in itertools.pairwise(ranges))
    for first, end in ranges:
        assert len({decisions[k].scan for k in range(first, end)}) == 1
        assert not any(decisions[k].completes_scan for k in range(first, end - 1))


def test_the_guess_proves_a_sparse_world_before_the_dive() -> None:
    """A 60-pose sparse world of 15 look-alike landmarks: the guess reaches the true
    correspondence a scan at a time, the witness search proves it, and the dive does not
    run; the search then completes with the same survivors as without the guess."""
    log, truth = _sparse(60)
    proven = solve_unknown(log, consistency="hull", prove=_prove(log))
    stats = proven.statistics
    assert stats["guess_proven"] == 1 and stats["dive_proven"] == 1
    assert stats["dive_nodes"] == 0 and 0 < stats["guess_scans"] <= len(log.observations)
    assert proven.hypotheses[0].status == PROVEN
    assert rank_of(proven.hypotheses[:1], truth.assignment) == 1
    plain = solve_unknown(log, consistency="hull")
    assert plain.statistics["guess_scans"] == 0  # no prove: no guess
    assert [h.assignment for h in plain.hypotheses] == [h.assignment for h in proven.hypotheses]


def test_a_guess_not_proven_leaves_the_dive_to_run() -> None:
    log, _ = _sparse(30)
    stages: list[str] = []
    solution = solve_unknown(log, consistency="hull", prove=lambda h, stage: stages.append(stage))
    stats = solution.statistics
    assert stats["guess_proven"] == 0 and stats["dive_proven"] == 0
    assert stats["dive_nodes"] >= len(log.observations)
    assert stages == ["guess_proof"]  # the dive's leaf is the guess's: not tried twice


def test_the_guess_stops_on_its_budget() -> None:
    log, _ = _sparse(30)
    explorer = Explorer(build_problem(log), 1e-3, "hull", 0, True)
    root = explorer.root()
    before = dict(vars(explorer.stats))
    guessed = first_guess(explorer, root, SearchLimit(max_nodes=5))
    assert guessed.leaf is None and guessed.scans + guessed.expansions == 5
    assert dict(vars(explorer.stats)) == before


def test_a_refuted_scan_is_decided_again_reading_by_reading() -> None:
    """Every scan at once refuted (a patched check): each is repaired by the search's own
    expansion, and the leaf is the one the dive finds along the first children."""
    log, _ = _sparse(20)
    explorer = Explorer(build_problem(log), 1e-3, "hull", 0, True)
    root = explorer.root()
    with mock.patch.object(guess_module, "_decided", lambda *args: None):
        guessed = first_guess(explorer, root, SearchLimit(max_nodes=100_000))
    assert guessed.leaf is not None and guessed.repairs == len(scans(explorer))
    leaf = dive(explorer, root, SearchLimit(max_nodes=100_000)).leaf
    assert guessed.leaf.decisions() == leaf.decisions()


def test_a_pinned_node_keeps_its_boxes_through_the_graph_s_housekeeping() -> None:
    """The early leaf is held across the exhaustive search, whose housekeeping rebases
    and compacts the shared graph (forced here after every expansion): ``explore``
    re-expresses it, so its boxes and rows are read back unchanged afterwards."""
    log, _ = _sparse(20)
    explorer = Explorer(build_problem(log), 1e-3, "hull", 0, True)
    root = explorer.root()
    leaf = dive(explorer, root, SearchLimit(max_nodes=100_000)).leaf
    every = np.arange(len(explorer.problem.lo))
    boxes = explorer.graph.values(leaf.overlay, every)
    rows = _sorted(explorer.graph.rows_of(leaf.overlay))
    explorer.expansions.clear()
    with (
        mock.patch.object(search, "MAINTAIN_EVERY", 1),
        mock.patch.object(_shared, "MIN_MAINTENANCE_LOAD", 0),
    ):
        outcome = explore(explorer, root, SearchLimit(max_nodes=300), 1, pinned=[leaf])
    [kept] = outcome.pinned
    assert kept is not leaf  # re-expressed
    after = explorer.graph.values(kept.overlay, every)
    assert all(np.array_equal(a, b) for a, b in zip(boxes, after, strict=True))
    assert np.array_equal(_sorted(explorer.graph.rows_of(kept.overlay)), rows)


def _sorted(rows: np.ndarray) -> np.ndarray:
    """Factor rows in one order (the pool numbers them in the order they were added)."""
    return rows[np.lexsort(rows.T[::-1])]


def test_a_scan_s_readings_are_assigned_jointly() -> None:
    """1,000-pose sparse world, seed 4 (50 landmarks of 3 look-alike classes): taken reading
    by reading, nearest first, 35 readings of scans that see two look-alike landmarks side
    by side got them swapped, and nothing refuted the swap; assigned jointly (least total
    distance), the guess is the true correspondence."""
    log, truth = simulate_random_world(
        seed=4, n_poses=1000, n_landmarks=50, size=(30.0, 20.0), max_range=6.0, unknown=True
    )
    explorer = Explorer(build_problem(log), 1e-3, "hull", 0, True)
    guessed = first_guess(explorer, explorer.root(), SearchLimit())
    assert guessed.leaf is not None
    assert rank_of([hypothesis_of(explorer, guessed.leaf)], truth.assignment) == 1
