"""The guarantee, on random true worlds from an independent generator (:mod:`worlds`).

When every measured interval contains its true value:

(a) solving with the true correspondence given (every observation named) is never
    refuted, and every box contains the truth (exactly; headings modulo 2π);
(b) the unknown-correspondence search keeps the true correspondence whenever it says it is
    complete, and its boxes contain the truth, at every level: ``hull``,
    ``lp`` after the search, and ``lp`` during it (``strengthen_during``);
(c) the same for mixed logs, where some observations name their landmark.

Worlds come with every kind of ``sensor`` record (or none), landmark priors, clustered
landmarks and revisits. The default run checks several hundred worlds, the same ones
each time (``derandomize``), its searches on logs of up to 10 observations;
``python -m pytest -m slow tests/test_guarantee.py`` checks thousands of new ones, its
searches on logs of up to 14. Set ``CUIKSLAM_GUARANTEE_FAILURES`` to a folder to have each
failing world written there as a log and its truth file (the last one written for a test
is Hypothesis' minimal example).
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st
from hypothesis.errors import UnsatisfiedAssumption

from _repeats import once_per_log, once_per_world
from cuikslam.hypotheses import solve_unknown
from cuikslam.hypotheses.bisection import Bisection, refute_by_bisection
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.problem import build_problem
from cuikslam.narrowing.propagation import DEFAULT_RTOL
from cuikslam.results.solution import Solution
from cuikslam.solver import solve
from worlds import (
    SEARCH_LEVELS,
    SEARCHED,
    SENSOR_KINDS,
    SMALL,
    World,
    log_violations,
    search_level,
    true_index,
    truth_misses,
    worlds,
)

HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]


def ci(n: int) -> settings:
    """The default run: ``n`` worlds, the same every time."""
    return settings(max_examples=n, deadline=None, derandomize=True, suppress_health_check=HEALTH)


def slow(n: int) -> settings:
    """The ``slow`` run: ``n`` new worlds each time."""
    return settings(max_examples=n, deadline=None, suppress_health_check=HEALTH)


TINY = {"poses": (3, 6), "landmarks": (2, 4), "max_observations": 8}
"""Worlds for the ``lp`` searches (an LP per survivor)."""
BUDGET = {"max_nodes": 2_000}
"""Node expansions before a search stops, incomplete (then it proves nothing)."""
LP_SURVIVORS = 10
"""The ``lp`` searches run on worlds whose ``hull`` search leaves at most this many
survivors (``lp`` costs an LP per variable of each; some tiny worlds leave 1,600)."""


@contextmanager
def reported(world: World, naming: str) -> Iterator[None]:
    """On failure: print the world with Hypothesis' report, and save it when asked to."""
    note(world.notes[0])
    note("\n".join(world.lines(naming)))
    note(f"true landmarks of the observations: {world.truth.assignment}")
    try:
        yield
    except UnsatisfiedAssumption:
        raise
    except BaseException:
        folder = os.environ.get("CUIKSLAM_GUARANTEE_FAILURES")
        if folder:
            test = os.environ.get("PYTEST_CURRENT_TEST", "test").split("::")[-1].split(" ")[0]
            stem = "".join(c if c.isalnum() or c in "-_" else "-" for c in test).strip("-")
            world.save(Path(folder), stem, naming)
        raise


def assert_valid(world: World, naming: str) -> None:
    """The log measures the world: every interval holds the truth, every sensor rule holds."""
    assert log_violations(world.log(naming), world.truth) == []


def assert_keeps_truth(world: World, naming: str, solution: Solution) -> None:
    """A complete search kept the true correspondence, with the truth in all its boxes, and
    every survivor keeps the names the log gives."""
    log = world.log(naming)
    named = [(k, o.landmark) for k, o in enumerate(log.observations) if o.landmark is not None]
    for h in solution.hypotheses:
        assert all(h.assignment[k] == lid for k, lid in named), "a named observation renamed"
    index = true_index(solution, world.truth, world.named_ids(naming))
    survivors = solution.statistics.get("survivors", len(solution.hypotheses))
    if solution.complete and survivors <= len(solution.hypotheses):  # all reported
        assert index >= 0, (
            f"complete search, {len(solution.hypotheses)} survivors, the true correspondence "
            f"{world.truth.assignment} discarded; {solution.messages}"
        )
    if index >= 0:
        misses = truth_misses(solution.hypotheses[index], world.truth, world.named_ids(naming))
        assert misses == [], misses[:5]


# --- the generator itself ----------------------------------------------------------------


@ci(60)
@given(worlds())
def test_generated_logs_measure_their_world(world: World) -> None:
    """Every generated log is valid and holds the truth: else the tests below prove nothing."""
    for naming in ("all", "none", "mixed"):
        with reported(world, naming):
            assert_valid(world, naming)
    log = world.log("all")
    assert [o.landmark for o in log.observations] == world.truth.assignment
    assert (log.sensor is None) == (world.sensor is None)


