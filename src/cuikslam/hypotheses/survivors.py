"""After the search: its survivors bisected (the reserve taking the place of those
refuted), each as the user sees it (a :class:`~cuikslam.outcome.solution.Hypothesis`),
and the stronger consistency level on the report, in rank order."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cuikslam.budget import SCHEDULE, expired
from cuikslam.hypotheses.bisection import Bisection, refute_by_bisection
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.outlier_option import OUTLIER
from cuikslam.hypotheses.problem import Problem
from cuikslam.hypotheses.tally import Tally
from cuikslam.hypotheses.tree import Node
from cuikslam.messages import Message
from cuikslam.options import Level
from cuikslam.outcome.naming import anonymous_names, partition
from cuikslam.outcome.solution import OUTLIER as OUTLIER_MARK
from cuikslam.outcome.solution import Hypothesis

__all__ = [
    "Entry",
    "Refute",
    "bisect_with_reserve",
    "hypothesis_of",
    "strengthen_report",
    "strengthen_with_reserve",
    "unreported",
]

MAX_UNREPORTED = 1000
"""Survivors beyond the report whose assignments the solution keeps (``unreported``), for
the least-squares fit that may report them instead (:mod:`.witness.fit`)."""
BEST_ATTEMPTS = 10
"""Beyond ``strengthen_limit`` survivors, the best-ranked are tried until one is not refuted."""
BISECTION_PARTS = 512
"""Parts each survivor's bisection may narrow at most."""
BISECTION_TOTAL_PARTS = 32_768
"""Parts the bisections of all survivors together may narrow at most (with a budget, its
share bounds them first)."""
BISECTION_PARTS_PER_NODE = 1
"""Without a budget, parts the bisections may narrow per node the search created (at
least ``BISECTION_MIN_PARTS``): bisection then costs about as much as the search did."""
BISECTION_MIN_PARTS = 256
Entry = tuple[Hypothesis, Node | None]
"""A reported hypothesis and its node (None when the ranking put it in the report)."""


def hypothesis_of(explorer: Explorer, node: Node) -> Hypothesis:
    """A survivor as the user sees it: landmark names, assignment in log order, boxes."""
    p = explorer.problem
    lo, hi = explorer.graph.materialize(node.overlay)
    xs = explorer.landmark_xs(node)
    first = [*p.first_seen, *(p.decisions[k].record for k in node.blocks)]
    order = sorted(range(len(xs)), key=lambda n: first[n])
    fresh = anonymous_names(set(p.named))
    names: dict[int, str] = {OUTLIER: OUTLIER_MARK}
    for n in order:
        names[n] = p.named[n] if n < explorer.n_named else next(fresh)
    assignment = [""] * p.n_observations
    for position, n in p.named_assignment.items():
        assignment[position] = names[n]
    for d, n in zip(p.decisions, node.decisions(), strict=True):
        assignment[d.position] = names[n]
    pose_ids = list(p.pose_x)  # in the order the log first mentions them, as a known solve
    cols = np.array([p.pose_x[q] for q in pose_ids], dtype=np.int64)[:, None] + np.arange(3)
    lcols = xs[order][:, None] + np.arange(2)
    return Hypothesis(
        assignment=assignment,
        pose_ids=pose_ids,
        poses=np.stack([lo[cols], hi[cols]], axis=-1),
        landmark_ids=[names[n] for n in order],
        landmark_classes=[explorer.landmark_class(node, n) for n in order],
        landmarks=np.stack([lo[lcols], hi[lcols]], axis=-1).reshape(-1, 2, 2),
        consistency=node.level,
    )


def unreported(tally: Tally, problem: Problem, report: list[Entry]) -> list[list[str]]:
    """The assignments of the first ``MAX_UNREPORTED`` survivors not in ``report`` (none
    when every survivor is reported)."""
    if tally.explorer.stats.survivors <= len(report):
        return []
    named = set(problem.named)
    shown = {tuple(partition(h.assignment, named)) for h, _ in report}
    unreported: list[list[str]] = []
    for a in tally.kept():
        if len(unreported) >= MAX_UNREPORTED:
            break
        if tuple(partition(a, named)) not in shown:
            unreported.append(a)
    return unreported


Refute = Callable[[list[Bisection], float | None, int, int], list[bool]]
"""Runs bisections (a list, a deadline, parts per bisection, parts in all) and says which
are refuted: :func:`~.bisection.refute_by_bisection`, or a cluster's map of it."""


def bisect_survivors(
    explorer: Explorer, survivors: list[Node], limit: int, refute: Refute = refute_by_bisection
) -> list[Node]:
    """The survivors that bisection does not prove impossible (:mod:`.bisection`), when
    there are 2 to ``limit`` of them; it may use the schedule's ``bisection`` share of the
    budget left and ``BISECTION_PARTS`` parts per survivor, ``BISECTION_TOTAL_PARTS`` in all, or
    without a budget ``BISECTION_PARTS_PER_NODE`` per node created by the search (at least
    ``BISECTION_MIN_PARTS``). ``refute`` runs them."""
    if len(survivors) < 2 or len(survivors) > limit:
        return survivors  # a lone survivor is left to the witness search to prove
    deadline = SCHEDULE.share(explorer.deadline, "bisection")
    bisections = [explorer.bisection(node) for node in survivors]
    total = BISECTION_TOTAL_PARTS
    if deadline is None or deadline.unlimited:
        per_node = BISECTION_PARTS_PER_NODE * explorer.stats.created
        total = min(total, max(BISECTION_MIN_PARTS, per_node))
    refuted = refute(bisections, deadline, BISECTION_PARTS, total)
    explorer.stats.refuted_by_bisection += sum(refuted)
    return [n for n, r in zip(survivors, refuted, strict=True) if not r]


