"""Benchmark: the whole ``cuikslam solve`` command against a codac fixpoint, as processes.

Writes the 10,000-pose log (the seed's octagon driven 1,250 times, known correspondence,
25,002 lines; :mod:`long_log`), then runs, each as a whole process timed by wall clock:

(a) ``cuikslam solve LOG --json OUT`` with its defaults (what a user types; more options
    with ``--solve-args``), after one untimed run so that numba's cache is filled: the
    figures are **warm**; and
(b) this script's ``--codac`` mode on the same log: read the JSON Lines with the standard
    library, then narrow to the fixpoint with codac's ``CtcPolar`` in a Python loop (a
    FIFO queue of factors, one ``CtcPolar`` call per factor application, a factor queued
    again when a variable it touches shrank by more than ``rtol`` of its width), and
    write the pose boxes.

It reports the wall times, their ratio, peak RSS, and whether cuikslam's pose boxes are
no wider than codac's (largest width ratio over every x, y and heading; headings capped
at 2 pi); and, in this process, the log reader's and the result writer's cost per line.
Results go to ``benchmarks/results/end_to_end.json``.

    python benchmarks/bench_end_to_end.py [--laps 1250] [--repeat 3] [--solve-args ARGS]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from collections import deque
from pathlib import Path

HERE = Path(__file__).resolve().parent
RTOL = 1e-3
"""Relative shrink below which the codac loop does not requeue (cuikslam's default)."""
FULL_TURN = 2.0 * math.pi


# --------------------------------------------------------------------------- codac side
def codac_fixpoint(log_path: Path, out_path: Path, rtol: float = RTOL) -> None:
    """Read the log with the standard library, narrow it with codac, write the pose boxes.

    Handles the records of a known-correspondence log: pose priors, odometry (turn, then
    drive: ``theta_b = theta_a + turn``, ``(x, y)_b - (x, y)_a = distance (cos, sin)
    theta_b``) and named observations (``(x, y)_landmark - (x, y)_pose = range (cos, sin)
    (theta + bearing)``). A sensor record adds nothing here.
    """
    from codac import CtcPolar, Interval

    inf = math.inf
    domains: list[Interval] = []
    pose_vars: dict[int, tuple[int, int, int]] = {}
    landmark_vars: dict[str, tuple[int, int]] = {}

    def new(lo: float = -inf, hi: float = inf) -> int:
        domains.append(Interval(lo, hi))
        return len(domains) - 1

    def pose(p: int) -> tuple[int, int, int]:
        if p not in pose_vars:
            pose_vars[p] = (new(), new(), new())
        return pose_vars[p]

    factors: list[tuple[bool, tuple[int, ...]]] = []  # (is odometry, variables)
    with open(log_path, encoding="utf-8") as handle:
        for line in handle:
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            r = json.loads(line)
            kind = r["type"]
            if kind == "prior":
                for var, key in zip(pose(r["pose"]), ("x", "y", "theta"), strict=True):
                    domains[var] &= Interval(*r[key])
            elif kind == "odometry":
                a, b = pose(r["from"]), pose(r["to"])
                turn, dist = new(*r["turn"]), new(*r["distance"])
                factors.append((True, (*a, *b, turn, dist)))
            elif kind == "observation":
                p = pose(r["pose"])
                if r["landmark"] not in landmark_vars:
                    landmark_vars[r["landmark"]] = (new(), new())
                rng = new(*r.get("range", (0.0, inf)))
                bearing = new(*r.get("bearing", (-inf, inf)))
                factors.append((False, (*p, *landmark_vars[r["landmark"]], rng, bearing)))
            elif kind != "sensor":
                raise ValueError(f"{log_path}: the codac side does not read {kind!r} records")

    factors_of: list[list[int]] = [[] for _ in domains]
    for f, (_, variables) in enumerate(factors):
        for var in variables:
            factors_of[var].append(f)
    polar = CtcPolar()
    queue, queued = deque(range(len(factors))), [True] * len(factors)
    applications = 0
    while queue:
        f = queue.popleft()
        queued[f] = False
        applications += 1
        odometry, variables = factors[f]
        d = [Interval(domains[v]) for v in variables]  # fresh copies: codac works in place
        if odometry:
            xa, ya, ta, xb, yb, tb, turn, dist = d
            tb &= ta + turn
            ta &= tb - turn
            turn &= tb - ta
            dx, dy, dist, tb = polar.contract(xb - xa, yb - ya, dist, tb)
            xb &= xa + dx
            xa &= xb - dx
            yb &= ya + dy
            ya &= yb - dy
            ta &= tb - turn
            turn &= tb - ta
            new_values = (xa, ya, ta, xb, yb, tb, turn, dist)
        else:
            x, y, t, lx, ly, rng, bearing = d
            phi = t + bearing
            dx, dy, rng, phi = polar.contract(lx - x, ly - y, rng, phi)
            lx &= x + dx
            x &= lx - dx
            ly &= y + dy
            y &= ly - dy
            t &= phi - bearing
            bearing &= phi - t
            new_values = (x, y, t, lx, ly, rng, bearing)
        if any(v.is_empty() for v in new_values):
            raise SystemExit(f"codac: the log {log_path} contracts to empty")
        for var, value in zip(variables, new_values, strict=True):
            old = domains[var]
            old_width = old.ub() - old.lb()
            value &= old
            domains[var] = value
            width = value.ub() - value.lb()
            if not (width < old_width if math.isinf(old_width) else width < old_width * (1 - rtol)):
                continue
            for g in factors_of[var]:
                if g != f and not queued[g]:
                    queue.append(g)
                    queued[g] = True
    boxes = {
        str(p): [[domains[v].lb(), domains[v].ub()] for v in variables]
        for p, variables in pose_vars.items()
    }
    text = json.dumps({"applications": applications, "poses": boxes}, allow_nan=True)
    out_path.write_text(text, encoding="utf-8")


# --------------------------------------------------------------------------- measuring
def run_process(argv: list[str]) -> tuple[float, float]:
    """Run ``argv`` to the end; its wall seconds and peak RSS in MB (fails on non-zero)."""
    start = time.perf_counter()
    child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    child.returncode = os.waitstatus_to_exitcode(status)
    error = child.stderr.read().decode() if child.stderr else ""
    if child.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({child.returncode}): {error}")
    return wall, usage.ru_maxrss / 1024.0


def width_ratios(cuikslam_json: Path, codac_json: Path) -> dict[str, float]:
    """Largest and median width ratio cuikslam / codac over pose x, y and heading."""
    ours = json.loads(cuikslam_json.read_text(encoding="utf-8"))["hypotheses"][0]["poses"]
    theirs = json.loads(codac_json.read_text(encoding="utf-8"))["poses"]
    ratios, wider = [], 0
    medians: dict[str, list[float]] = {"cuikslam": [], "codac": []}
    for p, box in theirs.items():
        mine = ours[p]
        for k, key in enumerate(("x", "y", "theta")):
            lo, hi = (math.inf if v is None else v for v in mine[key])
            lo = -math.inf if mine[key][0] is None else lo
            w_ours = min(hi - lo, FULL_TURN) if key == "theta" else hi - lo
            w_codac = box[k][1] - box[k][0]
            w_codac = min(w_codac, FULL_TURN) if key == "theta" else w_codac
            ratio = 1.0 if w_ours == w_codac else w_ours / w_codac
            ratios.append(ratio)
            wider += ratio > 1.0 + RTOL
            if key != "theta":
                medians["cuikslam"].append(w_ours)
                medians["codac"].append(w_codac)
    return {
        "max_width_ratio": max(ratios),
        "median_width_ratio": statistics.median(ratios),
        "coordinates_wider_than_codac_by_more_than_rtol": wider,
        "coordinates": len(ratios),
        "median_position_width_cuikslam_m": statistics.median(medians["cuikslam"]),
        "median_position_width_codac_m": statistics.median(medians["codac"]),
    }


def reader_writer_cost(log_path: Path, repeat: int) -> dict[str, float]:
    """µs per line of the log reader, and of the result writer, best of ``repeat``."""
    from cuikslam._json import HAVE_ORJSON
    from cuikslam.log.reader import read_log_file
    from cuikslam.results.io import write_result_file
    from cuikslam.solver import solve

    lines = sum(1 for _ in log_path.open(encoding="utf-8"))
    best_read = math.inf
    for _ in range(repeat):
        start = time.process_time()
        log = read_log_file(log_path)
        best_read = min(best_read, time.process_time() - start)
    start = time.process_time()
    solution = solve(log, consistency="hull", work_budget=None)
    solve_cpu = time.process_time() - start
    best_write = math.inf
    with tempfile.TemporaryDirectory() as folder:
        for _ in range(repeat):
            start = time.process_time()
            write_result_file(solution, Path(folder) / "result.json")
            best_write = min(best_write, time.process_time() - start)
    return {
        "lines": lines,
        "orjson": HAVE_ORJSON,
        "read_us_per_line": best_read / lines * 1e6,
        "write_us_per_line": best_write / lines * 1e6,
        "solve_hull_cpu_s_including_warm_up": solve_cpu,
        "narrowing_us_per_line": solution.timings["solve_s"] / lines * 1e6,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--laps", type=int, default=1250, help="octagon laps (8 poses each)")
    parser.add_argument("--repeat", type=int, default=3, help="timed cuikslam runs")
    parser.add_argument("--codac-repeat", type=int, default=1, help="timed codac runs")
    parser.add_argument(
        "--solve-args",
        default="",
        metavar="ARGS",
        help="more options for cuikslam solve, e.g. '--consistency hull' (default: none)",
    )
    parser.add_argument("--codac", nargs=2, metavar=("LOG", "OUT"), help=argparse.SUPPRESS)
    parser.add_argument("--json", type=Path, default=HERE / "results" / "end_to_end.json")
    args = parser.parse_args(argv)
    if args.codac:  # the codac process
        codac_fixpoint(Path(args.codac[0]), Path(args.codac[1]))
        return 0

    extra = shlex.split(args.solve_args)
    sys.path.insert(0, str(HERE))
    from long_log import write_octagon_log

    cuikslam = [sys.executable, "-m", "cuikslam.cli.main"]
    with tempfile.TemporaryDirectory() as folder:
        log = Path(folder) / "octagon.jsonl"
        write_octagon_log(log, args.laps, sensor=False)
        ours_out, codac_out = Path(folder) / "cuikslam.json", Path(folder) / "codac.json"
        solve = [*cuikslam, "solve", str(log), "--json", str(ours_out), *extra]
        run_process(solve)  # untimed: numba's cache filled, the OS's file cache too
        ours = [run_process(solve) for _ in range(args.repeat)]
        codac_cmd = [sys.executable, __file__, "--codac", str(log), str(codac_out)]
        theirs = [run_process(codac_cmd) for _ in range(args.codac_repeat)]
        widths = width_ratios(ours_out, codac_out)
        stages = reader_writer_cost(log, args.repeat)
        level = json.loads(ours_out.read_text(encoding="utf-8"))["consistency"]

    t_ours = min(w for w, _ in ours)
    t_codac = min(w for w, _ in theirs)
    figures = {
        "log": f"octagon, {args.laps} laps, {8 * args.laps + 1} poses, known correspondence",
        "lines": stages["lines"],
        "command": " ".join(["cuikslam solve LOG --json OUT", *extra]) + " (warm numba cache)",
        "cuikslam_level": level,
        "cuikslam_wall_s": [w for w, _ in ours],
        "cuikslam_peak_rss_mb": max(m for _, m in ours),
        "codac_wall_s": [w for w, _ in theirs],
        "codac_peak_rss_mb": max(m for _, m in theirs),
        "ratio_codac_over_cuikslam": t_codac / t_ours,
        "widths": widths,
        "no_wider_than_codac": widths["coordinates_wider_than_codac_by_more_than_rtol"] == 0,
        "in_process": stages,
        "python": platform.python_version(),
        "cpus": os.cpu_count(),
    }
    print(
        f"{figures['log']} ({stages['lines']:,} lines)\n"
        f"cuikslam solve --json (level {level}): best {t_ours:.2f} s wall of "
        f"{', '.join(f'{w:.2f}' for w, _ in ours)}; "
        f"peak RSS {figures['cuikslam_peak_rss_mb']:.0f} MB\n"
        f"codac CtcPolar fixpoint:       best {t_codac:.2f} s wall; peak RSS "
        f"{figures['codac_peak_rss_mb']:.0f} MB\n"
        f"ratio (codac / cuikslam): {figures['ratio_codac_over_cuikslam']:.1f}x\n"
        f"largest pose width ratio cuikslam / codac: {widths['max_width_ratio']:.4f} "
        f"(median {widths['median_width_ratio']:.4f}); median position width "
        f"{widths['median_position_width_cuikslam_m']:.3f} m vs "
        f"{widths['median_position_width_codac_m']:.3f} m\n"
        f"in process: read {stages['read_us_per_line']:.1f} us/line, write "
        f"{stages['write_us_per_line']:.1f} us/line, narrowing "
        f"{stages['narrowing_us_per_line']:.1f} us/line (orjson: {stages['orjson']})"
    )
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
