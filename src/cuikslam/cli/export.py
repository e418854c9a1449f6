"""``cuikslam export RESULT --format tum|g2o -o FILE``: a result (or a truth file) in the
formats of evo and g2o.

A result exports one hypothesis (``--hypothesis``, the best by default) as its witness or
its box centres (``--point``); a truth file exports the truth, so that
``evo_ape tum truth.txt traj.txt`` compares the two. ``g2o`` also needs the log (``--log``,
by default the log the result names).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cuikslam.cli._common import (
    EXIT_OK,
    CommandError,
    check_output_path,
    int_at_least,
    write_output,
)
from cuikslam.cli._messages import worded
from cuikslam.cli.mrclam import _positive
from cuikslam.errors import InputFileError

__all__ = ["add_export_parser"]


def add_export_parser(sub: argparse._SubParsersAction) -> None:
    """The ``export`` command (imports nothing heavy: every command builds it)."""
    p = sub.add_parser(
        "export",
        help="write a result or a truth file as a TUM trajectory (evo) or a g2o graph",
        description="Write one hypothesis of a result (its witness, or its box centres; "
        "the header says which), or a truth file, as a TUM trajectory that evo_traj, "
        "evo_ape and evo_rpe read (timestamp = pose id), or as a g2o graph (VERTEX_SE2, "
        "VERTEX_XY, EDGE_SE2, EDGE_SE2_XY, ...) with the log's readings as edges.",
    )
    p.add_argument("input", help="a result JSON (cuikslam solve --json) or a truth JSON")
    p.add_argument("--format", required=True, choices=["tum", "g2o"], help="the file format")
    p.add_argument("-o", "--output", required=True, help="the file to write")
    p.add_argument(
        "--hypothesis",
        type=int_at_least(1),
        default=1,
        metavar="RANK",
        help="which reported hypothesis of a result (default 1, the best-ranked)",
    )
    p.add_argument(
        "--point",
        choices=["auto", "witness", "centres"],
        default="auto",
        help="the hypothesis' witness, its box centres, or auto (default): the witness "
        "when it has one",
    )
    p.add_argument(
        "--log",
        help="g2o: the solved log (default: the log the result names); needed for a truth file",
    )
    p.add_argument(
        "--sigma-scale",
        type=_positive,
        default=1.0,
        metavar="S",
        help="g2o: standard deviation per interval half-width (default 1; 1/3 reads the "
        "intervals as 3-sigma bounds)",
    )
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_export)


def _is_truth(path: str) -> bool:
    """Whether ``path`` holds a truth file rather than a result (a result has hypotheses)."""
    try:
        with open(path, encoding="utf-8") as handle:
            doc = json.load(handle)
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return False  # the result reader says what is wrong with it
    return isinstance(doc, dict) and "hypotheses" not in doc and "poses" in doc


def _cmd_export(args: argparse.Namespace) -> int:
    from cuikslam.interop.estimate import hypothesis_estimate, truth_estimate
    from cuikslam.outcome.solution import no_hypothesis

    check_output_path(args.output)
    if _is_truth(args.input):
        from cuikslam.simulate.truth import read_truth_file

        truth = read_truth_file(args.input)
        point, assignment = truth_estimate(truth), truth.assignment
        what = f"the truth file {args.input}"
        log_path = args.log
    else:
        from cuikslam.results.io import read_result_file

        solution = read_result_file(args.input)
        if not solution.hypotheses:
            raise CommandError(
                f"{args.input}: no hypothesis to export ({worded(no_hypothesis(solution))})"
            )
        if args.hypothesis > len(solution.hypotheses):
            raise CommandError(
                f"{args.input}: --hypothesis {args.hypothesis}, but the result reports "
                f"{len(solution.hypotheses)}"
            )
        hypothesis = solution.hypotheses[args.hypothesis - 1]
        try:
            point = hypothesis_estimate(hypothesis, args.point)
        except ValueError as err:
            raise CommandError(f"{args.input}: hypothesis {args.hypothesis}: {err}") from None
        assignment = hypothesis.assignment
        what = f"hypothesis {args.hypothesis} ({hypothesis.status}) of {args.input}"
        log_path = args.log or solution.log_path
    comments = [f"exported from {what}"]
    if args.format == "tum":
        from cuikslam.interop.tum import write_tum_file

        write_output(args.output, lambda: write_tum_file(point, args.output, comments))
    else:
        _write_g2o(args, log_path, point, assignment, comments)
    if not args.quiet:
        print(
            f"wrote {args.output}: {len(point.pose_ids)} poses ({point.source}) of {what}",
            file=sys.stderr,
        )
    return EXIT_OK


def _write_g2o(args: argparse.Namespace, log_path: str | None, point, assignment, comments) -> None:
    """The g2o file: the log's records as edges under ``assignment``, vertices at ``point``."""
    from cuikslam.interop.g2o import write_g2o_file
    from cuikslam.log.reader import read_log_file

    if not log_path:
        raise CommandError(f"{args.input}: --format g2o needs the log: give --log LOG")
    if args.log is None and not Path(log_path).is_file():
        raise CommandError(
            f"{args.input}: the result's log {log_path} is not there: give --log LOG"
        )
    log = read_log_file(log_path)
    try:
        write_output(
            args.output,
            lambda: write_g2o_file(
                log, point, assignment, args.output, scale=args.sigma_scale, comments=comments
            ),
        )
    except ValueError as err:
        if isinstance(err, InputFileError):
            raise
        raise CommandError(f"{args.input} does not fit the log {log_path}: {err}") from None
