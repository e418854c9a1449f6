"""Every stage has a budget: cut anywhere, the result stays sound and says what it reached;
and a budget of work gives the same result at any load.

Some tests replace ``expired`` by counters (the n-th look says "expired"), so each cut
point is reached deterministically, without timed assertions.
"""

from __future__ import annotations

import ast
import itertools
import multiprocessing
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cuikslam.budget import (
    Budget,
    capped,
    deadline_after,
    expired,
    portion,
    remaining,
    spend,
    work_budget_for,
)
from cuikslam.cli.main import build_parser
from cuikslam.graph import KinematicGraph
from cuikslam.log import read_log_file
from cuikslam.narrowing import consistency, lp_bounds, propagate, sweeps
from cuikslam.narrowing.consistency import BUDGET_SUFFIX, StrengthenReport, strengthen
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL, Arrays, Status
from cuikslam.results.io import solution_to_json
from cuikslam.results.solution import NOT_REFUTED, PROVEN, check_truth
from cuikslam.simulate import simulate_paper
from cuikslam.solver import solve
from cuikslam.witness import certify

REPRO = Path(__file__).parent / "data" / "repro"


def _arrays(log) -> tuple[KinematicGraph, Arrays, np.ndarray, np.ndarray]:
    graph = KinematicGraph.from_log(log)
    result = propagate(graph)
    return graph, Arrays.of(graph), result.lo, result.hi


def _contains_truth(graph: KinematicGraph, lo: np.ndarray, hi: np.ndarray, truth) -> bool:
    poses = graph.pose_boxes(lo, hi)
    for pose, xyt in zip(truth.pose_ids, truth.poses_xyt, strict=True):
        box = poses[graph.pose_ids.index(pose)]
        if not (box[0, 0] <= xyt[0] <= box[0, 1] and box[1, 0] <= xyt[1] <= box[1, 1]):
            return False
    return True


class _Clock:
    """``expired`` that answers True from its ``n``-th call on (and counts the calls)."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.calls = 0

    def __call__(self, deadline: Budget | None) -> bool:
        self.calls += 1
        return self.calls > self.n


def test_deadline_helpers() -> None:
    assert deadline_after(None) is None and deadline_after(float("inf")) is None
    assert remaining(None) == float("inf") and not expired(None)
    assert expired(deadline_after(0.0)) and remaining(deadline_after(-5.0)) == 0.0
    assert not expired(deadline_after(3600.0))
    assert portion(None, 0.5) is None
    soon, later = portion(deadline_after(100.0), 0.1), deadline_after(100.0)
    assert soon is not None and later is not None and soon.clock < later.clock


def test_work_shares_count_on_one_meter() -> None:
    budget = Budget.start(work=100.0)
    first = portion(budget, 0.8)
    spend(first, 79.0)
    assert not expired(first) and budget.meter.bound is None
    spend(first, 1.0)
    assert expired(first) and not expired(budget) and budget.meter.bound == "work"
    second = portion(budget, 0.5)  # half of the 20 units left
    assert second.work == 90.0 and budget.left == 20.0
    cap = capped(budget, 5.0)
    spend(cap, 5.0)
    assert expired(cap) and budget.meter.spent == 85.0
    alone = budget.alone(0.5)  # a meter of its own: what it spends does not count here
    spend(alone, 7.5)
    assert expired(alone) and budget.meter.spent == 85.0
    assert remaining(budget) == float("inf")  # no wall-clock cap
    assert work_budget_for(0) < work_budget_for(10)


def test_a_wall_clock_cap_that_binds_is_recorded() -> None:
    budget = Budget.start(work=1e12, seconds=0.0)
    assert expired(budget) and budget.meter.bound == "time"
    log, _ = simulate_paper(seed=0)
    capped_solution = solve(log, consistency="lp", time_budget=1e-9)
    assert capped_solution.statistics["budget_bound"] == "time"
    assert any("may differ from run to run" in m for m in capped_solution.messages)
    default = solve(log, consistency="lp")
    assert default.statistics["budget_bound"] is None
    assert default.statistics["work_budget"] == work_budget_for(len(log.pose_ids))
    assert 0 < default.statistics["work_spent"] <= default.statistics["work_budget"]


def test_a_correspondence_search_gets_more_work_per_pose_by_default() -> None:
    """Without landmark ids the default budget is ``SEARCH_WORK_PER_POSE`` a pose, with
    them ``WORK_PER_POSE``; the seed's experiment decides both within it."""
    from cuikslam.budget import SEARCH_WORK_PER_POSE, WALK_RESERVE_PER_POSE, WORK_PER_POSE

    assert SEARCH_WORK_PER_POSE > WORK_PER_POSE
    log, _ = simulate_paper(seed=0, unknown=True)
    n = len(log.pose_ids)
    solution = solve(log, consistency="lp")
    assert solution.statistics["work_budget"] == work_budget_for(n, search=True) + (
        WALK_RESERVE_PER_POSE * n
    )
    assert work_budget_for(n, search=True) - work_budget_for(n) == pytest.approx(
        (SEARCH_WORK_PER_POSE - WORK_PER_POSE) * n, rel=1e-15
    )
    assert [h.status for h in solution.hypotheses] == ["proven consistent"] * 2


