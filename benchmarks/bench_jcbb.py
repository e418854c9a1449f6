"""GTSAM + JCBB against cuikslam's search, side by side on the same worlds (issue 28, item 5).

    python benchmarks/bench_jcbb.py                    # the seed's experiment + 5 sparse worlds
    python benchmarks/bench_jcbb.py --quick            # 2 worlds, a smoke run
    python benchmarks/bench_jcbb.py --no-paper --seeds 42 43 44 --poses 200 --landmarks 40 \
        --max-range 6 --output benchmarks/results/jcbb_200.json
    python benchmarks/bench_jcbb.py --sigma 0.3333 0.5774 --work-budget none

Each world is simulated with unknown correspondence. The baseline
(:mod:`benchmarks.jcbb`: incremental iSAM2, JCBB association per scan, 99 % gates) reads
every interval as a Gaussian centred on its midpoint, with a standard deviation of
``--sigma`` times its half-width: 1/3 (a 3-sigma bound) by default, and 1/sqrt(3), the
standard deviation of the simulator's errors (uniform over the interval), as a
best-tuned second run. cuikslam runs ``solve(log)`` with default options (its
deterministic work budget) and collects every survivor's partition.

Columns: ``=truth`` JCBB's partition is the true one; ``split``/``merge`` true landmarks
JCBB spread over several of its landmarks / JCBB landmarks holding several true ones;
``truth in`` the true partition is among cuikslam's survivors; ``JCBB in surv.`` JCBB's
is; ``wrong: search`` it is not, and the search was complete: a proof that JCBB's answer
is impossible. Two direct checks need no complete search: ``labelled`` the log labelled
with JCBB's assignment, solved with known correspondence (which uses no negative
information), is refuted; ``1 free`` the same log with its last observation unlabelled,
searched (one decision, with the sensor's negative information), is complete and excludes
JCBB's answer ("?" when it did not finish). ``proven wrong``: any of the three. Rows go
to ``benchmarks/results/jcbb.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from cuikslam.hypotheses.labelled import labelled_log  # noqa: E402
from cuikslam.log.records import Log, Observation  # noqa: E402
from cuikslam.results.association import named_landmarks, partition  # noqa: E402
from cuikslam.simulate import simulate_paper, simulate_random_world  # noqa: E402
from cuikslam.simulate.truth import GroundTruth  # noqa: E402
from cuikslam.solver import solve  # noqa: E402
from jcbb import run_gtsam_jcbb  # noqa: E402

RESULTS = HERE / "results" / "jcbb.json"
SIGMAS = (1 / 3, 1 / math.sqrt(3))


def worlds(args: argparse.Namespace) -> list[tuple[str, Log, GroundTruth]]:
    """The seed's experiment (unless ``--no-paper``) and the sparse random worlds."""
    out = []
    if not args.no_paper:
        out.append(("paper", *simulate_paper(seed=0, unknown=True)))
    for k, seed in enumerate(args.seeds):
        poses = args.poses[k % len(args.poses)]
        landmarks = args.landmarks[k % len(args.landmarks)]
        log, truth = simulate_random_world(
            seed=seed,
            n_poses=poses,
            n_landmarks=landmarks,
            classes=tuple(args.classes),
            size=tuple(args.size),
            max_range=args.max_range,
            fov=args.fov,
            unknown=True,
        )
        out.append((f"s{seed}-{poses}p-{landmarks}l", log, truth))
    return out


def split_merge(found: list[str], true: list[str]) -> tuple[int, int]:
    """True landmarks spread over several found ones; found landmarks holding several true."""
    by_true: dict[str, set[str]] = defaultdict(set)
    by_found: dict[str, set[str]] = defaultdict(set)
    for f, t in zip(found, true, strict=True):
        by_true[t].add(f)
        by_found[f].add(t)
    return sum(len(v) > 1 for v in by_true.values()), sum(len(v) > 1 for v in by_found.values())