def test_the_generator_makes_every_kind_of_world() -> None:
    """Sensor kinds, priors, clusters, mixed naming and ambiguity all occur."""
    seen: Counter[str] = Counter()

    @settings(max_examples=400, deadline=None, derandomize=True, suppress_health_check=HEALTH)
    @given(worlds())
    def census(world: World) -> None:
        kind = world.notes[0].split("sensor ")[1].split(",")[0]
        seen[f"sensor {kind}"] += 1
        types = [r["type"] for r in world.records]
        odometry = [(r["from"], r["to"]) for r in world.records if r["type"] == "odometry"]
        seen["loop closure"] += len({to for _, to in odometry}) < len(odometry)
        seen["pose ids not in time order"] += "shuffled" in world.notes[0]
        seen["landmark prior"] += "landmark" in types
        seen["extra pose prior"] += types.count("prior") > 1
        seen["mixed naming"] += 0 < sum(world.named) < len(world.named)
        pose_counts = Counter(world.truth.assignment)
        seen["re-observed landmark"] += any(c > 1 for c in pose_counts.values())
        xy = list(world.truth.landmarks.values())
        seen["clustered"] += any(
            abs(a[0] - b[0]) + abs(a[1] - b[1]) < 0.2 for i, a in enumerate(xy) for b in xy[:i]
        )
        observations = [r for r in world.records if r["type"] == "observation"]
        seen["range-only"] += any("bearing" not in r for r in observations)
        seen["bearing-only"] += any("range" not in r for r in observations)

    census()
    for kind in SENSOR_KINDS:
        assert seen[f"sensor {kind}"] >= 5, seen
    for feature in (
        "loop closure",
        "pose ids not in time order",
        "landmark prior",
        "extra pose prior",
        "mixed naming",
        "re-observed landmark",
        "clustered",
        "range-only",
        "bearing-only",
    ):
        assert seen[feature] >= 5, seen


# --- (a) the true correspondence given ---------------------------------------------------


@once_per_world
def check_known(world: World, level: str) -> None:
    """(a): the true correspondence given, one hypothesis, never refuted, truth inside."""
    with reported(world, "all"):
        assert_valid(world, "all")
        solution = solve(world.log("all"), consistency=level, certify_limit=0)
        assert not solution.refuted, f"a consistent log refuted at {level}: {solution.messages}"
        assert len(solution.hypotheses) == 1
        h = solution.hypotheses[0]
        assert h.assignment == world.truth.assignment
        assert truth_misses(h, world.truth, world.named_ids("all")) == []


@pytest.mark.parametrize("level", ["hull", "lp"])
@ci(100)
@given(world=worlds())
def test_known_correspondence_is_never_refuted(world: World, level: str) -> None:
    check_known(world, level)


@ci(60)
@given(world=worlds(**SMALL))
def test_named_search_keeps_the_only_correspondence(world: World) -> None:
    """Every observation named, through the search (its negative information included)."""
    with reported(world, "all"):
        assert_valid(world, "all")
        solution = solve_unknown(world.log("all"), consistency="hull", **BUDGET)
        assert solution.complete
        assert [h.assignment for h in solution.hypotheses] == [world.truth.assignment], (
            solution.messages
        )
        assert_keeps_truth(world, "all", solution)


# --- (b), (c) unknown and mixed correspondence -------------------------------------------


@once_per_log
def check_search(world: World, naming: str, level: str) -> None:
    """(b), (c): the search at ``level`` keeps the truth whenever it is complete."""
    with reported(world, naming):
        assert_valid(world, naming)
        log = world.log(naming)
        if level != "hull":
            hull = solve_unknown(log, **BUDGET, **SEARCH_LEVELS["hull"])
            assert_keeps_truth(world, naming, hull)
            assume(hull.complete and len(hull.hypotheses) <= LP_SURVIVORS)
        with search_level(level):
            solution = solve_unknown(log, **BUDGET, **SEARCH_LEVELS[level])
        assert_keeps_truth(world, naming, solution)


@pytest.mark.parametrize("naming", ["none", "mixed"])
@ci(100)
@given(world=worlds(**SEARCHED))
def test_search_keeps_the_truth_at_hull(world: World, naming: str) -> None:
    check_search(world, naming, "hull")


@pytest.mark.parametrize("naming", ["none", "mixed"])
@ci(60)
@given(
    world=worlds(**SMALL),
    share=st.sampled_from([1.0, 0.999, 0.5]),
    margin=st.sampled_from([0.0, 0.3]),
    extra=st.sampled_from([0, 0, 1]),
)
def test_class_priors_the_truth_meets_keep_it(
    world: World, naming: str, share: float, margin: float, extra: int
) -> None:
    """Class priors that hold in the true world (exact count, separation up to the closest
    true pair, region touching the landmarks) never refute the truth."""
    check_search(world.with_class_priors(share, margin, extra), naming, "hull")


