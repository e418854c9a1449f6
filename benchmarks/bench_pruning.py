"""Benchmark: how many more hypotheses the level `lp` prunes than `hull` (unknown correspondence).

The correspondence search keeps every hypothesis that narrowing cannot refute. At level
``hull`` only the fixpoint of the factors' operators refutes; at level ``lp`` the
polytope-hull rounds run on the hypotheses as well (``--strengthen-limit`` of them), and
refute the ones whose boxes contract to empty once correlations are kept. For each world
this prints the survivors at both levels, whether the true partition survived (it must),
and the times.

    python benchmarks/bench_pruning.py                      # random worlds, seeds 0-9
    python benchmarks/bench_pruning.py --paper 0            # also the seed's experiment
    python benchmarks/bench_pruning.py --json out.json

Random worlds: 12 poses, 6 landmarks in 2 classes, a sensor that sees 6 m ahead over a
half-plane, odometry errors of 0.15 rad and 0.3 m and observation errors of 0.1 m and
0.05 rad, so that many partitions stay possible. The search keeps at most
``--max-hypotheses`` (default 300); a world where it hit that limit is marked incomplete.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from cuikslam._atomic import atomic_write_text
from cuikslam.log.records import Log
from cuikslam.results.association import partition
from cuikslam.simulate import simulate_paper, simulate_random_world
from cuikslam.solver import solve

STRENGTHEN_ALL = 1_000_000


def measure(name: str, log: Log, true_assignment: list[str], max_hypotheses: int) -> dict[str, Any]:
    """Survivors and times at levels hull and lp (lp applied to every survivor)."""
    truth = partition(true_assignment)
    row: dict[str, Any] = {"world": name, "observations": len(log.observations)}
    for level in ("hull", "lp"):
        start = time.perf_counter()
        solution = solve(
            log,
            consistency=level,
            max_hypotheses=max_hypotheses,
            strengthen_limit=STRENGTHEN_ALL,
            certify_limit=0,
        )
        row[f"{level}_seconds"] = time.perf_counter() - start
        row[f"{level}_survivors"] = len(solution.hypotheses)
        row[f"{level}_complete"] = solution.complete
        row[f"{level}_true_kept"] = any(
            partition(h.assignment) == truth for h in solution.hypotheses
        )
    row["pruned_by_lp"] = row["hull_survivors"] - row["lp_survivors"]
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(10)))
    parser.add_argument("--paper", type=int, nargs="*", default=[], help="paper noise seeds")
    parser.add_argument("--max-hypotheses", type=int, default=300)
    parser.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = parser.parse_args(argv)
    solve(simulate_random_world(seed=0, n_poses=5, n_landmarks=3, unknown=True)[0])  # compile
    worlds = []
    for seed in args.paper:
        log, truth = simulate_paper(seed=seed, unknown=True)
        worlds.append((f"paper seed {seed}", log, truth.assignment))
    for seed in args.seeds:
        log, truth = simulate_random_world(
            seed=seed, n_poses=12, n_landmarks=6, classes=("door", "corridor"),
            size=(20.0, 15.0), max_range=6.0, fov=math.pi, odometry_bounds=(0.15, 0.3),
            observation_bounds=(0.1, 0.05), unknown=True,
        )  # fmt: skip
        worlds.append((f"random seed {seed}", log, truth.assignment))
    header = f"{'world':16} {'obs':>4} {'hull':>6} {'lp':>6} {'pruned':>7} {'truth':>6} "
    print(header + f"{'hull s':>8} {'lp s':>8}")
    rows = []
    for name, log, assignment in worlds:
        row = measure(name, log, assignment, args.max_hypotheses)
        rows.append(row)
        kept = "yes" if row["hull_true_kept"] and row["lp_true_kept"] else "NO"
        if not row["hull_complete"]:
            kept += " (incomplete)"
        print(
            f"{name:16} {row['observations']:>4} {row['hull_survivors']:>6} "
            f"{row['lp_survivors']:>6} {row['pruned_by_lp']:>7} {kept:>6} "
            f"{row['hull_seconds']:>8.2f} {row['lp_seconds']:>8.2f}",
            flush=True,
        )
    hull = sum(r["hull_survivors"] for r in rows)
    lp = sum(r["lp_survivors"] for r in rows)
    print(f"\nover all worlds: {hull} survivors at hull, {lp} at lp ({hull - lp} pruned by lp)")
    if args.json:
        atomic_write_text(args.json, json.dumps(rows, indent=2))
    complete = [r for r in rows if r["hull_complete"]]
    return 0 if all(r["hull_true_kept"] and r["lp_true_kept"] for r in complete) else 1


if __name__ == "__main__":
    sys.exit(main())