def run_cuikslam(log: Log, overrides: dict[str, Any]) -> dict[str, Any]:
    """Solve ``log`` with default options; every survivor's partition."""
    named = named_landmarks(log)
    survivors: set[tuple] = set()
    start = time.perf_counter()
    solution = solve(log, on_survivor=lambda a: survivors.add(tuple(partition(a, named))),
                     **overrides)  # fmt: skip
    elapsed = time.perf_counter() - start
    survivors |= {tuple(partition(h.assignment, named)) for h in solution.hypotheses}
    stats = solution.statistics
    return {
        "seconds": elapsed,
        "complete": solution.complete,
        "survivors": int((solution.correspondence or {}).get("survivors", len(survivors))),
        "collected": survivors,
        "proven": sum(h.status == "proven consistent" for h in solution.hypotheses),
        "work_spent": stats.get("work_spent"),
        "budget_bound": stats.get("budget_bound"),
    }


def labelled_refuted(log: Log, assignment: list[str]) -> tuple[bool, float]:
    """Whether the log labelled with ``assignment`` is proven inconsistent (known
    correspondence: no negative information); seconds."""
    start = time.perf_counter()
    solution = solve(labelled_log(log, assignment), certify_limit=0)
    return solution.refuted, time.perf_counter() - start


def one_free_refuted(log: Log, assignment: list[str]) -> tuple[bool | None, float]:
    """The log labelled with ``assignment`` except its last observation, searched: a tree
    of one decision, with the sensor's negative information. True when the search is
    complete and ``assignment`` is not among its survivors (a proof that it is
    impossible), None when the search did not finish; seconds."""
    start = time.perf_counter()
    near = labelled_log(log, assignment)
    last = max(i for i, r in enumerate(near.records) if isinstance(r, Observation))
    records = list(near.records)
    records[last] = replace(records[last], landmark=None)
    near = Log(records=records, path=log.path)
    named = named_landmarks(near)
    survivors: set[tuple] = set()
    solution = solve(near, certify_limit=0,
                     on_survivor=lambda a: survivors.add(tuple(partition(a, named))))  # fmt: skip
    survivors |= {tuple(partition(h.assignment, named)) for h in solution.hypotheses}
    elapsed = time.perf_counter() - start
    if not solution.complete:
        return None, elapsed
    return tuple(partition(assignment, named)) not in survivors, elapsed


def compare(name: str, log: Log, truth: GroundTruth, args: argparse.Namespace) -> list[dict]:
    """One row per JCBB noise level for world ``name``."""
    named = named_landmarks(log)
    true_part = tuple(partition(truth.assignment, named))
    ours = run_cuikslam(log, args.overrides)
    rows = []
    for fraction in args.sigma:
        start = time.perf_counter()
        result = run_gtsam_jcbb(log, fraction)
        jcbb_s = time.perf_counter() - start
        part = tuple(partition(result.assignment, named))
        split, merge = split_merge(result.assignment, truth.assignment)
        among = part in ours["collected"]
        if part == true_part:  # the truth is never refuted: nothing to prove
            refuted, label_s, free, free_s = False, 0.0, False, 0.0
        else:
            refuted, label_s = labelled_refuted(log, result.assignment)
            free, free_s = one_free_refuted(log, result.assignment)
        by_search = ours["complete"] and not among
        rows.append(
            {
                "world": name,
                "poses": len(truth.pose_ids),
                "observations": len(log.observations),
                "true_landmarks": len(set(truth.assignment)),
                "sigma_per_halfwidth": round(fraction, 4),
                "jcbb_seconds": round(jcbb_s, 3),
                "jcbb_landmarks": len(set(result.assignment)),
                "jcbb_is_truth": part == true_part,
                "jcbb_splits": split,
                "jcbb_merges": merge,
                "cuikslam_seconds": round(ours["seconds"], 2),
                "cuikslam_complete": ours["complete"],
                "cuikslam_survivors": ours["survivors"],
                "cuikslam_proven": ours["proven"],
                "truth_among_survivors": true_part in ours["collected"],
                "work_spent": ours["work_spent"],
                "budget_bound": ours["budget_bound"],
                "jcbb_among_survivors": among,
                "jcbb_proven_wrong_by_search": by_search,
                "jcbb_proven_wrong_labelled": refuted,
                "labelled_seconds": round(label_s, 2),
                "jcbb_proven_wrong_one_free": free,
                "one_free_seconds": round(free_s, 2),
                "jcbb_proven_wrong": bool(by_search or refuted or free),
            }
        )
    return rows


