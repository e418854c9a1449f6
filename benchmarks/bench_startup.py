"""Benchmark: the whole ``cuikslam paper`` command, warm and cold, and where its time goes.

Three parts, each run as whole processes (``--part``, default all):

``whole``
    ``cuikslam paper --figure TMP.png`` timed by wall clock and child CPU: first with an
    empty numba cache (``NUMBA_CACHE_DIR`` set to a new temporary folder: the first run
    after a fresh install, **cold**), then ``--repeat`` times with that folder filled
    (**warm**). ``--skip-cold`` uses the project's own cache instead (warm only).
``breakdown``
    One warm run of the same command in a fresh interpreter, its stages timed from
    inside: imports (the CLI, then what ``paper`` imports), the compiled kernels loaded
    from numba's cache (``solver.warm_up``), each solve (narrowing/search, bisection of
    the survivors, witness search), the terminal tables and the figure (matplotlib's
    import, drawing, saving). Each second goes to the innermost stage running (the
    bisection is not counted again in the search, nor the warm-up's tiny search). What
    the process spends outside (the interpreter's start and exit) is the whole wall time
    minus what the stages account for.
``importtime``
    The slowest imports of ``python -X importtime`` (cumulative) for the ``paper`` path.
``--fresh-install``
    Not a part: what a user sees. A new venv, ``pip install SOURCE`` timed (by default
    SOURCE is this repository's ``HEAD``, exported with ``git archive``; ``--source DIR``
    takes a tree as it is), then ``cuikslam paper`` three times (``--repeat``) in a temporary
    folder, each run marked cold when it says it compiled the kernels, else warm.
    ``--no-kernel-cache`` builds with ``CUIKSLAM_BUILD_KERNEL_CACHE=0`` (the wheel without
    compiled kernels, as before the build hook): the A/B.

The load average is printed with every figure (the machine is shared). Results go to
``benchmarks/results/startup.json``.

    python benchmarks/bench_startup.py [--part whole|breakdown|importtime] [--repeat 3]
        [--paper-args "--time-budget 60"] [--skip-cold]
    python benchmarks/bench_startup.py --fresh-install [--source DIR] [--no-kernel-cache]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

# Runs in the child: wraps the stages of ``cuikslam paper`` with timers, then runs it.
_CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
stages = dict()
import cuikslam.cli.main as cli_main
stages["import cli"] = time.perf_counter() - t0
t = time.perf_counter()
import cuikslam.cli.paper as paper
stages["import solver (paper path)"] = time.perf_counter() - t
active = []  # the stages entered, innermost last: time goes to the innermost only
mark = [0.0]

def charge(now):
    if active:
        stages[active[-1]] = stages.get(active[-1], 0.0) + now - mark[0]
    mark[0] = now

def timed(owner, name, key):
    inner = getattr(owner, name)
    def wrapper(*args, **kwargs):
        charge(time.perf_counter())
        active.append(key(*args) if callable(key) else key)
        try:
            return inner(*args, **kwargs)
        finally:
            charge(time.perf_counter())
            active.pop()
    setattr(owner, name, wrapper)

import cuikslam.solver as solver
import cuikslam.hypotheses.explorer as explorer
import cuikslam.hypotheses.finish as finish
timed(solver, "warm_up", "kernels loaded (warm_up)")
timed(solver, "certify", lambda log, *a: "witness search " + (
    "(unknown)" if log.has_unknown_correspondence else "(known)"))
timed(finish, "refute_by_bisection", "bisection")
timed(explorer, "refute_by_bisection", "bisection")
timed(solver, "solve_unknown", "search (+ lp on survivors)")
timed(solver, "_solve_known", "known correspondence (hull + lp)")
timed(paper, "simulate_paper", "simulate")
timed(paper.Console, "print", "tables")
FIGURE = __FIGURE__
if FIGURE:
    t = time.perf_counter()
    import cuikslam.results.figures as figures
    stages["figure: import"] = time.perf_counter() - t
    timed(figures, "plot_known_and_unknown", "figure: draw (matplotlib imported)")
    timed(figures, "save_figure", "figure: save")
    import cuikslam.cli.figure_job as figure_job
    timed(figure_job.FigureJob, "finish", "figure: waiting for the child")
    stages["figure drawn by a child process"] = 0.0 if not figure_job.spare_core() else -1.0
status = cli_main.main(__ARGV__)
stages["in process"] = time.perf_counter() - t0
sys.stdout.flush()
print("STAGES", json.dumps(stages), file=sys.stderr)
sys.stderr.flush()
import os
os._exit(status)  # as the cuikslam entry point does
"""


