"""Lost in the Woods, the whole run: truth inside the boxes, box widths and time per keyframe.

Imports ``dataset2.mat`` (``$CUIKSLAM_DATA`` or ``../shared/data``) with known
correspondence and the importer's default bounds (3 sd of the file's odometry variances
per sample; range 0.16 m and bearing 0.15 rad, above the documented largest errors), for
several keyframe spacings, solves each at the ``hull`` level, and prints one JSON line
per spacing: the share of poses with a Vicon pose inside their box, the median and 95th
percentile box widths (position: the wider of x and y; heading), and the import and
solve times (the solve is warm: numba's compiled kernels are cached on disk by a first
run). Writes them to ``benchmarks/results/lost_in_the_woods.json``.

Run: ``python benchmarks/lost_in_the_woods.py [KEYFRAME ...]`` (default 5 10 20).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from cuikslam.datasets import data_dir, read_lost_in_the_woods
from cuikslam.results.solution import check_truth
from cuikslam.solver import solve, warm_up


def run(path: Path, keyframe: int, every_observation: bool = True) -> dict:
    t0 = time.perf_counter()
    log, truth = read_lost_in_the_woods(
        path, unknown=False, keyframe=keyframe, every_observation=every_observation
    )
    t1 = time.perf_counter()
    solution = solve(log, consistency="hull", certify_limit=0)
    t2 = time.perf_counter()
    (hyp,) = solution.hypotheses
    report = check_truth(hyp, truth.pose_ids, truth.poses_xyt)
    missed = {m.split()[1] for m in report.misses}
    boxes = np.array([hyp.pose(p) for p in truth.pose_ids])
    widths = boxes[:, :, 1] - boxes[:, :, 0]
    position = np.maximum(widths[:, 0], widths[:, 1])
    heading = np.minimum(widths[:, 2], 2 * math.pi)
    return {
        "keyframe": keyframe,
        "every_observation": every_observation,
        "poses": len(log.pose_ids),
        "observations": len(log.observations),
        "poses_with_truth": len(truth.pose_ids),
        "truth_inside_share": 1.0 - len(missed) / len(truth.pose_ids),
        "median_position_m": round(float(np.median(position)), 3),
        "p95_position_m": round(float(np.percentile(position, 95)), 3),
        "median_heading_rad": round(float(np.median(heading)), 3),
        "p95_heading_rad": round(float(np.percentile(heading, 95)), 3),
        "import_s": round(t1 - t0, 2),
        "solve_s": round(t2 - t1, 2),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "keyframes", nargs="*", type=int, default=[5, 10, 20], help="samples per pose"
    )
    args = parser.parse_args(argv)
    folder = data_dir()
    path = folder / "lost-in-the-woods" / "dataset2.mat" if folder else None
    if path is None or not path.is_file():
        sys.exit("dataset2.mat not found: set CUIKSLAM_DATA")
    keyframes = args.keyframes
    warm_up()
    rows = [run(path, k) for k in keyframes]
    rows.append(run(path, 10, every_observation=False))
    for row in rows:
        print(json.dumps(row))
    out = Path(__file__).parent / "results" / "lost_in_the_woods.json"
    out.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
