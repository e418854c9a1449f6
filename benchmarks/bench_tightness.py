"""Benchmark: how far cuikslam's boxes are from the exact solution set (the paper's experiment).

For the seed paper's experiment (noise seeds 0-4, known correspondence) the exact hull of
every pose coordinate (x, y, theta) and landmark coordinate is estimated from INSIDE with
:func:`cuikslam.witness.inner_hull`: each coordinate is minimised and maximised
(SLSQP) over parameter vectors that satisfy every measured interval, from truth-free
starts (the witness found from the box centres, and random points of the boxes), and only
points that :func:`~cuikslam.witness.verify_witness` proves to be solutions
count. So ``inner width <= exact width <= box width`` and

    ratio = box width / inner width   (>= 1; 1 means the box is the exact hull)

is an upper bound of how much wider than the exact hull each box is. Printed per seed:
the solve time, the worst and median ratio over all pose positions, headings and landmark
coordinates (pose 1, known exactly, has inner width 0 and is skipped), and a soundness
check (every inner hull must lie inside its box).

The inner hulls do not depend on the solver, so they are cached in
``benchmarks/results/inner_hull_paper.json`` keyed by seed (with a fingerprint of the log);
re-runs with another ``--consistency`` level only solve. ``--recompute`` redoes them.

    python benchmarks/bench_tightness.py [--seeds 0 1 2 3 4] [--consistency LEVEL]
        [--recompute] [--jobs 2] [--random-starts 3] [--refine 3] [--json OUT] [--verbose]

``--consistency LEVEL`` is passed to :func:`cuikslam.solver.solve` when it takes that
keyword; by default nothing is passed (the solver's default level).
"""

from __future__ import annotations

import os

# SLSQP calls BLAS on tiny matrices: threads only add overhead (about 10x here).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import hashlib  # noqa: E402
import inspect  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from cuikslam._atomic import atomic_write_text  # noqa: E402
from cuikslam.log.records import Log  # noqa: E402
from cuikslam.simulate import simulate_paper  # noqa: E402
from cuikslam.solver import solve  # noqa: E402
from cuikslam.witness import inner_hull  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "benchmarks" / "results" / "inner_hull_paper.json"
SEEDS = (0, 1, 2, 3, 4)
ZERO_WIDTH = 1e-9
"""Inner widths below this (pose 1, known exactly) give no ratio."""
CACHE_VERSION = 1

__all__ = ["compute_inner_hull", "log_fingerprint", "main", "ratios", "solve_kwargs"]


def log_fingerprint(log: Log) -> str:
    """A hash of the log's records: a cached hull is reused only for the same log."""
    text = repr([r for r in log.records])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def solve_kwargs(consistency: str | None) -> dict[str, Any]:
    """``{"consistency": level}`` when asked for and :func:`solve` takes it, else ``{}``;
    plus ``work_budget=None`` (the full level is measured, not what a budget allows)."""
    parameters = set(inspect.signature(solve).parameters)
    try:  # the options are fields of SolveOptions since it exists
        from cuikslam.options import SolveOptions

        parameters |= {f.name for f in dataclasses.fields(SolveOptions)}
    except ImportError:
        pass
    kwargs: dict[str, Any] = {"time_budget": None} if "time_budget" in parameters else {}
    if consistency is None:
        return kwargs
    if "consistency" not in parameters:
        print(f"note: solve() has no 'consistency' keyword; ignoring --consistency {consistency}")
        return kwargs
    return {**kwargs, "consistency": consistency}


def compute_inner_hull(seed: int, random_starts: int = 3, refine: int = 3) -> dict[str, Any]:
    """The inner hull of paper seed ``seed`` (known correspondence), as a JSON-able dict.

    Starts come from the solver's boxes at its default level (truth-free); the hull itself
    depends only on the log.
    """
    log, _ = simulate_paper(seed)
    assignment = [str(o.landmark) for o in log.observations]
    start = time.perf_counter()
    h = solve(log, work_budget=None).best
    hull = inner_hull(
        log, assignment, h.poses, h.landmarks, n_random=random_starts, refine=refine, seed=seed
    )
    if hull is None:
        raise RuntimeError(f"seed {seed}: no verified witness; cannot measure the inner hull")
    out = hull.to_json()
    out["fingerprint"] = log_fingerprint(log)
    out["random_starts"] = random_starts
    out["refine"] = refine
    out["seconds_total"] = time.perf_counter() - start
    return out


