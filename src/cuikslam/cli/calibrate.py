"""``cuikslam calibrate mrclam DIR --robot N -o bounds.json``: bounds measured on a part of
a run with truth, and how many measurements of another part fall outside them."""

from __future__ import annotations

import argparse
import sys

from cuikslam.cli._common import CommandError, check_output_path, write_output
from cuikslam.cli.mrclam import _finite, _positive

__all__ = ["add_calibrate_parser"]


def add_calibrate_parser(sub: argparse._SubParsersAction) -> None:
    """The ``calibrate`` command (imports nothing heavy: every command builds it)."""
    p_cal = sub.add_parser(
        "calibrate",
        help="measure error bounds on a run with truth; check them on another part",
        description="Measure, on a part of a run with truth, the error bounds under which "
        "its measurements hold the truth, write them (a JSON file that `cuikslam import "
        "--bounds` accepts), and count the measurements of another part outside them.",
    )
    datasets = p_cal.add_subparsers(dest="dataset", required=True, metavar="DATASET")
    p = datasets.add_parser(
        "mrclam",
        help="a robot of a UTIAS MRCLAM dataset",
        description="Range and bearing bounds from the landmark sightings against Vicon; "
        "velocity and turn-rate bounds (with the lag) scaled until the part's moves hold "
        "the truth.",
    )
    p.add_argument("folder", help="the dataset folder")
    p.add_argument("--robot", type=int, required=True, choices=range(1, 6), help="robot 1-5")
    p.add_argument("-o", "--output", required=True, help="bounds file to write (.json)")
    p.add_argument("--start", type=_finite, default=0.0, help="part start [s] (default 0)")
    p.add_argument("--duration", type=_positive, help="part length [s] (default: to the end)")
    p.add_argument(
        "--quantile",
        type=_positive,
        default=1.0,
        help="share of the part's measurements of each kind the bounds must hold (default 1: "
        "all; below 1 the rest are outliers to declare)",
    )
    p.add_argument("--lag", type=_finite, help="command lag [s] kept as is (default 1.0)")
    p.add_argument("--check-robot", type=int, choices=range(1, 6), help="robot of the checked part")
    p.add_argument("--check-start", type=_finite, help="checked part start [s]")
    p.add_argument("--check-duration", type=_positive, help="checked part length [s]")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_calibrate_mrclam)

    from cuikslam.cli.lost_in_the_woods import add_litw_calibrate_parser

    add_litw_calibrate_parser(datasets)
    from cuikslam.cli.victoria_park import add_vp_calibrate_parser

    add_vp_calibrate_parser(datasets)
    p = datasets.add_parser(
        "check",
        help="count the measurements of a log whose interval misses the truth",
        description="Compare each range, bearing and move of a log (any importer's, e.g. "
        "the part imported with calibrated bounds) with its truth, count and list those "
        "outside their intervals. Poses without truth are skipped.",
    )
    p.add_argument("log", help="the log (.jsonl)")
    p.add_argument("--truth", required=True, help="its truth file (NAME.truth.json)")
    p.add_argument("--json", help="write the counts and the list as JSON")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_check)


def _cmd_calibrate_mrclam(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from cuikslam.datasets.calibrate import calibrate_mrclam, count_outside, write_bounds_file
    from cuikslam.datasets.mrclam import MrclamBounds

    check_output_path(args.output)
    if args.quantile > 1:
        raise CommandError(f"--quantile {args.quantile}: must be at most 1")
    base = MrclamBounds() if args.lag is None else replace(MrclamBounds(), lag=args.lag)
    calibration = calibrate_mrclam(
        args.folder,
        args.robot,
        start=args.start,
        duration=args.duration,
        quantile=args.quantile,
        base=base,
    )
    check = None
    if args.check_robot is not None or args.check_start is not None:
        robot = args.check_robot or args.robot
        start = args.check_start
        if start is None:  # the rest of the calibration robot's run, or another whole run
            start = args.start + args.duration if robot == args.robot and args.duration else 0.0
        check = count_outside(
            args.folder, robot, calibration.bounds, start=start, duration=args.check_duration
        )
        calibration.calibrated_on["checked_on"] = {
            "robot": robot,
            "start": start,
            "duration": args.check_duration,
            "outside": {
                "ranges": check.ranges,
                "bearings": check.bearings,
                "observations": check.observations_checked,
                "moves": check.moves,
                "moves_checked": check.moves_checked,
            },
        }
    write_output(args.output, lambda: write_bounds_file(calibration, args.output))
    if not args.quiet:
        b = calibration.bounds
        errors = calibration.errors
        print(
            f"calibrated on robot {args.robot} from {args.start} s"
            + (f" for {args.duration} s" if args.duration else " to the end")
            + f": range ±({b.range} m + {b.range_per_metre} × reading) (errors: median "
            f"{errors['range']['median']:.3f}, max {errors['range']['max']:.3f} m), "
            f"bearing ±{b.bearing} rad (median "
            f"{errors['bearing']['median']:.4f}, max {errors['bearing']['max']:.4f}), "
            f"velocity ±{b.velocity} m/s, turn rate ±{b.turn_rate} rad/s (lag {b.lag} s)",
            file=sys.stderr,
        )
        print(f"  the calibration part: {calibration.outside.describe()}", file=sys.stderr)
        if check is not None:
            where = calibration.calibrated_on["checked_on"]
            print(
                f"  checked on robot {where['robot']} from {where['start']} s: {check.describe()}",
                file=sys.stderr,
            )
        print(f"wrote {args.output}", file=sys.stderr)
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    import json

    from cuikslam._atomic import atomic_write_text
    from cuikslam.log.reader import read_log_file
    from cuikslam.results.measurement_check import check_log, outside_to_json
    from cuikslam.simulate.truth import check_truth_fits, read_truth_file

    if args.json:
        check_output_path(args.json)
    log = read_log_file(args.log)
    truth = read_truth_file(args.truth)
    check_truth_fits(truth, args.truth, log)
    found = check_log(log, truth)
    document = outside_to_json(found)
    verdict = None
    if log.outlier_bounds:
        from cuikslam.outliers import check_declaration

        holds, verdict = check_declaration(log, found.outside_observations, found.moves)
        document["declaration_holds"] = holds
    if args.json:
        text = json.dumps(document, indent=1) + "\n"
        write_output(args.json, lambda: atomic_write_text(args.json, text))
    if not args.quiet:
        print(found.describe())
        for line in found.details[:20]:
            print(f"  {line}")
        if len(found.details) > 20:
            print(f"  … {len(found.details) - 20} more (--json lists them all)")
        if verdict is not None:
            print(verdict)
            if found.observations_unchecked:
                print(
                    f"  ({found.observations_unchecked} observations from an uncertain sensor "
                    "offset were not checked: the verdict covers the others)"
                )
    return 0
