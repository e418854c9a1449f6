"""``cuikslam view RESULT.json -o page.html``: an interactive page of a result, one
self-contained HTML file (:func:`cuikslam.results.figures.page.write_page`).

Needs Bokeh (``pip install "cuikslam[view]"``); without it the command says so in one line
and exits with status 2, before reading anything.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cuikslam.cli._common import (
    EXIT_OK,
    CommandError,
    check_output_path,
    int_at_least,
    write_output,
)

__all__ = ["PAGE_SUFFIXES", "add_view_parser"]

PAGE_SUFFIXES = (".html", ".htm")


def add_view_parser(sub: argparse._SubParsersAction) -> None:
    """The ``view`` command (imports nothing heavy: every command builds it)."""
    p = sub.add_parser(
        "view",
        help="write an interactive page of a result JSON (one self-contained HTML file)",
        description="Write one self-contained HTML page (nothing fetched from the network) "
        "of a result: the path, pose boxes and heading intervals, landmarks, every reported "
        "hypothesis (a selector), the envelope, the truth (--truth), a slider that shows "
        "the boxes up to pose k, and what the survivors agree on. Long runs draw every k-th "
        "pose box, the last and the widest, and a zoom on the widest stretch. Needs pip "
        'install "cuikslam[view]" (Bokeh).',
    )
    p.add_argument("result", help="result JSON written by `cuikslam solve --json`")
    p.add_argument("-o", "--output", required=True, help="the page to write (.html)")
    p.add_argument("--truth", help="ground-truth JSON to draw as points")
    p.add_argument(
        "--max-pose-boxes",
        type=int_at_least(1),
        default=None,
        metavar="N",
        help="pose boxes drawn at most per hypothesis (every k-th, the last and the widest; "
        "default 60, as the figures; the path runs through every pose)",
    )
    p.add_argument("--title", help="the page's title (default: cuikslam view: RESULT)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_view)


def _cmd_view(args: argparse.Namespace) -> int:
    from cuikslam.results.figures.page import BokehMissingError, require_bokeh

    if Path(args.output).suffix.lower() not in PAGE_SUFFIXES:
        raise CommandError(f"{args.output}: a page's name ends with .html")
    check_output_path(args.output)
    try:
        require_bokeh()
    except BokehMissingError as err:
        raise CommandError(str(err)) from None

    from cuikslam.outcome.solution import no_hypothesis
    from cuikslam.results.figures.geometry import MAX_POSE_BOXES
    from cuikslam.results.figures.page import write_page
    from cuikslam.results.io import read_result_file
    from cuikslam.simulate.truth import check_truth_fits, read_truth_file

    solution = read_result_file(args.result)
    truth = read_truth_file(args.truth) if args.truth else None
    if not solution.hypotheses and solution.envelope is None:
        raise CommandError(f"{args.result}: nothing to view ({no_hypothesis(solution)})")
    if truth is not None:
        check_truth_fits(truth, args.truth, solution, args.result, assignment_optional=True)
    title = args.title or f"cuikslam view: {Path(args.result).name}"
    boxes = args.max_pose_boxes or MAX_POSE_BOXES
    write_output(
        args.output,
        lambda: write_page(solution, args.output, truth, title=title, max_pose_boxes=boxes),
    )
    if not args.quiet:
        size = Path(args.output).stat().st_size
        n = len(solution.hypotheses)
        print(
            f"wrote {args.output} ({size / 1e6:.1f} MB): {n} hypothes{'is' if n == 1 else 'es'}"
            f"{', the envelope' if solution.envelope is not None else ''}"
            f"{', the truth' if truth is not None else ''}",
            file=sys.stderr,
        )
    return EXIT_OK
