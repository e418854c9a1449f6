"""Declared outliers: the glue between the log and :mod:`cuikslam.narrowing.outliers`
(known correspondence) or :mod:`cuikslam.hypotheses.outlier_option` (unknown).

A log may say, with ``outliers`` records (``docs/log-format.md``), that at most q of its
observations miss their truth, in all and/or in each block of ``window`` poses. The boxes
then hold the truth whenever the declaration does, and the observations proven to be
outliers are listed: in the result JSON (key ``outliers``), in the solve's messages and on
the terminal. Nothing is dropped silently: an observation is only ever set aside by a
proof (no solution inside a box that holds the truth).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from cuikslam.budget import Budget
from cuikslam.graph.encoding import KIND, OBSERVATION
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.log.records import (
    Log,
    Observation,
    OutlierBound,
)
from cuikslam.messages import Message
from cuikslam.narrowing.outliers import NO_LIMIT, OutlierScope, RelaxedReport
from cuikslam.outcome.solution import Hypothesis, Solution

__all__ = [
    "LISTED",
    "certify_without_outliers",
    "check_declaration",
    "evaluation_note",
    "hypothesis_outlier_messages",
    "hypothesis_outliers",
    "log_without_observations",
    "outlier_messages",
    "outlier_scope",
    "outliers_to_json",
    "search_outliers_json",
]

LISTED = 10
"""Proven outliers named in the messages (the result JSON lists every one)."""


def search_outliers_json(
    log: Log, named_positions: list[int], report: RelaxedReport | None
) -> dict[str, Any] | None:
    """The result JSON's ``outliers`` of a correspondence search: the declaration and the
    named observations proven outliers at the root (``report``: members in the order of
    ``named_positions``); None when the log declares none."""
    if not log.outlier_bounds:
        return None
    mapped = RelaxedReport(
        proven=[named_positions[i] for i in (report.proven if report else [])],
        exceeded=bool(report and report.exceeded),
    )
    return outliers_to_json(log, mapped)


def hypothesis_outliers(log: Log, hypothesis: Hypothesis) -> list[dict[str, Any]]:
    """The observations ``hypothesis`` takes as outliers: index (log order), line, pose."""
    observations = log.observations
    return [
        {"observation": i, "line": observations[i].line, "pose": observations[i].pose}
        for i in hypothesis.outliers
    ]


def hypothesis_outlier_messages(log: Log, solution: Solution) -> list[str]:
    """Each reported hypothesis' outliers in words (the first ``LISTED`` hypotheses); also
    puts them in ``solution.outliers['hypotheses']`` (one list per reported hypothesis,
    in the report's order)."""
    if solution.outliers is None:
        return []
    listed = [hypothesis_outliers(log, h) for h in solution.hypotheses]
    solution.outliers["hypotheses"] = listed
    lines = []
    for rank, found in enumerate(listed[:LISTED], start=1):
        if not found:
            continue
        where = ", ".join(f"line {o['line']} (pose {o['pose']})" for o in found[:LISTED])
        more = f" and {len(found) - LISTED} more" if len(found) > LISTED else ""
        lines.append(
            f"hypothesis {rank} takes {len(found)} observation(s) as outliers: {where}{more}"
        )
    return lines


def outlier_scope(log: Log, graph: KinematicGraph) -> OutlierScope:
    """Every observation of ``log`` as a member that may be an outlier, with the log's
    declared allowances (``graph`` is ``KinematicGraph.from_log(log)``: its k-th
    ``OBSERVATION`` row is the log's k-th observation)."""
    members = np.flatnonzero(graph.factor_table()[:, KIND] == OBSERVATION).astype(np.int64)
    observations = log.observations
    assert members.size == len(observations)
    at_most, per_block, window = NO_LIMIT, NO_LIMIT, None
    for bound in log.outlier_bounds:
        if bound.window is None:
            at_most = bound.at_most
        else:
            per_block, window = bound.at_most, bound.window
    block = np.zeros(members.size, dtype=np.int64)
    if window is not None:
        rank = log.pose_order()
        block[:] = [rank[o.pose] // window for o in observations]
    return OutlierScope(members=members, block=block, at_most=at_most, per_block=per_block)


def outliers_to_json(log: Log, report: RelaxedReport) -> dict[str, Any]:
    """The result JSON's ``outliers``: the declaration and the proven outliers (log order)."""
    observations = log.observations
    proven = []
    for i in sorted(report.proven):
        o = observations[i]
        proven.append({"observation": i, "line": o.line, "pose": o.pose, "landmark": o.landmark})
    return {
        "declared": [
            {"at_most": b.at_most, "window": b.window, "line": b.line} for b in log.outlier_bounds
        ],
        "proven": proven,
        "exceeded": report.exceeded,
    }


def _declared_text(declared: list[dict[str, Any]]) -> str:
    parts = []
    for d in declared:
        if d["window"] is None:
            parts.append(f"at most {d['at_most']} in all")
        else:
            parts.append(f"at most {d['at_most']} per {d['window']} poses")
    return " and ".join(parts)


def evaluation_note(summary: dict[str, Any]) -> str:
    """What ``cuikslam evaluate`` says of a result whose log declares outliers."""
    declared, proven = _declared_text(summary["declared"]), len(summary["proven"])
    return Message(
        "outliers_declared",
        f"the log declares outliers ({declared}) and {proven} were proven: the boxes are "
        "guaranteed only if the declaration holds (checking the log against a truth, "
        "`cuikslam.results.measurement_check.check_log`, says whether it does)",
        declared=declared,
        proven=proven,
    )


def outlier_messages(summary: dict[str, Any]) -> list[str]:
    """What a solve says of its outliers, in words (for ``Solution.messages``)."""
    declared = _declared_text(summary["declared"])
    proven = summary["proven"]
    if summary["exceeded"]:
        return [
            f"the log is inconsistent with its outliers declaration ({declared}): more "
            f"observations are outliers than declared (a proof; {len(proven)} proven before "
            "the box became empty), or another record misses its truth"
        ]
    lines = [
        f"declared outliers: {declared}; {len(proven)} observation(s) proven to be outliers"
        + (
            " (each has no solution inside boxes that hold the truth whenever the declaration does)"
            if proven
            else ""
        )
        + "; the boxes hold the truth whenever the declaration does"
    ]
    for p in proven[:LISTED]:
        lines.append(f"  outlier: line {p['line']}, pose {p['pose']} sees {p['landmark']}")
    if len(proven) > LISTED:
        lines.append(f"  … {len(proven) - LISTED} more in the result JSON (key outliers)")
    return lines


def check_declaration(log: Log, outside: list[int], moves_outside: int = 0) -> tuple[bool, str]:
    """Whether the log's outlier declaration holds, given the observations (indices in log
    order) that truly miss their truth (e.g. from
    :func:`cuikslam.results.measurement_check.check_log`).

    Returns
    -------
    (bool, str)
        True when every ``outliers`` record holds (and no move misses its truth, which no
        declaration covers), and one sentence saying why.
    """
    rank = log.pose_order()
    observations = log.observations
    parts = []
    holds = True
    for bound in log.outlier_bounds:
        if bound.window is None:
            ok = len(outside) <= bound.at_most
            parts.append(f"at most {bound.at_most} in all: {len(outside)} outside")
        else:
            blocks: dict[int, int] = {}
            for i in outside:
                block = rank[observations[i].pose] // bound.window
                blocks[block] = blocks.get(block, 0) + 1
            most = max(blocks.values(), default=0)
            ok = most <= bound.at_most
            parts.append(
                f"at most {bound.at_most} per {bound.window} poses: {most} in the worst block"
            )
        parts[-1] += " (holds)" if ok else " (BROKEN)"
        holds &= ok
    if moves_outside:
        parts.append(f"{moves_outside} moves outside, which no declaration covers")
        holds = False
    verdict = "the declaration holds" if holds else "the guarantee does not hold"
    return holds, f"declared outliers: {'; '.join(parts)}: {verdict}"


def log_without_observations(log: Log, drop: set[int]) -> Log:
    """``log`` without the observations numbered ``drop`` (in log order) and without its
    ``outliers`` declarations: what a hypothesis that takes those as outliers must meet."""
    records = []
    k = -1
    for record in log.records:
        if isinstance(record, Observation):
            k += 1
            if k in drop:
                continue
        if not isinstance(record, OutlierBound):
            records.append(record)
    return Log(records=records, path=log.path)


def certify_without_outliers(
    log: Log, solution: Solution, certify: Callable[..., Any], deadline: Budget | None
) -> bool:
    """Try to prove the best-ranked hypothesis whose outliers, with the proven ones, meet the
    declaration consistent, with all of them left out; True when the witness search ran
    (its counts, ``proven_hypotheses`` and the ``witness_*`` statistics, are then in
    ``solution.statistics``).

    A verified point that satisfies every constraint but those of the proven outliers
    (fewer than declared, or the solve would have said so) is a world that meets the
    declaration: the hypothesis becomes *proven consistent*, its witness that point. The
    witness search (``certify``, :func:`cuikslam.witness.certify`) runs on the
    log without the proven outliers; an unproven outlier left in it makes the search fail,
    never a wrong proof. Not tried when a landmark is seen only by proven outliers, nor when
    the proven outliers and the hypothesis' own together break the declaration (in all or in
    some block of poses): a world without all of them would not meet it.
    """
    if not solution.hypotheses or solution.outliers is None:
        return False
    listed = {p["observation"] for p in solution.outliers["proven"]}
    best = next(
        (
            h
            for h in solution.hypotheses
            if check_declaration(log, sorted(listed | set(h.outliers)))[0]
        ),
        None,
    )  # a witness without more outliers than declared proves nothing
    if best is None:
        solution.messages.append(
            "not certified: each reported hypothesis takes observations as outliers that, with "
            "the proven ones, are more than the outliers record allows, so all stay 'not refuted'"
        )
        return False
    proven = listed | set(best.outliers)
    reduced = log_without_observations(log, proven)
    trial = replace(best, assignment=[a for i, a in enumerate(best.assignment) if i not in proven])
    named = set(trial.assignment) | {p.landmark for p in reduced.landmark_priors}
    if not set(best.landmark_ids) <= named:
        solution.messages.append(
            "not certified: a landmark is seen only by proven outliers, so the hypothesis "
            "stays 'not refuted'"
        )
        return False
    alone = replace(solution, hypotheses=[trial], messages=[], statistics={}, timings={})
    certify(reduced, alone, deadline=deadline)
    best.status, best.witness = trial.status, trial.witness
    solution.hypotheses.sort(key=lambda h: h.rank_key)  # a proven one ranks first
    solution.statistics.update(alone.statistics)
    solution.messages.extend(alone.messages)
    if proven and best.witness is not None:
        assumed = len(best.outliers)  # taken as outliers by the hypothesis itself
        parts = [f"{len(proven) - assumed} proven outlier(s)"] if len(proven) > assumed else []
        parts += [f"{assumed} observation(s) it takes as outliers"] if assumed else []
        what = " and the ".join(parts)
        solution.messages.append(
            f"the witness leaves out the {what} and meets every other constraint"
        )
    return True
