"""The dive finds a hypothesis early, cuts nothing, and its leaf is a survivor of the search.

Random true worlds from the independent generator (:mod:`worlds`). The dive follows the
same rules as the exhaustive search, so every leaf it contributes must be a survivor of a
complete search; the truth is never lost whatever the budget (the envelope holds it:
:mod:`test_envelope`), and a search cut by its budget after the dive found a leaf still
reports a hypothesis.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings

from _repeats import once_per_log
from cuikslam.budget import Budget
from cuikslam.hypotheses import _shared, search, solve_unknown
from cuikslam.hypotheses.dive import dive
from cuikslam.hypotheses.expansions import Expansions
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.problem import build_problem
from cuikslam.hypotheses.tree import SearchLimit
from cuikslam.log.records import Log
from cuikslam.options import SolveOptions
from cuikslam.results.association import partition
from cuikslam.results.io import solution_to_json
from cuikslam.results.solution import PROVEN, Solution
from cuikslam.simulate import simulate_paper, simulate_random_world
from cuikslam.solver import solve
from cuikslam.witness import certify
from worlds import SEARCHED, SMALL, World, worlds

HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]
WORK_CUTS = (1.0, 3e3, 1e4, 3e4)
MAX_NODES = 5_000
"""Expansions of the complete search the slow property waits for: a random world whose
search is not complete within them is assumed away (unlimited, one world's search took
more than a minute, and the slow run did not finish in 25 minutes)."""


def _named(log) -> set[str]:
    return {p.landmark for p in log.landmark_priors} | {
        str(o.landmark) for o in log.observations if o.landmark is not None
    }


@contextmanager
def maintained_at_every_expansion() -> Iterator[None]:
    """The shared graph rebased and compacted after every node expansion (a long search
    does so every ``MAINTAIN_EVERY`` expansions once its overlays have doubled)."""
    with (
        mock.patch.object(search, "MAINTAIN_EVERY", 1),
        mock.patch.object(_shared, "MIN_MAINTENANCE_LOAD", 0),
    ):
        yield


@once_per_log
def check_dive(
    world: World, naming: str, maintained: bool = False, max_nodes: int | None = None
) -> None:
    """Every leaf a search cut at each work budget finds is a survivor of the complete
    search (of at most ``max_nodes`` expansions, None: no limit; a world whose search needs
    more is assumed away), and a cut search whose dive found a leaf reports a hypothesis."""
    log = world.log(naming)
    note("\n".join(world.lines(naming)))
    named = _named(log)
    everything: list[list[str]] = []
    complete = solve_unknown(
        log, consistency="hull", max_nodes=max_nodes, on_survivor=everything.append
    )
    assume(complete.complete)
    survivors = {tuple(partition(a, named)) for a in everything}
    for work in WORK_CUTS:
        found: list[list[str]] = []
        with maintained_at_every_expansion() if maintained else nullcontext():
            cut = solve_unknown(
                log, consistency="hull", deadline=Budget.start(work=work), on_survivor=found.append
            )
        assert {tuple(partition(a, named)) for a in found} <= survivors, work
        if cut.statistics["dive_discrepancies"] >= 0 and not cut.refuted:
            assert cut.hypotheses, (work, cut.messages)


@pytest.mark.parametrize("naming", ["none", "mixed"])
@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_the_dive_adds_only_survivors_of_the_search(world: World, naming: str) -> None:
    check_dive(world, naming)


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_the_dive_adds_only_survivors_when_the_search_maintains_its_graph(world: World) -> None:
    check_dive(world, "none", maintained=True)


def test_the_resumed_dive_starts_from_the_root_after_the_graph_was_maintained() -> None:
    """A search that found nothing lets the dive go on; once the search's housekeeping had
    moved the shared graph's base, the root it went on from read the moved base: 3,048
    bounds narrower than the root's on Lost in the Woods without ids (2,000 steps), and one
    decision's row among the root's (found by reading the code after an adversarial run)."""
    log = simulate_random_world(seed=0, n_poses=40, n_landmarks=12, unknown=True)[0]
    fresh = Explorer.of(build_problem(log), SolveOptions())
    root = fresh.root()
    assert root is not None
    truth_lo, truth_hi = fresh.graph.materialize(root.overlay)
    resumed: list[tuple[np.ndarray, np.ndarray]] = []
    started = search.dive

    def spy(explorer, start, limit, resume=None, tracker=None):
        if resume is not None:
            resumed.append(explorer.graph.materialize(start.overlay))
        return started(explorer, start, limit, resume, tracker)

    with maintained_at_every_expansion(), mock.patch.object(search, "dive", spy):
        cut = solve_unknown(log, consistency="hull", deadline=Budget.start(work=3e4))
    assert not cut.complete and not cut.hypotheses and len(resumed) == 1
    lo, hi = resumed[0]
    assert np.array_equal(lo, truth_lo) and np.array_equal(hi, truth_hi)


@pytest.mark.slow
@pytest.mark.parametrize("naming", ["none", "mixed"])
@settings(max_examples=300, deadline=None, suppress_health_check=HEALTH)
@given(world=worlds(**SMALL))
def test_the_dive_adds_only_survivors_of_the_search_many(world: World, naming: str) -> None:
    check_dive(world, naming, max_nodes=MAX_NODES)


def test_the_dive_leaves_the_search_statistics_as_they_were() -> None:
    log, _ = simulate_random_world(seed=3, n_poses=20, n_landmarks=6, unknown=True)
    explorer = Explorer(build_problem(log), 1e-3, "hull", 0, True)
    root = explorer.root()
    before = dict(vars(explorer.stats))
    found = dive(explorer, root, SearchLimit(max_nodes=10_000))
    assert found.leaf is not None and found.nodes >= len(explorer.problem.decisions)
    assert found.discrepancies == 0  # the likeliest path holds a survivor here
    assert dict(vars(explorer.stats)) == before


def test_the_dive_reaches_a_leaf_of_a_sparse_world_within_its_share() -> None:
    """A 60-pose sparse world of 15 look-alike landmarks (189 readings, none labelled): the
    dive's quarter of the search's budget reaches a leaf along the likeliest path, and
    the search with the rest completes with that leaf among its survivors."""
    log, _ = simulate_random_world(
        seed=42, n_poses=60, n_landmarks=15, size=(30.0, 20.0), max_range=6.0, unknown=True
    )
    found: list[list[str]] = []
    solution = solve_unknown(
        log, consistency="hull", deadline=Budget.start(work=1e7), on_survivor=found.append
    )
    assert solution.statistics["dive_discrepancies"] == 0
    assert solution.statistics["dive_nodes"] >= len(log.observations)
    assert solution.complete and solution.hypotheses


def _certify_one(log):
    """The solver's ``prove``: the witness search on one hypothesis."""

    def prove(hypothesis, stage) -> None:
        certify(log, Solution([hypothesis]))

    return prove


