"""How ambiguous is one reading when every other reading is known?

For each chosen reading of an unknown-correspondence log with a truth file (``cuikslam
import ... -o LOG`` writes ``LOG.truth.json``), every other reading gets its true landmark
and the search decides that one alone: which landmarks can it be at the level given?
When a reading keeps several choices even then, no search order can decide it from the
rest of the log; its choices multiply with the other such readings' in a whole search.
With ``--together`` the chosen readings are left unknown at once, in one search: when its
survivors are the product of the readings' single counts, their choices combine freely.

    cuikslam import lost-in-the-woods dataset2.mat --bounds woods.bounds.json \\
        --steps 2000 --keyframe-observations --post-separation 1.0 -o w2000.jsonl
    python benchmarks/one_reading_ambiguity.py w2000.jsonl --readings 489 519 526 645
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from cuikslam.budget import deadline_after


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--truth", type=Path, help="default: LOG with .truth.json")
    parser.add_argument("--readings", type=int, nargs="+", required=True,
                        help="observation numbers (0-based, log order)")  # fmt: skip
    parser.add_argument("--level", default="hull", choices=("hull", "lp", "lp-split"))
    parser.add_argument("--budget", type=float, default=600.0, help="seconds per search")
    parser.add_argument("--together", action="store_true",
                        help="also leave the chosen readings unknown in one search")  # fmt: skip
    args = parser.parse_args(argv)

    from cuikslam.hypotheses import solve_unknown
    from cuikslam.log.reader import parse_log_lines

    lines = [ln for ln in args.log.read_text().splitlines() if ln.strip() and ln[0] != "#"]
    truth_path = args.truth or args.log.with_suffix(".truth.json")
    truth = json.loads(truth_path.read_text())["assignment"]
    observations = [i for i, ln in enumerate(lines) if json.loads(ln)["type"] == "observation"]

    def solve_leaving(unknown: set[int]):
        labelled = list(lines)
        for k, i in enumerate(observations):
            if k not in unknown:
                record = json.loads(labelled[i])
                record["landmark"] = truth[k]
                labelled[i] = json.dumps(record)
        start = time.perf_counter()
        log = parse_log_lines(labelled)
        solution = solve_unknown(log, consistency=args.level, deadline=deadline_after(args.budget))
        return solution, time.perf_counter() - start

    print(f"{'reading':>8} {'truth':>8} {'choices':>8} {'seconds':>8}  landmarks it can be")
    product = 1
    for r in args.readings:
        solution, seconds = solve_leaving({r})
        choices = [h.assignment[r] for h in solution.hypotheses]
        product *= len(choices)
        cut = "" if solution.complete else "  (INCOMPLETE: the budget ran out)"
        print(f"{r:>8} {truth[r]:>8} {len(choices):>8} {seconds:>8.1f}  {' '.join(choices)}{cut}")
    if args.together:
        solution, seconds = solve_leaving(set(args.readings))
        print(
            f"together: {solution.statistics['survivors']} "
            f"survivors (complete: {solution.complete}) against a product of {product}, "
            f"{seconds:.1f} s"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
