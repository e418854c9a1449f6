"""Benchmark of the witness search: how long logs and typical hypotheses get proven.

    python benchmarks/bench_witness.py                          # every case below
    python benchmarks/bench_witness.py --cases known-200-s42 paper
    python benchmarks/bench_witness.py --label before --seconds 120 --json out.json

Each case is solved without the witness search (``certify_limit=0``: known correspondence
at level ``hull``, the correspondence search at its default level, or at ``hull`` for the
dense worlds), then :func:`cuikslam.witness.certify` decides its hypotheses
with the work the solve's default budget (:func:`cuikslam.budget.work_budget_for`) has
left, as ``cuikslam solve`` gives it (``--seconds`` adds a wall-clock cap, for versions
whose search is slow). Reported per case: hypotheses proven / undecided, residual
evaluations, starts, the work units the search spent (the machine-independent measure),
its CPU seconds, and units per CPU microsecond (the calibration of
:data:`cuikslam.budget.COSTS`).

Cases (every world is a random world of :func:`cuikslam.simulate.simulate_random_world`):

* ``known-N-sS``: N poses, known correspondence, a 30 x 20 m room, a 6 m sensor, 40
  landmarks (80 and a 40 x 30 m room at 2,000 poses); ``known-200-s42`` is the world of
  ``cuikslam simulate random --seed 42 --poses 200 --landmarks 40 --size 30,20
  --max-range 6``;
* ``paper``: the seed's experiment without ids (two survivors);
* ``dense-N-sS``: the dense worlds of ``bench_hypotheses.py --dense`` that keep several
  survivors (unknown correspondence, level ``hull``); ``dense-60-s7``'s second survivor
  is refuted only by the ``lp`` level, so it stays undecided;
* ``woods-300``: 300 samples of Lost in the Woods from sample 3000 (relative poses, a
  laser offset), when the recording is found (``CUIKSLAM_DATA``); ``woods-1262`` the
  whole run (``cuikslam import lost-in-the-woods dataset2.mat --known``, level ``hull``).

Rows of a label already in the JSON file are replaced case by case.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_hypotheses import DENSE

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "witness.json"

ROOM = {"size": (30.0, 20.0), "max_range": 6.0}
KNOWN = [(50, 1), (200, 42), (200, 2), (500, 3), (1000, 4), (2000, 5)]
DENSE_CASES = [(30, 9), (60, 2), (60, 7), (100, 2)]


def _known(poses: int, seed: int):
    from cuikslam.simulate import simulate_random_world

    room = dict(ROOM, size=(40.0, 30.0)) if poses >= 2000 else ROOM
    landmarks = 80 if poses >= 2000 else 40
    log, _ = simulate_random_world(seed=seed, n_poses=poses, n_landmarks=landmarks, **room)
    return log, {"consistency": "hull"}


def _dense(poses: int, seed: int):
    from cuikslam.simulate import simulate_random_world

    log, _ = simulate_random_world(
        seed=seed, n_poses=poses, n_landmarks=16, classes=("door", "corridor"), unknown=True,
        **DENSE,
    )  # fmt: skip
    return log, {"consistency": "hull"}


def _paper():
    from cuikslam.simulate import simulate_paper

    return simulate_paper(seed=0, unknown=True)[0], {}


def _woods(whole: bool = False):
    from cuikslam.cli.main import main
    from cuikslam.datasets import data_dir
    from cuikslam.log import read_log_file

    folder = data_dir()
    mat = folder / "lost-in-the-woods" / "dataset2.mat" if folder else None
    if mat is None or not mat.exists():
        return None
    with tempfile.TemporaryDirectory() as tmp:
        bounds, out = Path(tmp) / "bounds.json", Path(tmp) / "k.jsonl"
        if whole:  # the whole run, default bounds, as on the Real data page
            main(["import", "lost-in-the-woods", str(mat), "--known", "-o", str(out)])
            return read_log_file(out), {"consistency": "hull"}
        main(["calibrate", "lost-in-the-woods", str(mat), "-o", str(bounds)])
        window = ["--start", "3000", "--steps", "300", "--keyframe-observations", "--known"]
        main(["import", "lost-in-the-woods", str(mat), "--bounds", str(bounds), *window,
              "-o", str(out)])  # fmt: skip
        return read_log_file(out), {}


CASES = {
    **{f"known-{n}-s{s}": (lambda n=n, s=s: _known(n, s)) for n, s in KNOWN},
    "paper": _paper,
    **{f"dense-{n}-s{s}": (lambda n=n, s=s: _dense(n, s)) for n, s in DENSE_CASES},
    "woods-300": _woods,
    "woods-1262": lambda: _woods(whole=True),
}


def run_case(name: str, seconds: float | None) -> dict | None:
    """Solve case ``name`` without witnesses, then certify its hypotheses with what the
    default budget has left; the measurements."""
    from cuikslam.budget import Budget, work_budget_for
    from cuikslam.solver import solve
    from cuikslam.witness import certify

    made = CASES[name]()
    if made is None:
        return None
    log, options = made
    n_poses = len({p for r in log.records for p in _poses_of(r)})
    start = time.perf_counter()
    solution = solve(log, certify_limit=0, **options)
    solve_s = time.perf_counter() - start
    left = work_budget_for(n_poses) - solution.statistics.get("work_spent", 0)
    budget = Budget.start(work=max(left, 0.0), seconds=seconds)
    cpu, wall = time.process_time(), time.perf_counter()
    stats = certify(log, solution, deadline=budget)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    statuses = [h.status for h in solution.hypotheses]
    return {
        "case": name,
        "poses": n_poses,
        "observations": len(log.observations),
        "hypotheses": len(statuses),
        "proven": statuses.count("proven consistent"),
        "undecided": len(statuses) - statuses.count("proven consistent"),
        "evaluations": stats.evaluations,
        "starts": stats.starts,
        "budget_units": round(left),
        "units": round(budget.meter.spent),
        "bound": budget.meter.bound,
        "cpu_s": round(cpu, 3),
        "wall_s": round(wall, 3),
        "units_per_cpu_us": round(budget.meter.spent / (cpu * 1e6), 3) if cpu > 0 else None,
        "solve_s": round(solve_s, 3),
        "load_average": round(os.getloadavg()[0], 2),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
    }


def _poses_of(record) -> list[int]:
    return [getattr(record, a) for a in ("pose", "source", "target") if hasattr(record, a)]


def _in_process(name: str, seconds: float | None) -> dict | None:
    """One case in a fresh process (its memory its own), after a warm-up solve."""
    here = str(Path(__file__).parent)
    code = (
        f"import json, sys; sys.path.insert(0, {here!r}); import bench_witness as b; "
        "from cuikslam.simulate import simulate_paper; from cuikslam.solver import solve; "
        f"solve(simulate_paper(seed=1)[0]); print(json.dumps(b.run_case({name!r}, {seconds!r})))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=False
    )  # fmt: skip
    if out.returncode != 0:
        print(out.stderr, file=sys.stderr)
        return {"case": name, "error": out.stderr.strip().splitlines()[-1:]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    parser.add_argument("--seconds", type=float, default=None,
                        help="a wall-clock cap on each certify (default: none)")  # fmt: skip
    parser.add_argument("--label", default="current", help="key of this run in the JSON")
    parser.add_argument("--json", type=Path, default=RESULTS, help=f"default {RESULTS}")
    args = parser.parse_args(argv)
    rows = []
    print(f"{'case':<16} {'poses':>5} {'hyp':>4} {'proven':>6} {'evals':>6} "
          f"{'units':>10} {'CPU s':>7} {'u/us':>5} {'load':>5}")  # fmt: skip
    for name in args.cases:
        row = _in_process(name, args.seconds)
        if row is None:
            continue
        rows.append(row)
        if "error" in row:
            print(f"{name:<16} error: {row['error']}")
            continue
        print(f"{name:<16} {row['poses']:>5} {row['hypotheses']:>4} {row['proven']:>6} "
              f"{row['evaluations']:>6} {row['units']:>10,} {row['cpu_s']:>7.2f} "
              f"{row['units_per_cpu_us'] or 0:>5.2f} {row['load_average']:>5.2f}",
              flush=True)  # fmt: skip
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True, check=False).stdout.strip()  # fmt: skip
    document = json.loads(args.json.read_text()) if args.json.exists() else {}
    ran = {row["case"] for row in rows}
    kept = [row for row in document.get(args.label, {}).get("runs", []) if row["case"] not in ran]
    document[args.label] = {
        "command": "python benchmarks/bench_witness.py " + " ".join(argv or sys.argv[1:]),
        "commit": commit,
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}",
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "runs": kept + rows,
    }
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(document, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