def test_the_dive_leaf_is_proven_before_the_exhaustive_search() -> None:
    """The seed's experiment without ids: the witness search proves the dive's leaf as soon
    as it is found, and the report keeps that proof (the witness lies in the hypothesis'
    final boxes, narrowed to ``lp`` after the proof)."""
    log, _ = simulate_paper(seed=0, unknown=True)
    proved: list[list[str]] = []

    def prove(hypothesis, stage) -> None:
        _certify_one(log)(hypothesis, stage)
        if hypothesis.status == PROVEN:
            proved.append(hypothesis.assignment)

    solution = solve_unknown(log, consistency="lp", prove=prove)
    assert solution.statistics["dive_proven"] == 1 and len(proved) == 1
    assert solution.statistics["dive_proven_work"] == 0  # no budget: nothing metered
    [early] = [h for h in solution.hypotheses if h.assignment == proved[0]]
    assert early.status == PROVEN and early.consistency == "lp"
    for boxes, points in ((early.poses[:, :2], early.witness["poses_xyt"][:, :2]),
                          (early.landmarks, early.witness["landmarks_xy"])):  # fmt: skip
        assert np.all(boxes[..., 0] <= points) and np.all(points <= boxes[..., 1])
    assert solution.hypotheses[0] is early  # a proven hypothesis ranks first
    witness = early.witness
    others = [h for h in solution.hypotheses if h is not early]
    searched = certify(log, solution)  # the early proof is kept, not searched again
    assert early.status == PROVEN and early.witness is witness
    assert searched.starts >= len(others) > 0
    assert solution.statistics["proven_hypotheses"] == sum(
        h.status == PROVEN for h in solution.hypotheses
    )


