"""``cuikslam import lost-in-the-woods`` and ``cuikslam calibrate lost-in-the-woods``: the UTIAS
run as a log and its truth, and bounds measured on a part of it."""

from __future__ import annotations

import argparse
import sys

from cuikslam.cli._common import CommandError, check_output_path, int_at_least, write_output
from cuikslam.cli.mrclam import _positive, add_map_option, add_outlier_options, declare_outliers

__all__ = ["add_litw_calibrate_parser", "add_litw_import_parser"]


_samples = int_at_least(1)
_first_sample = int_at_least(0)


def add_litw_import_parser(datasets: argparse._SubParsersAction) -> None:
    """The ``lost-in-the-woods`` choice of ``cuikslam import``."""
    p = datasets.add_parser(
        "lost-in-the-woods",
        help="a window of UTIAS Lost in the Woods (dataset2.mat)",
        description="Convert a window of Lost in the Woods to a log and NAME.truth.json.",
    )
    p.add_argument("file", help="the dataset file (dataset2.mat)")
    p.add_argument("-o", "--output", required=True, help="log file to write (.jsonl)")
    p.add_argument("--start", type=_first_sample, default=0, help="first sample (default 0)")
    p.add_argument("--steps", type=_samples, default=None, help="samples (default: to the end)")
    p.add_argument(
        "--keyframe",
        "--stride",
        type=_samples,
        default=10,
        help="samples per pose; the odometry between is composed (default 10)",
    )
    p.add_argument("--known", action="store_true", help="keep landmark ids (known correspondence)")
    p.add_argument(
        "--bounds",
        help="bounds written by `cuikslam calibrate lost-in-the-woods` (odometry composed at "
        "face value and widened by the calibrated model; --range-bound and --bearing-bound "
        "override theirs)",
    )
    p.add_argument(
        "--speed-bound",
        type=_positive,
        default=None,
        help="per-sample speed error bound [m/s] (default 3 sd of the file's v_var; not with "
        "--bounds)",
    )
    p.add_argument(
        "--turn-rate-bound",
        type=_positive,
        default=None,
        help="per-sample turn-rate error bound [rad/s] (default 3 sd of the file's om_var; "
        "not with --bounds)",
    )
    p.add_argument("--range-bound", type=_positive, help="range bound [m] (default 0.16)")
    p.add_argument("--bearing-bound", type=_positive, help="bearing bound [rad] (default 0.15)")
    p.add_argument(
        "--keyframe-observations",
        action="store_true",
        help="keep only the observations made at a keyframe sample",
    )
    p.add_argument(
        "--posts",
        type=_samples,
        help="write a class record: at most this many posts (default without --known: as "
        "many as the file's map, 17)",
    )
    p.add_argument("--no-post-count", action="store_true", help="no 'at most' record for the posts")
    p.add_argument(
        "--post-separation",
        type=_positive,
        help="two posts are at least this far apart [m] (a class record; default none)",
    )
    add_map_option(p, "post")
    add_outlier_options(p)
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_import)


def _cmd_import(args: argparse.Namespace) -> int:
    from cuikslam.cli.commands import log_and_truth_outputs, write_log_and_truth
    from cuikslam.datasets import read_lost_in_the_woods

    out, truth_out = log_and_truth_outputs(args.output)
    bounds = _read_bounds(args.bounds) if args.bounds else None
    if bounds is not None and (args.speed_bound or args.turn_rate_bound):
        raise CommandError(
            "--bounds sets the odometry bounds: drop --speed-bound/--turn-rate-bound"
        )
    posts = args.posts
    if posts is None and not args.known:
        posts = "file"
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
        bounds=bounds,
        posts_at_most=None if args.no_post_count else posts,
        post_separation=args.post_separation,
        map_bound=args.map,
    )
    declare_outliers(log, args)
    write_log_and_truth(log, truth, out, truth_out, quiet=args.quiet)
    return 0


def _read_bounds(path: str):
    from dataclasses import fields

    from cuikslam.datasets.calibrate import read_bounds_file
    from cuikslam.datasets.lost_in_the_woods_bounds import LitwBounds

    names = [f.name for f in fields(LitwBounds)]
    return LitwBounds.from_dict(read_bounds_file(path, "lost-in-the-woods", names), path)