def test_every_operator_application_of_the_search_is_spent_from_its_budget(monkeypatch) -> None:
    """The search's narrowings (its shared graph's kernel, the leaves' bisection and the
    windows narrowed in a local frame) all count against the work budget: on near-exact
    readings the windows are half the work, and uncounted they let a 2e6-unit search run
    for a minute."""
    from cuikslam.hypotheses import _kernels, bisection, local
    from cuikslam.hypotheses.search import solve_unknown
    from cuikslam.simulate import simulate_random_world

    applied = {"kernel": 0, "bisection": 0, "local": 0}

    def counting(module, name: str, key: str, get) -> None:
        original = getattr(module, name)

        def spy(*args, **kwargs):
            result = original(*args, **kwargs)
            applied[key] += get(result)
            return result

        monkeypatch.setattr(module, name, spy)

    counting(_kernels, "apply", "kernel", lambda r: r[1])
    counting(bisection, "narrow", "bisection", lambda r: r.applications)
    counting(local, "narrow", "local", lambda r: r.applications)
    log, _ = simulate_random_world(
        seed=2, n_poses=12, n_landmarks=6, size=(12.0, 8.0), max_range=6.0,
        odometry_bounds=(1e-12, 1e-12), observation_bounds=(1e-12, 1e-12), unknown=True,
    )  # fmt: skip
    budget = Budget.start(work=2e5)
    solve_unknown(log, consistency="hull", deadline=budget)
    assert min(applied.values()) > 0
    assert budget.meter.spent >= sum(applied.values())


def test_only_the_walk_spends_the_reserve_and_what_it_leaves_is_dropped() -> None:
    """What the walk spends beyond its share comes from the reserve, which the other
    shares never count; a walk that ends within its share leaves the later stages exactly
    the budget they had without a reserve."""
    from cuikslam.budget import SCHEDULE

    budget = Budget.start(work=1000, reserve=300)
    search = SCHEDULE.share(budget, "search")
    with SCHEDULE.walking(search) as walk:
        assert walk.left == 720 + 300
        spend(walk, 900)  # 180 beyond its share of 720
        assert (search.left, budget.left, budget.meter.credit) == (80, 280, 180)
        spend(walk, 200)  # the reserve runs out at 1,020: 80 of these count
        assert expired(walk) and walk.left == 0
        assert (budget.meter.credit, search.left) == (300, 0)
    assert budget.meter.spent == 1100 and budget.left == 200

    lean = Budget.start(work=1000, reserve=300)
    with SCHEDULE.walking(SCHEDULE.share(lean, "search")) as walk:
        spend(walk, 100)
    after = SCHEDULE.share(lean, "search")
    assert lean.meter.reserve == 0 and after.left == pytest.approx(0.8 * 900)
    assert lean.left == Budget.start(work=900).left


