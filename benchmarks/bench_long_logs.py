"""Benchmark: the default consistency level on long logs (time, box widths, memory per pose).

For each length, a known-correspondence log is written, then solved in a fresh process at
the default level (``auto``, i.e. ``lp``) with no time budget, so that every length reaches
the full level:

- ``octagon``: the seed's experiment (octagon in a 30 m room, four landmarks at the wall
  midpoints, the paper's error bounds) driven around ``poses / 8`` times;
- ``random``: ``cuikslam simulate random --seed S --poses N`` (10 landmarks in a 40 x 30 m
  room, 8 m sensor range: long stretches without any landmark in view).

Each run reports the seconds of the narrowing beyond the fixpoint (``lp_s``: the LP sweeps,
the part that grows with the log) and of the whole solve, per pose; the median and widest
pose box per coordinate; the LPs solved; and the peak resident memory of the process per
pose. Runs are *warm*: the process has loaded numba's compiled kernels before the clock
starts (a first run after installing compiles them once, see docs/benchmarks.md).

``--baseline DIR`` runs the same worker with another checkout's ``src`` first on the
Python path (e.g. ``git archive <commit> src | tar -x -C DIR``), to compare with the
``lp`` level of an earlier version; its figures are stored under ``baseline``.

    python benchmarks/bench_long_logs.py [--world octagon] [--poses 100,300,1000]
        [--seed 0] [--json benchmarks/results/long_logs.json] [--baseline DIR --baseline-poses 1000]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
COORDINATES = ("x", "y", "theta")


def octagon_log(n_poses: int, seed: int = 0):
    """The seed's octagon driven for ``n_poses`` poses (pose ``k`` at corner ``k mod 8``)."""
    from cuikslam.log.records import Log, Observation, Odometry, PosePrior, SensorModel
    from cuikslam.simulate import paper
    from cuikslam.simulate.truth import noisy_interval, wrap_angle

    rng = np.random.default_rng(seed)
    k = np.arange(n_poses)
    angles = -np.pi / 2 + k * np.pi / 4
    xyt = np.column_stack(
        (
            paper.CENTRE_XY[0] + paper.RADIUS * np.cos(angles),
            paper.CENTRE_XY[1] + paper.RADIUS * np.sin(angles),
            paper.FIRST_HEADING + k * np.pi / 4,
        )
    )
    marks = {lid: (cls, np.array(xy)) for lid, (cls, xy) in paper.LANDMARKS.items()}
    ids = list(marks)
    positions = np.array([xy for _, xy in marks.values()])
    x0, y0, t0 = (float(v) for v in xyt[0])
    records = [
        SensorModel(nearest_margin=paper.TIE_MARGIN),
        PosePrior(0, (x0, x0), (y0, y0), (t0, t0)),
    ]
    for i in range(n_poses):
        distances = np.hypot(*(positions - xyt[i, :2]).T)
        for j in np.flatnonzero(distances <= distances.min() + paper.TIE_MARGIN):
            dx, dy = positions[j] - xyt[i, :2]
            records.append(
                Observation(
                    pose=i,
                    landmark_class=marks[ids[j]][0],
                    range=noisy_interval(
                        math.hypot(dx, dy), paper.RANGE_BOUND, rng, non_negative=True
                    ),
                    bearing=noisy_interval(
                        wrap_angle(math.atan2(dy, dx) - xyt[i, 2]), paper.BEARING_BOUND, rng
                    ),
                    landmark=ids[j],
                )
            )
        if i + 1 < n_poses:
            dx, dy, turn = xyt[i + 1] - xyt[i]
            records.append(
                Odometry(
                    source=i,
                    target=i + 1,
                    turn=noisy_interval(float(turn), paper.TURN_BOUND, rng),
                    distance=noisy_interval(
                        math.hypot(dx, dy), paper.DISTANCE_BOUND, rng, non_negative=True
                    ),
                )
            )
    return Log(records=records, path=f"<octagon {n_poses}>")


def write_log(world: str, n_poses: int, seed: int, folder: Path) -> Path:
    """Write the ``world`` log of ``n_poses`` poses into ``folder``; returns its path."""
    path = folder / f"{world}-{n_poses}-seed{seed}.jsonl"
    if world == "octagon":
        from cuikslam.log.writer import write_log_file

        write_log_file(octagon_log(n_poses, seed), path)
    else:
        subprocess.run(
            [sys.executable, "-c", "from cuikslam.cli.main import entry; entry()", "simulate",
             "random", "--seed", str(seed), "--poses", str(n_poses), "-o", str(path), "-q"],
            check=True, cwd=ROOT,
        )  # fmt: skip
    return path


