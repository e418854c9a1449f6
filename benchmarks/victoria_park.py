"""Victoria Park: how many GPS fixes lie in the solved pose boxes.

Reads a log written by ``cuikslam import victoria-park``, its ``NAME.gps.json`` and the
result JSON of ``cuikslam solve``, maps each pose box to the GPS antenna (taken at the
laser, pose ⊕ (a, b)), grows it by the GPS error and counts the fixes inside: in the
``envelope`` (the boxes whatever the correspondence and whatever stopped the search), in
the best-ranked hypothesis, and in the boxes the motion alone gives (dead reckoning from
the prior, for comparison). GPS is a reference with metres of error, not a truth.

Run::

    cuikslam import victoria-park ../shared/data/victoria-park -o vp.jsonl --minutes 5 \\
        --max-range 30
    cuikslam solve vp.jsonl --consistency hull --json vp.result.json --no-table
    python benchmarks/victoria_park.py vp.jsonl vp.result.json [--gps-error 1 2.5 3]

Prints one JSON object. The figures of `docs/real-data.md` are in
``benchmarks/results/victoria_park.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from cuikslam.datasets.victoria_park import GpsReference, gps_inside
from cuikslam.log import read_log_file
from cuikslam.motion import compose_relative


def _reference(path: Path) -> GpsReference:
    doc = json.loads(path.read_text())
    poses = sorted(doc["poses"].items(), key=lambda item: int(item[0]))
    return GpsReference(
        [int(p) for p, _ in poses],
        [v["time"] for _, v in poses],
        np.array([[v["x"], v["y"]] for _, v in poses], dtype=float).reshape(-1, 2),
    )


def _box(b: dict) -> tuple | None:
    """A result's pose box; an unbounded heading is any direction (an interval wider than
    2π), an unbounded position leaves the pose out (None)."""
    if None in (*b["x"], *b["y"]):
        return None
    theta = (-4.0, 4.0) if None in b["theta"] else tuple(b["theta"])
    return tuple(b["x"]), tuple(b["y"]), theta


def _widths(boxes: dict) -> dict:
    if not boxes:
        return {}
    xy = np.array([max(b[0][1] - b[0][0], b[1][1] - b[1][0]) for b in boxes.values()])
    th = np.array([min(b[2][1] - b[2][0], 2 * np.pi) for b in boxes.values()])
    ids = sorted(boxes)
    along = {}
    for k in (10, 30, 60, 120, 180, 240, ids[-1]):
        if k in boxes:
            b = boxes[k]
            along[str(k)] = [
                round(max(b[0][1] - b[0][0], b[1][1] - b[1][0]), 2),
                round(min(b[2][1] - b[2][0], 2 * np.pi), 3),
            ]
    return {
        "at_pose_position_heading": along,
        "position_median": float(np.median(xy)),
        "position_max": float(xy.max()),
        "heading_median": float(np.median(th)),
        "heading_max": float(th.max()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("log")
    parser.add_argument("result")
    parser.add_argument("--gps-error", type=float, nargs="+", default=[1.0, 2.5, 3.0])
    args = parser.parse_args()
    log_path = Path(args.log)
    stem = log_path.name.removesuffix(".jsonl")
    reference = _reference(log_path.with_name(f"{stem}.gps.json"))
    log = read_log_file(log_path)
    prior = log.priors[0]
    motion = {prior.pose: (prior.x, prior.y, prior.theta)}
    for move in log.relative_poses:
        motion[move.target] = compose_relative(
            [motion[move.source], (move.dx, move.dy, move.dtheta)]
        )
    result = json.loads(Path(args.result).read_text())
    envelope = {int(p): _box(b) for p, b in (result.get("envelope") or {}).get("poses", {}).items()}
    envelope = {p: b for p, b in envelope.items() if b is not None}
    best = {}
    if result.get("hypotheses"):
        h = result["hypotheses"][0]
        best = {
            int(p): (tuple(b["x"]), tuple(b["y"]), tuple(b["theta"])) for p, b in h["poses"].items()
        }
    out = {
        "poses": len(log.pose_ids),
        "observations": len(log.observations),
        "gps_fixes": len(reference.pose_ids),
        "complete": result.get("complete"),
        "statistics": {
            k: result.get("statistics", {}).get(k)
            for k in ("survivors", "explored_fraction", "unexplored_subtrees", "budget_bound")
        },
        "timings": result.get("timings"),
    }
    for name, boxes in (("envelope", envelope), ("best_hypothesis", best), ("motion_only", motion)):
        entry = {"widths": _widths(boxes)}
        for error in args.gps_error:
            inside, compared, misses = gps_inside(boxes, reference, error)
            entry[f"gps_{error:g}m"] = {
                "inside": inside,
                "compared": compared,
                "worst_miss_m": max((d for _, d in misses), default=0.0),
            }
        out[name] = entry
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