def test_a_default_search_budget_holds_the_walks_reserve_and_an_explicit_one_does_not() -> None:
    from cuikslam.budget import WALK_RESERVE_PER_POSE
    from cuikslam.simulate import simulate_random_world

    log, _ = simulate_random_world(seed=1, n_poses=20, n_landmarks=6, unknown=True)
    n = len(log.pose_ids)
    auto = solve(log, consistency="hull", certify_limit=0)
    given = solve(log, consistency="hull", certify_limit=0, work_budget=3e6)
    assert auto.statistics["work_budget"] == work_budget_for(n, True) + WALK_RESERVE_PER_POSE * n
    assert given.statistics["work_budget"] == 3e6
    assert given.statistics["walk_reserve_spent"] == 0
    assert 0 <= auto.statistics["walk_reserve_spent"] <= WALK_RESERVE_PER_POSE * n


def test_a_branching_nodes_lp_window_keeps_its_cap_while_the_walk_spends_its_reserve(
    monkeypatch,
) -> None:
    """The walk's nodes spend from the walk's budget: measured on the search's share, whose
    reading the reserve holds still, one ``lp`` window once spent 8.7e6 units against its
    cap of ``branch_node_work`` (a review of the reserve, 2026-12-07)."""
    import cuikslam.options
    from cuikslam.budget import SCHEDULE
    from cuikslam.hypotheses.ambiguity import AmbiguityLp
    from cuikslam.simulate import simulate_random_world

    spent: list[float] = []
    original = AmbiguityLp.narrow

    def narrow(self, graph, overlay, pose, deadline):
        before = deadline.meter.spent
        result = original(self, graph, overlay, pose, deadline)
        spent.append(deadline.meter.spent - before)
        return result

    monkeypatch.setattr(AmbiguityLp, "narrow", narrow)
    monkeypatch.setattr(cuikslam.options, "work_budget_for", lambda n, search=False: 4e5)
    monkeypatch.setattr(cuikslam.options, "walk_reserve_for", lambda n: 2e7)
    log, _ = simulate_random_world(
        seed=7, n_poses=60, n_landmarks=12, unknown=True, size=(30.0, 20.0), max_range=6.0
    )
    solution = solve(log, certify_limit=0)
    assert solution.statistics["walk_reserve_spent"] > SCHEDULE.branch_node_work
    assert spent and max(spent) <= 1.1 * SCHEDULE.branch_node_work


def test_blas_single_thread_limits_scipys_own_blas() -> None:
    """scipy ships its own OpenBLAS, loaded on first use: loaded inside the block (as the
    witness search loads scipy.optimize), it must run on one thread too."""
    code = (
        "from threadpoolctl import threadpool_info\n"
        "from cuikslam.budget import blas_single_thread\n"
        "with blas_single_thread():\n"
        "    import scipy.optimize\n"
        "    print([i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'])\n"
    )
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    ).stdout
    threads = ast.literal_eval(out.strip().splitlines()[-1])
    assert len(threads) >= 2  # numpy's and scipy's
    assert threads == [1] * len(threads)


def test_an_expired_deadline_leaves_the_boxes_at_hull() -> None:
    log, _ = simulate_paper(seed=0)
    _, arrays, lo, hi = _arrays(log)
    lo0, hi0 = lo.copy(), hi.copy()
    report = StrengthenReport()
    result = strengthen(arrays, lo, hi, "lp", DEFAULT_RTOL, DEFAULT_ROUNDS,
                        deadline=deadline_after(0.0), report=report)  # fmt: skip
    assert result.status is Status.CONSISTENT and result.lo is lo and result.hi is hi
    assert report.level == "hull" and report.budget_exhausted
    assert np.array_equal(lo, lo0) and np.array_equal(hi, hi0)


