"""Correspondences compared up to renaming, and the truth check of a solve's result.

A hypothesis assigns a landmark to every observation. Two assignments are the same
hypothesis when they group the observations alike: landmarks the log names keep their
ids, the others are known only by the observations that see them. :func:`partition`
is that canonical form (it lives below the search, in :mod:`cuikslam.outcome.naming`,
with the names a solve gives a hypothesis' landmarks; this module re-exports them);
:func:`rank_of` finds the hypothesis whose partition is the true
one, and :func:`truth_verdict` says whether a result keeps the guarantee against a ground
truth (what ``cuikslam solve --truth`` and ``cuikslam paper`` print).

Examples
--------
>>> partition(["+1", "+2", "+1", "door"], named={"door"})
[0, 1, 0, 'door']
>>> partition(["a", "b", "a"]) == partition(["x", "y", "x"])
True
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass, field

from cuikslam.log.records import Log
from cuikslam.messages import Message
from cuikslam.outcome.naming import (
    anonymous_names,
    display_names,
    named_landmarks,
    new_mark,
    partition,
)
from cuikslam.outcome.solution import (
    OUTLIER,
    Hypothesis,
    Solution,
    TruthReport,
    check_envelope,
    check_truth,
)
from cuikslam.outcome.summary import summary_holds
from cuikslam.results.measurement_check import Outside
from cuikslam.simulate.truth import GroundTruth

__all__ = [
    "TruthVerdict",
    "anonymous_names",
    "display_names",
    "envelope_report",
    "named_landmarks",
    "new_mark",
    "paired_landmarks",
    "partition",
    "rank_of",
    "true_outliers",
    "true_ranks",
    "truth_verdict",
]

MISSES_SHOWN = 20
"""Boxes that miss the truth listed in a verdict at most."""


def paired_landmarks(hypothesis: Hypothesis, truth: GroundTruth) -> dict[str, list[str]]:
    """The true landmarks each landmark of ``hypothesis`` stands for.

    Paired through the association: a landmark of the hypothesis stands for the true
    landmark of every observation the hypothesis assigns to it, whatever the two name
    them (an unknown-correspondence solve names the landmarks it adds ``+1``, ``+2``, ... in
    order of first sighting).
    A wrong hypothesis may pair one of its landmarks with several true ones, or with
    ``"outlier"`` (an observation the truth says is an outlier). Without a true assignment
    of the same length, landmarks are paired by name.

    Parameters
    ----------
    hypothesis : Hypothesis
        Its ``assignment`` and ``landmark_ids`` are used.
    truth : GroundTruth
        Its ``assignment`` (the true landmark of each observation) and ``landmark_ids``.

    Returns
    -------
    dict[str, list[str]]
        Each of the hypothesis' landmark ids that is paired, to its true landmark ids
        (in the truth's order, ``"outlier"`` last). An observation the hypothesis takes as
        an outlier pairs with nothing.

    Examples
    --------
    >>> import numpy as np
    >>> h = Hypothesis(["L1", "L2", "L1"], [0], np.zeros((1, 3, 2)), ["L1", "L2"],
    ...                ["post", "post"], np.zeros((2, 2, 2)))
    >>> t = GroundTruth(np.zeros((1, 3)), [0], np.zeros((3, 2)), ["L13", "L15", "L1"],
    ...                 ["post"] * 3, ["L13", "L15", "L13"])
    >>> paired_landmarks(h, t)
    {'L1': ['L13'], 'L2': ['L15']}
    >>> paired_landmarks(h, GroundTruth(t.poses_xyt, [0], t.landmarks_xy, t.landmark_ids,
    ...                                 t.landmark_classes, []))  # no true assignment
    {'L1': ['L1']}
    """
    ids = set(hypothesis.landmark_ids)
    order = {lid: j for j, lid in enumerate(truth.landmark_ids)}
    if len(truth.assignment) != len(hypothesis.assignment) or not truth.assignment:
        return {lid: [lid] for lid in hypothesis.landmark_ids if lid in order}
    order[OUTLIER] = len(order)
    pairs: dict[str, set[str]] = {}
    for ours, theirs in zip(hypothesis.assignment, truth.assignment, strict=True):
        if ours in ids and theirs in order:
            pairs.setdefault(ours, set()).add(theirs)
    return {
        lid: sorted(pairs[lid], key=order.__getitem__)
        for lid in hypothesis.landmark_ids
        if lid in pairs
    }


def true_outliers(log: Log, found: Outside) -> tuple[list[int], list[int]]:
    """The unlabelled observations (indices in log order) whose interval misses the truth,
    and those that cannot be checked (from an uncertain sensor offset), out of ``found``
    (:func:`~cuikslam.results.measurement_check.check_log` of ``log``): what the true
    hypothesis of a search takes as outliers, for sure and perhaps. Named observations are
    left out: the search never takes them as outliers (their declaration is applied by the
    relaxed intersection, whose boxes hold the truth whenever it holds)."""
    unlabelled = {i for i, o in enumerate(log.observations) if o.landmark is None}
    return (
        [i for i in found.outside_observations if i in unlabelled],
        [i for i in found.unchecked_observations if i in unlabelled],
    )


def rank_of(
    hypotheses: Sequence[Hypothesis],
    assignment: Sequence[str],
    named: Collection[str] = (),
    outside: Collection[int] = (),
    unchecked: Collection[int] = (),
) -> int | None:
    """The rank (1 for the first) of the true hypothesis; None when none is.

    Without outliers it is the hypothesis whose partition is that of ``assignment``. A
    hypothesis that takes observations as outliers (an ``outliers`` declaration) is true
    when its partition of the other observations is that of ``assignment`` and its outliers
    are the observations whose interval misses the truth (``outside``, indices in log
    order), and perhaps some of those that cannot be checked (``unchecked``); failing that,
    the first whose outliers include them (its constraints are a subset of the true
    hypothesis', so its boxes hold the truth too).
    """
    ranks = true_ranks(hypotheses, assignment, named, outside, unchecked)
    return ranks[0] if ranks else None


def true_ranks(
    hypotheses: Sequence[Hypothesis],
    assignment: Sequence[str],
    named: Collection[str] = (),
    outside: Collection[int] = (),
    unchecked: Collection[int] = (),
) -> list[int]:
    """Every rank that may be the true hypothesis (see :func:`rank_of`), those whose
    outliers are all outside or unchecked first."""
    truth_out, maybe = set(outside), set(unchecked)
    exact, wider = [], []
    for rank, h in enumerate(hypotheses, start=1):
        mine = set(h.outliers)
        if not truth_out <= mine:
            continue
        keep = [i for i in range(len(assignment)) if i not in mine]
        ours = partition([h.assignment[i] for i in keep], named)
        if ours == partition([assignment[i] for i in keep], named):
            (exact if mine <= truth_out | maybe else wider).append(rank)
    return exact + wider


@dataclass
class TruthVerdict:
    """Whether a result keeps the guarantee against a ground truth, and why, in words."""

    ok: bool
    """False when the truth shows the guarantee broken (or the log refuted wrongly)."""
    lines: list[str] = field(default_factory=list)
    """What to tell the user, one line each."""


def truth_verdict(
    solution: Solution,
    truth: GroundTruth,
    named: Collection[str] = frozenset(),
    outside: Collection[int] = (),
    unchecked: Collection[int] = (),
) -> TruthVerdict:
    """Whether the true hypothesis survived and its boxes contain the truth.

    The true hypothesis is the survivor whose partition of the observations into
    landmarks is the true one (labels may differ), with the landmarks the log names
    (``named``) where the truth has them. Other hypotheses are wrong by construction, so
    their boxes need not contain the true poses. A true hypothesis that was not reported
    (beyond ``max_hypotheses``, or in the unexplored part of a search cut by its budget)
    breaks nothing, unless the correspondence summary of every survivor excludes it.

    Parameters
    ----------
    solution : Solution
        A solve's result.
    truth : GroundTruth
        The true poses, landmarks and assignment.
    named : collection of str
        Landmark ids the log names (see :func:`named_landmarks`).
    outside : collection of int
        With an ``outliers`` declaration, the observations (log order) whose interval misses
        the truth (:func:`true_outliers`): the true hypothesis takes those as outliers (see
        :func:`rank_of`).
    unchecked : collection of int
        The observations whose truth cannot be checked (:func:`true_outliers`): when the
        true hypothesis takes one of them as a landmark's and a box misses the truth, the
        verdict says it cannot tell (that observation may be the outlier).

    Returns
    -------
    TruthVerdict
        With an envelope (unknown correspondence), a last line says whether it holds the
        truth (:func:`envelope_report`); a miss makes the verdict fail.
    """
    verdict = _hypotheses_verdict(solution, truth, named, outside, unchecked)
    report = envelope_report(solution, truth, outside)
    if report is None:
        return verdict
    if report.ok:
        n = len(solution.envelope.pose_ids)
        m = len(solution.envelope.observations)
        verdict.lines.append(
            f"envelope: {n} poses and {m} observations, all contain the truth "
            f"({report.checked} bounds)"
        )
        return verdict
    verdict.lines.append(f"envelope: {len(report.misses)} boxes miss the truth:")
    verdict.lines.extend(f"  {miss}" for miss in report.misses[:MISSES_SHOWN])
    return TruthVerdict(False, verdict.lines)


def envelope_report(
    solution: Solution, truth: GroundTruth, outside: Collection[int] = ()
) -> TruthReport | None:
    """Whether ``solution``'s envelope holds the true poses and the true landmark of every
    observation (those in ``outside``, true outliers, unchecked); None without an envelope."""
    envelope = solution.envelope
    if envelope is None:
        return None
    skip = set(outside)
    observed = [
        None if i in skip or a == OUTLIER else truth.exact_landmark(a)
        for i, a in enumerate(truth.assignment)
    ]
    return check_envelope(envelope, truth.pose_ids, truth.exact_poses(), observed)


def _hypotheses_verdict(
    solution: Solution,
    truth: GroundTruth,
    named: Collection[str],
    outside: Collection[int],
    unchecked: Collection[int],
) -> TruthVerdict:
    """The verdict on the reported hypotheses and the correspondence summary."""
    unreported = int(solution.statistics.get("survivors", 0))
    if not solution.hypotheses and not solution.complete and not unreported:
        return TruthVerdict(
            True,
            [
                Message(
                    "truth_nothing_found",
                    "truth check: the search stopped on its budget before finding a "
                    "hypothesis (incomplete, not a refutation; raise work_budget)",
                )
            ],
        )
    if solution.refuted:
        return TruthVerdict(
            False, ["truth check: no hypothesis survived, yet the truth satisfies the log"]
        )
    marked = [OUTLIER if i in set(outside) else a for i, a in enumerate(truth.assignment)]
    if not solution.hypotheses:  # survivors remain, none reported
        return _truth_not_reported(solution, marked, named, unchecked)
    ranks = true_ranks(solution.hypotheses, truth.assignment, named, outside, unchecked)
    if not ranks:
        return _truth_not_reported(solution, marked, named, unchecked)
    for rank in ranks:  # an unchecked observation may be an outlier: the first that holds
        h = solution.hypotheses[rank - 1]
        report = _check(h, truth)
        doubtful = set(unchecked) - set(h.outliers)
        if report.ok or not doubtful:
            break
    if not report.ok and doubtful:
        return TruthVerdict(
            True,
            [
                f"truth check: cannot tell: {len(report.misses)} boxes of the hypothesis "
                f"closest to the truth miss it, and it takes {len(doubtful)} observation(s) "
                "made from an uncertain sensor offset as sightings, whose truth the truth file "
                "cannot check (any of them may be an outlier)"
            ],
        )
    if not report.ok:
        return TruthVerdict(
            False,
            [
                f"truth check: {len(report.misses)} boxes miss the truth:",
                *(f"  {miss}" for miss in report.misses[:MISSES_SHOWN]),
            ],
        )
    where = (
        f" (hypothesis {rank} of {len(solution.hypotheses)})"
        if len(solution.hypotheses) > 1
        else ""
    )
    return TruthVerdict(
        True,
        [
            f"truth check: the true correspondence survived{where} and its "
            f"{report.checked} bounds all contain the truth"
        ],
    )


def _check(h: Hypothesis, truth: GroundTruth):
    """Whether ``h``'s boxes hold the truth (its landmarks named as the truth names them)."""
    names = {
        ours: theirs
        for ours, theirs in zip(h.assignment, truth.assignment, strict=True)
        if ours != OUTLIER
    }
    landmark_xy = {ours: truth.exact_landmark(theirs) for ours, theirs in names.items()}
    return check_truth(h, truth.pose_ids, truth.exact_poses(), landmark_xy)


MAX_UNCHECKED_SETS = 4096
"""Sets of unchecked observations tried as outliers against the correspondence summary."""


def _summary_holds_truth(
    document: dict, assignment: list[str], named: Collection[str], unchecked: Collection[int]
) -> bool | None:
    """Whether the summary ``document`` holds the true hypothesis: ``assignment`` with any
    set of the ``unchecked`` observations taken as outliers too (each may be one); None when
    it cannot tell (the summary does not cover every survivor, or too many sets)."""
    maybe = sorted(i for i in set(unchecked) if assignment[i] != OUTLIER)
    if 2 ** len(maybe) > MAX_UNCHECKED_SETS:
        return True if summary_holds(document, assignment, set(named)) else None
    for mask in range(2 ** len(maybe)):
        row = list(assignment)
        for bit, i in enumerate(maybe):
            if mask >> bit & 1:
                row[i] = OUTLIER
        answer = summary_holds(document, row, set(named))
        if answer is None:
            return None
        if answer:
            return True
    return False


def _truth_not_reported(
    solution: Solution,
    assignment: list[str],
    named: Collection[str],
    unchecked: Collection[int] = (),
) -> TruthVerdict:
    """The verdict when no reported hypothesis is the true one (``assignment``: the truth,
    its outliers marked; ``unchecked``: observations that may be outliers too)."""
    survivors = int(solution.statistics.get("survivors", len(solution.hypotheses)))
    held = (
        None
        if solution.correspondence is None
        else _summary_holds_truth(solution.correspondence, assignment, named, unchecked)
    )
    if survivors > len(solution.hypotheses) and held is False and solution.complete:
        return TruthVerdict(
            False,
            [
                f"truth check: the true correspondence is not among the {survivors} survivors "
                "(the correspondence summary covers every one)"
            ],
        )
    if survivors > len(solution.hypotheses):
        return TruthVerdict(
            True,
            [
                Message(
                    "truth_unreported",
                    f"truth check: the true correspondence is not among the "
                    f"{len(solution.hypotheses)} reported of {survivors} survivors (raise "
                    "max_hypotheses to see it)",
                    reported=len(solution.hypotheses),
                    survivors=survivors,
                )
            ],
        )
    if solution.complete:
        return TruthVerdict(
            False, ["truth check: the true correspondence is not among the survivors"]
        )
    return TruthVerdict(
        True,
        [
            Message(
                "truth_search_incomplete",
                "truth check: the true correspondence is not among the survivors found before "
                "the search stopped on its budget (the search was incomplete; raise "
                "work_budget)",
            )
        ],
    )
