"""The correspondence search and batches of logs on Dask (``cuikslam[distributed]``).

The search split into subtrees and merged must give what one process gives: the same
survivors, boxes, summary and counts. Two counts are exempt: ``peak_frontier`` (each task
has its own stack) and ``operator_applications`` (propagation visits factors in the order
the shared graph pooled them, which depends on what was explored before). The searches here
run without the ``lp`` level on ambiguous nodes (``strengthen_during=0``): that level is cut
by time (``explorer.AMBIGUITY_LP_SECONDS``), so how far it narrows depends on the load of
the machine, and boxes compared bit for bit would too.
"""

from __future__ import annotations

import functools
import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cuikslam.hypotheses.search import solve_unknown
from cuikslam.log.writer import write_log_file
from cuikslam.options import SolveOptions
from cuikslam.results.solution import Solution
from cuikslam.simulate import simulate_random_world

CLI = [sys.executable, "-m", "cuikslam.cli.main"]
EXEMPT = {"peak_frontier", "operator_applications", "explored_fraction"}
"""Statistics that may differ (see the module docstring); the fraction up to rounding."""
ONLY_DISTRIBUTED = {"tasks", "resubmitted", "lost_on_replay", "worker_cpu_s"}


def ambiguous_log(seed: int):
    """A small world with one class of landmarks and wide observation bounds: 8-30
    survivors, a few hundred nodes."""
    log, _ = simulate_random_world(
        seed=seed, n_poses=12, n_landmarks=6, classes=("a",), size=(16.0, 12.0),
        max_range=6.0, odometry_bounds=(0.15, 0.3), observation_bounds=(0.5, 0.2),
        unknown=True,
    )  # fmt: skip
    return log


def assert_same_solution(one: Solution, many: Solution) -> None:
    assert one.complete == many.complete
    assert [h.assignment for h in one.hypotheses] == [h.assignment for h in many.hypotheses]
    for a, b in zip(one.hypotheses, many.hypotheses, strict=True):
        assert np.array_equal(a.poses, b.poses)
        assert np.array_equal(a.landmarks, b.landmarks)
        assert a.landmark_ids == b.landmark_ids and a.consistency == b.consistency
    assert one.correspondence == many.correspondence
    assert one.messages == many.messages
    s1, s2 = one.statistics, many.statistics
    assert set(s2) == set(s1) | ONLY_DISTRIBUTED
    assert {k: v for k, v in s1.items() if k not in EXEMPT} == {
        k: v for k, v in s2.items() if k in s1 and k not in EXEMPT
    }
    assert math.isclose(s1["explored_fraction"], s2["explored_fraction"], rel_tol=1e-12)


@pytest.fixture(scope="module")
def client():
    pytest.importorskip("distributed", reason='needs Dask: pip install "cuikslam[distributed]"')
    from cuikslam.cluster import dask_client

    with dask_client(workers=2, processes=False) as c:
        yield c


@pytest.mark.parametrize("seed", range(3))
def test_the_split_search_finds_what_one_process_finds(client, seed: int) -> None:
    from cuikslam.hypotheses.distributed import search_distributed

    log = ambiguous_log(seed)
    streamed_one: list[list[str]] = []
    one = solve_unknown(
        log,
        consistency="hull",
        max_hypotheses=1000,
        strengthen_during=0,
        on_survivor=streamed_one.append,
    )
    assert one.complete and one.statistics["survivors"] >= 8
    results = []
    streamed: list[list[str]] = []
    many = search_distributed(
        log, client=client, consistency="hull", max_hypotheses=1000, strengthen_during=0,
        quantum_nodes=10, on_result=results.append, on_survivor=streamed.append,
    )  # fmt: skip
    assert many.statistics["resubmitted"] == 0
    assert any(r.unexplored for r in results), "no task was split again"
    assert_same_solution(one, many)
    assert streamed == streamed_one  # in depth-first order


