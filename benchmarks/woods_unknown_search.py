"""The unknown-correspondence search on an imported Lost in the Woods window, against truth.

Runs only the search (:func:`cuikslam.hypotheses.solve_unknown`, level ``hull`` by
default: the survivors' stronger level and witnesses are left out, so that the figures
are the search's), streams every survivor, and reports whether it finished, how many
survived, whether the true association is among them, the nodes, the share of the tree
explored, the time and the peak RSS; appends one JSON row to
``benchmarks/results/woods_unknown_search.json``. The log and its truth come from the
importer (``LOG.truth.json`` beside ``LOG``)::

    cuikslam import lost-in-the-woods dataset2.mat --bounds woods.bounds.json \\
        --steps 2000 --keyframe-observations --post-separation 1.0 --map 0.05 \\
        -o w2000_map.jsonl
    python benchmarks/woods_unknown_search.py w2000_map.jsonl --budget 400

(without ``--map`` the posts are not surveyed: the search then stops on its budget).
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from datetime import UTC, datetime
from pathlib import Path

from cuikslam.budget import deadline_after

RESULTS = Path(__file__).parent / "results" / "woods_unknown_search.json"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--truth", type=Path, help="default: LOG with .truth.json")
    parser.add_argument(
        "--budget", type=float, default=400.0, help="seconds (the search takes 70 %%)"
    )
    parser.add_argument("--level", default="hull", choices=("hull", "lp"))
    args = parser.parse_args(argv)

    from cuikslam.hypotheses import solve_unknown
    from cuikslam.log.reader import read_log_file
    from cuikslam.results.association import named_landmarks

    log = read_log_file(args.log)
    truth = json.loads((args.truth or args.log.with_suffix(".truth.json")).read_text())
    named = bool(named_landmarks(log))  # else a hypothesis is a partition of the readings

    def key(assignment: list[str]) -> tuple:
        if named:
            return tuple(assignment)
        first: dict[str, int] = {}
        return tuple(first.setdefault(a, len(first)) for a in assignment)

    true = key(truth["assignment"])
    survivors: set[tuple] = set()
    start = time.perf_counter()
    solution = solve_unknown(
        log, consistency=args.level, deadline=deadline_after(args.budget),
        on_survivor=lambda a: survivors.add(key(a)),
    )  # fmt: skip
    seconds = time.perf_counter() - start
    stats = solution.statistics
    row = {
        "log": args.log.name,
        "level": args.level,
        "budget_s": args.budget,
        "complete": solution.complete,
        "survivors": stats["survivors"],
        "truth_among_survivors": true in survivors,
        "nodes": stats["created"],
        "explored_fraction": stats["explored_fraction"],
        "refuted_in_local_frame": stats["refuted_in_local_frame"],
        "seconds": round(seconds, 1),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024,
        "measured": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
    }
    print(json.dumps(row))
    rows = json.loads(RESULTS.read_text()) if RESULTS.exists() else []
    RESULTS.write_text(json.dumps([*rows, row], indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
