"""``cuikslam evaluate``: a result against its ground truth, as tables, JSON and a figure."""

from __future__ import annotations

import json
import math
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from cuikslam._atomic import atomic_write_text
from cuikslam.cli._common import CommandError, check_figure_path, check_output_path, write_output
from cuikslam.cli._messages import worded
from cuikslam.errors import InputFileError
from cuikslam.log.reader import read_log_file
from cuikslam.log.records import Log
from cuikslam.outcome.solution import no_hypothesis
from cuikslam.results.association import named_landmarks, true_outliers
from cuikslam.results.evaluate import Evaluation, evaluate, evaluation_to_json
from cuikslam.results.io import read_result_file
from cuikslam.results.measurement_check import check_log
from cuikslam.simulate.truth import check_truth_fits, read_truth_file

__all__ = ["print_evaluation", "run_evaluate"]


def _the_log(log_path: str | None, result_log: str, notes: list[str]) -> Log | None:
    """The log: from ``--log``, else the log the result names when it is still readable;
    else None (partitions are then compared without the log's landmark names)."""
    path = log_path or result_log
    if not path:
        notes.append("no log given: partitions compared without the log's landmark names")
        return None
    if log_path is None and not Path(path).is_file():
        notes.append(f"the result's log {path} is not there: partitions compared without names")
        return None
    try:
        return read_log_file(path)
    except InputFileError:
        if log_path is not None:
            raise
        notes.append(f"the result's log {path} is unreadable: partitions compared without names")
        return None


def _pct(part: int, whole: int) -> str:
    return f"{part} of {whole} ({100 * part / whole:.1f} %)" if whole else "none with truth"


def _num(value: float, digits: int = 3) -> str:
    return "unbounded" if math.isinf(value) else "—" if math.isnan(value) else f"{value:.{digits}f}"


def print_evaluation(ev: Evaluation, console: Console) -> None:
    """The evaluation as a few rich tables a reader takes in at a glance."""
    head = Table(title="Evaluation against the truth", show_header=False)
    head.add_column(style="bold")
    head.add_column()
    which = f"{ev.evaluated_rank} of {ev.reported} reported"
    wrong = not ev.evaluated_is_true and ev.correct_associations is not None
    if ev.evaluated_is_true:
        which += " (the true correspondence)"
    elif wrong:
        which += " (the best-ranked, not the true one: its boxes need not hold the truth)"
    head.add_row("hypothesis evaluated", which)
    head.add_row("poses with truth inside their box", _pct(ev.poses_inside, ev.poses_with_truth))
    if ev.poses_without_truth:
        head.add_row("poses without truth (not counted)", str(ev.poses_without_truth))
    if ev.hull_checked is not None and not ev.evaluated_is_true:
        head.add_row(
            "poses with truth inside their hull over all survivors",
            _pct(ev.hull_inside, ev.hull_checked),
        )
    if ev.truth_poses_not_in_result:
        head.add_row("truth poses not in the result", str(ev.truth_poses_not_in_result))
    head.add_row(
        "landmarks with truth inside their box", _pct(ev.landmarks_inside, ev.landmarks_with_truth)
    )
    if ev.landmarks_without_truth:
        head.add_row("landmarks without truth", str(ev.landmarks_without_truth))
    if ev.observations:
        rank = (
            str(ev.true_rank)
            if ev.true_rank
            else f"not among the {ev.reported} reported of {ev.survivors} survivors"
        )
        head.add_row("rank of the true correspondence", rank)
        if ev.correct_associations is not None:
            head.add_row(
                "observations associated correctly by the best",
                _pct(ev.correct_associations, ev.observations),
            )
    if not ev.complete:
        head.add_row("search", "INCOMPLETE (a budget stopped it)")
    console.print(head)

    widths = Table(title="Box widths")
    for name in ("", "median", "95 %", "max"):
        widths.add_column(name, justify="right" if name else "left")
    labels = {
        "x": "pose x [m]",
        "y": "pose y [m]",
        "theta": "pose θ [rad]",
        "landmark_x": "landmark x [m]",
        "landmark_y": "landmark y [m]",
    }
    for key, stats in ev.widths().items():
        if stats.count:
            widths.add_row(
                escape(labels[key]), _num(stats.median), _num(stats.p95), _num(stats.max)
            )
    console.print(widths)

    segments = ev.over_time()
    if len(segments) > 1:
        over = Table(title="Median pose widths over the run")
        for name in ("poses", "x [m]", "y [m]", "θ [rad]", "truth inside"):
            over.add_column(escape(name), justify="right")
        for seg in segments:
            over.add_row(
                f"{seg['first_pose']}–{seg['last_pose']}",
                _num(seg["median_x"]),
                _num(seg["median_y"]),
                _num(seg["median_theta"]),
                f"{seg['inside']}/{seg['with_truth']}",
            )
        console.print(over)
    if ev.misses:
        whose = " (of a hypothesis that is not the true one)" if wrong else ""
        console.print(f"{len(ev.misses)} bounds miss the truth{whose}:")
        for miss in ev.misses[:20]:
            console.print(f"  {miss}")
        if len(ev.misses) > 20:
            console.print(f"  … {len(ev.misses) - 20} more in the JSON (--json)")
    for note in ev.notes:
        console.print(f"note: {note}")
    if ev.guarantee_held is False:
        console.print("the guarantee did not hold: some measured interval misses its true value")


def run_evaluate(
    *,
    result_path: str,
    truth_path: str,
    log_path: str | None,
    json_path: str | None,
    figure_path: str | None,
    quiet: bool,
    console: Console,
) -> int:
    """Evaluate, print, write the JSON and figure. Returns 1 when the guarantee visibly
    failed (see :attr:`Evaluation.guarantee_held`), else 0."""
    if json_path:
        check_output_path(json_path)
    if figure_path:
        check_figure_path(figure_path)
    solution = read_result_file(result_path)
    truth = read_truth_file(truth_path)
    notes: list[str] = []
    if solution.outliers is not None:
        from cuikslam.outliers import evaluation_note

        notes.append(worded(evaluation_note(solution.outliers)))
    log = _the_log(log_path, solution.log_path, notes)
    named = set() if log is None else named_landmarks(log)
    if not solution.hypotheses:
        raise CommandError(
            f"{result_path}: no hypothesis to evaluate ({worded(no_hypothesis(solution))})"
        )
    if log is not None:
        check_truth_fits(truth, truth_path, log, assignment_optional=True)
    else:
        check_truth_fits(truth, truth_path, solution, result_path, assignment_optional=True)
    outside: list[int] = []  # the true outliers, when hypotheses may take some
    unchecked: list[int] = []
    if log is not None and log.outlier_bounds and log.has_unknown_correspondence:
        outside, unchecked = true_outliers(log, check_log(log, truth))
    try:
        ev = evaluate(solution, truth, named, outside, unchecked)
    except ValueError as err:
        raise CommandError(f"{truth_path}: does not match {result_path}: {err}") from None
    ev.notes[:0] = notes
    if json_path:
        text = json.dumps(evaluation_to_json(ev), indent=1, allow_nan=False) + "\n"
        write_output(json_path, lambda: atomic_write_text(json_path, text))
    if figure_path:
        from cuikslam.results.evaluation_figure import plot_evaluation
        from cuikslam.results.figures import save_figure

        figure = plot_evaluation(solution, truth, ev)
        write_output(figure_path, lambda: save_figure(figure, figure_path))
    if not quiet:
        print_evaluation(ev, console)
    return 1 if ev.guarantee_held is False else 0
