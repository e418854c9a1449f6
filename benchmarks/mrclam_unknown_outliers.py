"""MRCLAM with ids dropped and declared outliers: the search's "outlier" option, measured.

    python benchmarks/mrclam_unknown_outliers.py                 # robot 3, 250-256 s, Q = 4
    python benchmarks/mrclam_unknown_outliers.py --start 251 --duration 4 --outliers 1

One window of one robot of Dataset 6 (default bounds), imported with ``--unknown`` and
``--outliers Q``, solved by a fresh ``cuikslam solve`` process (``--time-budget``, default
level) under ``/usr/bin/time -v`` for the peak RSS; then the same log without the
declaration. For each: wall time, nodes expanded, survivors, explored share of the tree,
whether the true association is among the reported survivors (``--truth``), and, followed
decision by decision in this process, whether the true association survives every decision
(with the observations that miss their Vicon truth as outliers; without the declaration
those have no true branch). Rows go to benchmarks/results/mrclam_unknown_outliers.json,
with the load average before each solve.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _cuikslam(args: list[str], timed: bool = False) -> tuple[float, int | None, str]:
    prefix = ["/usr/bin/time", "-v"] if timed and Path("/usr/bin/time").exists() else []
    start = time.perf_counter()
    done = subprocess.run(
        [*prefix, sys.executable, "-m", "cuikslam.cli.main", *args], capture_output=True, text=True
    )
    if done.returncode not in (0, 1):
        raise SystemExit(f"cuikslam {' '.join(args)} failed: {done.stderr.strip()}")
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", done.stderr)
    return time.perf_counter() - start, int(rss.group(1)) if rss else None, done.stdout


def follow_truth(log_path: Path, truth_path: Path) -> str:
    """Whether the true association (outliers: the observations that miss their truth)
    survives every decision of the search, followed from the root."""
    from cuikslam.hypotheses.explorer import Explorer
    from cuikslam.hypotheses.outlier_option import OUTLIER
    from cuikslam.hypotheses.problem import build_problem
    from cuikslam.log import read_log_file
    from cuikslam.options import SolveOptions
    from cuikslam.results.measurement_check import check_log
    from cuikslam.simulate.truth import read_truth_file

    log, truth = read_log_file(log_path), read_truth_file(truth_path)
    outside = set(check_log(log, truth).outside_observations)
    problem = build_problem(log)
    if outside and problem.outlier is None:
        return f"no true branch: {len(outside)} observations miss their truth"
    numbers: dict[str, int] = {}
    path = []
    for d in problem.decisions:
        lid = truth.assignment[d.position]
        if d.position in outside:
            path.append(OUTLIER)
        else:
            path.append(numbers.setdefault(lid, len(problem.named) + len(numbers)))
    options = SolveOptions()
    explorer = Explorer(problem, options.rtol, "hull", options.strengthen_during, True)
    node = explorer.root()
    for k, number in enumerate(path):
        kids, _ = explorer.children(node)
        node = next((c for c in kids if c.assigned[0] == number), None)
        if node is None:
            return f"refuted at decision {k} of {len(path)}"
    return f"survives all {len(path)} decisions ({len(outside)} outliers)" + (
        ", refuted by the leaf bisection" if explorer.refuted_leaf(node) else ""
    )


def measure(folder: Path, work: Path, args: argparse.Namespace, declared: bool) -> dict:
    stem = work / f"r{args.robot}_{args.start:g}_{args.duration:g}_{'q' if declared else 'plain'}"
    log, truth = stem.with_suffix(".jsonl"), stem.with_suffix(".truth.json")
    extra = ["--outliers", str(args.outliers)] if declared else []
    _cuikslam(
        ["import", "mrclam", str(folder), "--robot", str(args.robot), "--start",
         str(args.start), "--duration", str(args.duration), "--unknown", *extra,
         "-o", str(log), "-q"]
    )  # fmt: skip
    load = os.getloadavg()
    result = stem.with_suffix(".result.json")
    seconds, rss, stdout = _cuikslam(
        ["solve", str(log), "--json", str(result), "--truth", str(truth), "--no-table",
         "--time-budget", str(args.time_budget)],
        timed=True,
    )  # fmt: skip
    doc = json.loads(result.read_text())
    stats = doc["statistics"]
    return {
        "robot": args.robot,
        "start_s": args.start,
        "duration_s": args.duration,
        "declared": f"at most {args.outliers} in all" if declared else None,
        "poses": stats["poses"],
        "observations": stats["observations"],
        "wall_s": round(seconds, 1),
        "peak_rss_mb": None if rss is None else round(rss / 1024),
        "load_before": [round(v, 2) for v in load],
        "complete": doc["complete"],
        "nodes_expanded": stats["branch_points"],
        "survivors": stats["survivors"],
        "outlier_options": stats.get("outlier_options", 0),
        "explored_fraction": round(stats["explored_fraction"], 3),
        "truth_check": [line for line in stdout.splitlines() if "truth check" in line],
        "true_path": follow_truth(log, truth),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=os.environ.get("CUIKSLAM_DATA", ROOT.parent / "shared/data"))
    p.add_argument("--robot", type=int, default=3)
    p.add_argument("--start", type=float, default=250.0)
    p.add_argument("--duration", type=float, default=6.0)
    p.add_argument("--outliers", type=int, default=4)
    p.add_argument("--time-budget", type=float, default=120.0)
    args = p.parse_args()
    folder = Path(args.data) / "mrclam-6"
    if not folder.is_dir():
        raise SystemExit(f"no MRCLAM Dataset 6 in {folder}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for declared in (True, False):
            rows.append(measure(folder, Path(tmp), args, declared))
            print(json.dumps(rows[-1]), flush=True)
    out = ROOT / "benchmarks/results/mrclam_unknown_outliers.json"
    out.write_text(json.dumps(rows, indent=1) + "\n", encoding="utf-8")
    print(f"rows written to {out}")


if __name__ == "__main__":
    main()
