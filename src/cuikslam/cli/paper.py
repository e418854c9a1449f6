"""``cuikslam paper``: the seed paper's experiment, solved and compared with its Table 1."""

from __future__ import annotations

import sys

from rich.console import Console
from rich.table import Table

from cuikslam.cli._common import check_figure_path, check_output_path, write_output
from cuikslam.cli._messages import worded
from cuikslam.cli.figure_job import start_figure
from cuikslam.cli.warm_up import note_compiling
from cuikslam.options import SolveOptions
from cuikslam.outcome.solution import PROVEN, Solution
from cuikslam.results.association import truth_verdict
from cuikslam.results.io import write_result_file
from cuikslam.results.table import comparison_table, hypothesis_rows, hypothesis_table
from cuikslam.simulate.paper import PAPER_SURVIVORS, paper_table1, simulate_paper
from cuikslam.simulate.truth import GroundTruth
from cuikslam.solver import solve

__all__ = ["run_paper"]


def _report_truth(solution: Solution, truth: GroundTruth, console: Console) -> bool:
    verdict = truth_verdict(solution, truth)
    for line in verdict.lines:
        console.print(worded(line))
    return verdict.ok


def _report_unknown(solution: Solution, truth: GroundTruth, console: Console) -> bool:
    """The experiment without landmark ids: the seed's Tables 2-6 question."""
    stats = solution.statistics
    table = Table(
        title="Unknown correspondence: the robot cannot tell the doors (or the corridors) apart",
        title_justify="left",
    )
    table.add_column("")
    table.add_column("cuikslam", justify="right")
    table.add_column("seed paper", justify="right")
    table.add_row(
        "surviving hypotheses", str(len(solution.hypotheses)), str(PAPER_SURVIVORS["hypotheses"])
    )
    pairs = PAPER_SURVIVORS["label_swapped_pairs"]
    table.add_row(
        "survivors that differ only in labels",
        "0 (never created)",
        f"{2 * pairs} ({pairs} pairs)",
    )
    fewest = min((h.n_landmarks for h in solution.hypotheses), default=0)
    table.add_row("fewest landmarks among survivors", str(fewest), "4")
    table.add_row(
        "label-permuted duplicates avoided", str(stats.get("avoided_by_labelling", 0)), "—"
    )
    table.add_row("candidates rejected by the gate", str(stats.get("gated", 0)), "—")
    table.add_row(
        "hypotheses proven impossible",
        str(
            stats.get("proven_empty", 0)
            + stats.get("refuted_by_negative_information", 0)
            + stats.get("refuted_by_consistency", 0)
        ),
        "—",
    )
    table.add_row("search complete", "yes" if solution.complete else "NO", "—")
    proven = sum(h.status == PROVEN for h in solution.hypotheses)
    undecided = len(solution.hypotheses) - proven
    table.add_row("proven consistent (verified witness)", str(proven), "—")
    table.add_row("undecided (budget ran out)", str(undecided), "—")
    table.add_row("time", f"{solution.timings['total_s']:.2f} s", "—")
    console.print(table)
    if solution.complete and not undecided:
        console.print(
            f"exactly {proven} correspondence hypotheses are consistent: each is proven by a "
            "verified witness, every other one is proven impossible"
        )
    elif undecided:
        console.print(
            f"{undecided} survivor(s) undecided within the budget ({_spent(solution)}); "
            "a larger --work-budget decides more of them"
        )
    for message in solution.messages:
        console.print(worded(message))
    return _report_truth(solution, truth, console)


def _spent(solution: Solution) -> str:
    """What the solve spent, in words."""
    stats = solution.statistics
    limit = stats.get("work_budget")
    spent = f"{stats.get('work_spent', 0):,} work units"
    return spent if limit is None else f"{spent} of {limit:,.0f}"


def run_paper(
    *,
    seed: int,
    figure: str | None,
    json_path: str | None,
    console: Console,
    options: SolveOptions | None = None,
) -> int:
    """Simulate the seed's experiment, solve it with and without landmark ids, report, and
    draw both in one figure (the known-correspondence solve beside each survivor).

    ``options`` (the command line's: its ``work_budget`` and ``time_budget``) are those of
    each of the two solves (see :class:`~cuikslam.options.SolveOptions`)."""
    if json_path:
        check_output_path(json_path)
    if figure:
        check_figure_path(figure)
    drawing = start_figure(figure) if figure else None  # a process importing Matplotlib
    # Without landmark ids first: the figure draws its survivors while the known part is
    # solved, then only the known panel (cli/figure_job.py). Reported in the usual order.
    unknown_log, unknown_truth = simulate_paper(seed=seed, unknown=True)
    unknown = solve(unknown_log, options)
    note_compiling(unknown.timings)
    if drawing is not None:
        drawing.send_unknown(unknown, unknown_truth, [o.pose for o in unknown_log.observations])
    log, truth = simulate_paper(seed=seed)
    solution = solve(log, options)
    if solution.refuted:  # cannot happen with a correct solver: the simulated log is consistent
        if drawing is not None:
            drawing.cancel()
        console.print("error: the simulated experiment was refuted; please report this bug")
        return 1
    if drawing is not None:
        drawing.send_known(solution)  # its panel is drawn while the tables are printed
    best = solution.best
    console.print(
        f"The seed paper's experiment (noise seed {seed}): 9 poses around a 30 m room, "
        f"{len(log.observations)} observations, known correspondence; "
        f"solved in {solution.timings['solve_s'] * 1e3:.1f} ms."
    )
    console.print(
        hypothesis_table(best, "cuikslam, known correspondence (the seed's Table 1 layout)")
    )
    ours = hypothesis_rows(best)
    ours = [r for r in ours if r[0].startswith("r ")] + sorted(
        (r for r in ours if r[0].startswith("l ")), key=lambda r: r[0]
    )
    console.print(
        comparison_table(
            ours,
            paper_table1(),
            "cuikslam beside the seed paper's Table 1 "
            "(the paper's θ is measured from +y; widths compare)",
        )
    )
    ok = _report_truth(solution, truth, console)
    ok &= _report_unknown(unknown, unknown_truth, console)
    if json_path:
        write_output(json_path, lambda: write_result_file(solution, json_path))
    if drawing is not None:
        drawing.finish()
        print(f"wrote {figure}", file=sys.stderr)
    return 0 if ok else 1
