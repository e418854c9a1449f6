"""The correspondence search's progress (issue 28: "progress a user can trust").

Random true worlds from the independent generator (:mod:`worlds`), each search reporting
after every node expansion: a reading reported decided stays decided, is associated alike
by every survivor and by the truth, and the bounds on the number of survivors hold.
"""

from __future__ import annotations

import io
import math
import sys
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings

from cuikslam.cli._common import progress_bar
from cuikslam.hypotheses import finish, search
from cuikslam.hypotheses.progress import SearchProgress, association_keys, decided_after_stop
from cuikslam.hypotheses.search import solve_unknown
from cuikslam.outcome.solution import OUTLIER
from cuikslam.simulate import simulate_paper
from worlds import SEARCHED, SMALL, World, worlds

HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]


def associations(assignment: list[str], named: set[str]) -> list[object]:
    """What each observation is associated with, written for the test: the index of the
    last earlier observation of its landmark, else its name when named, "new" for a
    first sighting of an anonymous landmark; an outlier as such."""
    last: dict[str, int] = {}
    out: list[object] = []
    for i, landmark in enumerate(assignment):
        if landmark == OUTLIER:
            out.append(OUTLIER)
            continue
        out.append(last.get(landmark, landmark if landmark in named else "new"))
        last[landmark] = i
    return out


MAX_NODES = 5_000
"""Expansions of a whole search the properties wait for: a random world whose tree is
larger is assumed away (its search reports after every expansion, and one such world
once held a run of 80 examples for more than 30 minutes)."""


def _reports(log, **options) -> tuple[list[SearchProgress], object]:
    """The search's reports, one after every expansion, and its solution."""
    reports: list[SearchProgress] = []
    with mock.patch.object(search, "REPORT_EVERY", 1):
        solution = solve_unknown(
            log, progress=lambda done, total, status: reports.append(status), **options
        )
    return reports, solution


def check_decided(world: World) -> None:
    """A decided reading stays decided, and every survivor and the truth agree on it."""
    log = world.log("mixed")
    assume(log.has_unknown_correspondence)
    note("\n".join(world.lines("mixed")))
    reports, solution = _reports(
        log, consistency="hull", max_hypotheses=10_000, max_nodes=MAX_NODES
    )
    assume(solution.complete)
    named = world.named_ids("mixed")
    truth = associations(list(world.truth.assignment), named)
    rows = [associations(h.assignment, named) for h in solution.hypotheses]
    searched = [r for r in reports if r.stage != "dive"]
    assert searched and searched[-1].stage == "done" and searched[-1].pending == 0
    check_reports(searched, rows, solution.statistics["survivors"], truth)
    assert searched[-1].found >= solution.statistics["survivors"]


def check_reports(
    searched: list[SearchProgress], rows: list[list[object]], survivors: int, truth: list[object]
) -> None:
    """Reports in order: a decided reading stays decided, every survivor's ``rows`` and the
    ``truth`` associate it alike, and the upper bound holds the ``survivors``."""
    before: set[int] = set()
    for status in searched:
        now = set(status.decided_positions)
        assert before <= now, "a decided reading was taken back"
        before = now
        for i in now:
            assert all(row[i] == truth[i] for row in rows), (i, status)
        assert status.found <= searched[-1].found
        assert survivors <= 10**status.upper_log10 * (1 + 1e-9) or survivors == 0


def check_cuts(world: World, cuts: tuple[int, ...]) -> None:
    """A search cut at each node budget: every reading its reports call decided is
    associated alike by every survivor of the complete search and by the truth, and its
    upper bound holds their number."""
    log = world.log("none")
    assume(log.has_unknown_correspondence)
    note("\n".join(world.lines("none")))
    whole = solve_unknown(log, consistency="hull", max_hypotheses=10_000, max_nodes=MAX_NODES)
    assume(whole.complete)
    truth = associations(list(world.truth.assignment), set())
    rows = [associations(h.assignment, set()) for h in whole.hypotheses]
    for cut in cuts:
        said: list[tuple[int, ...]] = []
        with mock.patch.object(finish, "decided_after_stop", _spy(said)):
            reports, cut_solution = _reports(log, consistency="hull", max_nodes=cut)
        for status in reports:
            if status.stage == "dive":
                continue
            for i in status.decided_positions:
                assert all(row[i] == truth[i] for row in rows), (cut, i, status)
            assert whole.statistics["survivors"] <= 10**status.upper_log10 * (1 + 1e-9)
        # what the result's message counts as decided when the cut stops the search
        assert len(said) == (not cut_solution.complete)
        for i in said[0] if said else ():
            assert all(row[i] == truth[i] for row in rows), (cut, i, "message")


