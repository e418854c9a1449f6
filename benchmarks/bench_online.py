"""Benchmark: following a log online (``cuikslam follow``), against its truth and the batch.

Sections (each writes its part of ``benchmarks/results/online.json``):

- ``known``: 2,000-pose known-correspondence logs from ``cuikslam simulate random --poses
  2000 --seed S --landmarks L`` (the default 10 landmarks: long stretches with nothing in
  view; 60: a landmark in view at nearly every pose), followed through the library path of
  ``cuikslam follow`` (:func:`cuikslam.online.follow.follow` over the file's lines). It
  checks one box per pose, in the order the log reaches the poses; every box against the
  truth file (exactly, headings modulo 2π); the latency per pose (wall clock, from the
  arrival of the record that finished the pose to its box) and the CPU time of the call
  that gave it; and the last pose's box against the batch ``hull`` solve's. It follows
  each log ``--repeats`` times (the latency's 99th percentile of each run: the machine's
  load moves), then once more narrowing to the fixpoint at every pose
  (``work_per_pose=None``), to count the lines that the work limit left wider. It then
  runs the command itself on the same log and checks that it writes the same lines.
- ``woods``: Lost in the Woods, the whole run with known correspondence (the importer's
  defaults: keyframes of 10 samples, every reading, each record stamped with its time),
  replayed at its recorded pace (``--rate 1``: about 21 minutes): whether the session ever
  fell behind, how long after its time each instant was fed (the lag), and every Vicon
  pose against its box.
- ``paper``: the seed's experiment with the landmark ids dropped, followed online: the
  live hypotheses of its last line against the batch solve's survivors.
- ``lp``: the lines at level ``lp`` (the polytope hull on the window of the last poses)
  against those at ``hull``, and what the window costs: the seed's experiment with known
  correspondence and a 300-pose random world with 60 landmarks.

Runs are warm (numba's cache is filled before the clock starts). The machine's load is
recorded with every section: wall-clock figures are inflated on a busy machine, CPU
figures much less.

    python benchmarks/bench_online.py known [--poses 2000] [--seed 0] [--landmarks 10 60]
                                            [--repeats 3]
    python benchmarks/bench_online.py woods [--rate 1]
    python benchmarks/bench_online.py paper
    python benchmarks/bench_online.py lp [--lp-poses 300]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuikslam.budget import ONLINE_WORK_PER_POSE
from cuikslam.online.estimate import PoseEstimate
from cuikslam.online.follow import FollowReport, follow, log_lines
from cuikslam.online.session import Session

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "online.json"
CLI = [sys.executable, "-m", "cuikslam.cli.main"]


def _load() -> list[float]:
    return [round(v, 2) for v in os.getloadavg()]


def _stats(values: list[float], scale: float = 1000.0) -> dict[str, float]:
    """Median, 99th percentile and maximum, times ``scale`` (ms by default), rounded."""
    a = np.asarray(values, dtype=float) * scale
    return {
        "p50": round(float(np.percentile(a, 50)), 3),
        "p99": round(float(np.percentile(a, 99)), 3),
        "max": round(float(a.max()), 3),
    }


@dataclass
class Followed:
    """What following one log gave, and what it cost."""

    session: Session
    report: FollowReport
    estimates: list[PoseEstimate] = field(default_factory=list)
    cpu_s: list[float] = field(default_factory=list)
    """CPU seconds of each call that gave a box."""
    applications: list[int] = field(default_factory=list)
    """Operator applications of each such call."""
    settle_cpu_s: list[float] = field(default_factory=list)
    """CPU seconds of each call of ``Session.settle`` (the rest of the narrowing, the
    ``lp`` level's window)."""
    wall_s: float = 0.0
    cpu_total_s: float = 0.0


def follow_file(
    path: Path,
    rate: float | None = None,
    consistency: str = "hull",
    work_per_pose: float | None = ONLINE_WORK_PER_POSE,
) -> Followed:
    """Follow the log at ``path`` as ``cuikslam follow`` does, measuring each pose."""
    session = Session(path=str(path), consistency=consistency, work_per_pose=work_per_pose)
    out = Followed(session, FollowReport())
    add, settle = session.add, session.settle

    def measured_settle(until=None):
        started = time.thread_time()
        done = settle(until)
        out.settle_cpu_s.append(time.thread_time() - started)
        return done

    def measured_add(record, received=None):
        before, started = session.applications, time.thread_time()
        estimate = add(record, received=received)
        if estimate is not None:
            out.cpu_s.append(time.thread_time() - started)
            out.applications.append(session.applications - before)
        return estimate

    session.add = measured_add
    session.settle = measured_settle
    wall, cpu = time.perf_counter(), time.process_time()
    with open(path, encoding="utf-8") as stream:
        lines = log_lines(stream, path=str(path))
        out.report = follow(lines, session, out.estimates.append, rate=rate)
    out.wall_s, out.cpu_total_s = time.perf_counter() - wall, time.process_time() - cpu
    return out


def _width_ratio(online: np.ndarray, batch: np.ndarray) -> list[float | None]:
    """Online over batch width per coordinate (1 when equal, infinite ones included)."""
    out = []
    for (olo, ohi), (blo, bhi) in zip(online, batch, strict=True):
        w_online, w_batch = ohi - olo, bhi - blo
        out.append(1.0 if w_online == w_batch else round(float(w_online / w_batch), 6))
    return out


def _boxes(line: dict) -> dict:
    """A JSON line without its latency (the one field that differs from run to run)."""
    return {k: v for k, v in line.items() if k != "latency_s"}


def _wider(boxes: list[np.ndarray], fixpoint: list[np.ndarray]) -> tuple[int, list[float]]:
    """Boxes wider than at the fixpoint, and the largest ratio of widths per coordinate."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.diff(np.array(boxes)).squeeze(-1) / np.diff(np.array(fixpoint)).squeeze(-1)
    ratio = np.where(np.isfinite(ratio), ratio, 1.0)
    return int(np.sum(np.any(ratio > 1.0, axis=1))), [round(float(v), 4) for v in ratio.max(0)]


def run_known(poses: int, seed: int, landmarks: int, folder: Path, repeats: int = 1) -> dict:
    from cuikslam.log.reader import read_log_file
    from cuikslam.online.estimate import check_estimates
    from cuikslam.simulate.truth import read_truth_file
    from cuikslam.solver import solve

    log_path = folder / f"random-{poses}-{landmarks}.jsonl"
    subprocess.run(
        [*CLI, "simulate", "random", "--poses", str(poses), "--seed", str(seed),
         "--landmarks", str(landmarks), "-o", str(log_path), "-q"],
        check=True,
    )  # fmt: skip
    truth = read_truth_file(log_path.with_name(log_path.stem + ".truth.json"))
    log = read_log_file(log_path)
    load_before = _load()
    run = follow_file(log_path)
    load_after = _load()
    again = [follow_file(log_path) for _ in range(repeats - 1)]
    load_end = _load()
    fixpoint = follow_file(log_path, work_per_pose=None)
    wider, wider_ratio = _wider([e.box for e in run.estimates], [e.box for e in fixpoint.estimates])
    estimates = run.estimates
    verdict = check_estimates(estimates, truth)
    batch = solve(log, consistency="hull", certify_limit=0).hypotheses[0]
    last = estimates[-1]
    out_path = folder / "follow.jsonl"
    command = subprocess.run(
        [*CLI, "follow", str(log_path), "-o", str(out_path), "-q"], check=False
    )
    written = [_boxes(json.loads(line)) for line in out_path.read_text().splitlines()]
    same = written == [_boxes(e.to_json()) for e in estimates]
    return {
        "log": f"cuikslam simulate random --poses {poses} --seed {seed} --landmarks {landmarks}",
        "records": len(log.records),
        "observations": len(log.observations),
        "poses": len(log.pose_ids),
        "lines": len(estimates),
        "lines_in_order": [e.pose for e in estimates] == list(log.pose_order()),
        "truth_bounds_checked": verdict.checked,
        "truth_misses": len(verdict.misses),
        "latency_ms": _stats([e.latency_s for e in estimates]),
        "cpu_per_pose_ms": _stats(run.cpu_s),
        "applications_per_pose": _stats(run.applications, scale=1.0),
        "work_per_pose": run.session.work_per_pose,
        "latency_p99_ms_repeats": [
            _stats([e.latency_s for e in r.estimates])["p99"] for r in (run, *again)
        ],
        "latency_max_ms_repeats": [
            _stats([e.latency_s for e in r.estimates])["max"] for r in (run, *again)
        ],
        "cpu_p99_ms_repeats": [_stats(r.cpu_s)["p99"] for r in (run, *again)],
        "load_after_repeats": load_end,
        "lines_wider_than_fixpoint": wider,
        "max_width_ratio_to_fixpoint": wider_ratio,
        "fixpoint_latency_ms": _stats([e.latency_s for e in fixpoint.estimates]),
        "fixpoint_cpu_per_pose_ms": _stats(fixpoint.cpu_s),
        "total_s": round(run.wall_s, 2),
        "total_cpu_s": round(run.cpu_total_s, 2),
        "last_pose": last.pose,
        "last_widths_online": [float(w) for w in np.diff(last.box).ravel()],
        "last_widths_batch": [float(w) for w in np.diff(batch.pose(last.pose)).ravel()],
        "last_width_ratio": _width_ratio(last.box, batch.pose(last.pose)),
        "command_exit": command.returncode,
        "command_lines_identical": same,
        "load_before": load_before,
        "load_after": load_after,
    }


def run_woods(rate: float, folder: Path) -> dict:
    from cuikslam.datasets import data_dir, read_lost_in_the_woods
    from cuikslam.log.writer import write_log_file
    from cuikslam.online.estimate import check_estimates

    source = (data_dir() or Path("missing")) / "lost-in-the-woods" / "dataset2.mat"
    if not source.is_file():
        sys.exit("dataset2.mat not found: set CUIKSLAM_DATA")
    log, truth = read_lost_in_the_woods(source, unknown=False)
    log_path = folder / "woods.jsonl"
    write_log_file(log, log_path, validate=False)
    stamps = [r.time for r in log.records if r.time is not None]
    load_before = _load()
    run = follow_file(log_path, rate)
    load_after = _load()
    report, estimates = run.report, run.estimates
    verdict = check_estimates(estimates, truth)
    return {
        "log": "cuikslam import lost-in-the-woods dataset2.mat --known (keyframe 10, every "
        "reading)",
        "rate": rate,
        "records": len(log.records),
        "poses": len(log.pose_ids),
        "recorded_s": round(stamps[-1] - stamps[0], 2),
        "replay_s": round(run.wall_s, 2),
        "cpu_s": round(run.cpu_total_s, 2),
        "time_stamps": report.instants,
        "behind": report.late,
        "worst_late_ms": round(1000 * report.worst_late_s, 3),
        "worst_late_line": report.worst_late_line,
        "lag_ms": _stats(report.lags_s),
        "lag_over_10ms": sum(lag > 0.010 for lag in report.lags_s),
        "lines": len(estimates),
        "vicon_poses_checked": verdict.checked // 3,
        "truth_misses": len(verdict.misses),
        "latency_ms": _stats([e.latency_s for e in estimates]),
        "cpu_per_pose_ms": _stats(run.cpu_s),
        "load_before": load_before,
        "load_after": load_after,
    }


def _save(section: str, value: object) -> None:
    results = json.loads(RESULTS.read_text()) if RESULTS.is_file() else {}
    results[section] = value
    RESULTS.write_text(json.dumps(results, indent=1) + "\n")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("section", choices=["known", "woods", "paper", "lp"])
    parser.add_argument("--poses", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--landmarks", type=int, nargs="+", default=[10, 60])
    parser.add_argument("--repeats", type=int, default=3, help="known: runs of each log")
    parser.add_argument("--rate", type=float, default=1.0, help="woods: replay pace")
    parser.add_argument("--lp-poses", type=int, default=300, help="lp: the random world's poses")
    args = parser.parse_args(argv)
    from cuikslam.online.session import warm_up as warm_up_online
    from cuikslam.solver import warm_up

    warm_up(unknown=args.section == "paper", lp=args.section == "lp")
    warm_up_online(unknown=args.section == "paper", lp=args.section == "lp")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.section == "known":
            rows = [
                run_known(args.poses, args.seed, n, folder, args.repeats) for n in args.landmarks
            ]
            for row in rows:
                print(json.dumps(row))
            _save("known", {"date": time.strftime("%Y-%m-%d %H:%M"), "runs": rows})
        elif args.section == "woods":
            row = run_woods(args.rate, folder)
            print(json.dumps(row))
            _save("woods", {"date": time.strftime("%Y-%m-%d %H:%M"), **row})
        elif args.section == "paper":
            row = run_paper(folder)
            print(json.dumps(row))
            _save("paper", {"date": time.strftime("%Y-%m-%d %H:%M"), **row})
        else:
            rows = run_lp(folder, args.lp_poses)
            for row in rows:
                print(json.dumps(row))
            _save("lp", {"date": time.strftime("%Y-%m-%d %H:%M"), "runs": rows})


def run_paper(folder: Path) -> dict:
    from cuikslam.log.writer import write_log_file
    from cuikslam.online.estimate import check_estimates
    from cuikslam.results.association import partition
    from cuikslam.simulate.paper import simulate_paper
    from cuikslam.solver import solve

    log, truth = simulate_paper(seed=0, unknown=True)
    log_path = folder / "paper-unknown.jsonl"
    write_log_file(log, log_path)
    load_before = _load()
    run = follow_file(log_path)
    load_after = _load()
    online = sorted(partition(a, set()) for a in run.session.assignments())
    batch = {}
    for level in ("auto", "hull"):
        solution = solve(log, consistency=level)
        survivors = sorted(partition(h.assignment, set()) for h in solution.hypotheses)
        batch[level] = {
            "survivors": solution.statistics["survivors"],
            "complete": solution.complete,
            "same_as_online": survivors == online,
        }
    return {
        "log": "cuikslam.simulate.paper.simulate_paper(seed=0, unknown=True)",
        "poses": len(log.pose_ids),
        "observations": len(log.observations),
        "hypotheses_per_line": [e.hypotheses for e in run.estimates],
        "last_line_hypotheses": run.estimates[-1].hypotheses,
        "batch": batch,
        "truth_misses": len(check_estimates(run.estimates, truth).misses),
        "latency_ms": _stats([e.latency_s for e in run.estimates]),
        "cpu_per_pose_ms": _stats(run.cpu_s),
        "load_before": load_before,
        "load_after": load_after,
    }


def run_lp(folder: Path, poses: int) -> list[dict]:
    """Lines at ``lp`` against lines at ``hull``: the seed's experiment (known
    correspondence) and a dense random world of ``poses`` poses."""
    from cuikslam.log.writer import write_log_file
    from cuikslam.simulate.paper import simulate_paper

    log, _ = simulate_paper(seed=0)
    paper = folder / "paper.jsonl"
    write_log_file(log, paper)
    dense = folder / f"random-{poses}-60.jsonl"
    subprocess.run(
        [*CLI, "simulate", "random", "--poses", str(poses), "--seed", "0",
         "--landmarks", "60", "-o", str(dense), "-q"],
        check=True,
    )  # fmt: skip
    rows = []
    for name, path in (("simulate_paper(seed=0)", paper), (f"random {poses} poses", dense)):
        runs = {level: follow_file(path, consistency=level) for level in ("hull", "lp")}
        widths = {
            level: np.diff(np.array([e.box for e in run.estimates])).squeeze(-1)
            for level, run in runs.items()
        }
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = widths["lp"] / widths["hull"]
        rows.append(
            {
                "log": name,
                "poses": len(widths["hull"]),
                "median_width_ratio_lp_to_hull": [
                    round(float(v), 3) for v in np.nanmedian(ratio, axis=0)
                ],
                "last_widths_hull": [round(float(v), 4) for v in widths["hull"][-1]],
                "last_widths_lp": [round(float(v), 4) for v in widths["lp"][-1]],
                "settle_cpu_per_pose_ms": {
                    level: _stats(run.settle_cpu_s) for level, run in runs.items()
                },
                "latency_ms": {
                    level: _stats([e.latency_s for e in run.estimates])
                    for level, run in runs.items()
                },
                "load": _load(),
            }
        )
    return rows


if __name__ == "__main__":
    main()
