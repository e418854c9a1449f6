"""``cuikslam solve``: solve a log, print its table, write JSON/CSV, check against truth."""

from __future__ import annotations

from rich.console import Console

from cuikslam.cli._common import check_output_path, write_output
from cuikslam.log.reader import read_log_file
from cuikslam.results.io import write_result_csv, write_result_file
from cuikslam.results.solution import Solution, check_truth
from cuikslam.results.table import hypothesis_table, summary_table
from cuikslam.simulate.truth import GroundTruth, read_truth_file

__all__ = ["print_solution", "report_truth", "run_solve"]


def print_solution(solution: Solution, console: Console, max_tables: int = 10) -> None:
    """Print every hypothesis (up to ``max_tables`` full tables) in the seed's layout."""
    for message in solution.messages:
        console.print(message)
    if not solution.hypotheses:
        return
    if len(solution.hypotheses) > 1:
        console.print(summary_table(solution))
    for rank, h in enumerate(solution.hypotheses[:max_tables], start=1):
        title = (
            f"Hypothesis {rank} of {len(solution.hypotheses)}: "
            f"{h.n_landmarks} landmarks, {h.status}"
        )
        console.print(hypothesis_table(h, title))
    if len(solution.hypotheses) > max_tables:
        console.print(
            f"… {len(solution.hypotheses) - max_tables} more hypotheses in the JSON result"
        )


def report_truth(solution: Solution, truth: GroundTruth, console: Console) -> bool:
    """Print whether the boxes contain the truth; True when they all do.

    The hypothesis whose assignment is the true one is checked in full (poses and
    landmarks); others only on poses. Without a true hypothesis among the survivors the
    guarantee is broken, and this says so.
    """
    landmark_xy = dict(zip(truth.landmark_ids, truth.landmarks_xy, strict=True))
    ok = True
    true_found = False
    for rank, h in enumerate(solution.hypotheses, start=1):
        is_true = list(h.assignment) == list(truth.assignment)
        true_found |= is_true
        report = check_truth(h, truth.pose_ids, truth.poses_xyt, landmark_xy if is_true else None)
        if not report.ok:
            ok = False
            console.print(f"hypothesis {rank}: {len(report.misses)} boxes miss the truth:")
            for miss in report.misses[:20]:
                console.print(f"  {miss}")
    if truth.assignment and not true_found and solution.complete:
        ok = False
        console.print("the true correspondence is not among the surviving hypotheses")
    if ok:
        console.print(
            f"truth check: every box of {len(solution.hypotheses)} hypotheses contains the truth"
        )
    return ok


def run_solve(
    *,
    log_path: str,
    json_path: str | None,
    csv_path: str | None,
    truth_path: str | None,
    quiet: bool,
    console: Console,
) -> int:
    # Everything that can be refused is checked before the solve (and before the solver,
    # slow to import, is loaded): a bad log or output path fails fast and writes nothing.
    for path in (json_path, csv_path):
        if path:
            check_output_path(path)
    log = read_log_file(log_path)
    truth = read_truth_file(truth_path) if truth_path else None

    from cuikslam.solver import solve

    solution = solve(log)
    if json_path:
        write_output(json_path, lambda: write_result_file(solution, json_path))
    if csv_path:
        write_output(csv_path, lambda: write_result_csv(solution, csv_path))
    if not quiet:
        print_solution(solution, console)
    else:  # no tables, but what the solve found out (e.g. "the log is inconsistent") is kept
        for message in solution.messages:
            console.print(message)
    status = 0
    if truth is not None and not report_truth(solution, truth, console):
        status = 1
    if solution.refuted:
        status = 1
    return status
