"""Is the compiled simplex (``narrowing/_simplex.py``) needed beside HiGHS?

    python benchmarks/bench_simplex.py                  # the seed's experiment, 200 poses
    python benchmarks/bench_simplex.py --poses 200 1000

The ``lp`` level bounds every variable of a window of poses by two LPs over one polytope
that differ only in their cost. With ``lp_bounds.SEQUENCE_KERNEL`` (the default) HiGHS
solves the first LP of a window and the compiled primal simplex the others from the last
optimum; without it HiGHS solves every LP (warm-started from the column's last basis).
This benchmark narrows the same logs (known correspondence, the fixpoint then
:func:`cuikslam.strengthen` at ``lp``, no budget) both ways and prints, for each, the CPU
seconds (best of ``--repeats``), the LPs solved and the median and widest pose box widths.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def _world(n_poses: int):
    from cuikslam.simulate import simulate_paper, simulate_random_world

    if n_poses == 0:
        return "seed's experiment", simulate_paper(seed=0)[0]
    log, _ = simulate_random_world(seed=0, n_poses=n_poses, n_landmarks=max(10, n_poses // 10))
    return f"random, {n_poses} poses", log


def _narrow(log, kernel: bool) -> tuple[float, int, np.ndarray]:
    from cuikslam.graph.kinematic_graph import KinematicGraph
    from cuikslam.narrowing import lp_bounds
    from cuikslam.narrowing.consistency import StrengthenReport, strengthen
    from cuikslam.narrowing.propagation import propagate

    lp_bounds.SEQUENCE_KERNEL = kernel
    graph = KinematicGraph.from_log(log)
    fixpoint = propagate(graph)
    report = StrengthenReport()
    start = time.process_time()
    strengthen(graph, fixpoint.lo, fixpoint.hi, level="lp", report=report, threads=1)
    seconds = time.process_time() - start
    boxes = graph.pose_boxes(fixpoint.lo, fixpoint.hi)
    return seconds, report.lp.solved, boxes[:, :, 1] - boxes[:, :, 0]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, nargs="*", default=[0, 200],
                        help="random worlds of these sizes (0: the seed's experiment)")  # fmt: skip
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    from cuikslam.narrowing.consistency import warm_up_lp

    warm_up_lp()
    print(f"{'log':>20} {'solver':>16} {'CPU s':>7} {'LPs':>7} {'x med':>7} {'x max':>7} "
          f"{'θ med':>7} {'θ max':>7}")  # fmt: skip
    for n in args.poses:
        name, log = _world(n)
        _narrow(log, True)  # loads the kernels the log needs
        for kernel, label in ((True, "HiGHS + kernel"), (False, "HiGHS alone")):
            runs = [_narrow(log, kernel) for _ in range(args.repeats)]
            seconds = min(r[0] for r in runs)
            _, solved, widths = runs[0]
            print(f"{name:>20} {label:>16} {seconds:7.2f} {solved:7d} "
                  f"{np.median(widths[:, 0]):7.3f} {widths[:, 0].max():7.3f} "
                  f"{np.median(widths[:, 2]):7.4f} {widths[:, 2].max():7.4f}")  # fmt: skip
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