def bisect_with_reserve(
    explorer: Explorer,
    tally: Tally,
    found: list[Node],
    reserve: list[Node],
    limit: int,
    refute: Refute,
) -> tuple[list[Node], int, list[Node]]:
    """The survivors of :func:`bisect_survivors` on ``found``; while it refutes some and
    time is left, the next of ``reserve`` (best-ranked first) are bisected in their place,
    so that a report is not left short (or empty) while survivors the search counted
    wait. Returns the survivors, how many were bisected, and the reserve left; those
    refuted leave the tally and the count."""
    survivors = bisect_survivors(explorer, found, limit, refute)
    tried = list(found)
    while reserve and len(survivors) < len(found) and not expired(explorer.deadline):
        take, reserve = (
            reserve[: len(found) - len(survivors)],
            reserve[len(found) - len(survivors) :],
        )
        tried += take
        survivors += bisect_survivors(explorer, take, limit, refute)
    alive = {tuple(n.decisions()) for n in survivors}
    for node in tried:
        if tuple(node.decisions()) not in alive:  # refuted by bisection
            tally.discard(node)
            explorer.stats.survivors -= 1
    return survivors, len(tried), reserve


def strengthen_report(
    explorer: Explorer,
    report: list[Entry],
    level: Level,
    limit: int,
    messages: list[str],
    labelled: Callable[[Hypothesis], Hypothesis | None] | None,
) -> tuple[list[Entry], list[Entry], str]:
    """Narrow the reported hypotheses to ``level`` in report order: all of them when at
    most ``limit`` are reported, else the first until one is not refuted. A hypothesis
    is narrowed on its labelled log (``labelled``, :func:`.labelled.solve_labelled`; None
    for a log without labelled logs) when it has no node (the ranking put it in the
    report) or the log has no negative information: the labelled log then holds the same
    constraints, without the search's unused landmark slots (on Lost in the Woods, 201
    poses, 4,541 variables instead of 6,645: ``lp`` in 6 s instead of 43 s, the same
    boxes to 1 %). Otherwise it is narrowed as a node of the search. Returns the report,
    the entries refuted, and the level all of them reach."""
    if level is Level.HULL or not report:
        return report, [], str(level)
    every = len(report) <= limit
    if not every:
        messages.append(
            Message(
                "strengthen_limit",
                f"{len(report)} hypotheses are reported: the '{level}' level was applied to "
                f"one of them only, the first in rank order (to all when at most {limit}; "
                "raise strengthen_limit); the others' boxes are at least hull-consistent",
                reported=len(report),
                level=str(level),
                limit=limit,
            )
        )
    same = labelled is not None and not explorer.problem.has_sensor  # the same constraints
    refuted: list[Entry] = []
    reached = [] if every else ["hull"]
    out: list[Entry] = []
    attempts, done = 0, False
    for h, node in report:
        wanted = every or (not done and attempts < BEST_ATTEMPTS)
        if not wanted or (node is None and labelled is None):
            reached.append(h.consistency)
            out.append((h, node))
            continue
        attempts += 1
        if labelled is not None and (node is None or same):
            better = labelled(h)
        else:
            narrowed = explorer.strengthen_node(node, level)
            better = None if narrowed is None else hypothesis_of(explorer, narrowed)
        if better is None:
            refuted.append((h, node))
            continue
        done = True
        better.fit = h.fit
        reached.append(better.consistency)
        out.append((better, node))
    short = [v for v in reached if v != level]  # cut short by a deadline, or never narrowed
    return out, refuted, short[0] if short else str(level)


def strengthen_with_reserve(
    explorer: Explorer,
    report: list[Entry],
    reserve: list[Node],
    level: Level,
    limit: int,
    messages: list[str],
    labelled: Callable[[Hypothesis], Hypothesis | None] | None,
) -> tuple[list[Entry], list[Entry], str]:
    """:func:`strengthen_report` on ``report``; when it refutes every entry and time is
    left, the next ``BEST_ATTEMPTS`` of ``reserve`` (best-ranked first) are narrowed in
    their place, so that the report is not left empty while survivors are counted.
    Returns the report, every entry refuted, and the level reached."""
    report, refuted, reached = strengthen_report(explorer, report, level, limit, messages, labelled)
    while not report and reserve and not expired(explorer.deadline):
        take, reserve = reserve[:BEST_ATTEMPTS], reserve[BEST_ATTEMPTS:]
        entries = [(hypothesis_of(explorer, n), n) for n in take]
        report, gone, reached = strengthen_report(
            explorer, entries, level, limit, messages, labelled
        )
        refuted += gone
    return report, refuted, reached
