"""Bisection of the survivors (``cuikslam.hypotheses.bisection``): it refutes hypotheses
that narrowing the whole box leaves, never the truth, and always stops.

The log of ``tests/data/bisection`` comes from the independent generator (``worlds.py``):
unlabelled observations of two classes, a sensor record, landmark priors; its exact truth
is beside it. The soundness of bisection on random worlds is tested in
``test_guarantee.py`` (every search there bisects its survivors).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import cuikslam.hypotheses.survivors as after_search
from cuikslam.budget import Budget
from cuikslam.hypotheses import solve_unknown
from cuikslam.hypotheses.bisection import Bisection, refute_by_bisection
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.problem import build_problem
from cuikslam.log import Log, read_log_file
from cuikslam.narrowing.propagation import DEFAULT_RTOL
from cuikslam.results.association import partition
from cuikslam.simulate import simulate_paper
from worlds import Truth, correspondence, true_index, truth_misses

LOG = Path(__file__).parent / "data" / "bisection" / "bisection-refutes.jsonl"


@pytest.fixture(scope="module")
def log() -> Log:
    return read_log_file(LOG)


@pytest.fixture(scope="module")
def truth() -> Truth:
    return Truth.from_file(LOG.with_name(LOG.stem + ".truth.json"))


def _bisections(log: Log, prefixes: list[list[int]] | None = None) -> list[Bisection]:
    """Bisections of the search's survivors (or of the nodes of ``prefixes``)."""
    problem = build_problem(log)
    explorer = Explorer(problem, DEFAULT_RTOL, "hull", 0)
    poses = np.array(sorted(problem.pose_x.values()), dtype=np.int64)
    out = []
    for prefix in prefixes or []:
        node = explorer.replay(prefix)
        assert node is not None
        lo, hi, arrays = explorer.graph.standalone(node.overlay)
        out.append(Bisection(lo, hi, arrays, poses, explorer.landmark_xs(node)))
    return out