def test_a_leaf_not_proven_leaves_the_report_as_it_was() -> None:
    log, _ = simulate_paper(seed=0, unknown=True)
    calls: list[int] = []
    plain = solve_unknown(log, consistency="hull")
    tried = solve_unknown(
        log, consistency="hull", prove=lambda h, stage: calls.append(len(h.assignment))
    )
    assert calls == [len(log.observations)]
    assert tried.statistics["dive_proven"] == 0
    assert [h.assignment for h in tried.hypotheses] == [h.assignment for h in plain.hypotheses]
    assert all(h.status != PROVEN for h in tried.hypotheses)


def test_the_solver_proves_the_dive_leaf_within_the_budget() -> None:
    """``solve`` gives the dive's leaf to the witness search (its share of the work
    budget): on a 60-pose sparse world of look-alike landmarks the hypothesis is proven
    before the exhaustive search goes on, and the work it took is recorded."""
    log, _ = simulate_random_world(
        seed=42, n_poses=60, n_landmarks=15, size=(30.0, 20.0), max_range=6.0, unknown=True
    )
    solution = solve(log, consistency="hull", work_budget=1e7)
    stats = solution.statistics
    assert stats["dive_proven"] == 1
    assert 0 < stats["dive_proven_work"] <= stats["work_spent"]
    assert solution.hypotheses[0].status == PROVEN
    assert "dive_proven_s" in solution.timings


def _without_work(solution: Solution) -> dict:
    """The result JSON less its timings and the operator applications: the work done
    once where it was done twice before."""
    data = solution_to_json(solution)
    data.pop("timings", None)
    data["statistics"].pop("operator_applications")
    return data


@once_per_log
def check_kept_expansions(world: World, naming: str) -> None:
    log = world.log(naming)
    note("\n".join(world.lines(naming)))
    limit = {"consistency": "hull", "max_nodes": 400}
    reused = solve_unknown(log, **limit)
    with mock.patch.object(Expansions, "keep", lambda *args: None):
        again = solve_unknown(log, **limit)
    assert _without_work(reused) == _without_work(again)


@pytest.mark.parametrize("naming", ["none", "mixed"])
@settings(max_examples=10, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_the_search_taking_back_the_dive_s_expansions_gives_the_same_result(
    world: World, naming: str
) -> None:
    """The exhaustive search takes back the expansions the dive made
    (:mod:`cuikslam.hypotheses.expansions`): its result, statistics included, is the one it
    gets expanding every node itself (a node budget: the same nodes counted), but for the
    operator applications, fewer by what is no longer done twice."""
    check_kept_expansions(world, naming)


def _sparse_60() -> Log:
    """A 60-pose sparse world without landmark ids."""
    return simulate_random_world(
        seed=42, n_poses=60, n_landmarks=15, size=(30.0, 20.0), max_range=6.0, unknown=True
    )[0]


def _counting_take(taken: list[bool]):
    """``Expansions.take`` that appends to ``taken`` whether it gave an expansion back."""
    original = Expansions.take

    def counting(self, node, stats):
        out = original(self, node, stats)
        taken.append(out is not None)
        return out

    return mock.patch.object(Expansions, "take", counting)


def test_the_search_takes_back_the_dive_s_path() -> None:
    """On a 60-pose sparse world the dive's path is as long as the log's readings, and the
    search takes back every expansion on it instead of making it again."""
    log = _sparse_60()
    taken: list[bool] = []
    with _counting_take(taken):
        solution = solve_unknown(log, consistency="hull")
    assert solution.complete
    assert sum(taken) >= len(log.observations)


def test_the_kept_expansions_stop_at_their_memory_cap() -> None:
    """Past ``MAX_KEPT_BYTES`` of children's overlays the dive keeps no more expansions
    (the whole Victoria Park run peaked at 5.2 GB without a cap) and the search expands
    those nodes itself: the same result, fewer expansions taken back."""
    from cuikslam.hypotheses import expansions

    log = _sparse_60()
    taken: list[bool] = []
    limit = {"consistency": "hull"}
    with _counting_take(taken):
        whole = solve_unknown(log, **limit)
        kept_all = sum(taken)
        taken.clear()
        with mock.patch.object(expansions, "MAX_KEPT_BYTES", 20_000):
            capped = solve_unknown(log, **limit)
    assert 0 < sum(taken) < kept_all
    assert _without_work(whole) == _without_work(capped)
