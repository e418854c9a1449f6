"""``cuikslam solve``: solve a log, print its table, write JSON/CSV, check against truth."""

from __future__ import annotations

import json
from collections.abc import Callable, Collection, Iterator, Sequence
from contextlib import contextmanager

from rich.console import Console

from cuikslam._atomic import atomic_open
from cuikslam.cli._common import (
    EXIT_INTERRUPTED,
    CommandError,
    check_output_path,
    progress_bar,
    write_output,
)
from cuikslam.cli._messages import worded
from cuikslam.cli.warm_up import note_compiling
from cuikslam.log.reader import read_log_file
from cuikslam.options import SolveOptions
from cuikslam.outcome.solution import Solution
from cuikslam.results.association import named_landmarks, true_outliers, truth_verdict
from cuikslam.results.io import write_result_csv, write_result_file
from cuikslam.results.measurement_check import check_log
from cuikslam.results.overview import envelope_lines, overview_lines
from cuikslam.results.table import hypothesis_table, summary_table
from cuikslam.simulate.truth import GroundTruth, check_truth_fits, read_truth_file

__all__ = ["TABLE_MAX_POSES", "print_solution", "report_truth", "run_solve"]


TABLE_MAX_POSES = 60
"""Results with more poses than this get an overview on the terminal, not every row."""
SUMMARY_ROWS = 20
"""Hypotheses listed (and observations of each assignment shown) in an overview."""


def print_solution(
    solution: Solution,
    console: Console,
    max_tables: int = 10,
    *,
    table: bool | None = None,
    outputs: Sequence[str] = (),
) -> None:
    """Print the hypotheses: full tables in the seed's layout, or an overview.

    Parameters
    ----------
    solution : Solution
        What the solve found.
    console : Console
        Where to print.
    max_tables : int
        Full tables printed at most (the best-ranked hypotheses).
    table : bool or None
        True: full tables; False: an overview of the best hypothesis; None (default):
        full tables when the result has at most :data:`TABLE_MAX_POSES` poses.
    outputs : sequence of str
        Files that hold every box (named in the overview).
    """
    for message in solution.messages:
        console.print(worded(message))
    if solution.envelope is not None and (not solution.complete or len(solution.hypotheses) != 1):
        for line in envelope_lines(solution.envelope, solution.complete):
            console.print(line, highlight=False, markup=False)
    if not solution.hypotheses:
        return
    if table is None:
        table = max(len(h.pose_ids) for h in solution.hypotheses) <= TABLE_MAX_POSES
    n = len(solution.hypotheses)
    if n > 1:
        console.print(summary_table(solution, limit=None if table else SUMMARY_ROWS))
        if not table and n > SUMMARY_ROWS:
            console.print(f"… {n - SUMMARY_ROWS:,} more hypotheses in the result files")
    shown = solution.hypotheses[: max_tables if table else 1]
    for rank, h in enumerate(shown, start=1):
        outliers = f"{len(h.outliers)} outliers, " if h.outliers else ""
        title = f"Hypothesis {rank} of {n}: {h.n_landmarks} landmarks, {outliers}{h.status}"
        if table:
            console.print(hypothesis_table(h, title))
        else:
            for line in overview_lines(h, title):
                console.print(line, highlight=False, markup=False)
    if not table:
        where = " and ".join(outputs) if outputs else "no file (give --json or --csv)"
        console.print(
            f"every box: {where}; --table prints them all here", highlight=False, markup=False
        )
    elif n > max_tables:
        console.print(f"… {n - max_tables} more hypotheses in the JSON result")


def report_truth(
    solution: Solution,
    truth: GroundTruth,
    console: Console,
    named: set[str] = frozenset(),
    outside: Collection[int] = (),
    unchecked: Collection[int] = (),
) -> bool:
    """Print :func:`~cuikslam.results.association.truth_verdict`; True when the guarantee
    held (``outside``, ``unchecked``: see :func:`~cuikslam.results.association.true_outliers`)."""
    verdict = truth_verdict(solution, truth, named, outside, unchecked)
    for line in verdict.lines:
        console.print(worded(line))
    return verdict.ok


@contextmanager
def _survivor_stream(
    path: str | None,
) -> Iterator[Callable[[list[str]], None] | None]:
    """A callback writing each survivor's assignment to ``path`` as one JSON line, as the
    search finds it (memory stays flat however many survive); the file appears complete
    at the end of the solve, or not at all."""
    if path is None:
        yield None
        return
    try:
        with atomic_open(path) as out:

            def write(assignment: list[str]) -> None:
                out.write(json.dumps({"assignment": assignment}) + "\n")

            yield write
    except OSError as err:
        raise CommandError(f"{path}: cannot write: {err.strerror or err}") from None


def run_solve(
    *,
    log_path: str,
    json_path: str | None,
    csv_path: str | None,
    truth_path: str | None,
    quiet: bool,
    console: Console,
    table: bool | None = None,
    options: SolveOptions | None = None,
    started: float | None = None,
    survivors_path: str | None = None,
    search: Callable[..., Solution] | None = None,
) -> int:
    # Everything that can be refused is checked before the solve (and before the solver,
    # slow to import, is loaded): a bad log or output path fails fast and writes nothing.
    for path in (json_path, csv_path, survivors_path):
        if path:
            check_output_path(path)
    log = read_log_file(log_path)
    truth = read_truth_file(truth_path) if truth_path else None
    if truth is not None:
        check_truth_fits(truth, truth_path, log)

    from cuikslam.solver import solve

    with (
        progress_bar("solving", enabled=not quiet) as progress,
        _survivor_stream(survivors_path) as on_survivor,
    ):
        solution = solve(
            log,
            options,
            progress=progress,
            on_survivor=on_survivor,
            search=search,
        )
    note_compiling(solution.timings)
    if json_path:
        write_output(json_path, lambda: write_result_file(solution, json_path))
    if csv_path:
        write_output(csv_path, lambda: write_result_csv(solution, csv_path))
    if not quiet:
        outputs = [str(path) for path in (json_path, csv_path) if path]
        print_solution(solution, console, table=table, outputs=outputs)
    else:  # no tables, but what the solve found out (e.g. "the log is inconsistent") is kept
        for message in solution.messages:
            console.print(worded(message))
    status = 0
    outside: list[int] = []  # with an outliers declaration, the true outliers
    unchecked: list[int] = []
    applies = True  # the truth meets the log's declaration, so the guarantee applies
    if truth is not None and log.outlier_bounds:
        from cuikslam.outliers import check_declaration

        found = check_log(log, truth)
        applies, why = check_declaration(log, found.outside_observations, found.moves)
        if not applies:
            console.print(f"truth check: no guarantee applies: {why}")
        outside, unchecked = true_outliers(log, found)
    if (
        truth is not None
        and not report_truth(solution, truth, console, named_landmarks(log), outside, unchecked)
        and applies
    ):
        status = 1
    if solution.refuted:
        status = 1
    if solution.statistics.get("budget_bound") == "interrupt":
        status = EXIT_INTERRUPTED
    return status
