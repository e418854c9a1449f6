"""Benchmark: narrowing-operator applications per second, cuikslam vs codac in a Python loop.

Builds a loop world (a robot driving twice around a circle of about 40 landmarks, with
known correspondence), then narrows it to the fixpoint with

(a) :func:`cuikslam.narrowing.propagate` (compiled; warmed up once so that numba's
    compile or cache load is excluded; best of ``--repeat`` runs), and
(b) ``tests/reference/codac_propagation.codac_propagate`` (the same chaotic iteration in
    plain Python with codac intervals and one ``CtcPolar`` call per factor application),

and prints applications, seconds and applications per second of both, their ratio, the
truth check and the largest width ratio cuikslam/codac over all pose coordinates (at most
1 when cuikslam is at least as tight). Everything runs on one core; times are CPU seconds
of this process (``time.process_time``), which other load on a shared machine disturbs
less than wall time.

    python benchmarks/bench_propagation.py [--poses 1000] [--seed 0] [--repeat 3] [--json OUT]
"""

from __future__ import annotations

import os

os.environ["NUMBA_NUM_THREADS"] = "1"  # one core; must precede the numba import

import argparse
import json
import math
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # for tests.reference

from cuikslam.graph.kinematic_graph import KinematicGraph  # noqa: E402
from cuikslam.interval.angles import angle_in, wrap_angle  # noqa: E402
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL, Status, propagate  # noqa: E402

TURN_BOUND = 0.02
"""Half-width (rad) of the odometry turn error."""
DISTANCE_BOUND = 0.05
"""Half-width (m) of the odometry distance error."""
RANGE_BOUND = 0.05
"""Half-width (m) of the observation range error."""
BEARING_BOUND = 0.02
"""Half-width (rad) of the observation bearing error."""
MAX_RANGE = 6.0
"""The robot observes every landmark within this distance."""
TRUTH_SLACK = 1e-9
"""Tolerance of the truth check (the float truth satisfies the relations up to rounding)."""


@dataclass
class LoopWorld:
    graph: KinematicGraph
    poses: np.ndarray
    """Truth, shape (n_poses, 3): x, y, theta (unwrapped, consistent with the turns)."""
    landmarks: np.ndarray
    """Truth, shape (n_landmarks, 2)."""
    n_observations: int


def _noisy(rng: np.random.Generator, value: float, bound: float) -> tuple[float, float]:
    """An interval of half-width ``bound`` around ``value`` + an error in [-bound, bound]."""
    measured = value + rng.uniform(-bound, bound)
    return measured - bound, measured + bound


def loop_world(
    n_poses: int = 1000,
    n_landmarks: int = 40,
    laps: float = 2.0,
    step: float = 0.5,
    seed: int = 0,
    turn_bound: float = TURN_BOUND,
) -> LoopWorld:
    """A robot driving ``laps`` times around a circle, observing landmarks near the path.

    The circle's radius makes each step about ``step`` metres long. Landmarks are spread
    along the circle, up to 4 m either side of it, so every lap re-observes all of them.
    Pose 0 has an exact prior; every measured interval contains the truth. ``turn_bound``
    is the half-width of the odometry turn error (the heading drift per step).
    """
    rng = np.random.default_rng(seed)
    per_lap = (n_poses - 1) / laps
    delta = 2.0 * math.pi / per_lap  # angle swept per step, = turn per step
    radius = step / (2.0 * math.sin(delta / 2.0))
    along = rng.uniform(0.0, 2.0 * math.pi, n_landmarks)
    across = radius + rng.uniform(-4.0, 4.0, n_landmarks)
    landmarks = np.stack([across * np.cos(along), across * np.sin(along)], axis=1)

    k = np.arange(n_poses, dtype=np.float64)
    around = k * delta
    # heading of pose k = direction of the chord from pose k-1 to pose k
    theta = around - delta / 2.0 + math.pi / 2.0
    poses = np.stack([radius * np.cos(around), radius * np.sin(around), theta], axis=1)

    graph = KinematicGraph()
    x0, y0, t0 = (float(v) for v in poses[0])
    graph.add_pose_prior(0, (x0, x0), (y0, y0), (t0, t0))
    n_observations = 0
    for i in range(n_poses):
        if i > 0:
            turn = float(poses[i, 2] - poses[i - 1, 2])
            distance = float(math.hypot(*(poses[i, :2] - poses[i - 1, :2])))
            graph.add_odometry(
                i - 1,
                i,
                _noisy(rng, turn, turn_bound),
                _noisy(rng, distance, DISTANCE_BOUND),
            )
        for m, (lx, ly) in enumerate(landmarks):
            dx, dy = lx - poses[i, 0], ly - poses[i, 1]
            rho = math.hypot(dx, dy)
            if rho > MAX_RANGE:
                continue
            bearing = wrap_angle(math.atan2(dy, dx) - poses[i, 2])
            graph.add_observation(
                i,
                f"L{m}",
                range=_noisy(rng, rho, RANGE_BOUND),
                bearing=_noisy(rng, bearing, BEARING_BOUND),
            )
            n_observations += 1
    observed = [int(name[1:]) for name in graph.landmark_ids]
    return LoopWorld(graph, poses, landmarks[observed], n_observations)


