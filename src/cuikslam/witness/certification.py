"""Certifying a solution: the witness search on every hypothesis, sharing one budget.

:func:`certify` runs a :class:`~.find.WitnessSearch` per hypothesis of a
:class:`~cuikslam.outcome.solution.Solution`, round-robin, marks the proven ones (only a point
:mod:`.verify` proves makes a hypothesis ``proven consistent``), ranks them again and
records the search's statistics and what it left undecided.
"""

from __future__ import annotations

import time

import numpy as np

from cuikslam.budget import Budget
from cuikslam.log.records import Log
from cuikslam.outcome.solution import NOT_REFUTED, PROVEN, Hypothesis, Solution
from cuikslam.witness.find import (
    MAX_EVALUATIONS,
    MAX_TOTAL_EVALUATIONS,
    WitnessSearch,
    WitnessStatistics,
)
from cuikslam.witness.model import HypothesisModel
from cuikslam.witness.verify import verified_box

FIRST_QUOTA = 64
"""Residual evaluations each start may use in the first round of :func:`certify` when
several hypotheses share it: the hypotheses proven at once are not kept waiting behind one
that is hard to prove. On the Lost in the Woods window (201 poses, 50 ms an evaluation)
most survivors were proven within 30-60 evaluations, while some use hundreds without
success. The starts cut short run again, whole, in the next round: doubling the quota
round after round instead cost up to twice the evaluations on dense worlds whose
hypotheses need 200-500, and resuming a cut start from its best point saved nothing."""


def certify(
    log: Log,
    solution: Solution,
    *,
    seed: int = 0,
    restarts: int | None = None,
    max_hypotheses: int | None = None,
    use_sensor: bool = True,
    deadline: Budget | None = None,
    max_evaluations: int = MAX_EVALUATIONS,
    max_total_evaluations: int = MAX_TOTAL_EVALUATIONS,
) -> WitnessStatistics:
    """Mark every hypothesis of ``solution`` whose consistency is proven.

    For each hypothesis (the first ``max_hypotheses`` when given) not proven already (one
    whose ``witness`` verifies again for its assignment, as the search's dive leaves it,
    keeps it), the search of
    :func:`find_witness` (started from its boxes, then midpoints, then random points) and
    :func:`verify_witness`; on success ``status`` becomes ``PROVEN`` and ``witness`` holds
    ``poses_xyt`` (rows in the hypothesis' ``pose_ids`` order), ``landmarks_xy`` (rows in
    its ``landmark_ids`` order) and ``params``, the verified point in the parameters of
    :class:`HypothesisModel` (the world is their image in floating point); otherwise they
    become (or stay) ``NOT_REFUTED`` without a witness. The decided hypotheses are then
    ranked again, proven ones first (:attr:`~cuikslam.outcome.solution.Hypothesis.rank_key`);
    those beyond ``max_hypotheses`` are untouched.

    The hypotheses share the budget round-robin: every one gets its first two starts (most
    consistent hypotheses are proven by the first), then the unproven ones get random
    starts in growing rounds. While several are open, a start may use at most
    ``FIRST_QUOTA`` residual evaluations in the first round (a start cut short runs again,
    whole, in the next one), so that one hard hypothesis does not hold back the easy
    ones; this goes on until each is proven, has used ``max_evaluations`` residual
    evaluations (or ``2 + restarts`` starts, when given), all of them together have used
    ``max_total_evaluations`` (checked between rounds), or ``deadline`` (a
    :func:`time.perf_counter` value) passes. Returns the search's
    :class:`WitnessStatistics`; they are also recorded in ``solution.statistics``
    (``proven_hypotheses``, ``undecided_hypotheses``, ``witness_starts``,
    ``witness_evaluations``, ``witness_budget_exhausted``), with a message in
    ``solution.messages`` naming the hypotheses left undecided and why.
    """
    start = time.perf_counter()
    stats = WitnessStatistics()
    chosen = solution.hypotheses if max_hypotheses is None else solution.hypotheses[:max_hypotheses]
    most = None if restarts is None else 2 + restarts
    searches: list[WitnessSearch | None] = []
    for h in chosen:
        model = HypothesisModel(log, h.assignment, use_sensor=use_sensor)
        if _witness_holds(model, h):  # proven before (the search's dive), verified again
            searches.append(None)
            continue
        poses_box = {pid: h.poses[k] for k, pid in enumerate(h.pose_ids)}
        landmarks_box = {lid: h.landmarks[k] for k, lid in enumerate(h.landmark_ids)}
        searches.append(
            WitnessSearch(model, poses_box, landmarks_box, seed, deadline, max_evaluations, stats)
        )
    batch, quota = 2, FIRST_QUOTA  # the first round only: later ones run whole starts
    while True:
        open_ = [
            s
            for s in searches
            if s is not None and not s.finished and (most is None or s.tried < most)
        ]
        if not open_:
            break
        if stats.evaluations >= max_total_evaluations:
            stats.out_of_work = True
            break
        for search in open_:
            search.run(
                batch if most is None else min(batch, most - search.tried),
                quota if len(open_) > 1 else None,
            )
        batch, quota = min(2 * batch, 32), None
    proven = 0
    for h, search in zip(chosen, searches, strict=True):
        if search is None:
            proven += 1
            continue
        if search.box is None:
            h.status, h.witness = NOT_REFUTED, None
            continue
        point = search.point
        assert point is not None
        poses = np.full((len(h.pose_ids), 3), np.nan)
        for k, pid in enumerate(h.pose_ids):
            if pid in point.pose_ids:
                poses[k] = point.pose(pid)
        landmarks = np.full((len(h.landmark_ids), 2), np.nan)
        for k, lid in enumerate(h.landmark_ids):
            if lid in point.landmark_ids:
                landmarks[k] = point.landmark(lid)
        h.status = PROVEN
        h.witness = {
            "poses_xyt": poses,
            "landmarks_xy": landmarks,
            "params": np.asarray(point.params, dtype=float),
        }
        proven += 1
    # proven ones first (see Hypothesis.rank_key); the order is otherwise kept
    chosen.sort(key=lambda h: h.rank_key)
    solution.hypotheses[: len(chosen)] = chosen
    unfinished = [rank for rank, h in enumerate(chosen, start=1) if h.status != PROVEN]
    solution.timings["certify_s"] = time.perf_counter() - start
    solution.statistics["proven_hypotheses"] = proven
    solution.statistics["undecided_hypotheses"] = len(unfinished)
    solution.statistics["witness_starts"] = stats.starts
    solution.statistics["witness_evaluations"] = stats.evaluations
    solution.statistics["witness_failed_starts"] = stats.failed_starts
    solution.statistics["witness_budget_exhausted"] = int(stats.budget_exhausted)
    if unfinished:
        why = (
            "its budget"
            if stats.out_of_time
            else f"its work limit ({max_evaluations} evaluations per hypothesis, "
            f"{max_total_evaluations} in all)"
            if stats.out_of_work
            else "its starts"
        )
        solution.messages.append(
            f"the witness search stopped at {why}: {len(unfinished)} of {len(chosen)} "
            f"hypotheses undecided (not refuted, not proven): "
            f"{'rank' if len(unfinished) == 1 else 'ranks'} {_ranges(unfinished)}"
        )
    return stats


