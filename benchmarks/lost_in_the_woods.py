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

``--calibrated``: the bounds are calibrated on the first half of the run
(:func:`~cuikslam.datasets.lost_in_the_woods_bounds.calibrate_lost_in_the_woods`, quantile
1), the stretches and sightings of the second half outside them are counted, and the whole
run is imported with them (keyframes of 10 samples, keyframe observations, known
correspondence) and solved at the default level; the figures are given for the second half
(the poses the bounds were not measured on) and the whole run. Writes
``benchmarks/results/lost_in_the_woods_calibrated.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
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


def _widths(boxes: np.ndarray) -> dict:
    widths = boxes[:, :, 1] - boxes[:, :, 0]
    position = np.maximum(widths[:, 0], widths[:, 1])
    heading = np.minimum(widths[:, 2], 2 * math.pi)
    return {
        "median_position_m": round(float(np.median(position)), 3),
        "p95_position_m": round(float(np.percentile(position, 95)), 3),
        "median_heading_rad": round(float(np.median(heading)), 3),
        "p95_heading_rad": round(float(np.percentile(heading, 95)), 3),
    }


def run_calibrated(path: Path, level: str, every_observation: bool, margin: float = 1.0) -> dict:
    """Calibrate on the first half, solve the whole run, evaluate each half."""
    import resource

    from cuikslam.datasets.lost_in_the_woods_bounds import (
        calibrate_lost_in_the_woods,
        count_outside_lost_in_the_woods,
    )

    half = 6304
    t0 = time.perf_counter()
    calibration = calibrate_lost_in_the_woods(path, steps=half, motion_margin=margin)
    rest = count_outside_lost_in_the_woods(path, calibration.bounds, start=half)
    t1 = time.perf_counter()
    log, truth = read_lost_in_the_woods(
        path, unknown=False, bounds=calibration.bounds, every_observation=every_observation
    )
    t2 = time.perf_counter()
    solution = solve(log, consistency=level, certify_limit=0, work_budget=None)
    t3 = time.perf_counter()
    (hyp,) = solution.hypotheses
    report = check_truth(hyp, truth.pose_ids, truth.poses_xyt)
    missed = {int(m.split()[1]) for m in report.misses}
    boxes = np.array([hyp.pose(p) for p in truth.pose_ids])
    second = np.array([p * 10 >= half for p in truth.pose_ids])  # pose i: sample 10 i
    ids = np.array(truth.pose_ids)
    return {
        "level": level,
        "every_observation": every_observation,
        "motion_margin": margin,
        "bounds": vars(calibration.bounds),
        "second_half_outside": rest.to_json(),
        "poses": len(log.pose_ids),
        "observations": len(log.observations),
        "second_half": {
            "poses_with_truth": int(second.sum()),
            "truth_inside": int(second.sum()) - len(missed & set(ids[second].tolist())),
            **_widths(boxes[second]),
        },
        "whole_run": {
            "poses_with_truth": len(ids),
            "truth_inside": len(ids) - len(missed),
            **_widths(boxes),
        },
        "calibrate_s": round(t1 - t0, 2),
        "import_s": round(t2 - t1, 2),
        "solve_s": round(t3 - t2, 2),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
        "load": os.getloadavg()[0],
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "keyframes", nargs="*", type=int, default=[5, 10, 20], help="samples per pose"
    )
    parser.add_argument(
        "--calibrated", action="store_true", help="bounds calibrated on the first half"
    )
    parser.add_argument("--level", default="auto", help="level of --calibrated (default auto)")
    parser.add_argument(
        "--every-observation", action="store_true", help="--calibrated: every observation"
    )
    parser.add_argument(
        "--motion-margin", type=float, default=1.0, help="--calibrated: factor on the motion"
    )
    args = parser.parse_args(argv)
    folder = data_dir()
    path = folder / "lost-in-the-woods" / "dataset2.mat" if folder else None
    if path is None or not path.is_file():
        sys.exit("dataset2.mat not found: set CUIKSLAM_DATA")
    warm_up()
    if args.calibrated:
        row = run_calibrated(path, args.level, args.every_observation, args.motion_margin)
        print(json.dumps(row))
        out = Path(__file__).parent / "results" / "lost_in_the_woods_calibrated.json"
        rows = json.loads(out.read_text()) if out.is_file() else []
        out.write_text(json.dumps([*rows, row], indent=1) + "\n")
        return
    keyframes = args.keyframes
    rows = [run(path, k) for k in keyframes]
    rows.append(run(path, 10, every_observation=False))
    for row in rows:
        print(json.dumps(row))
    out = Path(__file__).parent / "results" / "lost_in_the_woods.json"
    out.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