def add_litw_calibrate_parser(datasets: argparse._SubParsersAction) -> None:
    """The ``lost-in-the-woods`` choice of ``cuikslam calibrate``."""
    p = datasets.add_parser(
        "lost-in-the-woods",
        help="a part of UTIAS Lost in the Woods (dataset2.mat)",
        description="Range and bearing bounds from the post sightings against Vicon; a "
        "motion model (a constant plus a part per metre travelled or radian turned) for "
        "the odometry composed over each keyframe step and its parts. By default it is "
        "calibrated on the first half and checked on the second.",
    )
    p.add_argument("file", help="the dataset file (dataset2.mat)")
    p.add_argument("-o", "--output", required=True, help="bounds file to write (.json)")
    p.add_argument("--start", type=_first_sample, default=0, help="first sample (default 0)")
    p.add_argument("--steps", type=_samples, help="samples calibrated on (default: the first half)")
    p.add_argument(
        "--keyframe",
        type=_samples,
        default=10,
        help="longest stretch of odometry measured [samples]: imports may use keyframes up "
        "to it (default 10)",
    )
    p.add_argument(
        "--quantile",
        type=_positive,
        default=1.0,
        help="share of the part's sightings the range and bearing bounds must hold "
        "(default 1: all; below 1 the rest are outliers to declare with --outliers-window)",
    )
    p.add_argument(
        "--motion-quantile",
        type=_positive,
        default=1.0,
        help="the same for the stretches of odometry (default 1: a move outside its "
        "interval cannot be declared an outlier)",
    )
    p.add_argument(
        "--motion-margin",
        type=_positive,
        default=1.0,
        help="factor (>= 1) on the odometry bounds, for what the calibrated part did not "
        "show (default 1)",
    )
    p.add_argument(
        "--check-start",
        type=_first_sample,
        help="first sample of the checked part (default: where the calibrated part ends)",
    )
    p.add_argument("--check-steps", type=_samples, help="samples checked (default: to the end)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_calibrate)


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from cuikslam.datasets._litw_file import load_dataset
    from cuikslam.datasets.calibrate import write_bounds_file
    from cuikslam.datasets.lost_in_the_woods_bounds import (
        calibrate_lost_in_the_woods,
        count_outside_lost_in_the_woods,
    )

    check_output_path(args.output)
    for name in ("quantile", "motion_quantile"):
        if getattr(args, name) > 1:
            raise CommandError(f"--{name.replace('_', '-')} {getattr(args, name)}: at most 1")
    if args.motion_margin < 1:
        raise CommandError(f"--motion-margin {args.motion_margin}: at least 1")
    steps = args.steps
    if steps is None:
        steps = (load_dataset(args.file)["t"].size - args.start) // 2
    calibration = calibrate_lost_in_the_woods(
        args.file,
        start=args.start,
        steps=steps,
        keyframe=args.keyframe,
        quantile=args.quantile,
        motion_quantile=args.motion_quantile,
        motion_margin=args.motion_margin,
    )
    check_start = args.start + steps if args.check_start is None else args.check_start
    check = count_outside_lost_in_the_woods(
        args.file, calibration.bounds, start=check_start, steps=args.check_steps
    )
    calibration.calibrated_on["checked_on"] = {
        "start": check_start,
        "steps": args.check_steps,
        "outside": check.to_json(),
    }
    write_output(
        args.output,
        lambda: write_bounds_file(calibration, args.output, dataset="lost-in-the-woods"),
    )
    if not args.quiet:
        b, e = calibration.bounds, calibration.errors
        print(
            f"calibrated on samples {args.start}..{args.start + steps}: range ±{b.range} m "
            f"(errors: median {e['range']['median']:.3f}, max {e['range']['max']:.3f}), "
            f"bearing ±{b.bearing} rad (median {e['bearing']['median']:.4f}, max "
            f"{e['bearing']['max']:.4f}); odometry per stretch of up to {b.max_samples} "
            f"samples: x ±({b.move_x} m + {b.move_x_per_metre} per m), y ±({b.move_y} m + "
            f"{b.move_y_per_metre} per m), θ ±({b.move_theta} rad + "
            f"{b.move_theta_per_radian} per rad turned)",
            file=sys.stderr,
        )
        print(f"  the calibrated part: {calibration.outside.describe()}", file=sys.stderr)
        print(f"  checked on samples from {check_start}: {check.describe()}", file=sys.stderr)
        for line in check.worst[:10]:
            print(f"    {line}", file=sys.stderr)
        print(f"wrote {args.output}", file=sys.stderr)
    return 0
