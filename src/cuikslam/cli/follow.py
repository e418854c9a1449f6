"""``cuikslam follow``: the boxes of a log as it is written, one JSON line per pose."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import TYPE_CHECKING, TextIO

from cuikslam.budget import ONLINE_WORK_PER_POSE
from cuikslam.cli._common import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_RESULT,
    CommandError,
    check_output_path,
    limit_or_none,
    positive_float,
)
from cuikslam.errors import InputFileError

if TYPE_CHECKING:
    from cuikslam.online.estimate import PoseEstimate
    from cuikslam.online.follow import FollowReport
    from cuikslam.simulate.truth import GroundTruth

MISSES_SHOWN = 5
"""Bounds that miss the truth shown by ``--truth``."""

__all__ = ["add_follow_parser", "run_follow"]


def add_follow_parser(sub: argparse._SubParsersAction) -> None:
    """The ``follow`` subcommand's parser."""
    p = sub.add_parser(
        "follow",
        help="the boxes of a log as it is written: one JSON line per pose",
        description="Read a log as it is written (a file, standard input, or a growing "
        "file) and, as each pose is finished (a record reaches a later pose, or the input "
        'ends), write one JSON line: {"pose", "x", "y", "theta", "latency_s", '
        '"hypotheses"}. An unbounded side is null. On a terminal a status line shows the '
        "newest box.",
    )
    p.add_argument("log", help="the log (JSON Lines, see docs/log-format.md); - for standard input")
    p.add_argument(
        "-o", "--output", metavar="FILE", help="write the JSON lines here (default: stdout)"
    )
    p.add_argument(
        "--wait",
        nargs="?",
        type=positive_float,
        const=math.inf,
        default=None,
        metavar="SECONDS",
        help="follow a growing file, like tail -f: at its end, wait for more lines, until "
        "Ctrl-C, or until it has not grown for SECONDS",
    )
    p.add_argument(
        "--rate",
        type=positive_float,
        default=None,
        metavar="FACTOR",
        help='feed the records at their recorded times (their "time" field), FACTOR times '
        "as fast (1: the recorded pace), and report whether the boxes ever fell behind",
    )
    p.add_argument(
        "--consistency",
        choices=["hull", "lp"],
        default="hull",
        help="'hull' (default): the fixpoint of the narrowing operators; 'lp': also, once a "
        "pose's line is written, the polytope-hull operator on the window of the last "
        "poses, when time allows (known correspondence)",
    )
    p.add_argument(
        "--work-per-pose",
        type=_work,
        default=ONLINE_WORK_PER_POSE,
        metavar="UNITS",
        help="work units the narrowing may spend before a finished pose's box is written "
        "(the rest is done right after; the boxes stay sound); 'none': to the fixpoint "
        "(default %(default)g)",
    )
    p.add_argument(
        "--truth",
        metavar="FILE",
        help="ground-truth JSON: at the end, report whether every box written holds its "
        "true pose (exit status 1 if not)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no status line, no summary")
    p.set_defaults(func=run_follow)


def _work(text: str) -> float | None:
    return limit_or_none(text, "work units")