def test_the_split_search_with_declared_outliers_matches(client) -> None:
    """The outlier option: a subtree's outlier count is a function of its prefix, so tasks
    rebuilt from their decisions give what one process gives."""
    from cuikslam.hypotheses.distributed import search_distributed
    from cuikslam.log.records import OutlierBound

    log, _ = simulate_random_world(
        seed=2, n_poses=6, n_landmarks=3, classes=("a",), size=(10.0, 8.0), max_range=6.0,
        odometry_bounds=(0.05, 0.1), observation_bounds=(0.2, 0.1), unknown=True,
    )  # fmt: skip
    log.records.insert(0, OutlierBound(1))
    options = {"consistency": "hull", "max_hypotheses": 1000, "strengthen_during": 0}
    one = solve_unknown(log, **options)
    assert one.complete and one.statistics["outlier_options"] > 0
    assert sum(1 for h in one.hypotheses if h.outliers) >= 2
    many = search_distributed(log, client=client, quantum_nodes=10, **options)
    assert_same_solution(one, many)


def test_the_best_ranked_and_the_stronger_level_match(client) -> None:
    """A report shorter than the survivors, and the lp level on the best-ranked; the same
    with a ranking (``rank``: here the fit, with its promotion of unreported survivors)."""
    from cuikslam.hypotheses.distributed import search_distributed
    from cuikslam.hypotheses.labelled import solve_labelled
    from cuikslam.witness import fit_hypotheses

    log = ambiguous_log(2)
    known = functools.partial(solve_labelled, log)
    for rank in [None, lambda report: fit_hypotheses(log, report, known=known)]:
        one = solve_unknown(
            log, consistency="lp", max_hypotheses=3, strengthen_limit=2, strengthen_during=0,
            rank=rank,
        )  # fmt: skip
        many = search_distributed(
            log, client=client, consistency="lp", max_hypotheses=3, strengthen_limit=2,
            strengthen_during=0, quantum_nodes=25, rank=rank,
        )  # fmt: skip
        assert len(one.hypotheses) == 3 and one.statistics["survivors"] > 3
        assert_same_solution(one, many)
        assert one.statistics.get("fitted_hypotheses") == (None if rank is None else 3)


def test_a_node_budget_stop_names_every_unexplored_subtree(client) -> None:
    """What the budget run found plus what its unexplored subtrees hold is everything."""
    from cuikslam.hypotheses.distributed import (
        TaskOptions,
        explore_prefixes,
        search_distributed,
    )

    log = ambiguous_log(2)

    def survivors_of(results) -> list[tuple[int, ...]]:
        """Every survivor's decisions, in depth-first order (by position)."""
        pairs = [
            (tuple(at), tuple(d))
            for r in results
            for at, d in zip(r.positions.tolist(), r.survivors.tolist(), strict=True)
        ]
        assert len(set(pairs)) == len(pairs)
        return [d for _, d in sorted(pairs)]

    full: list = []
    search_distributed(
        log, client=client, consistency="hull", quantum_nodes=10, strengthen_during=0,
        on_result=full.append, on_survivor=lambda _: None,
    )  # fmt: skip
    part: list = []
    left: list = []
    stopped = search_distributed(
        log, client=client, consistency="hull", quantum_nodes=10, strengthen_during=0, max_nodes=60,
        on_result=part.append, on_unexplored=left.append, on_survivor=lambda _: None,
    )  # fmt: skip
    assert not stopped.complete
    [prefixes] = left
    assert stopped.statistics["unexplored_subtrees"] == len(prefixes) > 0
    assert stopped.statistics["branch_points"] <= 60
    assert "INCOMPLETE" in " ".join(stopped.messages)
    options = TaskOptions(
        key="rest", search=SolveOptions(consistency="hull", strengthen_during=0), keep=1,
        all_survivors=True, quantum_s=None, deadline=None,
    )  # fmt: skip
    rest = explore_prefixes(log, prefixes, options, None)
    assert not rest.unexplored
    assert survivors_of([*part, rest]) == survivors_of(full)
    assert stopped.statistics["explored_fraction"] + rest.done == pytest.approx(1.0, abs=1e-12)


