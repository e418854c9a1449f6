"""A long known-correspondence log: the seed's octagon driven lap after lap.

The seed's experiment (:mod:`cuikslam.simulate.paper`) is one lap of 8 steps around an
octagon in a 30 m room with four landmarks. Driving it ``laps`` times gives a log of
``8 * laps + 1`` poses whose every pose sees the same landmarks as in the seed (its
nearest, and every landmark within the tie margin of it), with the seed's error bounds,
uniform errors drawn from ``numpy.random.default_rng(seed)`` in record order. 1,250 laps
give the 10,000-pose log (25,002 lines) of the end-to-end benchmark.

    python benchmarks/long_log.py --laps 1250 -o long.jsonl   # also writes long.truth.json
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from cuikslam.log.records import Log, Observation, Odometry, PosePrior, Record, SensorModel
from cuikslam.log.writer import write_log_file
from cuikslam.simulate.paper import (
    BEARING_BOUND,
    DISTANCE_BOUND,
    LANDMARKS,
    RANGE_BOUND,
    TIE_MARGIN,
    TURN_BOUND,
    paper_truth,
)
from cuikslam.simulate.truth import GroundTruth, noisy_interval, wrap_angle, write_truth_file

__all__ = ["octagon_log", "write_octagon_log"]

STEPS_PER_LAP = 8


def octagon_log(laps: int, seed: int = 0, sensor: bool = True) -> tuple[Log, GroundTruth]:
    """The seed's octagon driven ``laps`` times, known correspondence, and its truth.

    Parameters
    ----------
    laps : int
        Laps of the octagon; the log has ``8 * laps + 1`` poses, numbered from 1.
    seed : int
        Seed of the measurement errors.
    sensor : bool
        Start with the seed's sensor record (nearest landmark and ties within 0.5 m).
    """
    one_lap = paper_truth()
    corners = one_lap.poses_xyt[:STEPS_PER_LAP]
    n_poses = STEPS_PER_LAP * laps + 1
    k = np.arange(n_poses)
    poses_xyt = corners[k % STEPS_PER_LAP].copy()
    poses_xyt[:, 2] = corners[0, 2] + k * (math.pi / 4)  # unwrapped: the running sum of turns
    landmarks_xy = one_lap.landmarks_xy
    ids = list(LANDMARKS)
    seen = [_seen_from(corner[:2], landmarks_xy) for corner in corners]

    rng = np.random.default_rng(seed)
    x1, y1, t1 = (float(v) for v in poses_xyt[0])
    records: list[Record] = [PosePrior(1, (x1, x1), (y1, y1), (t1, t1))]
    if sensor:
        records.insert(0, SensorModel(nearest_margin=TIE_MARGIN))
    assignment: list[str] = []
    step = float(np.hypot(*(corners[1, :2] - corners[0, :2])))
    for i in range(n_poses):
        x, y, theta = poses_xyt[i]
        for j in seen[i % STEPS_PER_LAP]:
            dx, dy = landmarks_xy[j, 0] - x, landmarks_xy[j, 1] - y
            bearing = wrap_angle(math.atan2(dy, dx) - theta)
            records.append(
                Observation(
                    pose=i + 1,
                    landmark_class=LANDMARKS[ids[j]][0],
                    range=noisy_interval(math.hypot(dx, dy), RANGE_BOUND, rng, non_negative=True),
                    bearing=noisy_interval(bearing, BEARING_BOUND, rng),
                    landmark=ids[j],
                )
            )
            assignment.append(ids[j])
        if i + 1 < n_poses:
            records.append(
                Odometry(
                    source=i + 1,
                    target=i + 2,
                    turn=noisy_interval(math.pi / 4, TURN_BOUND, rng),
                    distance=noisy_interval(step, DISTANCE_BOUND, rng, non_negative=True),
                )
            )
    truth = GroundTruth(
        poses_xyt=poses_xyt,
        pose_ids=[int(p) for p in k + 1],
        landmarks_xy=landmarks_xy,
        landmark_ids=ids,
        landmark_classes=[LANDMARKS[m][0] for m in ids],
        assignment=assignment,
    )
    return Log(records=records, path=f"<octagon laps={laps} seed={seed}>"), truth


def _seen_from(position_xy: np.ndarray, landmarks_xy: np.ndarray) -> list[int]:
    """Indices of the landmarks seen from ``position_xy`` (the seed's rule)."""
    distances = np.hypot(*(landmarks_xy - position_xy).T)
    return [int(j) for j in np.flatnonzero(distances <= distances.min() + TIE_MARGIN)]


def truth_path_for(log_path: Path) -> Path:
    """``NAME.truth.json`` beside ``NAME.jsonl`` (where ``cuikslam simulate`` puts it)."""
    stem = log_path.name.removesuffix(".jsonl")
    return log_path.with_name(f"{stem}.truth.json")


def write_octagon_log(path: Path, laps: int, seed: int = 0, sensor: bool = True) -> GroundTruth:
    """Write :func:`octagon_log` to ``path`` and its truth beside it; return the truth."""
    log, truth = octagon_log(laps, seed, sensor)
    write_log_file(log, path)
    write_truth_file(truth, truth_path_for(path))
    return truth


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--laps", type=int, default=1250)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-sensor", action="store_true", help="leave out the sensor record")
    parser.add_argument("-o", "--output", type=Path, required=True)
    args = parser.parse_args(argv)
    write_octagon_log(args.output, args.laps, args.seed, sensor=not args.no_sensor)
    lines = sum(1 for _ in args.output.open(encoding="utf-8"))
    print(f"wrote {args.output}: {lines} lines, {8 * args.laps + 1} poses", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