def load() -> str:
    """The load averages (1, 5, 15 min) as a string."""
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def run_process(
    argv: list[str], env: dict[str, str] | None = None, cwd: Path | None = None
) -> dict[str, float | str]:
    """Run ``argv`` to the end; its wall clock, child CPU seconds, stderr and load."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, env=env, check=False, cwd=cwd)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"{argv} exited with {done.returncode}: {done.stderr[-2000:]}")
    user = after.ru_utime - before.ru_utime
    return {
        "wall_s": wall,
        "cpu_s": user + after.ru_stime - before.ru_stime,
        "user_s": user,
        "load": load(),
        "stdout": done.stdout,
        "stderr": done.stderr,
    }


def paper_command(figure: Path, extra: list[str], venv: Path | None = None) -> list[str]:
    """``cuikslam paper`` as a user types it (the installed entry point, or ``venv``'s)."""
    if venv is not None:
        return [str(venv / "bin" / "cuikslam"), "paper", "--figure", str(figure), *extra]
    exe = shutil.which("cuikslam") or sys.executable
    head = [exe] if exe != sys.executable else [exe, "-m", "cuikslam.cli.main"]
    return [*head, "paper", "--figure", str(figure), *extra]


def part_whole(repeat: int, extra: list[str], skip_cold: bool, tmp: Path) -> dict:
    """Cold then warm whole-command runs.

    Python writes its byte-code caches as a user's would (``PYTHONDONTWRITEBYTECODE`` is
    dropped: with it, every module edited since its ``.pyc`` was written is compiled again
    on every run, about 0.05 s here)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    rows: dict[str, list[dict]] = {"cold": [], "warm": []}
    if not skip_cold:
        env["NUMBA_CACHE_DIR"] = str(tmp / "numba-cache")
        rows["cold"].append(run_process(paper_command(tmp / "cold.png", extra), env))
    else:
        run_process(paper_command(tmp / "fill.png", extra), env)  # fill the cache
    for i in range(repeat):
        rows["warm"].append(run_process(paper_command(tmp / f"warm{i}.png", extra), env))
    for kind, runs in rows.items():
        for run in runs:
            run.pop("stderr")
            summary = [ln for ln in str(run.pop("stdout")).splitlines() if "undecided" in ln]
            run["undecided_line"] = summary[0] if summary else ""
            print(
                f"{kind:5s} wall {run['wall_s']:6.2f} s  CPU {run['cpu_s']:6.2f} s  "
                f"load {run['load']}"
            )
    warm = [r["wall_s"] for r in rows["warm"]]
    if warm:
        print(f"warm median wall {statistics.median(warm):.2f} s (best {min(warm):.2f} s)")
    return rows


def part_breakdown(extra: list[str], tmp: Path) -> dict:
    """One warm run with its stages timed from inside."""
    figure = str(tmp / "breakdown.png")
    argv = ["paper", "--figure", figure, *extra]
    run_process(paper_command(Path(figure), extra))  # the cache is warm afterwards
    code = _CHILD.replace("__FIGURE__", repr(figure)).replace("__ARGV__", repr(argv))
    run = run_process([sys.executable, "-c", code])
    lines = [ln for ln in str(run["stderr"]).splitlines() if ln.startswith("STAGES ")]
    if not lines:
        raise RuntimeError(str(run["stderr"])[-2000:])
    stages: dict[str, float] = json.loads(lines[-1][len("STAGES ") :])
    wall = float(run["wall_s"])
    inside = stages.pop("in process")
    in_child = stages.pop("figure drawn by a child process", 0.0) < 0
    accounted = sum(stages.values())
    stages["other (argparse, solve set-up, json)"] = inside - accounted
    stages["interpreter start and exit"] = wall - inside
    where = "a child process" if in_child else "this process"
    print(f"breakdown of one warm run: wall {wall:.2f} s, load {run['load']}; figure in {where}")
    for name, seconds in stages.items():
        print(f"  {name:36s} {seconds:6.3f} s")
    return {"wall_s": wall, "load": run["load"], "figure_child": in_child, "stages_s": stages}


def part_importtime(top: int = 15) -> list[tuple[str, float]]:
    """The slowest packages (cumulative import time, at any depth) on the ``paper`` path."""
    code = "import cuikslam.cli.main, cuikslam.cli.paper"
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", code], capture_output=True, text=True
    )
    total, own, packages = 0.0, 0.0, {}
    for line in done.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        self_us, cumulative, name = line[len("import time:") :].split("|")
        seconds = int(cumulative) / 1e6
        if not name[1:].startswith(" "):  # imported by the probe itself
            total += seconds
        name = name.strip()
        if name.split(".")[0] == "cuikslam":
            own += int(self_us) / 1e6
        elif "." not in name or (name.startswith("scipy.") and name.count(".") == 1):
            packages[name] = max(seconds, packages.get(name, 0.0))
    packages["cuikslam's own modules (their self time)"] = own
    rows = sorted(packages.items(), key=lambda r: -r[1])[:top]
    print(f"imports of the paper path: {total:.2f} s in all (load {load()}); slowest:")
    for name, seconds in rows:
        print(f"  {name:42s} {seconds:6.3f} s")
    return rows


def fresh_install(source: Path | None, repeat: int, kernel_cache: bool, tmp: Path) -> dict:
    """A new venv, ``pip install SOURCE`` timed, then ``repeat`` runs of ``cuikslam paper``."""
    commit = None
    if source is None:  # the committed state, not a half-edited working tree
        source = tmp / "src"
        source.mkdir()
        git = ["git", "-C", str(HERE.parent)]
        revision = [*git, "rev-parse", "--short", "HEAD"]
        done = subprocess.run(revision, capture_output=True, text=True, check=True)
        commit = done.stdout.strip()
        archive = subprocess.run([*git, "archive", commit], capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(source)], input=archive.stdout, check=True)
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["CUIKSLAM_BUILD_KERNEL_CACHE"] = "1" if kernel_cache else "0"
    load_before = load()
    install = run_process([str(venv / "bin" / "pip"), "install", "-q", str(source)], env, tmp)
    install.pop("stdout"), install.pop("stderr")
    install["load_before"] = load_before
    label = "with" if kernel_cache else "without"
    print(
        f"pip install ({label} the kernel cache): wall {install['wall_s']:6.2f} s  "
        f"user {install['user_s']:6.2f} s  load {load_before} -> {install['load']}"
    )
    runs = []
    for i in range(repeat):
        run = run_process(paper_command(tmp / f"run{i}.png", [], venv), env, tmp)
        run["kind"] = "cold" if "compiled the kernels" in str(run.pop("stderr")) else "warm"
        run.pop("stdout")
        runs.append(run)
        print(
            f"run {i + 1} ({run['kind']}): wall {run['wall_s']:6.2f} s  "
            f"user {run['user_s']:6.2f} s  load {run['load']}"
        )
    return {
        "source": commit or str(source),
        "kernel_cache": kernel_cache,
        "install": install,
        "runs": runs,
    }


def main(argv: list[str] | None = None) -> int:
    """Run the parts asked for and write ``benchmarks/results/startup.json``."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--part", choices=["all", "whole", "breakdown", "importtime"])
    parser.add_argument("--repeat", type=int, default=3, help="warm whole-command runs")
    parser.add_argument("--paper-args", default="", help="more arguments for cuikslam paper")
    parser.add_argument("--skip-cold", action="store_true", help="no cold run")
    parser.add_argument("--json", type=Path, default=HERE / "results" / "startup.json")
    parser.add_argument("--fresh-install", action="store_true", help="time a new venv's install")
    parser.add_argument("--source", type=Path, help="tree to install (default: HEAD's export)")
    parser.add_argument("--no-kernel-cache", action="store_true", help="build without kernels")
    args = parser.parse_args(argv)
    part = args.part or "all"
    if args.fresh_install:
        part = "fresh install " + ("no kernel cache" if args.no_kernel_cache else "kernel cache")
    extra = shlex.split(args.paper_args)
    result: dict = {
        "command": f"cuikslam paper {args.paper_args}".strip(),
        "python": platform.python_version(),
        "cpus": os.cpu_count(),
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
    }
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        if args.fresh_install:
            source = args.source.resolve() if args.source else None
            kernel_cache = not args.no_kernel_cache
            result["fresh_install"] = fresh_install(source, args.repeat, kernel_cache, tmp)
        if part in ("all", "importtime"):
            result["importtime"] = part_importtime()
        if part in ("all", "whole"):
            result["whole"] = part_whole(args.repeat, extra, args.skip_cold, tmp)
        if part in ("all", "breakdown"):
            result["breakdown"] = part_breakdown(extra, tmp)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    previous = json.loads(args.json.read_text()) if args.json.exists() else {}
    key = f"{result['command']} [{part}]"
    previous[key] = result
    args.json.write_text(json.dumps(previous, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