def _angle_inside(lo: np.ndarray, hi: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Whether some representative angle + 2 pi k lies in [lo, hi] widened by ``TRUTH_SLACK``
    (boxes are periodic)."""
    return np.array(
        [
            angle_in(a - TRUTH_SLACK, b + TRUTH_SLACK, t)
            for a, b, t in zip(lo, hi, angle, strict=True)
        ],
        dtype=bool,
    )


def truth_inside(world: LoopWorld, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether every pose and landmark box contains its truth (up to ``TRUTH_SLACK``);
    headings modulo 2 pi."""
    pb = world.graph.pose_boxes(lo, hi)
    lb = world.graph.landmark_boxes(lo, hi)
    xy = world.poses[:, :2]
    ok = np.all(pb[:, :2, 0] <= xy + TRUTH_SLACK) and np.all(xy - TRUTH_SLACK <= pb[:, :2, 1])
    ok = ok and np.all(_angle_inside(pb[:, 2, 0], pb[:, 2, 1], world.poses[:, 2]))
    ok = ok and np.all(lb[..., 0] <= world.landmarks + TRUTH_SLACK)
    ok = ok and np.all(world.landmarks - TRUTH_SLACK <= lb[..., 1])
    return bool(ok)


def pose_widths(graph: KinematicGraph, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Widths of the pose boxes, shape (n_poses, 3); headings capped at 2 pi (any angle)."""
    widths = np.diff(graph.pose_boxes(lo, hi), axis=-1)[..., 0]
    widths[:, 2] = np.minimum(widths[:, 2], 2.0 * math.pi)
    return widths


def max_width_ratio(graph: KinematicGraph, lo_a, hi_a, lo_b, hi_b) -> float:
    """Largest width(a) / width(b) over all pose coordinates (0/0 counts as 1)."""
    wa = pose_widths(graph, lo_a, hi_a)
    wb = pose_widths(graph, lo_b, hi_b)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(wb > 0, wa / wb, np.where(wa > 0, np.inf, 1.0))
    return float(ratio.max())


def _best_of(run, repeat: int):
    best, result = math.inf, None
    for _ in range(repeat):
        start = time.process_time()
        result = run()
        best = min(best, time.process_time() - start)
    return best, result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--poses", type=int, default=1000)
    parser.add_argument("--landmarks", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--turn-bound", type=float, default=TURN_BOUND, help="odometry turn half-width [rad]"
    )
    parser.add_argument("--repeat", type=int, default=3, help="cuikslam runs (best is kept)")
    parser.add_argument("--codac-repeat", type=int, default=1, help="codac runs (best is kept)")
    parser.add_argument("--rtol", type=float, default=DEFAULT_RTOL)
    parser.add_argument("--max-rounds", type=int, default=None, help="propagate's max_rounds")
    parser.add_argument("--json", type=Path, default=None, metavar="OUT")
    args = parser.parse_args(argv)

    try:
        from tests.reference.codac_propagation import codac_propagate
    except ImportError as error:
        print(f"codac is needed for the baseline: {error}", file=sys.stderr)
        return 2

    world = loop_world(args.poses, args.landmarks, seed=args.seed, turn_bound=args.turn_bound)
    graph = world.graph
    print(
        f"loop world: {len(graph.pose_ids)} poses, {len(graph.landmark_ids)} landmarks, "
        f"{graph.n_factors} factors ({world.n_observations} observations), seed {args.seed}; "
        "single core (NUMBA_NUM_THREADS=1)"
    )

    kwargs = {"rtol": args.rtol}
    if args.max_rounds is not None:
        kwargs["max_rounds"] = args.max_rounds
    propagate(graph, **kwargs)  # warm-up: numba compile or cache load
    t_cuik, result = _best_of(lambda: propagate(graph, **kwargs), args.repeat)
    t_codac, (lo_c, hi_c, consistent_c, apps_c) = _best_of(
        lambda: codac_propagate(graph, rtol=args.rtol), args.codac_repeat
    )

    rate_cuik = result.applications / t_cuik
    rate_codac = apps_c / t_codac
    ratio = rate_cuik / rate_codac
    width_ratio = max_width_ratio(graph, result.lo, result.hi, lo_c, hi_c)
    truth_cuik = truth_inside(world, result.lo, result.hi)
    truth_codac = truth_inside(world, lo_c, hi_c)

    rows = [
        ("cuikslam propagate", result.applications, t_cuik, rate_cuik,
         result.status is Status.CONSISTENT, truth_cuik),
        ("codac (Python loop)", apps_c, t_codac, rate_codac, consistent_c, truth_codac),
    ]  # fmt: skip
    header = f"{'':22}{'applications':>14}{'cpu s':>11}{'applications/s':>16}"
    print(header + f"{'consistent':>12}{'truth in':>10}")
    for name, apps, secs, rate, cons, truth in rows:
        print(f"{name:22}{apps:>14,}{secs:>11.4f}{rate:>16,.0f}{cons!s:>12}{truth!s:>10}")
    print(f"speed ratio (applications/s, cuikslam / codac): {ratio:,.1f}x")
    print(f"time ratio (cuikslam / codac, to the fixpoint): {t_cuik / t_codac:.4f}")
    print(f"max width ratio cuikslam/codac over pose coordinates: {width_ratio:.4f}")
    median_cuik = np.median(pose_widths(graph, result.lo, result.hi), axis=0)
    median_codac = np.median(pose_widths(graph, lo_c, hi_c), axis=0)
    print(
        "median pose widths x, y [m], theta [rad]: "
        f"cuikslam {np.array2string(median_cuik, precision=3)}, "
        f"codac {np.array2string(median_codac, precision=3)}"
    )

    if args.json is not None:
        figures = {
            "poses": len(graph.pose_ids),
            "landmarks": len(graph.landmark_ids),
            "factors": graph.n_factors,
            "observations": world.n_observations,
            "seed": args.seed,
            "turn_bound": args.turn_bound,
            "timer": "process_time (CPU seconds, best of repeats)",
            "rtol": args.rtol,
            "max_rounds": DEFAULT_ROUNDS if args.max_rounds is None else args.max_rounds,
            "single_core": True,
            "python": platform.python_version(),
            "cuikslam": {
                "applications": result.applications,
                "seconds": t_cuik,
                "applications_per_second": rate_cuik,
                "status": result.status.name,
                "truth_inside": truth_cuik,
            },
            "codac": {
                "applications": apps_c,
                "seconds": t_codac,
                "applications_per_second": rate_codac,
                "consistent": consistent_c,
                "truth_inside": truth_codac,
            },
            "speed_ratio": ratio,
            "max_pose_width_ratio": width_ratio,
            "median_pose_widths": {
                "cuikslam": median_cuik.tolist(),
                "codac": median_codac.tolist(),
            },
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
