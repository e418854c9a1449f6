"""``cuikslam import mrclam DIR --robot N``: a MRCLAM robot's run as a log and its truth."""

from __future__ import annotations

import argparse
import math
import sys

from cuikslam.cli._common import CommandError

__all__ = [
    "add_bound_options",
    "add_mrclam_parser",
    "add_outlier_options",
    "bounds_from_args",
    "declare_outliers",
]


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: need a finite number >= 0")
    return value


def _positive(text: str) -> float:
    value = _finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: need a number > 0")
    return value


def add_bound_options(p: argparse.ArgumentParser) -> None:
    """``--range-bound``, ``--bearing-bound``, ``--velocity-bound``, ``--turn-rate-bound``,
    ``--lag`` (None when not given: the defaults or a bounds file decide)."""
    for name, unit in (
        ("range", "m"),
        ("range-per-metre", "m/m"),
        ("bearing", "rad"),
        ("velocity", "m/s"),
        ("turn-rate", "rad/s"),
    ):
        p.add_argument(
            f"--{name}-bound",
            type=_finite,
            help=f"{name} error bound [{unit}] (default: measured on Dataset 6, see "
            "cuikslam.datasets.mrclam.MrclamBounds)",
        )
    p.add_argument(
        "--lag",
        type=_finite,
        help="longest time [s] the robot takes to follow a command (default 1.0)",
    )


def _whole(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: need a whole number >= 0")
    return value


def add_map_option(p: argparse.ArgumentParser, landmark: str) -> None:
    """``--map BOUND``: write the dataset's surveyed landmark positions into the log."""
    p.add_argument(
        "--map",
        type=_positive,
        metavar="BOUND",
        help=f"write the dataset's surveyed map: each {landmark}'s surveyed position +/- "
        "BOUND [m] as a landmark record (localization against a known map; with unknown "
        f"correspondence the search matches each reading to a surveyed {landmark})",
    )


def add_outlier_options(p: argparse.ArgumentParser) -> None:
    """``--outliers Q`` and ``--outliers-window P W``: ``outliers`` records in the log."""
    p.add_argument(
        "--outliers",
        type=_whole,
        metavar="Q",
        help="declare in the log that at most Q observations in all miss their truth "
        "(with --unknown: one more option per observation in the search, 'outlier')",
    )
    p.add_argument(
        "--outliers-window",
        type=_whole,
        nargs=2,
        metavar=("P", "W"),
        help="declare at most P outliers among the observations of each block of W "
        "consecutive poses (W >= 1; with or without --outliers)",
    )


def declare_outliers(log, args: argparse.Namespace) -> None:
    """Put the ``outliers`` records the options ask for at the head of ``log``."""
    from cuikslam.log.records import OutlierBound

    declared = []
    if args.outliers is not None:
        declared.append(OutlierBound(args.outliers))
    if args.outliers_window is not None:
        per_block, window = args.outliers_window
        if window < 1:
            raise CommandError("--outliers-window P W: W must be at least 1 pose")
        declared.append(OutlierBound(per_block, window))
    log.records[0:0] = declared


def add_mrclam_parser(datasets: argparse._SubParsersAction) -> None:
    """The ``mrclam`` choice of ``cuikslam import`` (imports nothing heavy: every command
    builds this parser)."""
    p = datasets.add_parser(
        "mrclam",
        help="a robot of a UTIAS MRCLAM dataset (1-9)",
        description="Convert one robot's run of a MRCLAM dataset folder to a log and, beside "
        "it, NAME.truth.json (Vicon interpolated at each pose; landmark truth). The default "
        "bounds were measured on Dataset 6 and do not cover its gross outliers.",
    )
    p.add_argument("folder", help="the dataset folder (Barcodes.dat, Robot1_Odometry.dat, ...)")
    p.add_argument("--robot", type=int, required=True, choices=range(1, 6), help="robot 1-5")
    p.add_argument("-o", "--output", required=True, help="log file to write (.jsonl)")
    p.add_argument(
        "--start", type=_finite, default=0.0, help="window start [s after the first command]"
    )
    p.add_argument("--duration", type=_positive, help="window length [s] (default: to the end)")
    p.add_argument(
        "--keyframe-gap",
        type=_positive,
        default=1.0,
        help="longest time between poses [s]; poses also at every image (default %(default)s)",
    )
    p.add_argument(
        "--robots",
        choices=["drop", "class"],
        default="drop",
        help="sightings of other robots: drop them (default) or keep them as class 'robot', "
        "each its own landmark",
    )
    p.add_argument("--unknown", action="store_true", help="leave out landmark ids")
    add_map_option(p, "landmark")
    add_outlier_options(p)
    add_bound_options(p)
    p.add_argument(
        "--bounds",
        metavar="FILE",
        help="bounds written by `cuikslam calibrate mrclam`; --*-bound and --lag override them",
    )
    p.add_argument(
        "--truth-gap",
        type=_positive,
        default=0.25,
        help="longest Vicon gap [s] a pose's truth is interpolated across (default %(default)s)",
    )
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_import_mrclam)


def bounds_from_args(args: argparse.Namespace):
    """MrclamBounds: the defaults, then ``--bounds FILE``, then the single options."""
    from dataclasses import replace

    from cuikslam.datasets.calibrate import read_bounds_file
    from cuikslam.datasets.mrclam import MrclamBounds

    bounds = MrclamBounds()
    if getattr(args, "bounds", None):
        bounds = replace(bounds, **read_bounds_file(args.bounds))
    given = {
        "range": args.range_bound,
        "range_per_metre": args.range_per_metre_bound,
        "bearing": args.bearing_bound,
        "velocity": args.velocity_bound,
        "turn_rate": args.turn_rate_bound,
        "lag": args.lag,
    }
    return replace(bounds, **{k: v for k, v in given.items() if v is not None})


def _cmd_import_mrclam(args: argparse.Namespace) -> int:
    from cuikslam.cli.commands import log_and_truth_outputs, write_log_and_truth
    from cuikslam.datasets.mrclam import read_mrclam

    out, truth_out = log_and_truth_outputs(args.output)
    bounds = bounds_from_args(args)
    try:
        log, truth, report = read_mrclam(
            args.folder,
            args.robot,
            start=args.start,
            duration=args.duration,
            keyframe_gap=args.keyframe_gap,
            robots=args.robots,
            unknown=args.unknown,
            bounds=bounds,
            truth_gap=args.truth_gap,
            map_bound=args.map,
        )
    except ValueError as err:
        if type(err) is not ValueError:  # an InputFileError names its file: main prints it
            raise
        raise CommandError(f"import mrclam: {err}") from None
    declare_outliers(log, args)
    write_log_and_truth(log, truth, out, truth_out, quiet=args.quiet)
    if not args.quiet:
        print(report.describe(), file=sys.stderr)
    return 0
