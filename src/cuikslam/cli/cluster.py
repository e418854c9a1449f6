"""``cuikslam solve`` on a Dask cluster (``--workers N``, ``--scheduler ADDRESS``) and on
several logs at once.

One log: its correspondence search runs on the cluster
(:func:`cuikslam.hypotheses.distributed.search_distributed`); everything else is
``cuikslam solve`` as usual. Several logs: each is solved whole by one worker
(:func:`~cuikslam.hypotheses.distributed.solve_batch`), or one after the other without a
cluster; ``--json DIR`` and ``--csv DIR`` then name folders, and each log's result is
``DIR/NAME.json`` (``NAME.csv``), NAME being the log's file name without ``.jsonl``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from functools import partial
from pathlib import Path

from rich.console import Console

from cuikslam.cli._common import CommandError, write_output
from cuikslam.cli._messages import worded
from cuikslam.cluster import INSTALL_HINT
from cuikslam.log.reader import read_log_file
from cuikslam.log.records import Log
from cuikslam.options import SolveOptions

__all__ = ["output_name", "run_solve_cluster"]


def output_name(log_path: str) -> str:
    """The name of a log's results in an output folder: its file name without ``.jsonl``."""
    name = Path(log_path).name
    return name[: -len(".jsonl")] if name.endswith(".jsonl") else Path(name).stem


def _require_dask(option: str) -> None:
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise CommandError(f"{option} {INSTALL_HINT}") from None


def _output_folder(path: str | None, option: str) -> Path | None:
    """``--json``/``--csv`` with several logs: a folder, created when missing."""
    if path is None:
        return None
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise CommandError(f"{path}: with several logs {option} names a folder, not a file")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise CommandError(f"{path}: cannot create the folder: {err.strerror or err}") from None
    return folder


def run_solve_cluster(
    *,
    log_paths: Sequence[str],
    workers: int | None,
    scheduler: str | None,
    json_path: str | None,
    csv_path: str | None,
    truth_path: str | None,
    quiet: bool,
    console: Console,
    table: bool | None,
    options: SolveOptions,
    started: float | None,
    survivors_path: str | None,
) -> int:
    """``cuikslam solve`` with ``--workers``/``--scheduler`` or several logs."""
    cluster = workers is not None or scheduler is not None
    if cluster:
        _require_dask("--scheduler" if scheduler is not None else "--workers")
    if len(log_paths) == 1:
        from cuikslam.cli.solve import run_solve

        run = partial(
            run_solve, log_path=log_paths[0], json_path=json_path, csv_path=csv_path,
            truth_path=truth_path, quiet=quiet, console=console, table=table, options=options,
            survivors_path=survivors_path,
        )  # fmt: skip
        if not cluster:
            return run(started=started)
        from cuikslam.cluster import dask_client
        from cuikslam.hypotheses.distributed import search_distributed

        connecting = time.perf_counter()
        with dask_client(workers, scheduler) as client:
            if started is not None:  # the cluster's start-up is not taken from the solve
                started += time.perf_counter() - connecting
            return run(started=started, search=partial(search_distributed, client=client))
    for option, value in (("--truth", truth_path), ("--survivors", survivors_path)):
        if value is not None:
            raise CommandError(f"{option} takes one log; {len(log_paths)} were given")
    names = [output_name(p) for p in log_paths]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice and (json_path or csv_path):
        raise CommandError(f"two logs would write the same results: {', '.join(twice)}")
    json_dir = _output_folder(json_path, "--json")
    csv_dir = _output_folder(csv_path, "--csv")
    logs = [read_log_file(p) for p in log_paths]  # every log checked before any work
    return _solve_logs(
        logs, log_paths, names, workers, scheduler, json_dir, csv_dir, quiet, console, table,
        options,
    )  # fmt: skip


def _solve_logs(
    logs: list[Log],
    log_paths: Sequence[str],
    names: list[str],
    workers: int | None,
    scheduler: str | None,
    json_dir: Path | None,
    csv_dir: Path | None,
    quiet: bool,
    console: Console,
    table: bool | None,
    options: SolveOptions,
) -> int:
    from cuikslam.cli.solve import print_solution
    from cuikslam.results.io import write_result_csv, write_result_file
    from cuikslam.solver import solve

    if workers is None and scheduler is None:
        solutions = [solve(log, options) for log in logs]
    else:
        from cuikslam.cluster import dask_client, solve_batch

        with dask_client(workers, scheduler) as client:
            solutions = solve_batch(logs, client, options=options)
    status = 0
    for path, name, solution in zip(log_paths, names, solutions, strict=True):
        outputs = []
        if json_dir is not None:
            target = json_dir / f"{name}.json"
            write_output(target, partial(write_result_file, solution, target))
            outputs.append(str(target))
        if csv_dir is not None:
            target = csv_dir / f"{name}.csv"
            write_output(target, partial(write_result_csv, solution, target))
            outputs.append(str(target))
        console.print(f"== {path}", highlight=False, markup=False)
        if quiet:
            for message in solution.messages:
                console.print(worded(message))
        else:
            print_solution(solution, console, table=table, outputs=outputs)
        if solution.refuted:
            status = 1
    return status
