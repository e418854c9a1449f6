"""The ``lp`` sweeps cut into parts (:mod:`cuikslam.narrowing.parts`): the same boxes for
any number of threads, and the truth inside them on random true worlds.

The parts start at ``MIN_PART_WINDOWS`` windows each (200 poses); the tests lower it so
that short logs are cut too.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from cuikslam.graph import KinematicGraph
from cuikslam.narrowing import parts as parts_module
from cuikslam.narrowing import propagate
from cuikslam.narrowing import sweeps as sweeps_module
from cuikslam.narrowing.consistency import StrengthenReport, strengthen
from cuikslam.narrowing.parts import default_threads, partition
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL, Arrays
from cuikslam.options import SolveOptions
from cuikslam.simulate import simulate_random_world
from cuikslam.solver import solve
from worlds import World, log_violations, truth_misses, worlds


@pytest.mark.parametrize("n_windows", [1, 7, 79, 80, 81, 199, 2000])
def test_partition_covers_the_windows_in_order(n_windows: int) -> None:
    ranges = partition(n_windows)
    assert [w for r in ranges for w in r] == list(range(n_windows))
    expected = max(1, min(parts_module.PARTS, n_windows // parts_module.MIN_PART_WINDOWS))
    assert len(ranges) == expected
    assert max(len(r) for r in ranges) - min(len(r) for r in ranges) <= 1


def test_default_threads_leave_busy_cores_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(parts_module.os, "sched_getaffinity", lambda _: {0, 1})
    for load, expected in ((0.0, 2), (0.4, 2), (1.0, 1), (1.6, 1), (7.0, 1)):
        monkeypatch.setattr(parts_module.os, "getloadavg", lambda load=load: (load, 0.0, 0.0))
        assert default_threads() == expected, load


def test_threads_must_be_positive() -> None:
    with pytest.raises(ValueError, match="threads"):
        SolveOptions(threads=0)


def test_the_command_line_sets_the_threads() -> None:
    from cuikslam.cli.main import build_parser

    parser = build_parser()
    assert parser.parse_args(["solve", "trip.jsonl"]).threads == SolveOptions().threads is None
    assert parser.parse_args(["solve", "trip.jsonl", "--threads", "2"]).threads == 2
    with pytest.raises(SystemExit):
        parser.parse_args(["solve", "trip.jsonl", "--threads", "0"])


def _lp(graph: KinematicGraph, threads: int) -> tuple[np.ndarray, np.ndarray, StrengthenReport]:
    fixpoint = propagate(graph, rtol=DEFAULT_RTOL)
    lo, hi = fixpoint.lo.copy(), fixpoint.hi.copy()
    report = StrengthenReport()
    result = strengthen(
        Arrays.of(graph), lo, hi, "lp", DEFAULT_RTOL, DEFAULT_ROUNDS, report=report,
        threads=threads,
    )  # fmt: skip
    assert not result.is_empty
    return lo, hi, report


def test_same_boxes_for_any_number_of_threads(monkeypatch: pytest.MonkeyPatch) -> None:
    """Bit for bit, and the same LP counts: the parts' copies are merged by max / min."""
    monkeypatch.setattr(parts_module, "MIN_PART_WINDOWS", 3)
    used = []
    run_parts = parts_module.run_parts

    def spy(parts, *args):
        used.append(len(parts))
        return run_parts(parts, *args)

    monkeypatch.setattr(sweeps_module, "run_parts", spy)
    log, _ = simulate_random_world(seed=4, n_poses=60)
    graph = KinematicGraph.from_log(log)
    runs = [_lp(graph, threads) for threads in (1, 2, 2, 3)]
    assert used and set(used) == {2}  # the parts ran, two of them
    for lo, hi, report in runs[1:]:
        np.testing.assert_array_equal(lo, runs[0][0])
        np.testing.assert_array_equal(hi, runs[0][1])
        assert report.lp == runs[0][2].lp
        assert report.lp_rounds == runs[0][2].lp_rounds


def test_a_failing_part_stops_the_others(monkeypatch: pytest.MonkeyPatch) -> None:
    """An exception in the first part (Ctrl-C, say) is raised at once: the other threads
    stop at their next window instead of finishing their sweep.

    The second part's first window waits until the first part has failed (the order a
    slow window on a busy machine could give), so that the count does not depend on how
    the threads are scheduled; without the stop it would visit all its windows."""
    import threading
    import time

    monkeypatch.setattr(parts_module, "MIN_PART_WINDOWS", 3)
    visit = sweeps_module._visit
    other = []
    give_up = time.monotonic() + 60.0  # only if the failure never reaches the part

    def slow_visit(part, *args):
        if threading.current_thread() is threading.main_thread():
            raise RuntimeError("interrupted")
        other.append(part.windows)
        while not part.abandon and time.monotonic() < give_up:
            time.sleep(0.001)
        return visit(part, *args)

    monkeypatch.setattr(sweeps_module, "_visit", slow_visit)
    log, _ = simulate_random_world(seed=4, n_poses=60)
    graph = KinematicGraph.from_log(log)
    with pytest.raises(RuntimeError, match="interrupted"):
        _lp(graph, 2)
    assert len(other) <= 1, len(other)  # of the 5 or 6 windows of the second part


