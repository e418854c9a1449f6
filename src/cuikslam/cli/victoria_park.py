"""``cuikslam import victoria-park`` and ``cuikslam calibrate victoria-park``: the ACFR car
among trees as a log with its GPS reference, and motion bounds measured against GPS."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cuikslam.cli._common import CommandError, check_output_path, write_output
from cuikslam.cli.mrclam import _finite, _positive, add_outlier_options, declare_outliers

__all__ = ["add_vp_calibrate_parser", "add_vp_import_parser", "gps_path_for"]


def gps_path_for(log_path: Path) -> Path:
    """``NAME.gps.json`` beside ``NAME.jsonl``: the GPS reference of an imported log."""
    name = log_path.name
    stem = name[: -len(".jsonl")] if name.endswith(".jsonl") else log_path.stem
    return log_path.with_name(f"{stem}.gps.json")


def add_vp_import_parser(datasets: argparse._SubParsersAction) -> None:
    """The ``victoria-park`` choice of ``cuikslam import``."""
    p = datasets.add_parser(
        "victoria-park",
        help="a window of the Victoria Park car among trees (unknown correspondence)",
        description="Convert a window of Victoria Park (inputs.dat, measurements.dat, gps.dat) "
        "to a log of unlabelled trees and NAME.gps.json, the GPS at the poses' times (a "
        "reference with metres of error, of the antenna at the laser: not a truth).",
    )
    p.add_argument("folder", help="the dataset folder")
    p.add_argument("-o", "--output", required=True, help="log file to write (.jsonl)")
    p.add_argument("--start", type=_finite, default=0.0, help="window start [s] (default 0)")
    p.add_argument("--minutes", type=_positive, help="window length [min] (default: to the end)")
    p.add_argument(
        "--keyframe", type=_positive, default=1.0, help="seconds between poses (default 1)"
    )
    p.add_argument("--bounds", help="bounds written by `cuikslam calibrate victoria-park`")
    p.add_argument(
        "--max-range",
        type=_positive,
        help="keep only trunks nearer than this [m] (default: all)",
    )
    p.add_argument(
        "--every-scan",
        action="store_true",
        help="also keep the scans between keyframes (from the sensor pose reached since)",
    )
    add_outlier_options(p)
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_import)


def read_vp_bounds(path: str):
    """The :class:`VictoriaParkBounds` of a bounds file."""
    from cuikslam.datasets.calibrate import read_bounds_file
    from cuikslam.datasets.victoria_park import VictoriaParkBounds

    names = VictoriaParkBounds.names()
    return VictoriaParkBounds.from_dict(read_bounds_file(path, "victoria-park", names), path)


def _cmd_import(args: argparse.Namespace) -> int:
    from cuikslam._atomic import atomic_write_text
    from cuikslam.datasets.victoria_park import read_victoria_park
    from cuikslam.log.writer import write_log_file

    out = Path(args.output)
    gps_out = gps_path_for(out)
    check_output_path(out)
    check_output_path(gps_out)
    bounds = read_vp_bounds(args.bounds) if args.bounds else None
    log, reference = read_victoria_park(
        args.folder,
        start=args.start,
        duration=None if args.minutes is None else 60.0 * args.minutes,
        keyframe=args.keyframe,
        bounds=bounds,
        max_range=args.max_range,
        every_scan=args.every_scan,
    )
    declare_outliers(log, args)
    write_output(out, lambda: write_log_file(log, out))
    text = json.dumps(reference.to_json(), indent=1, allow_nan=False) + "\n"
    write_output(gps_out, lambda: atomic_write_text(gps_out, text))
    if not args.quiet:
        print(
            f"wrote {out} ({len(log.relative_poses)} moves, {len(log.observations)} "
            f"unlabelled tree observations) and its GPS reference {gps_out} "
            f"({len(reference.pose_ids)} poses with a fix)",
            file=sys.stderr,
        )
    return 0


def add_vp_calibrate_parser(datasets: argparse._SubParsersAction) -> None:
    """The ``victoria-park`` choice of ``cuikslam calibrate``."""
    p = datasets.add_parser(
        "victoria-park",
        help="the motion bounds of Victoria Park, against GPS",
        description="Scale the motion margins (speed scale and offset, steering, first "
        "heading) until every window's dead-reckoned boxes hold the GPS fixes within "
        "--gps-error; range and bearing stay stated (GPS sees no trunk), with the "
        "scan-to-scan consistency of the trunks reported. Checked on the next part.",
    )
    p.add_argument("folder", help="the dataset folder")
    p.add_argument("-o", "--output", required=True, help="bounds file to write (.json)")
    p.add_argument("--start", type=_finite, default=0.0, help="part start [s] (default 0)")
    p.add_argument(
        "--duration", type=_positive, default=300.0, help="part length [s] (default 300)"
    )
    p.add_argument("--window", type=_positive, default=20.0, help="window [s] (default 20)")
    p.add_argument(
        "--gps-error",
        type=_positive,
        default=2.5,
        help="GPS error allowed [m] in the windows' check (default 2.5)",
    )
    p.add_argument(
        "--window-heading",
        type=_positive,
        default=0.1,
        help="margin [rad] of each window's first heading around the one fitted to GPS "
        "(default 0.1)",
    )
    p.add_argument(
        "--quantile",
        type=_positive,
        default=1.0,
        help="share of the windows that must hold (default 1: all)",
    )
    p.add_argument(
        "--check-duration",
        type=_positive,
        default=300.0,
        help="length [s] of the checked part, after the calibrated one (default 300)",
    )
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_calibrate)


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from cuikslam.datasets.calibrate import write_bounds_file
    from cuikslam.datasets.victoria_park_calibrate import (
        calibrate_victoria_park,
        check_victoria_park,
        scan_consistency,
        window_starts,
    )
    from cuikslam.datasets.victoria_park_files import read_victoria_park_tables

    check_output_path(args.output)
    if args.quantile > 1:
        raise CommandError(f"--quantile {args.quantile}: at most 1")
    tables = read_victoria_park_tables(args.folder)
    calibration = calibrate_victoria_park(
        tables,
        start=args.start,
        duration=args.duration,
        window=args.window,
        quantile=args.quantile,
        gps_check=args.gps_error,
        window_heading=args.window_heading,
    )
    check_start = args.start + args.duration
    checked = check_victoria_park(
        tables,
        replace(calibration.bounds, heading=args.window_heading),
        window_starts(check_start, check_start + args.check_duration, args.window),
        window=args.window,
        keyframe=1.0,
        gps_check=args.gps_error,
    )
    calibration.calibrated_on["checked_on"] = {
        "start": check_start,
        "duration": args.check_duration,
        **checked,
    }
    calibration.errors["scan_to_scan"] = scan_consistency(
        tables, args.start, args.start + args.duration
    )
    write_output(
        args.output,
        lambda: write_bounds_file(calibration, args.output, dataset="victoria-park"),
    )
    if not args.quiet:
        b, w = calibration.bounds, calibration.errors["windows"]
        s = calibration.errors["scan_to_scan"]
        print(
            f"calibrated on {args.start:g}..{check_start:g} s ({w['windows']} windows of "
            f"{args.window:g} s, GPS error {args.gps_error:g} m): speed x[{b.speed_scale_min}, "
            f"{b.speed_scale_max}] ±{b.speed} m/s, steering ±{b.steering} rad, first heading "
            f"±{b.heading} rad; range ±{b.range} m, bearing ±{b.bearing} rad (stated; one "
            f"trunk in consecutive scans differs by p99 {s.get('range_p99', float('nan')):.3f} "
            f"m, {s.get('bearing_p99', float('nan')):.4f} rad)",
            file=sys.stderr,
        )
        print(
            f"  checked on {check_start:g}..{check_start + args.check_duration:g} s: "
            f"{checked['held']} of {checked['windows']} windows hold, {checked['inside']} of "
            f"{checked['fixes']} GPS fixes inside (worst {checked['worst']:.2f} m out)",
            file=sys.stderr,
        )
        print(f"wrote {args.output}", file=sys.stderr)
    return 0