def _load_cache(path: Path) -> dict[str, Any]:
    if not path.exists():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return {}
    if data.get("version") != CACHE_VERSION:
        return {}
    return dict(data.get("seeds", {}))


def _angle_shift(box: np.ndarray, inner: np.ndarray) -> float:
    """2 pi k that brings the inner heading interval nearest the box's centre."""
    k = round(((box[0] + box[1]) - (inner[0] + inner[1])) / 2 / (2 * math.pi))
    return 2 * math.pi * k


def ratios(hypothesis: Any, inner: dict[str, Any]) -> dict[str, Any]:
    """Width ratios box / inner for every coordinate, and inner-inside-box violations."""
    rows: list[dict[str, Any]] = []
    outside: list[str] = []
    for k, pid in enumerate(inner["pose_ids"]):
        box = hypothesis.pose(pid)
        ih = np.asarray(inner["poses"][k])
        for c, name in enumerate(("x", "y", "theta")):
            lo, hi = ih[c]
            if c == 2:
                shift = _angle_shift(box[c], ih[c])
                lo, hi = lo + shift, hi + shift
            tol = 1e-9 * max(1.0, abs(lo), abs(hi))
            if lo < box[c, 0] - tol or hi > box[c, 1] + tol:
                outside.append(f"pose {pid} {name}: inner [{lo}, {hi}] box {box[c].tolist()}")
            rows.append(
                {
                    "variable": f"pose {pid} {name}",
                    "kind": "heading" if c == 2 else "position",
                    "box": float(box[c, 1] - box[c, 0]),
                    "inner": float(hi - lo),
                }
            )
    for k, lid in enumerate(inner["landmark_ids"]):
        box = hypothesis.landmark(lid)
        ih = np.asarray(inner["landmarks"][k])
        for c, name in enumerate(("x", "y")):
            lo, hi = ih[c]
            tol = 1e-9 * max(1.0, abs(lo), abs(hi))
            if lo < box[c, 0] - tol or hi > box[c, 1] + tol:
                outside.append(f"landmark {lid} {name}: inner [{lo}, {hi}] box {box[c].tolist()}")
            rows.append(
                {
                    "variable": f"landmark {lid} {name}",
                    "kind": "landmark",
                    "box": float(box[c, 1] - box[c, 0]),
                    "inner": float(hi - lo),
                }
            )
    for row in rows:
        row["ratio"] = row["box"] / row["inner"] if row["inner"] > ZERO_WIDTH else None
    summary: dict[str, Any] = {}
    for kind in ("all", "position", "heading", "landmark"):
        chosen = [r for r in rows if r["ratio"] is not None and kind in ("all", r["kind"])]
        if not chosen:
            continue
        worst = max(chosen, key=lambda r: r["ratio"])
        summary[kind] = {
            "worst": worst["ratio"],
            "worst_variable": worst["variable"],
            "median": float(np.median([r["ratio"] for r in chosen])),
        }
    return {"rows": rows, "summary": summary, "outside": outside}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS))
    parser.add_argument("--consistency", default=None, help="passed to solve() if it takes it")
    parser.add_argument("--recompute", action="store_true", help="recompute the inner hulls")
    parser.add_argument("--jobs", type=int, default=2, help="processes for the inner hulls")
    parser.add_argument("--random-starts", type=int, default=3, help="random starts per run")
    parser.add_argument(
        "--refine", type=int, default=3, help="restarts from the most extreme points found"
    )
    parser.add_argument("--cache", type=Path, default=CACHE)
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    parser.add_argument("--verbose", action="store_true", help="print every coordinate")
    args = parser.parse_args(argv)

    kwargs = solve_kwargs(args.consistency)
    cache = _load_cache(args.cache)
    logs = {seed: simulate_paper(seed)[0] for seed in args.seeds}
    todo = [
        seed
        for seed in args.seeds
        if args.recompute
        or str(seed) not in cache
        or cache[str(seed)].get("fingerprint") != log_fingerprint(logs[seed])
        or cache[str(seed)].get("random_starts") != args.random_starts
        or cache[str(seed)].get("refine") != args.refine
    ]
    if todo:
        print(f"inner hulls: computing seeds {todo} on {min(args.jobs, len(todo))} process(es)")
        start = time.perf_counter()
        if args.jobs > 1 and len(todo) > 1:
            with ProcessPoolExecutor(max_workers=min(args.jobs, len(todo))) as pool:
                results = list(pool.map(compute_inner_hull, todo, [args.random_starts] * len(todo)))
        else:
            results = [compute_inner_hull(seed, args.random_starts) for seed in todo]
        for seed, result in zip(todo, results, strict=True):
            cache[str(seed)] = result
            print(
                f"  seed {seed}: {result['seconds']:.1f} s, {result['optimisations']} SLSQP runs,"
                f" {result['verified_points']} verified points"
            )
        print(f"  wall time {time.perf_counter() - start:.1f} s")
        args.cache.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(
            args.cache, json.dumps({"version": CACHE_VERSION, "seeds": cache}, indent=1) + "\n"
        )
    else:
        print(f"inner hulls: cached in {args.cache}")

    solve(logs[args.seeds[0]], **kwargs)  # warm-up: JIT compilation / cache load
    level = kwargs.get("consistency", "(default)")
    print(f"\nconsistency level: {level}")
    header = (
        f"{'seed':>4} {'solve s':>8} {'cert s':>6} {'worst':>7} {'worst variable':<18}"
        f" {'median':>7}"
        f" {'pos worst':>9} {'pos med':>7} {'hdg worst':>9} {'hdg med':>7}"
        f" {'lm worst':>8} {'lm med':>7} {'sound':>5}"
    )
    print(header)
    report: dict[str, Any] = {
        "consistency": level,
        "platform": platform.platform(),
        "python": sys.version.split()[0],
        "seeds": {},
    }
    all_ratios: list[float] = []
    for seed in args.seeds:
        log = logs[seed]
        start = time.perf_counter()
        solution = solve(log, **kwargs)
        elapsed = time.perf_counter() - start
        certify_s = float(solution.timings.get("certify_s", 0.0))
        elapsed -= certify_s  # the narrowing alone (solve() may certify its best hypothesis)
        inner = cache[str(seed)]
        figures = ratios(solution.best, inner)
        s = figures["summary"]
        all_ratios += [r["ratio"] for r in figures["rows"] if r["ratio"] is not None]
        sound = "yes" if not figures["outside"] else f"NO({len(figures['outside'])})"
        print(
            f"{seed:>4} {elapsed:>8.3f} {certify_s:>6.3f} {s['all']['worst']:>7.3f}"
            f" {s['all']['worst_variable']:<18}"
            f" {s['all']['median']:>7.3f} {s['position']['worst']:>9.3f}"
            f" {s['position']['median']:>7.3f} {s['heading']['worst']:>9.3f}"
            f" {s['heading']['median']:>7.3f} {s['landmark']['worst']:>8.3f}"
            f" {s['landmark']['median']:>7.3f} {sound:>5}"
        )
        for line in figures["outside"]:
            print(f"     UNSOUND? {line}")
        if args.verbose:
            for row in figures["rows"]:
                ratio = "-" if row["ratio"] is None else f"{row['ratio']:.3f}"
                print(
                    f"     {row['variable']:<18} box {row['box']:.4f}"
                    f" inner {row['inner']:.4f} ratio {ratio}"
                )
        report["seeds"][str(seed)] = {
            "solve_s": elapsed,
            "certify_s": certify_s,
            "inner_hull_s": inner.get("seconds"),
            **figures,
        }
    if all_ratios:
        print(
            f"\nover all seeds: worst ratio {max(all_ratios):.3f},"
            f" median {float(np.median(all_ratios)):.3f}"
        )
        report["worst"] = max(all_ratios)
        report["median"] = float(np.median(all_ratios))
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.json, json.dumps(report, indent=1) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
