"""The correspondence search on Dask: speed-up, overhead, and many small workers.

Usage::

    python benchmarks/bench_distributed.py                      # all three parts
    python benchmarks/bench_distributed.py --part speedup --repeat 2
    python benchmarks/bench_distributed.py --part overhead
    python benchmarks/bench_distributed.py --part many --many 16,32,64

- **speedup**: a log with thousands of surviving hypotheses (10 poses, 8 identical
  landmarks, ids dropped, wide observation bounds: 3,584 survivors, 15,360 nodes), solved
  at level ``hull`` in this process and on a local cluster of 1 and 2 worker processes
  (warm: every worker has loaded the compiled kernels). Wall and CPU seconds; the results
  are compared (survivors, summary, reported hypotheses, boxes).
- **overhead**: the seed's experiment (``cuikslam paper``'s log, unknown correspondence,
  default level) on a warm 2-worker cluster against one process, best and median of
  ``--repeat-overhead`` runs.
- **client**: the client's CPU per task on 2 worker processes with that small quantum.
- **many**: ``--many`` workers simulated as threads of one process with a small work
  quantum (``--quantum-nodes``): per task, nodes explored and replayed, CPU seconds,
  bytes sent each way; the client's seconds per task and the merge. Threads share one
  interpreter, so the wall time says nothing here; the per-task figures do.

The machine is shared: the load average is recorded with every run, and CPU seconds
next to wall seconds. Results go to ``benchmarks/results/distributed.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import statistics
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

from cuikslam.cluster import dask_client
from cuikslam.hypotheses.distributed import search_distributed
from cuikslam.hypotheses.search import solve_unknown
from cuikslam.simulate import simulate_paper, simulate_random_world
from cuikslam.solver import warm_up

RESULTS = Path(__file__).parent / "results" / "distributed.json"


def many_hypotheses_log():
    """10 poses, 8 landmarks of one class, ids dropped, observations +-0.8 m / +-0.3 rad."""
    log, _ = simulate_random_world(
        seed=1, n_poses=10, n_landmarks=8, classes=("a",), size=(16.0, 12.0), max_range=6.0,
        odometry_bounds=(0.1, 0.2), observation_bounds=(0.8, 0.3), unknown=True,
    )  # fmt: skip
    return log


def _load() -> float:
    return round(os.getloadavg()[0], 2)


def _timed(fn):
    load = _load()
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, {
        "wall_s": round(time.perf_counter() - wall, 3),
        "client_cpu_s": round(time.process_time() - cpu, 3),
        "load_before": load,
        "load_after": _load(),
    }


def compare(one, many) -> dict:
    """How the cluster's result differs from one process's."""
    a = {tuple(h.assignment): h for h in one.hypotheses}
    b = {tuple(h.assignment): h for h in many.hypotheses}
    widest = 0.0
    for key in a.keys() & b.keys():
        for x, y in ((a[key].poses, b[key].poses), (a[key].landmarks, b[key].landmarks)):
            finite = np.isfinite(x) & np.isfinite(y)
            widest = max(widest, float(np.max(np.abs(x - y)[finite], initial=0.0)))
    return {
        "survivors": [one.statistics["survivors"], many.statistics["survivors"]],
        "complete": [one.complete, many.complete],
        "same_reported": list(a) == list(b),
        "reported_in_common": len(a.keys() & b.keys()),
        "same_summary": one.correspondence == many.correspondence,
        "largest_box_bound_difference_m": widest,
        "branch_points": [one.statistics["branch_points"], many.statistics["branch_points"]],
    }


def _process_cpu() -> float:
    import psutil

    t = psutil.Process().cpu_times()
    return t.user + t.system


def part_speedup(repeat: int, limit: int | None) -> dict:
    log = many_hypotheses_log()
    extra = {} if limit is None else {"strengthen_limit": limit}
    runs: dict[str, list] = {"one_process": [], "workers_1": [], "workers_2": []}
    one = None
    clusters = {n: dask_client(n) for n in (1, 2)}
    clients = {n: c.__enter__() for n, c in clusters.items()}
    try:
        for _ in range(repeat):
            one, row = _timed(lambda: solve_unknown(log, consistency="hull", **extra))
            row["survivors"] = one.statistics["survivors"]
            runs["one_process"].append(row)
            print("one process", row, flush=True)
            for n in (2, 1) if _ == 0 else (2,):
                before = clients[n].run(_process_cpu)
                many, row = _timed(
                    lambda n=n: search_distributed(
                        log, client=clients[n], consistency="hull", **extra
                    )
                )
                after = clients[n].run(_process_cpu)
                per_worker = [round(after[w] - before[w], 3) for w in before]
                tail = many.timings["split_s"] + many.timings["merge_s"] + many.timings["finish_s"]
                # on dedicated cores: the busiest worker, then the client's serial tail
                dedicated = max(per_worker) + tail
                row.update(
                    worker_process_cpu_s=per_worker,
                    client_tail_s=round(tail, 3),
                    dedicated_cores_estimate_s=round(dedicated, 3),
                )
                row.update(
                    worker_cpu_s=round(many.statistics["worker_cpu_s"], 3),
                    tasks=many.statistics["tasks"],
                    split_s=round(many.timings["split_s"], 3),
                    client_s=round(many.timings["client_s"], 3),
                    merge_s=round(many.timings["merge_s"], 3),
                    **compare(one, many),
                )
                runs[f"workers_{n}"].append(row)
                print(f"{n} workers", row, flush=True)
    finally:
        for c in clusters.values():
            c.__exit__(None, None, None)
    best = {k: min(r["wall_s"] for r in v) for k, v in runs.items()}
    one_cpu = min(r["client_cpu_s"] for r in runs["one_process"])
    estimate = min(r["dedicated_cores_estimate_s"] for r in runs["workers_2"])
    return {
        "log": "simulate_random_world(seed=1, n_poses=10, n_landmarks=8, classes=('a',), "
        "size=(16, 12), max_range=6, odometry_bounds=(0.1, 0.2), "
        "observation_bounds=(0.8, 0.3), unknown=True); level hull",
        "strengthen_limit": limit,
        "runs": runs,
        "best_wall_s": best,
        "speedup_2_workers": round(best["one_process"] / best["workers_2"], 2),
        "speedup_1_worker": round(best["one_process"] / best["workers_1"], 2),
        "one_process_cpu_s": one_cpu,
        "speedup_2_workers_dedicated_cores_estimate": round(one_cpu / estimate, 2),
    }


def part_overhead(repeat: int) -> dict:
    log, _ = simulate_paper(0, unknown=True)
    one_rows, many_rows = [], []
    with dask_client(2) as client:
        for _ in range(repeat):
            one, row = _timed(lambda: solve_unknown(log))
            one_rows.append(row)
            many, row = _timed(lambda: search_distributed(log, client=client))
            row.update(tasks=many.statistics["tasks"], **compare(one, many))
            many_rows.append(row)
    walls = [r["wall_s"] for r in one_rows], [r["wall_s"] for r in many_rows]
    result = {
        "log": "simulate_paper(0, unknown=True); default level (lp on the survivors)",
        "one_process": one_rows,
        "workers_2": many_rows,
        "best_s": [min(w) for w in walls],
        "median_s": [statistics.median(w) for w in walls],
    }
    result["overhead_best_s"] = round(result["best_s"][1] - result["best_s"][0], 3)
    result["overhead_median_s"] = round(result["median_s"][1] - result["median_s"][0], 3)
    print("overhead", result["best_s"], result["median_s"], flush=True)
    return result


def part_many(sizes: list[int], quantum_nodes: int) -> dict:
    log = many_hypotheses_log()
    rows = []
    for n in sizes:
        tasks: list = []
        with dask_client(n, processes=False) as client:
            many, row = _timed(
                partial(
                    search_distributed, log, client=client, consistency="hull",
                    quantum_nodes=quantum_nodes, quantum_s=None, on_result=tasks.append,
                )
            )  # fmt: skip
        sent = [len(pickle.dumps((t.prefixes, quantum_nodes))) for t in tasks]
        back = [len(pickle.dumps(t)) for t in tasks]
        explored = [t.expanded for t in tasks]
        replayed = [t.replayed for t in tasks]
        cpu = [t.cpu_s for t in tasks]
        row.update(
            workers=n,
            quantum_nodes=quantum_nodes,
            tasks=len(tasks),
            survivors=many.statistics["survivors"],
            nodes_per_task_median=statistics.median(explored),
            nodes_replayed_per_task_median=statistics.median(replayed),
            replayed_share_of_nodes=round(sum(replayed) / (sum(replayed) + sum(explored)), 3),
            task_cpu_ms_median=round(1000 * statistics.median(cpu), 2),
            replay_cpu_share=round(sum(t.replay_s for t in tasks) / sum(cpu), 3),
            bytes_sent_per_task_median=statistics.median(sent),
            bytes_back_per_task_median=statistics.median(back),
            bytes_back_per_task_max=max(back),
            client_ms_per_task=round(1000 * many.timings["client_s"] / len(tasks), 3),
            split_s=round(many.timings["split_s"], 3),
            merge_s=round(many.timings["merge_s"], 3),
            worker_cpu_s=round(sum(cpu), 2),
        )
        rows.append(row)
        print(row, flush=True)
    return {"log": "as in speedup", "rows": rows}


def part_client(quantum_nodes: int) -> dict:
    """The client's CPU per task on a 2-process cluster with a small quantum (many tasks),
    less what an idle client uses over the same time."""
    log = many_hypotheses_log()
    with dask_client(2) as client:
        idle = time.process_time()
        time.sleep(5.0)
        idle_per_s = (time.process_time() - idle) / 5.0
        many, row = _timed(
            partial(
                search_distributed, log, client=client, consistency="hull",
                quantum_nodes=quantum_nodes, quantum_s=None, strengthen_limit=1,
            )
        )  # fmt: skip
    tail = many.timings["split_s"] + many.timings["merge_s"] + many.timings["finish_s"]
    busy = row["client_cpu_s"] - idle_per_s * row["wall_s"] - tail
    row.update(
        tasks=many.statistics["tasks"],
        idle_client_cpu_per_s=round(idle_per_s, 4),
        client_tail_s=round(tail, 3),
        client_cpu_ms_per_task=round(1000 * busy / many.statistics["tasks"], 2),
        quantum_nodes=quantum_nodes,
    )
    print("client", row, flush=True)
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--part", choices=["all", "speedup", "overhead", "many", "client"], default="all"
    )
    parser.add_argument("--repeat", type=int, default=2, help="speed-up runs (best kept)")
    parser.add_argument("--repeat-overhead", type=int, default=5)
    parser.add_argument("--many", default="16,32,64", help="simulated worker counts")
    parser.add_argument(
        "--strengthen-limit", type=int, default=None,
        help="speed-up part: 1 skips what follows the search on the 100 reported survivors "
        "(bisection), which runs on the client alone; results under 'speedup_search_only'",
    )  # fmt: skip
    parser.add_argument("--quantum-nodes", type=int, default=50)
    parser.add_argument("--json", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    warm_up(True)
    out = json.loads(args.json.read_text()) if args.json.exists() else {}
    out["machine"] = {"cpus": os.cpu_count(), "python": sys.version.split()[0]}
    if args.part in ("all", "speedup"):
        key = "speedup" if args.strengthen_limit is None else "speedup_search_only"
        out[key] = part_speedup(args.repeat, args.strengthen_limit)
    if args.part in ("all", "overhead"):
        out["overhead"] = part_overhead(args.repeat_overhead)
    if args.part in ("all", "client"):
        out["client"] = part_client(args.quantum_nodes)
    if args.part in ("all", "many"):
        many = part_many([int(n) for n in args.many.split(",")], args.quantum_nodes)
        done = {r["workers"] for r in many["rows"]}
        earlier = [r for r in out.get("many", {}).get("rows", []) if r["workers"] not in done]
        many["rows"] = sorted(earlier + many["rows"], key=lambda r: r["workers"])
        out["many"] = many
    out["measured"] = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    args.json.write_text(json.dumps(out, indent=1) + "\n")
    print(f"written {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