@pytest.mark.parametrize("naming", ["none", "mixed"])
@ci(60)
@given(world=worlds(**SMALL))
def test_bisection_never_refutes_the_true_correspondence(world: World, naming: str) -> None:
    """The true correspondence's node (its decisions replayed), bisected part by part
    with its negative information, never contracts to empty in every part."""
    with reported(world, naming):
        assert_valid(world, naming)
        problem = build_problem(world.log(naming))
        explorer = Explorer(problem, DEFAULT_RTOL, "hull", 0)
        named = {name: i for i, name in enumerate(problem.named)}
        new: dict[str, int] = {}
        prefix = [
            named[a] if a in named else new.setdefault(a, len(named) + len(new))
            for a in (world.truth.assignment[d.position] for d in problem.decisions)
        ]
        node = explorer.replay(prefix)
        assert node is not None, "the search refuted the true correspondence"
        lo, hi, arrays = explorer.graph.standalone(node.overlay)
        poses = np.array(sorted(problem.pose_x.values()), dtype=np.int64)
        bisection = Bisection(lo, hi, arrays, poses, explorer.landmark_xs(node))
        assert refute_by_bisection([bisection], None, 200) == [False]


OFFSETS = {"sensors": ("none",), "offsets": True}


@ci(60)
@given(world=worlds(**SMALL, **OFFSETS))
def test_offset_worlds_measure_their_world_and_keep_their_truth(world: World) -> None:
    """Sensors mounted off the robot's centre (one or two, a scan each): the logs are
    valid, and the true correspondence given is never refuted."""
    check_known(world, "hull")


@pytest.mark.parametrize("naming", ["none", "mixed"])
@ci(15)
@given(world=worlds(**SEARCHED, **OFFSETS))
def test_search_keeps_the_truth_with_sensor_offsets(world: World, naming: str) -> None:
    """Unknown correspondence from offset sensors: each observation is seen from its
    sensor's pose, and two scans of one pose may see the same landmark."""
    check_search(world, naming, "hull")


@pytest.mark.parametrize("naming", ["none", "mixed"])
@pytest.mark.parametrize("level", ["lp", "lp-during"])
@ci(25)
@given(world=worlds(**TINY))
def test_search_keeps_the_truth_at_lp(world: World, naming: str, level: str) -> None:
    check_search(world, naming, level)


@ci(50)
@given(world=worlds(**TINY, named_fractions=(0.0, 0.3, 0.6)))
def test_solve_keeps_the_truth(world: World) -> None:
    """The entry point with its defaults (level ``auto``: ``lp`` on these small logs)."""
    with reported(world, "mixed"):
        assert_valid(world, "mixed")
        assert_keeps_truth(world, "mixed", solve(world.log("mixed"), certify_limit=0))


@pytest.mark.parametrize(
    "size",
    [
        pytest.param(SEARCHED, id="searched"),
        pytest.param(SMALL, id="small", marks=pytest.mark.slow),
    ],
)
def test_most_searches_complete(size: dict) -> None:
    """The search tests above must not pass vacuously: most of their searches complete, in
    the default run's worlds (and in the slow run's, checked in the slow run)."""
    done: Counter[bool] = Counter()

    @settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=HEALTH)
    @given(worlds(**size))
    def count(world: World) -> None:
        log = world.log("none")
        done[solve_unknown(log, consistency="hull", **BUDGET).complete] += 1

    count()
    assert done[True] >= 0.75 * sum(done.values()), done


# --- the slow run: thousands of new worlds -----------------------------------------------


@pytest.mark.slow
@slow(2000)
@given(world=worlds(), level=st.sampled_from(["hull", "lp"]))
def test_slow_known_correspondence(world: World, level: str) -> None:
    check_known(world, level)


@pytest.mark.slow
@slow(3000)
@given(world=worlds(**SMALL), naming=st.sampled_from(["none", "mixed", "all"]))
def test_slow_search_at_hull(world: World, naming: str) -> None:
    check_search(world, naming, "hull")


@pytest.mark.slow
@slow(1000)
@given(world=worlds(**SMALL, **OFFSETS), naming=st.sampled_from(["none", "mixed"]))
def test_slow_search_with_sensor_offsets(world: World, naming: str) -> None:
    check_search(world, naming, "hull")


@pytest.mark.slow
@slow(1000)
@given(
    world=worlds(**TINY),
    naming=st.sampled_from(["none", "mixed"]),
    level=st.sampled_from(["lp", "lp-during"]),
)
def test_slow_search_at_lp(world: World, naming: str, level: str) -> None:
    check_search(world, naming, level)
