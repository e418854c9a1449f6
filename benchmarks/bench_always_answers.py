"""Benchmark: what a user gets from ``cuikslam solve`` on sparse worlds without landmark ids.

    python benchmarks/bench_always_answers.py                      # 10 worlds of 200 poses
    python benchmarks/bench_always_answers.py --seeds 3 --poses 100 --json out.json
    python benchmarks/bench_always_answers.py --poses 1000 --landmarks 50
    python benchmarks/bench_always_answers.py --poses 1000 --landmarks 50 --seed 4 --seeds 1 \
        --work-budget 2e9                                            # how much work seed 4 needs

The worlds are the issue's (``cuikslam simulate random --poses 200 --landmarks 40 --size
30,20 --max-range 6 --unknown``: every reading unlabelled, 40 landmarks of three look-alike
classes, a 6 m sensor). Each is solved as the CLI solves it (``solve`` with the default
options: the work budget ``auto``), in its own process after a warm-up, and the result is
checked against the world's exact truth. Columns:

- ``proven``: a hypothesis proven consistent (a verified witness) is in the result;
  ``early``: a leaf was proven before the exhaustive search went on, with the work units
  and the seconds at that moment (``early work``, ``early s``); ``guess``: that leaf was
  the guess's (a scan at a time), not the dive's;
- ``hyps``: hypotheses reported; ``complete``: the search finished; ``truth``: the true
  correspondence is among them;
- ``envelope``: every pose's envelope box holds the true pose (the answer a user gets
  whatever the search reached);
- ``work``: work units spent, of the budget; ``wall s`` and ``cpu s``: seconds of the
  whole solve (a warm run; the load is printed, the work is the same on any machine, and
  the CPU seconds are what a quiet machine's wall time would be).

``--landmarks`` and ``--classes`` change the world (the issue's 1,000-pose worlds: 50
landmarks; the simulator's three classes by default). ``--work-budget`` replaces the
default budget (for measuring what a world needs; no walk reserve then). The JSON rows
also hold the solve's expansions, operator applications and stage timings.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import time
from pathlib import Path

WORLD = {"n_landmarks": 40, "size": (30.0, 20.0), "max_range": 6.0}


def _run(
    seed: int, n_poses: int, world: dict, work_budget: float | None, queue: multiprocessing.Queue
) -> None:
    from cuikslam.results.association import envelope_report, rank_of
    from cuikslam.results.solution import PROVEN
    from cuikslam.simulate import simulate_random_world
    from cuikslam.solver import solve

    solve(simulate_random_world(seed=seed, n_poses=5, n_landmarks=3, unknown=True)[0])
    log, truth = simulate_random_world(seed=seed, n_poses=n_poses, unknown=True, **world)
    start, cpu = time.perf_counter(), time.process_time()
    solution = solve(log) if work_budget is None else solve(log, work_budget=work_budget)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    stats = solution.statistics
    envelope = envelope_report(solution, truth)
    queue.put(
        {
            "seed": seed,
            "poses": n_poses,
            "observations": len(log.observations),
            "proven": any(h.status == PROVEN for h in solution.hypotheses),
            "early": bool(stats.get("dive_proven", 0)),
            "by_guess": bool(stats.get("guess_proven", 0)),
            "early_work": stats.get("dive_proven_work", 0),
            "early_s": solution.timings.get("dive_proven_s"),
            "hypotheses": len(solution.hypotheses),
            "complete": solution.complete,
            "truth": rank_of(solution.hypotheses, truth.assignment) is not None,
            "envelope": envelope is not None and envelope.ok,
            "work_spent": stats.get("work_spent"),
            "work_budget": stats.get("work_budget"),
            "wall_s": wall,
            "cpu_s": cpu,
            "dive_nodes": stats.get("dive_nodes"),
            "expansions": stats.get("branch_points"),
            "operator_applications": stats.get("operator_applications"),
            "timings": solution.timings,
            "load": os.getloadavg()[0],
        }
    )


def _units(text: str) -> float:
    """A work budget from the command line: a positive number of units."""
    try:
        units = float(text)
    except ValueError:
        units = -1.0
    if not units > 0 or units == float("inf"):
        raise argparse.ArgumentTypeError(f"not a positive number of work units: {text!r}")
    return units


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0, help="first seed")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--landmarks", type=int, default=WORLD["n_landmarks"])
    parser.add_argument(
        "--classes", help="landmark classes, comma-separated (default: the simulator's three)"
    )
    parser.add_argument(
        "--work-budget", type=_units, help="work units of each solve (default: its auto budget)"
    )
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    world = {**WORLD, "n_landmarks": args.landmarks}
    if args.classes:
        world["classes"] = tuple(args.classes.split(","))
    header = ("seed", "obs", "proven", "early", "guess", "early work", "early s", "hyps",
              "complete", "truth", "envelope", "work", "wall s", "cpu s", "load")  # fmt: skip
    print(" ".join(f"{h:>10}" for h in header))
    rows = []
    for seed in range(args.seed, args.seed + args.seeds):
        queue: multiprocessing.Queue = multiprocessing.Queue()
        process = multiprocessing.Process(
            target=_run, args=(seed, args.poses, world, args.work_budget, queue)
        )
        process.start()
        r = queue.get()
        process.join()
        rows.append(r)
        early_s = "—" if r["early_s"] is None else f"{r['early_s']:.1f}"
        print(f"{r['seed']:>10} {r['observations']:>10} {r['proven']!s:>10} {r['early']!s:>10} "
              f"{r['by_guess']!s:>10} "
              f"{r['early_work']:>10,} {early_s:>10} {r['hypotheses']:>10} "
              f"{r['complete']!s:>10} {r['truth']!s:>10} {r['envelope']!s:>10} "
              f"{r['work_spent']:>10,} {r['wall_s']:>10.1f} {r['cpu_s']:>10.1f} "
              f"{r['load']:>10.1f}")  # fmt: skip
        sys.stdout.flush()
    n = len(rows)
    keys = ("proven", "early", "by_guess", "complete", "truth", "envelope")
    counts = {k: sum(r[k] for r in rows) for k in keys}
    print(", ".join(f"{k}: {v}/{n}" for k, v in counts.items()))
    if args.json:
        args.json.write_text(json.dumps({"world": world, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
