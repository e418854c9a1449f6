"""End-to-end time of ``cuikslam solve`` under its time budget, on hard and ordinary logs.

Runs the command as a user would (a fresh process: imports and the numba cache load
included) on the issue-9 reproducers and on simulated worlds of up to 50 poses, and
prints the wall time with what the result says it reached: the consistency level, each
hypothesis' status, and which budget ran out.

    python benchmarks/bench_budget.py                       # default options
    python benchmarks/bench_budget.py --consistency lp-split --time-budget none
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
REPRO = ROOT / "tests" / "data" / "repro"


def _simulated(folder: Path) -> list[Path]:
    """Random worlds of 20 and 50 poses (known and unknown correspondence), in ``folder``."""
    from cuikslam.log.writer import write_log_file
    from cuikslam.simulate import simulate_random_world

    paths = []
    for seed, poses, unknown in ((1, 20, False), (1, 50, False), (2, 50, False),
                                 (1, 20, True), (1, 50, True)):  # fmt: skip
        log, _ = simulate_random_world(seed=seed, n_poses=poses, unknown=unknown)
        kind = "unknown" if unknown else "known"
        path = folder / f"random-{poses}-{kind}-seed{seed}.jsonl"
        write_log_file(log, path)
        paths.append(path)
    return paths


def _run(log: Path, out: Path, extra: list[str]) -> tuple[float, int, dict]:
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "cuikslam.cli.main", "solve", str(log), "--json", str(out), "-q",
         *extra],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    elapsed = time.perf_counter() - start
    if "Traceback" in result.stderr:
        print(result.stderr, file=sys.stderr)
    doc = json.loads(out.read_text()) if out.exists() else {}
    return elapsed, result.returncode, doc


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--consistency", default=None, help="passed to cuikslam solve")
    parser.add_argument("--time-budget", default=None, help="passed to cuikslam solve")
    parser.add_argument("logs", nargs="*", type=Path, help="logs (default: repro + simulated)")
    args = parser.parse_args(argv)
    extra = []
    if args.consistency:
        extra += ["--consistency", args.consistency]
    if args.time_budget:
        extra += ["--time-budget", args.time_budget]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        logs = args.logs or [*sorted(REPRO.glob("*.jsonl")), *_simulated(folder)]
        _run(logs[0], folder / "warm.json", extra)  # the numba cache and imports, once
        print(f"cuikslam solve {' '.join(extra) or '(default options)'}")
        print(f"{'log':<28} {'wall s':>7} {'exit':>4} {'level':<18} {'status':<18} budget")
        for log in logs:
            elapsed, code, doc = _run(log, folder / f"{log.stem}.json", extra)
            stats = doc.get("statistics", {})
            ran_out = [k.removesuffix("_budget_exhausted") for k, v in stats.items()
                       if k.endswith("budget_exhausted") and v]  # fmt: skip
            if not doc.get("complete", True):
                ran_out.append("search")
            status = doc["hypotheses"][0]["status"] if doc.get("hypotheses") else "refuted"
            level = doc.get("consistency", "?")
            print(f"{log.name[:28]:<28} {elapsed:7.2f} {code:>4} {level:<18} {status:<18} "
                  f"{','.join(ran_out) or '-'}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