def table(rows: list[dict]) -> None:
    """The rows as a rich table on the terminal."""
    from rich.console import Console
    from rich.table import Table

    t = Table(title="GTSAM + JCBB vs cuikslam (unknown correspondence)")
    cols = ["world", "obs", "σ/hw", "JCBB s", "lm (true)", "=truth", "split/merge",
            "cuik s", "complete", "surv.", "proven", "truth in", "JCBB in surv.",
            "wrong: search", "labelled", "1 free", "proven wrong"]  # fmt: skip
    for c in cols:
        t.add_column(c, justify="left" if c == "world" else "right")

    def yes(v: bool | None) -> str:
        return "?" if v is None else "yes" if v else "no"

    for r in rows:
        t.add_row(
            r["world"],
            str(r["observations"]),
            f"{r['sigma_per_halfwidth']:.3f}",
            f"{r['jcbb_seconds']:.2f}",
            f"{r['jcbb_landmarks']} ({r['true_landmarks']})",
            yes(r["jcbb_is_truth"]),
            f"{r['jcbb_splits']}/{r['jcbb_merges']}",
            f"{r['cuikslam_seconds']:.1f}",
            yes(r["cuikslam_complete"]),
            str(r["cuikslam_survivors"]),
            str(r["cuikslam_proven"]),
            yes(r["truth_among_survivors"]),
            yes(r["jcbb_among_survivors"]),
            yes(r["jcbb_proven_wrong_by_search"]),
            yes(r["jcbb_proven_wrong_labelled"]),
            yes(r["jcbb_proven_wrong_one_free"]),
            yes(r["jcbb_proven_wrong"]),
        )
    console = Console(width=max(Console().width, 200))
    console.print(t)
    for sigma in sorted({r["sigma_per_halfwidth"] for r in rows}):
        some = [r for r in rows if r["sigma_per_halfwidth"] == sigma]
        count = {k: sum(bool(r[k]) for r in some) for k in some[0] if k.startswith("jcbb_")}
        console.print(
            f"σ = {sigma:.3f} hw: JCBB true in {count['jcbb_is_truth']}/{len(some)} worlds, "
            f"among cuikslam's survivors in {count['jcbb_among_survivors']}/{len(some)}, "
            f"proven wrong in {count['jcbb_proven_wrong']}/{len(some)}; JCBB "
            f"{sum(r['jcbb_seconds'] for r in some):.1f} s in all, cuikslam "
            f"{sum(r['cuikslam_seconds'] for r in some):.1f} s"
        )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="2 worlds: the paper + a 60-pose one")
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    p.add_argument("--poses", type=int, nargs="+", default=[100, 150])
    p.add_argument("--landmarks", type=int, nargs="+", default=[20, 30])
    p.add_argument("--classes", nargs="+", default=["door", "corridor"])
    p.add_argument("--size", type=float, nargs=2, default=[30.0, 20.0])
    p.add_argument("--max-range", type=float, default=8.0)
    p.add_argument("--fov", type=float, default=2.0)
    p.add_argument("--no-paper", action="store_true", help="leave out the seed's experiment")
    p.add_argument("--sigma", type=float, nargs="+", default=list(SIGMAS),
                   help="JCBB std. dev. per interval half-width (one row each)")  # fmt: skip
    p.add_argument("--work-budget", default=None, help="cuikslam's work budget (default: auto)")
    p.add_argument("--time-budget", type=float, default=None, help="cuikslam's time budget, s")
    p.add_argument("--output", type=Path, default=RESULTS)
    args = p.parse_args(argv)
    if args.quick:
        args.seeds, args.poses, args.landmarks = [1], [60], [12]
    args.overrides = {}
    if args.work_budget is not None:
        wb = args.work_budget
        args.overrides["work_budget"] = None if wb == "none" else float(wb)
    if args.time_budget is not None:
        args.overrides["time_budget"] = args.time_budget
    rows: list[dict] = []
    for name, log, truth in worlds(args):
        rows += compare(name, log, truth, args)
        print(f"{name}: done", file=sys.stderr, flush=True)
    table(rows)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    doc = {"command": " ".join(["python benchmarks/bench_jcbb.py", *sys.argv[1:]]), "rows": rows}
    args.output.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"rows written to {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
