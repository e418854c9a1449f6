"""MRCLAM with declared outliers (docs/real-data.md, "Declared outliers").

    python benchmarks/mrclam_outliers.py                    # ../shared/data/mrclam-6, robots 1-5
    python benchmarks/mrclam_outliers.py --robots 3 --part window

Two parts, each robot with known correspondence, every command a fresh ``cuikslam``
process (warm numba cache), solved at level ``lp`` with a 120 s budget:

- ``run``: the whole run with the default bounds, declared "at most 5 observations in
  all, at most 1 per pose" (``--outliers 5 --outliers-window 1 1``);
- ``window``: 60 s after the first 440 s, with range and bearing bounds calibrated on the
  first 440 s at quantile 0.99 (the motion bounds at quantile 1, since a declaration
  covers observations only), declared "at most 2 % of the observations in all, at most 2
  per 10 poses".

Each is solved with and without the declaration, checked against Vicon (``cuikslam
calibrate check`` counts the observations that really miss their truth, so the table says
whether the declaration held) and evaluated. Rows go to benchmarks/results/mrclam_outliers.json.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(args: list[str]) -> float:
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "cuikslam.cli.main", *args], capture_output=True, text=True
    )
    if done.returncode not in (0, 1):
        raise SystemExit(f"cuikslam {' '.join(args)} failed: {done.stderr.strip()}")
    return time.perf_counter() - start


def _evaluate(result: Path, truth: Path) -> dict:
    out = result.with_suffix(".eval.json")
    _run(["evaluate", str(result), "--truth", str(truth), "--json", str(out), "-q"])
    doc = json.loads(out.read_text())
    return {
        "poses_inside": [doc["poses"]["inside"], doc["poses"]["with_truth"]],
        "landmarks_inside": [doc["landmarks"]["inside"], doc["landmarks"]["with_truth"]],
        "median_width": {k: doc["widths"][k]["median"] for k in doc["widths"]},
    }


def _solve(log: Path, truth: Path) -> dict:
    result = log.with_suffix(".result.json")
    seconds = _run(["solve", str(log), "--json", str(result), "-q", "--consistency", "lp",
                    "--time-budget", "120"])  # fmt: skip
    doc = json.loads(result.read_text())
    row = {"solve_s": round(seconds, 2), "refuted": doc["refuted"]}
    if "outliers" in doc:
        row["proven_outliers"] = doc["outliers"]["proven"]
    if not doc["refuted"]:
        row.update(_evaluate(result, truth))
    return row


def _outside(log: Path, truth: Path, block: int) -> dict:
    """The observations that really miss their truth, and the most in one block of poses."""
    check = log.with_suffix(".check.json")
    _run(["calibrate", "check", str(log), "--truth", str(truth), "--json", str(check), "-q"])
    doc = json.loads(check.read_text())
    from cuikslam.log import read_log_file
    from cuikslam.outliers import pose_order

    parsed = read_log_file(log)
    rank = pose_order(parsed)
    observations = parsed.observations
    per_block = Counter(rank[observations[i].pose] // block for i in doc["outside_observations"])
    return {
        "observations": len(observations),
        "outside": len(doc["outside_observations"]),
        "most_in_one_block": max(per_block.values(), default=0),
        "moves_outside": doc["moves_outside"],
    }


def main() -> None:
    from cuikslam.datasets import data_dir
    from cuikslam.datasets.calibrate import calibrate_mrclam, write_bounds_file

    default = (data_dir() or ROOT.parent / "shared" / "data") / "mrclam-6"
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=default)
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--part", choices=["run", "window", "both"], default="both")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for robot in args.robots:
            base = ["import", "mrclam", str(args.folder), "--robot", str(robot), "-q"]
            parts = []
            if args.part in ("run", "both"):
                parts.append(("run", [], (5, 1, 1)))
            if args.part in ("window", "both"):
                tight = calibrate_mrclam(args.folder, robot, duration=440.0, quantile=0.99)
                loose = calibrate_mrclam(args.folder, robot, duration=440.0, quantile=1.0)
                bounds = folder / f"r{robot}.bounds.json"
                write_bounds_file(tight, bounds)
                window = ["--start", "440", "--duration", "60", "--bounds", str(bounds),
                          "--velocity-bound", str(loose.bounds.velocity),
                          "--turn-rate-bound", str(loose.bounds.turn_rate)]  # fmt: skip
                parts.append(("window", window, (None, 2, 10)))
            for part, options, (in_all, per_block, block) in parts:
                plain = folder / f"r{robot}{part}.jsonl"
                truth = plain.with_suffix(".truth.json")
                _run([*base, *options, "-o", str(plain)])
                outside = _outside(plain, truth, block)
                if in_all is None:  # 2 % of the observations
                    in_all = math.ceil(0.02 * outside["observations"])
                declared = folder / f"r{robot}{part}q.jsonl"
                _run([*base, *options, "--outliers", str(in_all), "--outliers-window",
                      str(per_block), str(block), "-o", str(declared)])  # fmt: skip
                os.replace(declared.with_suffix(".truth.json"), truth)
                row = {
                    "robot": robot,
                    "part": part,
                    "declared": {"in_all": in_all, "per_block": per_block, "block_poses": block},
                    "truth": outside,
                    "declaration_holds": outside["outside"] <= in_all
                    and outside["most_in_one_block"] <= per_block,
                    "plain": _solve(plain, truth),
                    "declared_solve": _solve(declared, truth),
                }
                rows.append(row)
                print(json.dumps(row), flush=True)
    out = ROOT / "benchmarks" / "results" / "mrclam_outliers.json"
    out.write_text(json.dumps(rows, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