def _ranges(ranks: list[int]) -> str:
    """``[1, 2, 3, 7]`` as ``"1-3, 7"``."""
    parts = []
    first = last = ranks[0]
    for r in ranks[1:]:
        if r == last + 1:
            last = r
            continue
        parts.append(f"{first}-{last}" if last > first else str(first))
        first = last = r
    parts.append(f"{first}-{last}" if last > first else str(first))
    return ", ".join(parts)


def _witness_holds(model: HypothesisModel, hypothesis: Hypothesis) -> bool:
    """Whether the witness ``hypothesis`` holds already is verified again for ``model``
    (its assignment now): rigorous, as every proof (a hypothesis edited after its proof, or
    a witness that does not verify, gets the search like any other).

    The verified point is the witness' ``params`` when it has them for this model; a
    witness without them (written by hand, or by a version before them) is taken from its
    world, whose rounded poses may miss a bound by an ulp where the parameters did not."""
    witness = hypothesis.witness
    if hypothesis.status != PROVEN or witness is None:
        return False
    params = np.asarray(witness.get("params", ()), dtype=float)
    if params.shape != (model.n_params,):
        poses = dict(zip(hypothesis.pose_ids, witness["poses_xyt"], strict=True))
        landmarks = dict(zip(hypothesis.landmark_ids, witness["landmarks_xy"], strict=True))
        try:
            params = model.params_from_world(poses, landmarks, clip=False)
        except (KeyError, ValueError):
            return False
    return bool(np.all(np.isfinite(params))) and verified_box(model, params) is not None