@pytest.mark.parametrize("level", ["lp", "lp-split"])
def test_cut_at_every_point_the_truth_stays_inside(level: str, monkeypatch) -> None:
    """The deadline strikes after the n-th look at the clock, for n = 0, 1, 2, ...: the
    boxes always hold the truth, and the level reached is reported honestly."""
    log, truth = simulate_paper(seed=1)
    graph, arrays, lo0, hi0 = _arrays(log)
    full_lo, full_hi = lo0.copy(), hi0.copy()
    full = StrengthenReport()
    strengthen(arrays, full_lo, full_hi, level, DEFAULT_RTOL, DEFAULT_ROUNDS, report=full)
    assert full.level == level and not full.budget_exhausted
    seen_levels = set()
    for n in itertools.chain(range(6), range(10, 200, 37)):
        clock = _Clock(n)
        monkeypatch.setattr(consistency, "expired", clock)
        monkeypatch.setattr(sweeps, "expired", clock)
        monkeypatch.setattr(lp_bounds, "expired", clock)
        lo, hi = lo0.copy(), hi0.copy()
        report = StrengthenReport()
        result = strengthen(arrays, lo, hi, level, DEFAULT_RTOL, DEFAULT_ROUNDS,
                            deadline=Budget.start(work=1e12), report=report)  # fmt: skip
        assert result.status is Status.CONSISTENT
        assert _contains_truth(graph, lo, hi, truth), (n, report)
        assert np.all(lo >= lo0) and np.all(hi <= hi0)  # never wider than the fixpoint
        assert report.budget_exhausted == (report.level != level), (n, report.level)
        assert report.level in ("hull", "lp", level, "lp" + BUDGET_SUFFIX, level + BUDGET_SUFFIX)
        seen_levels.add(report.level)
    assert "hull" in seen_levels and "lp" + BUDGET_SUFFIX in seen_levels


def test_lps_stopped_by_their_limits_still_give_sound_bounds(monkeypatch) -> None:
    """Every LP stopped after one simplex iteration: bounds from whatever multipliers the
    LP had, so the boxes hold the truth (and are never wider than the fixpoint)."""
    monkeypatch.setattr(lp_bounds, "LP_MIN_ITERATIONS", 1)
    monkeypatch.setattr(lp_bounds, "LP_ITERATIONS_PER_SIZE", 0)
    log, truth = simulate_paper(seed=2)
    graph, arrays, lo0, hi0 = _arrays(log)
    lo, hi = lo0.copy(), hi0.copy()
    report = StrengthenReport()
    strengthen(arrays, lo, hi, "lp", DEFAULT_RTOL, DEFAULT_ROUNDS, report=report)
    assert report.lp.solved == report.lp.limit_hits > 0 and report.lp.optimal == 0
    assert report.level == "lp"  # limits of single LPs are not the level's budget
    assert _contains_truth(graph, lo, hi, truth)
    assert np.all(lo >= lo0) and np.all(hi <= hi0)


def test_a_spent_budget_is_reported_not_hidden() -> None:
    log, truth = simulate_paper(seed=0)
    spent = solve(log, consistency="lp", work_budget=1.0)
    assert spent.consistency == "hull" and spent.best.consistency == "hull"
    assert spent.best.status == NOT_REFUTED and spent.best.witness is None
    assert spent.statistics["lp_budget_exhausted"] == 1
    assert spent.statistics["witness_budget_exhausted"] == 1
    assert spent.statistics["budget_bound"] == "work"
    assert any("budget ran out" in m for m in spent.messages)
    assert any("witness search stopped" in m for m in spent.messages)
    # in words for both a command-line and a Python user: no flag, no keyword argument
    assert not any("--" in m or "budget=" in m for m in spent.messages), spent.messages
    assert check_truth(spent.best, truth.pose_ids, truth.poses_xyt).ok
    unlimited = solve(log, consistency="lp", work_budget=None)
    assert unlimited.consistency == "lp" and unlimited.best.status == PROVEN
    assert unlimited.statistics["lp_budget_exhausted"] == 0
    assert not any("budget" in m for m in unlimited.messages)


