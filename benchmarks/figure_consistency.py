"""Figure of docs/concepts/levels.md: the seed's experiment, boxes at each level and the inner hull.

    python benchmarks/figure_consistency.py [--seed 0] [-o docs/consistency.png]

The inner hull comes from ``benchmarks/results/inner_hull_paper.json`` (written by
``bench_tightness.py``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from cuikslam.results.figures import plot_comparison_on_axes, save_figure
from cuikslam.simulate import simulate_paper
from cuikslam.solver import solve

CACHE = Path(__file__).parent / "results" / "inner_hull_paper.json"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("-o", "--output", default="docs/consistency.png")
    args = parser.parse_args(argv)
    log, truth = simulate_paper(seed=args.seed)
    boxes = {}
    for level in ("hull", "lp", "lp-split"):
        boxes[f"level '{level}'"] = solve(log, consistency=level, work_budget=None).best.poses
    inner = json.loads(CACHE.read_text())["seeds"][str(args.seed)]
    boxes["inner hull (exact hull is between)"] = np.array(inner["poses"])
    figure, ax = plt.subplots(figsize=(7.5, 7))
    plot_comparison_on_axes(
        ax, boxes, truth, title=f"The seed's experiment (noise seed {args.seed})"
    )
    save_figure(figure, args.output)
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