def test_a_worker_killed_mid_search_changes_nothing() -> None:
    """A process cluster; one worker is killed while it holds tasks: Dask runs them again
    elsewhere, and the result is the one-process result."""
    pytest.importorskip("distributed", reason='needs Dask: pip install "cuikslam[distributed]"')
    from cuikslam.cluster import dask_client
    from cuikslam.hypotheses.distributed import search_distributed

    log = ambiguous_log(2)
    one = solve_unknown(log, consistency="hull", max_hypotheses=1000, strengthen_during=0)
    with dask_client(workers=2) as client:
        before = client.run(os.getpid)
        killed: list[str] = []

        def kill_a_busy_worker(_result) -> None:
            busy = [w for w, tasks in client.processing().items() if tasks]
            if not killed and busy:
                os.kill(before[busy[0]], signal.SIGKILL)
                killed.append(busy[0])

        many = search_distributed(
            log, client=client, consistency="hull", max_hypotheses=1000, strengthen_during=0,
            quantum_nodes=10, on_result=kill_a_busy_worker,
        )  # fmt: skip
        assert killed, "no worker was busy when a result arrived"
        assert before[killed[0]] not in client.run(os.getpid).values()
    assert_same_solution(one, many)


def test_a_batch_of_logs_gives_one_result_per_log(client) -> None:
    from cuikslam.cluster import solve_batch
    from cuikslam.solver import solve

    logs = [ambiguous_log(seed) for seed in (0, 1)]
    options = {
        "consistency": "hull",
        "certify_limit": 0,
        "work_budget": None,
        "strengthen_during": 0,
    }
    batch = solve_batch(logs, client, **options)
    for log, solution in zip(logs, batch, strict=True):
        alone = solve(log, **options)
        assert [h.assignment for h in solution.hypotheses] == [
            h.assignment for h in alone.hypotheses
        ]
        assert solution.correspondence == alone.correspondence


def _write_logs(folder: Path, seeds: range) -> list[Path]:
    paths = []
    for seed in seeds:
        path = folder / f"world{seed}.jsonl"
        write_log_file(ambiguous_log(seed), path)
        paths.append(path)
    return paths


def test_cli_several_logs_write_one_result_each(tmp_path: Path) -> None:
    logs = _write_logs(tmp_path, range(2))
    out = tmp_path / "results"
    result = subprocess.run(
        [*CLI, "solve", *map(str, logs), "--consistency", "hull", "--strengthen-during", "0",
         "-q", "--json", str(out)],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in out.iterdir()) == ["world0.json", "world1.json"]
    assert result.stdout.count("== ") == 2


def test_cluster_options_without_dask_say_what_to_install(tmp_path: Path) -> None:
    [log] = _write_logs(tmp_path, range(1))
    code = (
        "import sys; sys.modules['distributed'] = None\n"
        "from cuikslam.cli.main import main\n"
        f"sys.exit(main(['solve', {str(log)!r}, '--workers', '2']))"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert 'pip install "cuikslam[distributed]"' in result.stderr


def test_one_process_does_not_import_dask(tmp_path: Path) -> None:
    [log] = _write_logs(tmp_path, range(1))
    code = (
        "import sys\n"
        "from cuikslam.cli.main import main\n"
        f"status = main(['solve', {str(log)!r}, '-q', '--consistency', 'hull'])\n"
        "assert 'distributed' not in sys.modules and 'dask' not in sys.modules\n"
        "sys.exit(status)"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 0, result.stderr


def test_cli_scheduler_runs_the_search_on_an_existing_cluster(tmp_path: Path) -> None:
    """``--scheduler ADDRESS``: the command's search runs on a cluster started here (one
    worker thread of this process, reached over TCP) and finds what the single-process
    command finds."""
    distributed = pytest.importorskip(
        "distributed", reason='needs Dask: pip install "cuikslam[distributed]"'
    )
    [log] = _write_logs(tmp_path, range(1))
    args = [
        *CLI,
        "solve",
        str(log),
        "-q",
        "--consistency",
        "hull",
        "--strengthen-during",
        "0",
    ]
    alone = subprocess.run(args, capture_output=True, text=True, timeout=300, check=False)
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, protocol="tcp",
        dashboard_address=":0", memory_limit=0,
    ) as cluster:  # fmt: skip
        on_cluster = subprocess.run(
            [*args, "--scheduler", cluster.scheduler_address], capture_output=True, text=True,
            timeout=300, check=False,
        )  # fmt: skip
    assert alone.returncode == on_cluster.returncode == 0, on_cluster.stderr
    summary = alone.stdout.splitlines()[0]  # then the witness search, which is timed
    assert "survivors" in summary
    assert on_cluster.stdout.splitlines()[0] == summary
