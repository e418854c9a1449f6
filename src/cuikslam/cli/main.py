"""The ``cuikslam`` command: thin argument parsing around library calls.

Exit status: 0 success; 1 when the result itself reports a problem (the log is proven
inconsistent, or ``--truth`` found a box that misses the truth); 2 for bad input or usage
(one line naming the file and line, no traceback, no partial output file).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

from cuikslam import __version__
from cuikslam.budget import (
    COMMAND_TARGET,
    DEFAULT_TIME_BUDGET,
    MIN_COMMAND_BUDGET,
    SECONDS_PER_POSE,
)
from cuikslam.cli._common import (
    CommandError,
    check_figure_path,
    check_output_path,
    write_output,
)
from cuikslam.errors import InputFileError
from cuikslam.options import Level, SolveOptions

if TYPE_CHECKING:
    from rich.console import Console

__all__ = ["main"]

STARTED = time.perf_counter()
"""When the command started (near enough: this module is the first one it imports)."""

EXIT_OK = 0
EXIT_RESULT = 1
EXIT_INPUT = 2


def _console() -> Console:
    """stdout console; wide when piped so tables do not wrap."""
    from rich.console import Console

    if sys.stdout.isatty():
        return Console()
    return Console(width=220, color_system=None, soft_wrap=False)


def _truth_path_for(log_path: Path) -> Path:
    """Where ``simulate`` writes the ground truth of ``log_path``: ``NAME.truth.json`` beside it."""
    name = log_path.name
    stem = name[: -len(".jsonl")] if name.endswith(".jsonl") else log_path.stem
    return log_path.with_name(f"{stem}.truth.json")


# --------------------------------------------------------------------------- commands
def _cmd_paper(args: argparse.Namespace) -> int:
    # Output paths are checked before the (slow) solver import; run_paper checks them too.
    if args.json:
        check_output_path(args.json)
    if args.figure:
        check_figure_path(args.figure)
    from cuikslam.cli.paper import run_paper

    budget = args.time_budget
    if budget == "auto":
        budget = DEFAULT_TIME_BUDGET
    return run_paper(
        seed=args.seed,
        figure=args.figure,
        json_path=args.json,
        console=_console(),
        time_budget=budget,
    )


def _cmd_solve(args: argparse.Namespace) -> int:
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
        console=_console(),
        table=args.table,
        options=SolveOptions(
            consistency=args.consistency,
            max_hypotheses=args.max_hypotheses,
            strengthen_limit=args.strengthen_limit,
            strengthen_during=args.strengthen_during,
        ),
        time_budget=args.time_budget,
        started=STARTED,
        survivors_path=args.survivors,
    )


def _log_and_truth_outputs(output: str) -> tuple[Path, Path]:
    """The log path and its truth file beside it, both checked writable before any work."""
    out = Path(output)
    truth_out = _truth_path_for(out)
    check_output_path(out)
    check_output_path(truth_out)
    return out, truth_out


def _cmd_simulate(args: argparse.Namespace) -> int:
    from cuikslam.simulate import simulate_paper, simulate_random_world

    out, truth_out = _log_and_truth_outputs(args.output)
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
    _write_log_and_truth(log, truth, out, truth_out, quiet=args.quiet)
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


def _write_log_and_truth(log, truth, out: Path, truth_out: Path, *, quiet: bool) -> None:
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


def _cmd_import(args: argparse.Namespace) -> int:
    from cuikslam.datasets import read_lost_in_the_woods

    out, truth_out = _log_and_truth_outputs(args.output)
    log, truth = read_lost_in_the_woods(
        args.file,
        start=args.start,
        steps=args.steps,
        keyframe=args.keyframe,
        unknown=not args.known,
        speed_bound=args.speed_bound,
        turn_rate_bound=args.turn_rate_bound,
        range_bound=args.range_bound,
        bearing_bound=args.bearing_bound,
        every_observation=not args.keyframe_observations,
    )
    _write_log_and_truth(log, truth, out, truth_out, quiet=args.quiet)
    return EXIT_OK


def _cmd_plot(args: argparse.Namespace) -> int:
    from cuikslam.results.io import read_result_file
    from cuikslam.simulate.truth import read_truth_file

    # Inputs and the output folder first: a bad file fails before matplotlib is imported.
    check_figure_path(args.output)
    solution = read_result_file(args.result)
    truth = read_truth_file(args.truth) if args.truth else None
    if not solution.hypotheses:
        raise CommandError(f"{args.result}: no hypothesis to plot (the log was refuted)")

    from cuikslam.results.figures import plot_solution, save_figure

    figure = plot_solution(solution, truth, max_hypotheses=args.max_panels)
    write_output(args.output, lambda: save_figure(figure, args.output))
    if not args.quiet:
        print(f"wrote {args.output}", file=sys.stderr)
    return EXIT_OK


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from cuikslam.cli.evaluate import run_evaluate

    return run_evaluate(
        result_path=args.result,
        truth_path=args.truth,
        log_path=args.log,
        json_path=args.json,
        figure_path=args.figure,
        quiet=args.quiet,
        console=_console(),
    )


# --------------------------------------------------------------------------- parser
def _add_solver_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--consistency",
        choices=[level.value for level in Level],
        default=SolveOptions.consistency.value,
        help="how hard to narrow: 'hull' = fixpoint of the narrowing operators (fastest); "
        "'lp' = plus rounds of the rigorous polytope-hull operator (much tighter); "
        "'lp-split' = plus bisection of the widest headings (tighter, slower than 'lp'); "
        "'auto' (default) = 'lp', at any length",
    )
    p.add_argument(
        "--survivors",
        metavar="FILE",
        help="write every survivor of the correspondence search to FILE, one JSON line "
        '{"assignment": [...]} each, as it is found (all of them, beyond --max-hypotheses; '
        '"+k" is the k-th landmark a hypothesis adds)',
    )
    p.add_argument(
        "--max-hypotheses",
        type=_positive_int,
        default=SolveOptions.max_hypotheses,
        help="surviving correspondence hypotheses reported in detail (the best-ranked); the "
        "search explores and counts all of them, and --survivors writes all of them "
        "(default %(default)s)",
    )
    p.add_argument(
        "--strengthen-limit",
        type=_positive_int,
        default=SolveOptions.strengthen_limit,
        help="apply the --consistency level to every surviving hypothesis when at most this "
        "many survive, else to the best-ranked one only (default %(default)s)",
    )
    p.add_argument(
        "--strengthen-during",
        type=_non_negative_int,
        default=SolveOptions.strengthen_during,
        help="also apply level lp after every ambiguous observation while at most this many "
        "hypotheses live: fewer survivors, slower (default %(default)s: off)",
    )
    p.add_argument(
        "--time-budget",
        type=_time_budget,
        default="auto",
        metavar="SECONDS",
        help="seconds the solve may take, shared by its stages; a stage that runs out stops "
        "soundly and says so (boxes at a weaker level, a hypothesis left 'not refuted', an "
        f"incomplete search); 'none' for no limit; 'auto' (default): the command aims at "
        f"{COMMAND_TARGET:g} s end to end, the solve gets what start-up left (at least "
        f"{MIN_COMMAND_BUDGET:g} s, and at least {SECONDS_PER_POSE:g} s per pose of the log)",
    )


def _int_at_least(minimum: int) -> Callable[[str], int]:
    """An argparse type: an integer of at least ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value

    return parse


