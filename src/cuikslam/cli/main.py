"""The ``cuikslam`` command: thin argument parsing around library calls.

Exit status: 0 success; 1 when the result itself reports a problem (the log is proven
inconsistent, or ``--truth`` found a box that misses the truth); 2 for bad input or usage
(one line naming the file and line, no traceback, no partial output file).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from cuikslam import __version__
from cuikslam.budget import (
    DEFAULT_WORK_BUDGET,
    SEARCH_WORK_PER_POSE,
    WALK_RESERVE_PER_POSE,
    WORK_PER_POSE,
)
from cuikslam.cli._common import (
    EXIT_INPUT,
    EXIT_INTERRUPTED,
    CommandError,
    int_at_least,
    limit_or_none,
)
from cuikslam.cli._messages import worded
from cuikslam.cli.commands import (
    cmd_evaluate,
    cmd_paper,
    cmd_plot,
    cmd_simulate,
    cmd_solve,
)
from cuikslam.errors import InputFileError
from cuikslam.options import AMBIGUITY_LP_MIN_DECISIONS, Level, SolveOptions

__all__ = ["main"]


# --------------------------------------------------------------------------- parser
def _add_solver_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--consistency",
        type=_level,
        choices=list(Level),
        default=SolveOptions.consistency,
        help="how hard to narrow: 'hull' = fixpoint of the narrowing operators (fastest); "
        "'lp' (default, at any length; 'auto' is an older name of it) = plus rounds of the "
        "rigorous polytope-hull operator (much tighter); 'lp-split' = plus bisection of the "
        "widest headings (tighter, slower than 'lp')",
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
        help="apply the --consistency level to every reported hypothesis when at most this "
        "many are reported, else to the best-ranked one only (default %(default)s)",
    )
    p.add_argument(
        "--strengthen-during",
        type=_non_negative_int,
        default=SolveOptions.strengthen_during,
        help="narrow a search node to level lp before it branches, during the first N "
        "decisions of the search (default: all of them; 0: off); a search of fewer than "
        f"{AMBIGUITY_LP_MIN_DECISIONS} decisions never does (its tree is small)",
    )
    add_budget_arguments(p)


WORK_HELP = (
    "work units the solve may spend, shared by its stages (counted work, not seconds: the "
    "same log and options give the same result on any machine, at any load); a stage that "
    "runs out stops soundly and says so (boxes at a weaker level, a hypothesis left 'not "
    "refuted', an incomplete search); 'none' for no limit; 'auto' (default): "
    f"{DEFAULT_WORK_BUDGET:.3g} plus {WORK_PER_POSE:.3g} per pose of the log "
    f"({SEARCH_WORK_PER_POSE:.3g} when some reading lacks its landmark id, and "
    f"{WALK_RESERVE_PER_POSE:.3g} more per pose that only the search's walk may spend)"
)
TIME_HELP = (
    "an optional wall-clock cap in seconds on top of the work budget (default: none); when "
    "it binds, the result says so, and may then differ from run to run"
)


def add_budget_arguments(p: argparse.ArgumentParser) -> None:
    """``--work-budget`` and ``--time-budget``, as every solving command takes them."""
    p.add_argument(
        "--work-budget", type=_work_budget, default="auto", metavar="UNITS", help=WORK_HELP
    )
    p.add_argument(
        "--time-budget", type=_time_budget, default=None, metavar="SECONDS", help=TIME_HELP
    )


def _level(text: str) -> Level:
    """An argparse type: a consistency level by its name (``auto`` is ``lp``)."""
    try:
        return Level.parse(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _work_budget(text: str) -> float | str | None:
    """An argparse type: work units (a number >= 0), ``none`` / ``inf`` for no limit, or
    ``auto``."""
    if text.strip().lower() == "auto":
        return "auto"
    return limit_or_none(text, "work units")


def _time_budget(text: str) -> float | None:
    """An argparse type: seconds (a positive number), ``none`` / ``inf`` for no cap."""
    return limit_or_none(text, "seconds")


_positive_int = int_at_least(1)
_non_negative_int = int_at_least(0)


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
    add_budget_arguments(p)
    p.set_defaults(func=cmd_paper)

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
    p.add_argument(
        "--threads",
        type=_positive_int,
        metavar="N",
        default=SolveOptions.threads,
        help="threads of the lp sweeps on a long log, with or without landmark ids (default: "
        "the cores not already busy, from the load average); the boxes are the same for any N",
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
    p.set_defaults(func=cmd_solve)

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
    p.set_defaults(func=cmd_simulate)

    p_import = sub.add_parser(
        "import",
        help="convert a real dataset to a log and its ground truth",
        description="Convert a window of a real dataset to a log and, beside it, NAME.truth.json.",
    )
    datasets = p_import.add_subparsers(dest="dataset", required=True, metavar="DATASET")
    from cuikslam.cli.mrclam import add_mrclam_parser

    add_mrclam_parser(datasets)
    from cuikslam.cli.lost_in_the_woods import add_litw_import_parser

    add_litw_import_parser(datasets)
    from cuikslam.cli.victoria_park import add_vp_import_parser

    add_vp_import_parser(datasets)

    p = sub.add_parser("plot", help="draw a result JSON", description="Draw the boxes of a result.")
    p.add_argument("result", help="result JSON written by `cuikslam solve --json`")
    p.add_argument("-o", "--output", required=True, help="figure file (.png, .pdf, .svg)")
    p.add_argument("--truth", help="ground-truth JSON to draw as points")
    p.add_argument("--max-panels", type=int, default=12, help="hypotheses drawn at most")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_plot)

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
    p.set_defaults(func=cmd_evaluate)

    from cuikslam.cli.calibrate import add_calibrate_parser
    from cuikslam.cli.export import add_export_parser
    from cuikslam.cli.follow import add_follow_parser
    from cuikslam.cli.view import add_view_parser
    from cuikslam.cli.warm_up import add_warm_up_parser

    add_follow_parser(sub)

    add_calibrate_parser(sub)
    add_export_parser(sub)
    add_view_parser(sub)
    add_warm_up_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``cuikslam`` command."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except InputFileError as err:
        text = str(err)  # the problem in the command line's words (naming a flag)
        print(f"cuikslam: error: {text.replace(err.problem, worded(err.problem))}", file=sys.stderr)
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
        return EXIT_INTERRUPTED


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