def _spy(said: list[tuple[int, ...]]):
    """``decided_after_stop`` that keeps what it returns in ``said``."""

    def spy(*args):
        out = decided_after_stop(*args)
        said.append(out)
        return out

    return spy


@settings(max_examples=8, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_a_decided_reading_stays_decided_and_the_truth_agrees(world: World) -> None:
    check_decided(world)


@settings(max_examples=5, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**SEARCHED))
def test_what_a_cut_search_reports_decided_holds_for_the_whole_search(world: World) -> None:
    check_cuts(world, (1, 3, 8))


@pytest.mark.slow
@settings(max_examples=150, deadline=None, suppress_health_check=HEALTH)
@given(world=worlds(**SMALL))
def test_a_decided_reading_stays_decided_and_the_truth_agrees_many(world: World) -> None:
    check_decided(world)


@pytest.mark.slow
@settings(max_examples=80, deadline=None, suppress_health_check=HEALTH)
@given(world=worlds(**SMALL))
def test_what_a_cut_search_reports_decided_holds_for_the_whole_search_many(world: World) -> None:
    check_cuts(world, (1, 2, 3, 5, 8, 13, 21))


def test_the_seed_experiment_reports_its_one_ambiguous_reading() -> None:
    """13 readings, 2 survivors that differ in one: 12 decided at the end, and the upper
    bound is then the count itself."""
    log = simulate_paper(seed=0, unknown=True)[0]
    reports, solution = _reports(log, consistency="hull")
    last = reports[-1]
    assert (last.stage, last.readings, last.decided, last.pending) == ("done", 13, 12, 0)
    assert last.found == 2 and math.isclose(last.upper_log10, math.log10(2))
    assert sum(solution.correspondence["certain"]) == 12
    assert last.describe() == "12 of 13 readings decided · 2 survivors found · exactly 2 left"


def test_a_callback_of_two_arguments_gets_decided_readings_of_readings() -> None:
    log = simulate_paper(seed=0, unknown=True)[0]
    calls: list[tuple[int, int]] = []
    solve_unknown(log, consistency="hull", progress=lambda done, total: calls.append((done, total)))
    assert calls[-1] == (12, 13)


def test_association_keys_do_not_depend_on_landmark_numbers() -> None:
    """Two numberings of one partition (anonymous landmarks 3 and 4 swapped) give the same
    keys; a different partition does not; a labelled sighting between counts."""
    positions = np.arange(4)
    same = association_keys([3, 4, 3, 0], positions, {}, 2)
    assert same.tolist() == association_keys([4, 3, 4, 0], positions, {}, 2).tolist()
    assert same.tolist() != association_keys([3, 4, 4, 0], positions, {}, 2).tolist()
    assert association_keys([0, 0], np.array([0, 2]), {1: 0}, 1).tolist() == [-3, 1]


def test_the_terminal_bar_shows_the_search_status() -> None:
    status = SearchProgress("search", 1052, 480, 3, 1, 52, 17.5, 900, 0.9)
    stream = io.StringIO()
    stream.isatty = lambda: True  # type: ignore[method-assign]
    with (
        mock.patch.object(sys, "stderr", stream),
        mock.patch.dict("os.environ", {"COLUMNS": "120"}),
        progress_bar("solving") as advance,
    ):
        assert advance is not None
        advance(480, 1052, status)
    shown = stream.getvalue()
    assert "480/1052" in shown
    assert "decided · 3 found, 1 proven · at most 10^17 · 52 pending" in shown
