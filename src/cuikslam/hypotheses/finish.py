"""What follows the correspondence search, wherever it ran (one process or a cluster):
the survivors' bisection, their ranking, the stronger level in that order, the reported
hypotheses, the summary, the statistics and the account of a budget stop
(:func:`finish_search`).

Messages that name an option are :class:`~cuikslam.messages.Message` objects, worded as
the Python API spells the option; the command line words them with its flags
(:mod:`cuikslam.cli._messages`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict

from cuikslam.hypotheses.bisection import refute_by_bisection
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.labelled import has_labelled_logs, solve_labelled
from cuikslam.hypotheses.problem import Problem
from cuikslam.hypotheses.progress import decided_after_stop
from cuikslam.hypotheses.survivors import (
    Entry,
    Refute,
    bisect_with_reserve,
    hypothesis_of,
    strengthen_with_reserve,
    unreported,
)
from cuikslam.hypotheses.tally import Tally
from cuikslam.hypotheses.tree import Node
from cuikslam.log.records import Log
from cuikslam.messages import Message
from cuikslam.options import SolveOptions
from cuikslam.outcome.solution import Solution
from cuikslam.outcome.summary import describe, summarize, summary_to_json
from cuikslam.outliers import search_outliers_json

__all__ = ["SHOWN_PLACES", "Rank", "branch_places", "finish_search"]

SHOWN_PLACES = 5
"""Observations named, where unexplored subtrees branch, in the message of a search stopped
by its budget."""


Rank = Callable[[Solution], object]
"""Orders the hull-level report before the stronger level narrows it (the least-squares
fit, :func:`~.witness.fit.fit_hypotheses`): it may reorder ``Solution.hypotheses``, put
``Solution.unreported`` survivors in place of reported ones (with boxes of their own,
level ``hull``), and add statistics, timings and messages."""


def branch_places(log: Log, explorer: Explorer, unexplored: list[list[int]]) -> str:
    """Where the unexplored subtrees branch, for a message: the observation whose other
    landmarks each would try (its log line, or its place in the log when it was built in
    code), the next to explore first, each observation once.

    >>> from cuikslam.log import parse_log_lines
    >>> from cuikslam.hypotheses.problem import build_problem
    >>> log = parse_log_lines([
    ...     '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
    ...     '{"type": "observation", "pose": 0, "class": "c", "range": [1, 2], "bearing": [0, 1]}',
    ...     '{"type": "observation", "pose": 0, "class": "c", "range": [3, 4], "bearing": [0, 1]}',
    ... ])
    >>> explorer = Explorer(build_problem(log), 1e-3, "hull", 0, True)
    >>> branch_places(log, explorer, [[0], [0, 1], [1, 0]])
    'line 3 (pose 0), line 2 (pose 0)'
    """
    decisions = explorer.problem.decisions
    places: list[str] = []
    for prefix in unexplored[::-1]:
        if not prefix:
            place = "the first observation without a landmark id"
        else:
            decision = decisions[len(prefix) - 1]
            record = log.records[decision.record]
            where = (
                f"line {record.line}"
                if record.line
                else f"the observation of index {decision.position}"
            )
            place = f"{where} (pose {decision.pose})"
        if place not in places:
            places.append(place)
        if len(places) == SHOWN_PLACES:
            break
    return ", ".join(places)


def _decided(problem: Problem, tally: Tally, unexplored: list[list[int]]) -> str:
    """What a stopped search decided, for its message ('' when its survivors were too
    many to hold)."""
    found = tally.found()
    if found is None:
        return ""
    decided = len(decided_after_stop(problem, unexplored, found))
    return (
        f"{decided:,} of {len(problem.decisions):,} readings are decided (associated alike "
        "by every survivor found and every subtree left); "
    )


def finish_search(
    log: Log,
    explorer: Explorer,
    tally: Tally,
    found: list[Node],
    unexplored: list[list[int]],
    stop_reason: str | None,
    options: SolveOptions,
    progress: Callable[[int, int], None] | None,
    start: float,
    messages: list[str],
    refute: Refute = refute_by_bisection,
    rank: Rank | None = None,
    reserve: list[Node] | None = None,
    unexplored_covered: bool = False,
) -> Solution:
    """What follows the search, wherever it ran: the survivors' bisection, their ranking
    (``rank``, when given), the stronger level in that order, the reported hypotheses,
    the summary, the statistics and the account of a budget stop.

    ``options`` are the search's (its level and ``strengthen_limit`` here), ``found``
    are the best-ranked survivors (nodes of ``explorer``), ``explorer.stats``
    counts the whole search, ``unexplored`` names the subtrees left by a budget stop
    (``stop_reason``), the next one to explore last; ``refute`` runs the survivors'
    bisections (on a cluster, their share on each worker); ``reserve`` are the next
    best-ranked survivors, bisected in turn to take the place of those it refutes.
    ``unexplored_covered`` says the boxes of the ``unexplored`` subtrees' nodes are in
    ``tally.envelope`` already; else the envelope takes the root's boxes for them.
    """
    problem = explorer.problem
    stats = explorer.stats
    consistency, strengthen_limit = options.consistency, options.strengthen_limit
    complete = stop_reason is None
    if unexplored and not unexplored_covered:
        tally.envelope.cover_root()
    if not complete:
        stats.unexplored_subtrees = len(unexplored)
        one = len(unexplored) == 1
        messages.append(
            f"the search stopped on its {stop_reason} with {len(unexplored):,} "
            f"{'subtree' if one else 'subtrees'} unexplored: the result is INCOMPLETE, and the "
            f"true hypothesis may be in {'it' if one else 'them'}; "
            f"{_decided(problem, tally, unexplored)}the next ones to explore try other "
            f"landmarks for the observations at {branch_places(log, explorer, unexplored)}"
        )
    as_leaves = stats.refuted_by_bisection
    survivors, bisected, spare = bisect_with_reserve(
        explorer, tally, found, reserve or [], strengthen_limit, refute
    )
    if stats.refuted_by_bisection:
        after = stats.refuted_by_bisection - as_leaves
        words = ("hypothesis", "its", "box"), ("hypotheses", "their", "boxes")
        what, whose, boxes = words[stats.refuted_by_bisection != 1]
        messages.append(
            f"bisection proved {stats.refuted_by_bisection} {what} impossible that narrowing "
            f"{whose} whole {boxes} left ({as_leaves} as the search reached them, {after} of "
            f"{bisected} survivors after it): every part of {whose} {boxes} contracts to "
            "empty"
        )
    report: list[Entry] = sorted(
        ((hypothesis_of(explorer, n), n) for n in survivors), key=lambda r: r[0].rank_key
    )
    ranked = Solution([h for h, _ in report], unreported=unreported(tally, problem, report))
    if rank is not None and (len(report) > 1 or ranked.unreported):
        node_of = {id(h): n for h, n in report}
        rank(ranked)
        report = [(h, node_of.get(id(h))) for h in ranked.hypotheses]
        ranked.unreported = []  # used
    rtol, deadline = explorer.graph.rtol, explorer.deadline
    labelled = (
        (lambda h: solve_labelled(log, h.assignment, consistency, rtol, deadline, options.threads))
        if has_labelled_logs(log)
        else None
    )
    report, refuted, level = strengthen_with_reserve(
        explorer, report, spare, consistency, strengthen_limit, messages, labelled
    )
    for h, node in refuted:  # by the stronger level
        if node is None:
            tally.discard_assignment(h.assignment)
        else:
            tally.discard(node)
        stats.survivors -= 1
    hypotheses = sorted((h for h, _ in report), key=lambda h: h.rank_key)
    messages.extend(ranked.messages)
    if stats.survivors > len(found):
        messages.append(
            Message(
                "survivors_beyond_report",
                f"{stats.survivors} hypotheses survived; the {len(hypotheses)} best-ranked are "
                "reported (raise max_hypotheses to see more)",
                survivors=stats.survivors,
                reported=len(hypotheses),
            )
        )
    correspondence = None
    if hypotheses or stats.survivors:  # survivors beyond the report still count
        kept = tally.kept()
        summary = summarize(kept, set(problem.named), tally.poses())
        messages.append(describe(summary, stats.survivors, complete, len(kept)))
        correspondence = {
            **summary_to_json(summary),
            "reported": len(hypotheses),
            "survivors": stats.survivors,
            "summarised": len(kept),
            "complete": complete,
        }
    if not hypotheses and stats.survivors:
        messages.append(
            Message(
                "reported_survivors_refuted",
                f"the {len(found)} best-ranked survivors were proven impossible after the "
                f"search; the other {stats.survivors} were not kept for the report (raise "
                "max_hypotheses): the log is NOT proven inconsistent",
                refuted=len(found),
                others=stats.survivors,
            )
        )
    elif not hypotheses:
        messages.append(
            "every correspondence hypothesis is proven impossible: the log is inconsistent"
            if complete
            else "no hypothesis found in the explored part of the search (not a proof)"
        )
    stats.operator_applications += explorer.graph.applications
    statistics = {key: float(v) if isinstance(v, float) else v for key, v in asdict(stats).items()}
    statistics.update(
        poses=len(problem.pose_x),
        observations=problem.n_observations,
        hypotheses=len(hypotheses),
        **ranked.statistics,
    )
    if progress is not None and complete:
        progress(1000, 1000)
    outliers = search_outliers_json(log, problem.named_positions, problem.named_outliers)
    if outliers is not None:
        statistics["outliers_proven"] = len(outliers["proven"])
    return Solution(
        hypotheses=hypotheses,
        complete=complete,
        statistics=statistics,
        timings={
            "solve_s": time.perf_counter() - start,
            "ambiguity_lp_s": explorer.ambiguity_lp_s,
            **({} if explorer.proven_at is None else {"dive_proven_s": explorer.proven_at - start}),
            **ranked.timings,
        },
        log_path=log.path,
        consistency=str(level if hypotheses else consistency),
        messages=messages,
        correspondence=correspondence,
        outliers=outliers,
        envelope=tally.envelope.boxes(),
        unreported=ranked.unreported,
    )
