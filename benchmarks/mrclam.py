"""MRCLAM figures of docs/real-data.md: import sizes and times, calibrated bounds and what
falls outside them on the rest of each run, and a solved, evaluated window.

    python benchmarks/mrclam.py                      # ../shared/data/mrclam-6, robots 1-5
    python benchmarks/mrclam.py --folder DIR --robots 1 3 --split 440 --window 60

Each import and solve runs as a user would run it (a fresh ``cuikslam`` process, warm
numba cache); calibration runs in this process. Rows are printed and written to
benchmarks/results/mrclam.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(args: list[str]) -> tuple[float, str]:
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "cuikslam.cli.main", *args], capture_output=True, text=True
    )
    if done.returncode not in (0, 1):
        raise SystemExit(f"cuikslam {' '.join(args)} failed: {done.stderr.strip()}")
    return time.perf_counter() - start, done.stderr + done.stdout


def main() -> None:
    from cuikslam.datasets import data_dir
    from cuikslam.datasets.calibrate import calibrate_mrclam, count_outside, write_bounds_file
    from cuikslam.datasets.mrclam_files import read_mrclam_tables

    default = (data_dir() or ROOT.parent / "shared" / "data") / "mrclam-6"
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=default)
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--split", type=float, default=440.0, help="calibration part [s]")
    parser.add_argument("--window", type=float, default=60.0, help="solved window [s]")
    parser.add_argument("--quantiles", type=float, nargs="+", default=[1.0, 0.99])
    args = parser.parse_args()

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for robot in args.robots:
            log = folder / f"r{robot}.jsonl"
            seconds, said = _run(["import", "mrclam", str(args.folder), "--robot", str(robot),
                                  "-o", str(log)])  # fmt: skip
            row: dict = {"robot": robot, "import_s": round(seconds, 2), "import": said.strip()}
            tables = read_mrclam_tables(args.folder, robot)
            for q in args.quantiles:
                start = time.perf_counter()
                cal = calibrate_mrclam(tables, robot, duration=args.split, quantile=q)
                rest = count_outside(tables, robot, cal.bounds, start=args.split)
                row[f"q{q}"] = {
                    "bounds": {k: getattr(cal.bounds, k)
                               for k in ("range", "range_per_metre", "bearing", "velocity",
                                         "turn_rate")},
                    "calibration_outside": [cal.outside.ranges, cal.outside.bearings,
                                            cal.outside.moves],
                    "rest_outside": {"ranges": rest.ranges, "bearings": rest.bearings,
                                     "observations": rest.observations_checked,
                                     "moves": rest.moves, "moves_checked": rest.moves_checked},
                    "seconds": round(time.perf_counter() - start, 1),
                }  # fmt: skip
                if q == 1.0:
                    bounds = folder / f"r{robot}.bounds.json"
                    write_bounds_file(cal, bounds)
            if args.window and (folder / f"r{robot}.bounds.json").exists():
                window = folder / f"r{robot}w.jsonl"
                _run(["import", "mrclam", str(args.folder), "--robot", str(robot), "--start",
                      str(args.split), "--duration", str(args.window), "--bounds",
                      str(folder / f"r{robot}.bounds.json"), "-o", str(window), "-q"])  # fmt: skip
                result = folder / f"r{robot}w.result.json"
                seconds, _ = _run(["solve", str(window), "--json", str(result), "-q",
                                   "--consistency", "lp", "--time-budget", "120"])  # fmt: skip
                evaluation = folder / f"r{robot}w.eval.json"
                _run(["evaluate", str(result), "--truth", str(folder / f"r{robot}w.truth.json"),
                      "--json", str(evaluation), "-q"])  # fmt: skip
                doc = json.loads(evaluation.read_text())
                row["window"] = {
                    "solve_s": round(seconds, 1),
                    "poses": doc["poses"],
                    "landmarks": doc["landmarks"],
                    "widths": {k: doc["widths"][k] for k in ("x", "y", "theta")},
                }
            rows.append(row)
            print(json.dumps(row), flush=True)
    out = ROOT / "benchmarks" / "results" / "mrclam.json"
    out.write_text(json.dumps(rows, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