def _time_budget(text: str) -> float | str | None:
    """An argparse type: seconds (a positive number), ``none`` / ``inf`` for no limit, or
    ``auto``."""
    if text.strip().lower() in ("none", "inf", "infinity"):
        return None
    if text.strip().lower() == "auto":
        return "auto"
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number of seconds: {text!r}") from None
    if not value > 0 or math.isnan(value):
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return None if math.isinf(value) else value


_positive_int = _int_at_least(1)
_non_negative_int = _int_at_least(0)


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cuikslam",
        description=(
            "Guaranteed 2-D SLAM with bounded errors and unknown landmark correspondence: "
            "interval boxes that always contain the truth, hypotheses discarded only by proof."
        ),
    )
    parser.add_argument("--version", action="version", version=f"cuikslam {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser(
        "paper",
        help="simulate and solve the seed paper's experiment; compare with its Table 1",
        description="Simulate the seed paper's experiment (30 m room, octagon loop), solve it, "
        "print the boxes beside the paper's Table 1, and write a figure.",
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument(
        "--figure", default="cuikslam-paper.png", help="figure to write (default %(default)s)"
    )
    p.add_argument("--json", help="also write the result JSON here")
    p.add_argument(
        "--time-budget",
        type=_time_budget,
        default="auto",
        metavar="SECONDS",
        help=f"seconds each solve may take ('auto': {DEFAULT_TIME_BUDGET:g} s; 'none': no "
        "limit); survivors the witness search has not proven by then stay undecided "
        "(a larger budget decides more of them)",
    )
    p.set_defaults(func=_cmd_paper)

    p = sub.add_parser("solve", help="solve a JSON Lines log", description="Solve a log file.")
    p.add_argument(
        "log",
        nargs="+",
        help="the log (JSON Lines, see docs/log-format.md); several logs are solved one "
        "after the other, or in parallel with --workers/--scheduler",
    )
    p.add_argument("--json", help="write the result JSON here (with several logs: a folder)")
    p.add_argument("--csv", help="write the boxes as CSV here (with several logs: a folder)")
    p.add_argument(
        "--workers",
        type=_positive_int,
        metavar="N",
        help="run on a local Dask cluster of N worker processes: one log's correspondence "
        'search, or several logs at once (needs pip install "cuikslam[distributed]")',
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on the Dask cluster whose scheduler is at ADDRESS (e.g. tcp://host:8786)",
    )
    p.add_argument("--truth", help="ground-truth JSON: report whether every box contains it")
    p.add_argument("-q", "--quiet", action="store_true", help="print no table")
    p.add_argument(
        "--table",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="print every box (--table) or an overview (--no-table); default: every box "
        "up to 60 poses, an overview beyond",
    )
    _add_solver_options(p)
    p.set_defaults(func=_cmd_solve)

    p = sub.add_parser(
        "simulate",
        help="write a simulated log and its ground truth",
        description="Write a simulated log and, beside it, NAME.truth.json.",
    )
    p.add_argument("world", choices=["paper", "random"], help="which world")
    p.add_argument("-o", "--output", required=True, help="log file to write (.jsonl)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--unknown", action="store_true", help="drop landmark ids (unknown correspondence)"
    )
    p.add_argument("--poses", type=int, default=50, help="random world: poses (default 50)")
    p.add_argument("--landmarks", type=int, default=10, help="random world: landmarks (default 10)")
    p.add_argument(
        "--classes",
        default="door,corridor,post",
        help="random world: landmark classes, comma-separated",
    )
    p.add_argument("--max-range", type=float, default=8.0, help="random world: sensor range [m]")
    p.add_argument(
        "--fov", type=float, default=6.283185307179586, help="random world: field of view [rad]"
    )
    p.add_argument(
        "--size", default="40,30", help="random world: room width,height [m] (default 40,30)"
    )
    p.add_argument(
        "--step", default="0.5,2", help="random world: shortest,longest step [m] (default 0.5,2)"
    )
    p.add_argument(
        "--odometry-bounds",
        default="0.05,0.1",
        help="random world: turn [rad],distance [m] error bounds (default 0.05,0.1)",
    )
    p.add_argument(
        "--observation-bounds",
        default="0.05,0.02",
        help="random world: range [m],bearing [rad] error bounds (default 0.05,0.02)",
    )
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_simulate)

    p_import = sub.add_parser(
        "import",
        help="convert a real dataset to a log and its ground truth",
        description="Convert a window of a real dataset to a log and, beside it, NAME.truth.json.",
    )
    datasets = p_import.add_subparsers(dest="dataset", required=True, metavar="DATASET")
    from cuikslam.cli.mrclam import add_mrclam_parser

    add_mrclam_parser(datasets)
    p = datasets.add_parser(
        "lost-in-the-woods",
        help="a window of UTIAS Lost in the Woods (dataset2.mat)",
        description="Convert a window of Lost in the Woods to a log and NAME.truth.json.",
    )
    p.add_argument("file", help="the dataset file (dataset2.mat)")
    p.add_argument("-o", "--output", required=True, help="log file to write (.jsonl)")
    p.add_argument("--start", type=int, default=0, help="first sample (default 0)")
    p.add_argument(
        "--steps", type=_positive_int, default=None, help="samples (default: to the end)"
    )
    p.add_argument(
        "--keyframe",
        "--stride",
        type=_positive_int,
        default=10,
        help="samples per pose; the odometry between is composed (default 10)",
    )
    p.add_argument("--known", action="store_true", help="keep landmark ids (known correspondence)")
    p.add_argument(
        "--speed-bound",
        type=_positive_float,
        default=None,
        help="per-sample speed error bound [m/s] (default 3 sd of the file's v_var)",
    )
    p.add_argument(
        "--turn-rate-bound",
        type=_positive_float,
        default=None,
        help="per-sample turn-rate error bound [rad/s] (default 3 sd of the file's om_var)",
    )
    p.add_argument(
        "--range-bound", type=_positive_float, default=0.16, help="range bound [m] (default 0.16)"
    )
    p.add_argument(
        "--bearing-bound",
        type=_positive_float,
        default=0.15,
        help="bearing bound [rad] (default 0.15)",
    )
    p.add_argument(
        "--keyframe-observations",
        action="store_true",
        help="keep only the observations made at a keyframe sample",
    )
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_import)

    p = sub.add_parser("plot", help="draw a result JSON", description="Draw the boxes of a result.")
    p.add_argument("result", help="result JSON written by `cuikslam solve --json`")
    p.add_argument("-o", "--output", required=True, help="figure file (.png, .pdf, .svg)")
    p.add_argument("--truth", help="ground-truth JSON to draw as points")
    p.add_argument("--max-panels", type=int, default=12, help="hypotheses drawn at most")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_plot)

    p = sub.add_parser(
        "evaluate",
        help="measure a result against its ground truth",
        description="Share of boxes holding the truth, box widths, and (unknown "
        "correspondence) the rank of the true association and the share of observations "
        "the best hypothesis associates correctly. Exit status 1 when the guarantee visibly "
        "failed (the true hypothesis has a box missing the truth, or a complete search "
        "refuted it).",
    )
    p.add_argument("result", help="result JSON written by `cuikslam solve --json`")
    p.add_argument("--truth", required=True, help="ground-truth JSON (may cover only some poses)")
    p.add_argument(
        "--log",
        help="the solved log, for the landmark ids it names (default: the log the result "
        "names, when it is still there)",
    )
    p.add_argument("--json", help="write the evaluation as JSON for scripts")
    p.add_argument("--figure", help="draw boxes, truth and widths over time (.png, .pdf, .svg)")
    p.add_argument("-q", "--quiet", action="store_true", help="no tables")
    p.set_defaults(func=_cmd_evaluate)

    from cuikslam.cli.calibrate import add_calibrate_parser

    add_calibrate_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``cuikslam`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except InputFileError as err:
        print(f"cuikslam: error: {err}", file=sys.stderr)
        return EXIT_INPUT
    except CommandError as err:
        print(f"cuikslam: error: {err}", file=sys.stderr)
        return EXIT_INPUT
    except OSError as err:
        where = f"{err.filename}: " if err.filename else ""
        print(f"cuikslam: error: {where}{err.strerror or err}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("cuikslam: interrupted", file=sys.stderr)
        return 130


def entry() -> None:
    """The console script: :func:`main`, then end the process at once.

    Finalising the interpreter once the compiled kernels are loaded (numba, LLVM) takes
    a noticeable part of a second, for nothing: by then every output file is written and
    closed, and the streams are flushed here. An exception (a bug) or ``SystemExit``
    (usage errors, ``--help``) leaves the normal way.
    """
    status = main()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # a closed pipe: nothing more can be said
        pass
    os._exit(status)


if __name__ == "__main__":
    entry()