def _no_bisection_after_the_search(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(after_search, "BISECTION_MIN_PARTS", 0)
    monkeypatch.setattr(after_search, "BISECTION_PARTS_PER_NODE", 0)


def test_bisection_refutes_survivors_and_keeps_the_truth(
    log: Log, truth: Truth, monkeypatch: pytest.MonkeyPatch
) -> None:
    bisected = solve_unknown(log, consistency="hull")
    _no_bisection_after_the_search(monkeypatch)
    monkeypatch.setattr("cuikslam.hypotheses.explorer.LEAF_BISECTION_PARTS", 0)
    whole = solve_unknown(log, consistency="hull")
    assert bisected.complete and whole.complete
    assert whole.statistics["refuted_by_bisection"] == 0
    refuted = bisected.statistics["refuted_by_bisection"]
    assert refuted > 0
    assert len(bisected.hypotheses) == len(whole.hypotheses) - refuted
    named = {r.landmark for r in log.landmark_priors}
    kept = {correspondence(h.assignment, named) for h in bisected.hypotheses}
    assert kept < {correspondence(h.assignment, named) for h in whole.hypotheses}
    i = true_index(bisected, truth, named)
    assert i >= 0, "bisection refuted the true correspondence"
    assert truth_misses(bisected.hypotheses[i], truth, named) == []
    assert any("bisection proved" in m for m in bisected.messages)


def test_leaves_refuted_by_bisection_are_never_survivors(
    log: Log, truth: Truth, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Bisected as the search reaches them (the survivors' round after it is off), refuted
    leaves are neither counted nor streamed; the truth is among those left."""
    _no_bisection_after_the_search(monkeypatch)
    streamed: list[list[str]] = []
    solution = solve_unknown(log, consistency="hull", on_survivor=streamed.append)
    assert solution.complete and solution.statistics["refuted_by_bisection"] > 0
    assert len(streamed) == solution.statistics["survivors"] == len(solution.hypotheses)
    named = {r.landmark for r in log.landmark_priors}
    i = true_index(solution, truth, named)
    assert i >= 0, "bisection refuted the true correspondence"
    assert truth_misses(solution.hypotheses[i], truth, named) == []


def test_a_box_with_nothing_to_split_ends_the_bisection(log: Log, truth: Truth) -> None:
    (whole,) = _bisections(log, [[]])
    nothing = Bisection(
        whole.lo, whole.hi, whole.arrays, np.zeros(0, np.int64), np.zeros(0, np.int64)
    )
    assert refute_by_bisection([nothing], None, 100) == [False]
    assert nothing.exhausted and not nothing.refuted
    assert nothing.narrowed_parts == 0
    lo, hi = nothing.best()
    assert np.array_equal(lo, whole.lo) and np.array_equal(hi, whole.hi)


def test_each_bisection_gets_its_share_whatever_the_others_do(log: Log) -> None:
    """The total budget is split evenly (16 parts each of 50 among 3, give or take one
    split), so a bisection run with others proves what it proves alone: the survivors'
    bisections can be split among workers with the same result."""
    together = _bisections(log, [[], [], []])
    refute_by_bisection(together, None, max_parts=1000, max_total_parts=50)
    assert all(16 <= b.narrowed_parts <= 17 for b in together)
    (alone,) = _bisections(log, [[]])
    refute_by_bisection([alone], None, max_parts=1000, max_total_parts=16)
    assert alone.narrowed_parts == together[0].narrowed_parts
    assert len(alone.parts) == len(together[0].parts)
    for (lo_a, hi_a), (lo_t, hi_t) in zip(alone.parts, together[0].parts, strict=True):
        assert np.array_equal(lo_a, lo_t) and np.array_equal(hi_a, hi_t)


def test_a_deadline_in_the_past_stops_before_any_work(log: Log) -> None:
    (b,) = _bisections(log, [[]])
    spent = Budget.start(work=0.0)
    assert refute_by_bisection([b], deadline=spent, max_parts=100) == [False]
    assert b.narrowed_parts == 0 and len(b.parts) == 1


def test_a_bisection_whose_waiting_parts_outgrow_the_limit_gives_up(log: Log) -> None:
    """Memory stays bounded: beyond ``max_pending`` waiting parts a bisection stops for good,
    its hypothesis not refuted and its deepest part kept for the witness; with room it runs
    as before."""
    (tight,) = _bisections(log, [[]])
    tight.run(None, max_parts=200, max_pending=2)
    assert tight.gave_up and tight.exhausted and not tight.refuted
    assert tight.parts == [] and tight.best() is not None
    assert tight.narrowed_parts < 200
    (roomy,) = _bisections(log, [[]])
    roomy.run(None, max_parts=tight.narrowed_parts, max_pending=10_000)
    assert not roomy.gave_up
    assert roomy.narrowed_parts == tight.narrowed_parts
    assert len(roomy.parts) > 2


def test_survivors_refuted_after_the_search_give_their_place_to_the_next(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """When the bisection after the search refutes the survivors kept for the report, the
    next best-ranked ones the search counted are bisected in their place, so the report
    is not left empty while survivors wait (a sparse 200-pose world reported none of 50)."""
    log, _ = simulate_paper(seed=0, unknown=True)
    rounds: list[list[tuple[int, ...]]] = []
    refuting = [False]

    def refute_the_first_round(explorer, nodes, limit, refute):  # type: ignore[no-untyped-def]
        rounds.append([tuple(n.decisions()) for n in nodes])
        return [] if refuting[0] and len(rounds) == 1 else nodes

    monkeypatch.setattr(after_search, "bisect_survivors", refute_the_first_round)
    whole = solve_unknown(log, consistency="hull", max_hypotheses=3, local_frame=False)
    rounds.clear()
    refuting[0] = True
    solution = solve_unknown(log, consistency="hull", max_hypotheses=3, local_frame=False)
    assert whole.statistics["survivors"] > 6
    assert [len(r) for r in rounds] == [3, 3]
    assert not set(rounds[0]) & set(rounds[1])
    assert solution.statistics["survivors"] == whole.statistics["survivors"] - 3
    shown = {tuple(partition(h.assignment, set())) for h in solution.hypotheses}
    before = {tuple(partition(h.assignment, set())) for h in whole.hypotheses}
    assert len(shown) == 3
    assert not shown & before


def test_a_report_refuted_by_the_stronger_level_is_refilled(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """When the stronger level refutes every reported survivor, the next best-ranked ones
    the search kept in reserve are narrowed in their place: the report is not empty
    while survivors are counted (``--max-hypotheses 1`` left none of 29,266)."""
    log, _ = simulate_paper(seed=0, unknown=True)
    real = after_search.strengthen_report
    calls: list[int] = []

    def refute_the_first_report(explorer, report, *args):  # type: ignore[no-untyped-def]
        calls.append(len(report))
        if len(calls) == 1:
            return [], report, "lp"
        return real(explorer, report, *args)

    monkeypatch.setattr(after_search, "strengthen_report", refute_the_first_report)
    solution = solve_unknown(log, consistency="lp", max_hypotheses=1, local_frame=False)
    assert calls == [1, 1]
    assert len(solution.hypotheses) == 1
    assert solution.hypotheses[0].consistency == "lp"
    total = solve_unknown(log, consistency="hull", max_hypotheses=1, local_frame=False)
    assert solution.statistics["survivors"] == total.statistics["survivors"] - 1
