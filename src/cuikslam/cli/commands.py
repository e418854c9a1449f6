"""The subcommands of the ``cuikslam`` command: each turns parsed arguments into one
library call (the parser is :func:`cuikslam.cli.main.build_parser`)."""

from __future__ import annotations

import argparse
import math
import sys
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

from cuikslam.cli._common import (
    EXIT_OK,
    STARTED,
    CommandError,
    check_figure_path,
    check_output_path,
    write_output,
)
from cuikslam.cli._messages import worded
from cuikslam.options import SolveOptions

if TYPE_CHECKING:
    from rich.console import Console

__all__ = [
    "cmd_evaluate",
    "cmd_paper",
    "cmd_plot",
    "cmd_simulate",
    "cmd_solve",
    "console",
    "log_and_truth_outputs",
    "write_log_and_truth",
]


def console() -> Console:
    """stdout console; wide when piped so tables do not wrap, and a message longer than
    that stays one line (a file or a pager gets sentences whole)."""
    from rich.console import Console

    if sys.stdout.isatty():
        return Console()
    return Console(width=220, color_system=None, soft_wrap=True)


def _truth_path_for(log_path: Path) -> Path:
    """Where ``simulate`` writes the ground truth of ``log_path``: ``NAME.truth.json`` beside it."""
    name = log_path.name
    stem = name[: -len(".jsonl")] if name.endswith(".jsonl") else log_path.stem
    return log_path.with_name(f"{stem}.truth.json")


def cmd_paper(args: argparse.Namespace) -> int:
    # Output paths are checked before the (slow) solver import; run_paper checks them too.
    if args.json:
        check_output_path(args.json)
    if args.figure:
        check_figure_path(args.figure)
    from cuikslam.cli.paper import run_paper

    return run_paper(
        seed=args.seed,
        figure=args.figure,
        json_path=args.json,
        console=console(),
        options=SolveOptions(work_budget=args.work_budget, time_budget=args.time_budget),
    )


def cmd_solve(args: argparse.Namespace) -> int:
    from cuikslam.cli.solve import run_solve

    if len(args.log) > 1 or args.workers is not None or args.scheduler is not None:
        from cuikslam.cli.cluster import run_solve_cluster

        run = partial(
            run_solve_cluster, log_paths=args.log, workers=args.workers, scheduler=args.scheduler
        )
    else:
        run = partial(run_solve, log_path=args.log[0])
    return run(
        json_path=args.json,
        csv_path=args.csv,
        truth_path=args.truth,
        quiet=args.quiet,
        console=console(),
        table=args.table,
        options=SolveOptions(
            consistency=args.consistency,
            max_hypotheses=args.max_hypotheses,
            strengthen_limit=args.strengthen_limit,
            strengthen_during=args.strengthen_during,
            threads=args.threads,
            work_budget=args.work_budget,
            time_budget=args.time_budget,
        ),
        started=STARTED,
        survivors_path=args.survivors,
    )


def log_and_truth_outputs(output: str) -> tuple[Path, Path]:
    """The log path and its truth file beside it, both checked writable before any work."""
    out = Path(output)
    truth_out = _truth_path_for(out)
    check_output_path(out)
    check_output_path(truth_out)
    return out, truth_out


def cmd_simulate(args: argparse.Namespace) -> int:
    from cuikslam.simulate import simulate_paper, simulate_random_world

    out, truth_out = log_and_truth_outputs(args.output)
    classes = tuple(c.strip() for c in args.classes.split(","))
    if not all(classes):
        raise CommandError(f"--classes {args.classes!r}: class names must be non-empty")
    for option, value in (("--max-range", args.max_range), ("--fov", args.fov)):
        if not math.isfinite(value):
            raise CommandError(f"{option} {value}: must be a finite number")
    pairs = {
        name: _number_pair(option, getattr(args, name))
        for name, option in (
            ("size", "--size"),
            ("step", "--step"),
            ("odometry_bounds", "--odometry-bounds"),
            ("observation_bounds", "--observation-bounds"),
        )
    }
    try:
        if args.world == "paper":
            log, truth = simulate_paper(seed=args.seed, unknown=args.unknown)
        else:
            log, truth = simulate_random_world(
                seed=args.seed,
                n_poses=args.poses,
                n_landmarks=args.landmarks,
                classes=classes,
                max_range=args.max_range,
                fov=args.fov,
                size=pairs["size"],
                step_length=pairs["step"],
                odometry_bounds=pairs["odometry_bounds"],
                observation_bounds=pairs["observation_bounds"],
                unknown=args.unknown,
            )
    except ValueError as err:  # an impossible world (WorldSpec checks its parameters)
        problem = str(err).removeprefix("WorldSpec: ")
        raise CommandError(f"simulate {args.world}: {problem}") from None
    write_log_and_truth(log, truth, out, truth_out, quiet=args.quiet)
    return EXIT_OK


def _number_pair(option: str, text: str) -> tuple[float, float]:
    """Two finite numbers written ``A,B`` (an option's value)."""
    parts = text.split(",")
    try:
        a, b = (float(p) for p in parts)
    except ValueError:
        raise CommandError(f"{option} {text!r}: expected two numbers A,B") from None
    if not (math.isfinite(a) and math.isfinite(b)):
        raise CommandError(f"{option} {text!r}: must be finite numbers")
    return a, b


def write_log_and_truth(log, truth, out: Path, truth_out: Path, *, quiet: bool) -> None:
    """Write a log and its ground truth beside it (both atomically), and say so."""
    from cuikslam.log.writer import write_log_file
    from cuikslam.simulate import write_truth_file

    write_output(out, lambda: write_log_file(log, out))
    write_output(truth_out, lambda: write_truth_file(truth, truth_out))
    if not quiet:
        print(
            f"wrote {out} ({len(log.records)} records: "
            f"{len(log.odometry) + len(log.relative_poses)} moves, "
            f"{len(log.observations)} observations) and its ground truth {truth_out}",
            file=sys.stderr,
        )


def cmd_plot(args: argparse.Namespace) -> int:
    from cuikslam.outcome.solution import no_hypothesis
    from cuikslam.results.io import read_result_file
    from cuikslam.simulate.truth import check_truth_fits, read_truth_file

    # Inputs and the output folder first: a bad file fails before matplotlib is imported.
    check_figure_path(args.output)
    solution = read_result_file(args.result)
    truth = read_truth_file(args.truth) if args.truth else None
    if not solution.hypotheses and solution.envelope is None:  # with one: the envelope alone
        raise CommandError(
            f"{args.result}: no hypothesis to plot ({worded(no_hypothesis(solution))})"
        )
    if truth is not None:
        check_truth_fits(truth, args.truth, solution, args.result, assignment_optional=True)

    from cuikslam.results.figures import plot_solution, save_figure

    figure = plot_solution(solution, truth, max_hypotheses=args.max_panels)
    write_output(args.output, lambda: save_figure(figure, args.output))
    if not args.quiet:
        print(f"wrote {args.output}", file=sys.stderr)
    return EXIT_OK


def cmd_evaluate(args: argparse.Namespace) -> int:
    from cuikslam.cli.evaluate import run_evaluate

    return run_evaluate(
        result_path=args.result,
        truth_path=args.truth,
        log_path=args.log,
        json_path=args.json,
        figure_path=args.figure,
        quiet=args.quiet,
        console=console(),
    )