def test_the_witness_work_limit_leaves_the_hypothesis_not_refuted() -> None:
    log, _ = simulate_paper(seed=0)
    solution = solve(log, consistency="hull", certify_limit=0, work_budget=None)
    stats = certify(log, solution, max_evaluations=0)
    assert stats.out_of_work and not stats.out_of_time
    assert solution.best.status == NOT_REFUTED
    assert solution.statistics["witness_budget_exhausted"] == 1
    assert any("work limit" in m for m in solution.messages)
    certify(log, solution)
    assert solution.best.status == PROVEN


@pytest.mark.parametrize(
    ("text", "value"), [("2.5", 2.5), ("0.01", 0.01), ("none", None), ("inf", None)]
)
@pytest.mark.parametrize("command", ["solve", "paper"])
def test_budget_options(command: str, text: str, value: float | None) -> None:
    log = ["log.jsonl"] if command == "solve" else []
    parse = build_parser().parse_args
    assert parse([command, *log, "--time-budget", text]).time_budget == value
    assert parse([command, *log, "--work-budget", text]).work_budget == value
    assert parse([command, *log, "--work-budget", "auto"]).work_budget == "auto"
    defaults = parse([command, *log])
    assert defaults.time_budget is None and defaults.work_budget == "auto"


@pytest.mark.parametrize("text", ["0", "-1", "nan", "abc", ""])
@pytest.mark.parametrize("option", ["--time-budget", "--work-budget"])
def test_bad_budgets_are_refused(option: str, text: str) -> None:
    with pytest.raises(SystemExit) as caught:
        build_parser().parse_args(["solve", "log.jsonl", option, text])
    assert caught.value.code == 2


def _busy(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def _without_timings(doc: dict) -> dict:
    return {k: v for k, v in doc.items() if k != "timings"}


def test_the_same_log_gives_the_same_result_beside_cpu_bound_processes() -> None:
    """The seed's experiment with ids dropped, at a work budget that cuts its stages (the
    search's stronger level and the witness search): the result JSON, timings aside, is
    the same alone and beside two CPU-bound processes. Nothing here depends on how fast
    the machine runs: only whether the verdict is the same."""
    log, _ = simulate_paper(seed=0, unknown=True)
    options = {"work_budget": 4e5}
    alone = solution_to_json(solve(log, **options))
    assert alone["statistics"]["budget_bound"] == "work"
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        busy = pool.map_async(_busy, [20.0, 20.0])
        loaded = [solution_to_json(solve(log, **options)) for _ in range(2)]
        pool.terminate()
    del busy
    for doc in loaded:
        assert _without_timings(doc) == _without_timings(alone)


def test_the_repro_log_that_hung_the_lp_level_stops_on_its_work_budget() -> None:
    """``lp-slow-or-hang.jsonl`` once ran for more than 10 minutes at ``lp-split`` with
    certify off: under a work budget it stops, and the same way twice."""
    log = read_log_file(REPRO / "lp-slow-or-hang.jsonl")
    first = solve(log, consistency="lp-split", certify_limit=0, work_budget=2e5)
    second = solve(log, consistency="lp-split", certify_limit=0, work_budget=2e5)
    assert first.statistics["budget_bound"] == "work"
    assert _without_timings(solution_to_json(first)) == _without_timings(solution_to_json(second))


def test_the_schedule_alone_decides_the_shares() -> None:
    """No module but ``budget.py`` names a share of the budget or cuts one out: each stage
    asks ``SCHEDULE`` (issue 29)."""
    import re

    import cuikslam
    from cuikslam.budget import SCHEDULE

    src = Path(cuikslam.__file__).parent
    found = [
        f"{path.relative_to(src)}:{number}: {line.strip()}"
        for path in sorted(src.rglob("*.py"))
        if path.name != "budget.py"
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if re.search(r"\b[A-Z_]*SHARE\s*=|\bportion\(|\bcapped\(|\.share\(\s*[0-9]", line)
    ]
    assert found == []
    assert (SCHEDULE.search, SCHEDULE.walk, SCHEDULE.dive) == (0.8, 0.9, 0.6)
