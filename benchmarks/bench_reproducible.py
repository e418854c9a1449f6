"""Same verdict on any machine: results under load, and the wall time of ``cuikslam paper``.

    python benchmarks/bench_reproducible.py                 # both parts
    python benchmarks/bench_reproducible.py --skip-load     # the paper's wall time only

1. ``cuikslam paper`` (warm: the kernels are loaded from numba's cache first), run
   ``--repeats`` times in fresh processes: wall time of each, and whether both survivors of
   the unknown-correspondence part were proven.
2. The seed's experiment with ids dropped and a dense 60-pose unknown-correspondence world
   (``bench_hypotheses.py --dense``'s first seed), solved with default options alone and
   then beside two CPU-bound processes: the result JSON, timings aside, must be identical.

Writes ``benchmarks/results/reproducible.json`` (``--json`` to change), with the machine's
load average before each part.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))  # bench_hypotheses: the dense worlds
RESULTS = Path(__file__).parent / "results" / "reproducible.json"
CLI = [sys.executable, "-m", "cuikslam.cli.main"]
PROVEN_LINE = "correspondence hypotheses are consistent: each is proven"


def _busy(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def paper_runs(repeats: int) -> list[dict]:
    """Wall time of ``cuikslam paper`` in fresh processes, after one warm-up run."""
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        figure = str(Path(folder) / "paper.png")
        subprocess.run([*CLI, "paper", "--figure", figure], capture_output=True, check=True)
        for _ in range(repeats):
            load = os.getloadavg()[0]
            start = time.perf_counter()
            done = subprocess.run(
                [*CLI, "paper", "--figure", figure], capture_output=True, text=True, check=False
            )
            rows.append(
                {
                    "wall_s": round(time.perf_counter() - start, 3),
                    "both_proven": PROVEN_LINE in done.stdout,
                    "exit": done.returncode,
                    "load": round(load, 2),
                }
            )
    return rows


def _worlds() -> list[tuple[str, object]]:
    from bench_hypotheses import DENSE
    from cuikslam.simulate import simulate_paper, simulate_random_world

    dense = simulate_random_world(
        seed=0, n_poses=60, n_landmarks=16, classes=("door", "corridor"), unknown=True, **DENSE
    )[0]
    return [("paper, ids dropped", simulate_paper(seed=0, unknown=True)[0]), ("dense 60", dense)]


def load_runs() -> list[dict]:
    """Each world solved alone, then beside two CPU-bound processes: same JSON?"""
    from cuikslam.results.io import solution_to_json
    from cuikslam.solver import solve

    def doc(log: object) -> dict:
        out = solution_to_json(solve(log))
        out.pop("timings")
        return out

    rows = []
    for name, log in _worlds():
        doc(log)  # loads the kernels
        start = time.perf_counter()
        alone = doc(log)
        alone_s = time.perf_counter() - start
        with multiprocessing.get_context("spawn").Pool(2) as pool:
            pool.map_async(_busy, [3600.0, 3600.0])
            time.sleep(1.0)
            start = time.perf_counter()
            loaded = doc(log)
            loaded_s = time.perf_counter() - start
            pool.terminate()
        rows.append(
            {
                "world": name,
                "identical": loaded == alone,
                "alone_s": round(alone_s, 2),
                "beside_two_busy_processes_s": round(loaded_s, 2),
                "work_spent": alone["statistics"]["work_spent"],
                "budget_bound": alone["statistics"]["budget_bound"],
                "consistency": alone["consistency"],
                "hypotheses": len(alone["hypotheses"]),
                "proven": sum(h["status"] == "proven consistent" for h in alone["hypotheses"]),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--skip-load", action="store_true")
    parser.add_argument("--json", type=Path, default=RESULTS)
    args = parser.parse_args()
    report: dict = {"date": datetime.now(UTC).isoformat(timespec="seconds"), "cpus": os.cpu_count()}
    report["paper"] = paper_runs(args.repeats)
    for row in report["paper"]:
        print("cuikslam paper (warm):", row)
    if not args.skip_load:
        report["load"] = load_runs()
        for row in report["load"]:
            print("alone vs beside two busy processes:", row)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