def test_parts_stay_close_to_one_part(monkeypatch: pytest.MonkeyPatch) -> None:
    """Cutting the chain loses only what crosses the cut within a sweep: the total width of
    the poses stays within 5 % of the single part's (the issue's tightness claim)."""
    log, _ = simulate_random_world(seed=4, n_poses=60)
    graph = KinematicGraph.from_log(log)
    lo1, hi1, _ = _lp(graph, 1)
    monkeypatch.setattr(parts_module, "MIN_PART_WINDOWS", 3)
    lo2, hi2, _ = _lp(graph, 2)
    poses = graph.pose_boxes(lo1, hi1), graph.pose_boxes(lo2, hi2)
    widths = [b[..., 1] - b[..., 0] for b in poses]
    finite = np.isfinite(widths[0]) & np.isfinite(widths[1])
    assert finite.sum() > 0.5 * finite.size
    one, two = widths[0][finite].sum(), widths[1][finite].sum()
    assert two <= 1.05 * one, (one, two)


HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(poses=(12, 30), max_observations=40))
def test_parts_keep_the_truth(world: World) -> None:
    """Every box holds the truth when the windows are cut into parts run on two threads."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(parts_module, "MIN_PART_WINDOWS", 1)
        log = world.log("all")
        assert log_violations(log, world.truth) == []
        solution = solve(log, consistency="lp", certify_limit=0, work_budget=None, threads=2)
    assert not solution.refuted, solution.messages
    h = solution.hypotheses[0]
    assert h.consistency == "lp"
    assert truth_misses(h, world.truth, world.named_ids("all")) == []


def test_no_lp_depends_on_the_clock_without_a_deadline(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without a deadline an LP has no time limit (the iteration limit bounds it): a busy
    machine cannot stop one early and change a bound. With the limit cut to nothing, the
    boxes and counts stay those of a normal run."""
    from cuikslam.narrowing import lp_bounds

    log, _ = simulate_random_world(seed=4, n_poses=30)
    graph = KinematicGraph.from_log(log)
    lo, hi, report = _lp(graph, 1)
    monkeypatch.setattr(lp_bounds, "LP_TIME_LIMIT", 0.0)
    lo2, hi2, report2 = _lp(graph, 1)
    assert report2.lp.limit_hits == 0
    assert report2.lp == report.lp
    np.testing.assert_array_equal(lo2, lo)
    np.testing.assert_array_equal(hi2, hi)


def test_parts_keeping_different_2pi_copies_of_a_wide_heading_get_their_hull() -> None:
    """A heading narrowed from a box wider than 2π keeps one copy of its interval; two parts
    may keep different copies (found possible by an adversarial tester on 500-pose logs,
    whose headings are often still unbounded when the sweeps start). Their boxes do not
    meet, yet neither part proved anything impossible: the result is their hull, not an
    "empty" proof. A variable whose box was narrower than 2π keeps the intersection, and
    its empty intersection stays a proof."""
    from cuikslam.narrowing.parts import Part, run_parts

    def sweep(part: Part, lo: np.ndarray, hi: np.ndarray) -> bool:
        shift = 2 * np.pi * part.windows.start  # part 0: copy 0, part 1: copy 1
        lo[0], hi[0] = 0.5 + shift, 1.0 + shift
        return True

    parts = [Part(range(0, 1), 2, None), Part(range(1, 2), 2, None)]
    lo, hi = np.array([-np.inf, 0.0]), np.array([np.inf, 3.0])
    assert run_parts(parts, lo, hi, sweep, threads=1) == (True, False)
    assert (lo[0], hi[0]) == (0.5, 1.0 + 2 * np.pi)

    def split(part: Part, lo: np.ndarray, hi: np.ndarray) -> bool:
        lo[1], hi[1] = (0.0, 1.0) if part.windows.start == 0 else (2.0, 3.0)
        return True

    lo, hi = np.array([-np.inf, 0.0]), np.array([np.inf, 3.0])
    assert run_parts(parts, lo, hi, split, threads=1) == (True, True)