def worker(log_path: str, level: str, threads: int | None = None) -> dict:
    """Solve one log in this process (known correspondence) and measure it (``threads``:
    of the ``lp`` sweeps; None: as the solver decides, from the load)."""
    from cuikslam.graph.kinematic_graph import KinematicGraph
    from cuikslam.log.reader import read_log_file
    from cuikslam.narrowing.consistency import StrengthenReport, strengthen
    from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL, Arrays, propagate
    from cuikslam.options import Level
    from cuikslam.solver import warm_up

    warm_up()
    start = time.perf_counter()
    log = read_log_file(log_path)
    graph = KinematicGraph.from_log(log)
    result = propagate(graph, rtol=DEFAULT_RTOL)
    hull_s = time.perf_counter() - start
    arrays = Arrays.of(graph)
    lo, hi = result.lo.copy(), result.hi.copy()
    report = StrengthenReport()
    chosen = Level.parse(level)
    try:
        from cuikslam.narrowing.parts import default_threads
    except ImportError:  # a baseline from before the parts
        threads, extra = 1, {}
    else:
        threads = default_threads() if threads is None else threads
        extra = {"threads": threads}
    load = os.getloadavg()[0]
    lp_start, cpu_start = time.perf_counter(), time.process_time()
    strengthen(arrays, lo, hi, chosen, DEFAULT_RTOL, DEFAULT_ROUNDS, report=report, **extra)
    lp_s, lp_cpu_s = time.perf_counter() - lp_start, time.process_time() - cpu_start
    total_s = time.perf_counter() - start
    boxes = graph.pose_boxes(lo, hi)
    widths = boxes[..., 1] - boxes[..., 0]
    hull_boxes = graph.pose_boxes(result.lo, result.hi)
    hull_widths = hull_boxes[..., 1] - hull_boxes[..., 0]
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return {
        "poses": len(graph.pose_ids),
        "factors": graph.n_factors,
        "level": report.level,
        "hull_s": hull_s,
        "lp_s": lp_s,
        "lp_cpu_s": lp_cpu_s,
        "solve_s": total_s,
        "lp_ms_per_pose": 1e3 * lp_s / len(graph.pose_ids),
        "lps": report.lp.solved,
        "lp_rounds": report.lp_rounds,
        "peak_rss_mib": peak_kib / 1024,
        "load_average": load,
        "load_average_after": os.getloadavg()[0],
        "threads": threads,
        "peak_rss_kib_per_pose": peak_kib / len(graph.pose_ids),
        "widths": {
            c: {"median": float(np.median(widths[:, i])), "max": float(np.max(widths[:, i]))}
            for i, c in enumerate(COORDINATES)
        },
        "hull_widths": {
            c: {
                "median": float(np.median(hull_widths[:, i])),
                "max": float(np.max(hull_widths[:, i])),
            }
            for i, c in enumerate(COORDINATES)
        },
    }


def run(log_path: Path, level: str, source: Path | None = None, threads: int | None = None) -> dict:
    """:func:`worker` in a fresh process (``source``: a ``src`` folder put first on the path)."""
    env = dict(os.environ)
    if source is not None:
        env["PYTHONPATH"] = str(source) + os.pathsep + env.get("PYTHONPATH", "")
    more = [] if threads is None else ["--threads", str(threads)]
    done = subprocess.run(
        [sys.executable, __file__, "--worker", str(log_path), "--level", level, *more],
        check=True, capture_output=True, text=True, env=env,
    )  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def _row(label: str, r: dict) -> str:
    w = r["widths"]
    return (
        f"{label:<10} {r['poses']:>6} {r['lp_s']:8.1f} {r['lp_cpu_s']:8.1f} {r['threads']:>3} "
        f"{r['load_average']:5.2f} {r['lp_ms_per_pose']:8.1f} "
        f"{r['lps']:>7} {r['level']:<14} {w['x']['median']:7.3f} {w['x']['max']:7.3f} "
        f"{w['theta']['median']:7.4f} {w['theta']['max']:7.4f} {r['peak_rss_kib_per_pose']:7.1f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", choices=["octagon", "random"], default="octagon")
    parser.add_argument("--poses", default="100,300,1000")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--level", default="auto")
    parser.add_argument("--json", help="write the figures here (merged under the world's name)")
    parser.add_argument("--baseline", type=Path, help="a checkout folder holding src/cuikslam")
    parser.add_argument("--baseline-poses", default="1000")
    parser.add_argument("--baseline-level", default="lp")
    parser.add_argument("--key", help="store the figures under this name (default: the world)")
    parser.add_argument(
        "--threads", type=int, help="threads of the lp sweeps (default: as the solver decides)"
    )
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker, args.level, args.threads)))
        return
    print(
        f"{'':<10} {'poses':>6} {'lp s':>8} {'CPU s':>8} {'thr':>3} {'load':>5} {'ms/pose':>8} "
        f"{'LPs':>7} {'level':<14} "
        f"{'x med':>7} {'x max':>7} {'θ med':>7} {'θ max':>7} {'KiB/pose':>7}"
    )
    results: dict = {"runs": [], "baseline": []}
    with tempfile.TemporaryDirectory() as folder:
        if args.baseline is not None:
            for n in (int(p) for p in args.baseline_poses.split(",")):
                log = write_log(args.world, n, args.seed, Path(folder))
                r = run(log, args.baseline_level, args.baseline / "src")
                results["baseline"].append(r)
                print(_row("baseline", r), flush=True)
        for n in (int(p) for p in args.poses.split(",")):
            log = write_log(args.world, n, args.seed, Path(folder))
            r = run(log, args.level, threads=args.threads)
            results["runs"].append(r)
            print(_row(args.level, r), flush=True)
    if args.json:
        path = Path(args.json)
        document = json.loads(path.read_text()) if path.exists() else {}
        document[args.key or args.world] = {
            "command": "python benchmarks/bench_long_logs.py " + " ".join(sys.argv[1:]),
            "seed": args.seed,
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, "
            f"Python {platform.python_version()}",
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "warm": True,
            **results,
        }
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(document, indent=1) + "\n")


if __name__ == "__main__":
    main()
