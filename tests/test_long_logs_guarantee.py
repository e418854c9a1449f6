"""The guarantee on LONG logs: hundreds of poses, so that the ``lp`` level cuts the chain of
windows into parts (:mod:`cuikslam.narrowing.parts`), sweeps each on its own copy of the
boxes and intersects the copies.

The worlds of ``test_guarantee.py`` have 4 to 12 poses: one window, one part. Bugs of
what only a long chain does went unseen there: a variable holding an empty box (the
out-of-view arc of a sensor that sees all around, a sentinel [1, 0]) made the
intersection of the parts "empty", and every hypothesis of a 500-pose log was refuted,
the true one included (fixed in ae15826). These tests draw long worlds from the same
independent generator (:mod:`worlds`, exact truths) with few landmarks and few
observations, so that each solve stays cheap, and check at ``lp``:

(a) known correspondence: never refuted, every box holds the truth;
(b) one to three observations without their landmark id: the search keeps the true
    correspondence, its boxes hold the truth.

Each example checks that its log really has several parts (else it would prove nothing
new). Slow: ``python -m pytest -m slow tests/test_long_logs_guarantee.py`` (each example
takes a few seconds; see ``EXAMPLES``).
"""

from __future__ import annotations

from dataclasses import replace

import pytest
from hypothesis import HealthCheck, Phase, assume, given, note, settings
from hypothesis import strategies as st

from cuikslam.hypotheses import solve_unknown
from cuikslam.hypotheses.problem import build_problem
from cuikslam.narrowing.parts import partition
from cuikslam.narrowing.sweeps import chain_windows
from cuikslam.solver import solve
from test_guarantee import assert_keeps_truth, assert_valid, reported
from worlds import SEARCH_LEVELS, World, truth_misses, worlds

LONG = {
    "poses": (450, 700),
    "landmarks": (2, 4),
    "max_observations": 80,
    "scan_probability": 0.02,
    "max_range": (0.4, 1.6),
    "true_random": True,
    # a sensor without max_range sees (nearly) every landmark from every pose: too many
    # observations for a long log
    "sensors": ("none", "R", "RF", "RM", "RFM"),
}
"""Sizes of :func:`worlds.worlds` for long logs: 450 to 700 poses (at least 405 make two
parts), 2 to 4 landmarks, a short sensor range, so that most worlds have a few dozen
observations."""
EXAMPLES = 25
"""Worlds per test in the slow run (about 2 s each with known correspondence, 2 to 30 s
with a search: a minute and a few minutes)."""
BUDGET = {"max_nodes": 2_000}

HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]
long_run = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=HEALTH,
    # no shrinking: a long world shrinks for many minutes and stays long (its size is what
    # matters); set CUIKSLAM_GUARANTEE_FAILURES to have a failing world written out
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
)


def parts_of(world: World, naming: str) -> int:
    """The parts the ``lp`` sweeps cut the log's chain into."""
    problem = build_problem(world.log(naming))
    return len(partition(len(chain_windows(problem.root_rows))))


def few_unnamed(world: World, picks: list[int]) -> World:
    """``world`` with every observation named but those at ``picks`` (mod the count)."""
    unnamed = {p % world.n_observations for p in picks}
    return replace(world, named=[k not in unnamed for k in range(world.n_observations)])


@pytest.mark.slow
@long_run
@given(world=worlds(**LONG))
def test_long_log_known_correspondence_keeps_the_truth_at_lp(world: World) -> None:
    """(a): the true correspondence given, at ``lp`` over several parts."""
    with reported(world, "all"):
        assert_valid(world, "all")
        assert parts_of(world, "all") >= 2
        solution = solve(world.log("all"), consistency="lp", certify_limit=0)
        assert not solution.refuted, f"a consistent long log refuted: {solution.messages}"
        [h] = solution.hypotheses
        assert h.assignment == world.truth.assignment
        assert truth_misses(h, world.truth, world.named_ids("all")) == []


@pytest.mark.slow
@long_run
@given(
    world=worlds(**LONG),
    picks=st.lists(st.integers(0, 10**6), min_size=1, max_size=3),
)
def test_long_log_few_unlabelled_readings_keep_the_truth_at_lp(
    world: World, picks: list[int]
) -> None:
    """(b): one to three observations name no landmark; the search at ``lp`` (its
    survivors narrowed over several parts) keeps the true correspondence and the truth."""
    assume(world.n_observations >= 1)
    world = few_unnamed(world, picks)
    with reported(world, "mixed"):
        assert_valid(world, "mixed")
        assert parts_of(world, "mixed") >= 2
        solution = solve_unknown(world.log("mixed"), **BUDGET, **SEARCH_LEVELS["lp"])
        note(f"{len(solution.hypotheses)} survivors, complete: {solution.complete}")
        assert solution.complete, solution.messages
        assert_keeps_truth(world, "mixed", solution)
