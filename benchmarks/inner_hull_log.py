"""How far a known-correspondence log's boxes are from its exact solution set, from inside.

Solves LOG at ``lp`` (no time budget), then computes
:func:`cuikslam.witness.inner_hull`: the hull of solution points each verified in
interval arithmetic, so every inner interval lies inside the exact hull of its coordinate.
Prints the median over the poses of the wider of the x and y widths and of the heading width,
for the inner hull and for the ``lp`` boxes, their per-pose median ratio, and how many poses
have an inner heading width above ``--heading`` rad (such a heading box cannot be narrower
than that, whatever the method, as long as it is sound). Writes one JSON object with
``--json``.

The logs measured in docs/real-data.md were made by::

    cuikslam calibrate lost-in-the-woods dataset2.mat -o woods.bounds.json
    cuikslam import lost-in-the-woods dataset2.mat --bounds woods.bounds.json --known \\
        --keyframe-observations --start 3000 --steps 300 --map 0.05 -o w3000m.jsonl
    python benchmarks/inner_hull_log.py w3000m.jsonl --random-starts 1 --refine 1
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from cuikslam import read_log_file, solve
from cuikslam.witness import inner_hull


def _medians(boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    widths = boxes[:, :, 1] - boxes[:, :, 0]
    return np.maximum(widths[:, 0], widths[:, 1]), np.minimum(widths[:, 2], 2 * np.pi)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", help="a log with known correspondence (.jsonl)")
    parser.add_argument("--random-starts", type=int, default=2, help="inner_hull's n_random")
    parser.add_argument("--refine", type=int, default=3, help="inner_hull's refine")
    parser.add_argument("--heading", type=float, default=0.1, help="heading width to count")
    parser.add_argument("--json", help="write the figures here")
    args = parser.parse_args(argv)

    log = read_log_file(args.log)
    assignment = [str(o.landmark) for o in log.observations]
    start = time.perf_counter()
    best = solve(log, consistency="lp", work_budget=None).best
    solve_s = time.perf_counter() - start
    hull = inner_hull(
        log, assignment, best.poses, best.landmarks, n_random=args.random_starts,
        refine=args.refine,
    )  # fmt: skip
    if hull is None:
        print(f"{args.log}: no verified witness; the inner hull is unknown", file=sys.stderr)
        return 1
    inner_xy, inner_t = _medians(np.asarray(hull.poses))
    lp_xy, lp_t = _medians(np.asarray(best.poses))
    out = {
        "log": args.log,
        "poses": len(inner_xy),
        "inner_position_median_m": float(np.median(inner_xy)),
        "inner_heading_median_rad": float(np.median(inner_t)),
        "lp_position_median_m": float(np.median(lp_xy)),
        "lp_heading_median_rad": float(np.median(lp_t)),
        "ratio_position_median": float(np.median(lp_xy / inner_xy)),
        "ratio_heading_median": float(np.median(lp_t / inner_t)),
        "poses_inner_heading_above": int(np.count_nonzero(inner_t > args.heading)),
        "heading_threshold_rad": args.heading,
        "verified_points": hull.verified_points,
        "random_starts": args.random_starts,
        "refine": args.refine,
        "solve_s": round(solve_s, 2),
        "inner_hull_s": round(hull.seconds, 1),
    }
    print(json.dumps(out, indent=1))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