class _Status:
    """The live status line on a terminal's stderr (nothing elsewhere)."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self.shown = False

    def show(self, text: str) -> None:
        if self.enabled:
            sys.stderr.write("\r\x1b[K" + text)
            sys.stderr.flush()
            self.shown = True

    def clear(self) -> None:
        if self.shown:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()
            self.shown = False


def _status_text(estimate: PoseEstimate) -> str:
    import numpy as np

    with np.errstate(invalid="ignore"):
        x, y, theta = (f"{w:.3g}" for w in estimate.box[:, 1] - estimate.box[:, 0])
    return (
        f"pose {estimate.pose}: x {x} m, y {y} m, θ {theta} rad wide; "
        f"{1000 * estimate.latency_s:.1f} ms; hypotheses {estimate.hypotheses}"
    )


class _LazyFile:
    """An output file created at its first line, each line written whole and flushed, so
    that a reader following it never sees half a line, and bad input before the first
    pose leaves no file."""

    def __init__(self, path: str | None) -> None:
        self.path = path
        self.file: TextIO | None = None

    def write_line(self, text: str) -> None:
        if self.file is None:
            if self.path is None:
                self.file = sys.stdout
            else:
                try:
                    self.file = open(self.path, "w", encoding="utf-8")
                except OSError as err:
                    raise CommandError(f"{self.path}: cannot write: {err.strerror}") from None
        self.file.write(text + "\n")
        self.file.flush()

    def close(self) -> None:
        if self.file is not None and self.file is not sys.stdout:
            self.file.close()


def run_follow(args: argparse.Namespace) -> int:
    """Follow ``args.log``; returns the exit status."""
    if args.output:
        check_output_path(args.output)
    from cuikslam.online.follow import follow, log_lines
    from cuikslam.online.session import Session, warm_up

    truth = None
    if args.truth:
        from cuikslam.simulate.truth import read_truth_file

        truth = read_truth_file(args.truth)
    name = "<stdin>" if args.log == "-" else args.log
    source = sys.stdin if args.log == "-" else _open_log(args.log)
    warm_up(unknown=True, lp=args.consistency == "lp")
    status = _Status(not args.quiet)
    sink = _LazyFile(args.output)
    to_terminal = args.output is None and sys.stdout.isatty()

    given: list[PoseEstimate] = []

    def on_pose(estimate: PoseEstimate) -> None:
        given.append(estimate)
        if to_terminal:
            status.clear()
        sink.write_line(json.dumps(estimate.to_json()))
        status.show(_status_text(estimate))

    started = time.perf_counter()
    session = Session(consistency=args.consistency, path=name, work_per_pose=args.work_per_pose)
    try:
        lines = log_lines(source, path=name, wait=args.wait)
        report = follow(lines, session, on_pose, rate=args.rate)
    finally:
        status.clear()
        sink.close()
        if source is not sys.stdin:
            source.close()
    if not args.quiet:
        _summary(report, time.perf_counter() - started, args.rate)
    if report.refuted is not None:
        print(f"cuikslam: {report.refuted}", file=sys.stderr)
        return EXIT_RESULT
    if truth is not None and not _truth_holds(given, truth):
        return EXIT_RESULT
    return EXIT_INTERRUPTED if report.interrupted else EXIT_OK


def _truth_holds(given: list[PoseEstimate], truth: GroundTruth) -> bool:
    """Say on stderr whether every box written holds its true pose."""
    from cuikslam.online.estimate import check_estimates

    report = check_estimates(given, truth)
    poses = report.checked // 3
    if report.ok:
        print(f"cuikslam: truth: all {poses} boxes with a true pose hold it", file=sys.stderr)
        return True
    print(f"cuikslam: truth: {len(report.misses)} bounds miss it, e.g.:", file=sys.stderr)
    for miss in report.misses[:MISSES_SHOWN]:
        print(f"  {miss}", file=sys.stderr)
    return False


def _open_log(path: str) -> TextIO:
    try:
        return open(path, encoding="utf-8-sig")
    except OSError as err:
        raise InputFileError(path, None, f"cannot read the log: {err.strerror or err}") from None


def _summary(report: FollowReport, elapsed: float, rate: float | None) -> None:
    if report.poses:
        print(
            f"cuikslam: {report.poses} poses in {elapsed:.2f} s; latency per pose: median "
            f"{1000 * report.latency_percentile(50):.2f} ms, 99th percentile "
            f"{1000 * report.latency_percentile(99):.2f} ms, max "
            f"{1000 * max(report.latencies_s):.2f} ms",
            file=sys.stderr,
        )
    if rate is not None:
        if report.instants == 0:
            print(
                "cuikslam: --rate: the log has no time stamps; fed as fast as read", file=sys.stderr
            )
        elif report.late == 0:
            print(
                f"cuikslam: at {rate:g}x the recorded pace: never behind "
                f"({report.instants} time stamps)",
                file=sys.stderr,
            )
        else:
            print(
                f"cuikslam: at {rate:g}x the recorded pace: behind at {report.late} of "
                f"{report.instants} time stamps (worst {1000 * report.worst_late_s:.1f} ms "
                f"late, line {report.worst_late_line})",
                file=sys.stderr,
            )
