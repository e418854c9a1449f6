"""Correspondences compared up to renaming, and the truth check of a solve's result.

A hypothesis assigns a landmark to every observation. Two assignments are the same
hypothesis when they group the observations alike: landmarks the log names keep their
ids, the others are known only by the observations that see them. :func:`partition`
is that canonical form; :func:`rank_of` finds the hypothesis whose partition is the true
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
from cuikslam.results.solution import Hypothesis, Solution, check_truth
from cuikslam.results.summary import summary_holds
from cuikslam.simulate.truth import GroundTruth

__all__ = ["TruthVerdict", "named_landmarks", "partition", "rank_of", "truth_verdict"]

MISSES_SHOWN = 20
"""Boxes that miss the truth listed in a verdict at most."""


def partition(assignment: Sequence[str], named: Collection[str] = frozenset()) -> list[int | str]:
    """The assignment up to renaming: a named landmark keeps its id, the others become
    the index of their first appearance among the unnamed ones.

    Parameters
    ----------
    assignment : sequence of str
        The landmark of each observation, in log order.
    named : collection of str
        Landmark ids the log itself gives (see :func:`named_landmarks`).

    Returns
    -------
    list of int or str
        Equal for two assignments exactly when they are the same hypothesis.
    """
    first: dict[str, int] = {}
    return [a if a in named else first.setdefault(a, len(first)) for a in assignment]


def named_landmarks(log: Log) -> set[str]:
    """Landmark ids the log itself gives (named sightings and landmark priors)."""
    return {r.landmark for r in log.records if getattr(r, "landmark", None) is not None}


def rank_of(
    hypotheses: Sequence[Hypothesis], assignment: Sequence[str], named: Collection[str] = ()
) -> int | None:
    """The rank (1 for the first) of the hypothesis whose partition is that of
    ``assignment``; None when none is."""
    wanted = partition(assignment, named)
    for rank, h in enumerate(hypotheses, start=1):
        if partition(h.assignment, named) == wanted:
            return rank
    return None


@dataclass
class TruthVerdict:
    """Whether a result keeps the guarantee against a ground truth, and why, in words."""

    ok: bool
    """False when the truth shows the guarantee broken (or the log refuted wrongly)."""
    lines: list[str] = field(default_factory=list)
    """What to tell the user, one line each."""


def truth_verdict(
    solution: Solution, truth: GroundTruth, named: Collection[str] = frozenset()
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

    Returns
    -------
    TruthVerdict
    """
    unreported = int(solution.statistics.get("survivors", 0))
    if not solution.hypotheses and not solution.complete and not unreported:
        return TruthVerdict(
            True,
            [
                "truth check: the search stopped on its budget before finding a hypothesis "
                "(incomplete, not a refutation; raise --time-budget)"
            ],
        )
    if solution.refuted:
        return TruthVerdict(
            False, ["truth check: no hypothesis survived, yet the truth satisfies the log"]
        )
    if not solution.hypotheses:  # survivors remain, none reported
        return _truth_not_reported(solution, truth, named)
    rank = rank_of(solution.hypotheses, truth.assignment, named)
    if rank is None:
        return _truth_not_reported(solution, truth, named)
    h = solution.hypotheses[rank - 1]
    names = dict(zip(h.assignment, truth.assignment, strict=True))
    landmark_xy = {ours: truth.exact_landmark(theirs) for ours, theirs in names.items()}
    report = check_truth(h, truth.pose_ids, truth.exact_poses(), landmark_xy)
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


def _truth_not_reported(
    solution: Solution, truth: GroundTruth, named: Collection[str]
) -> TruthVerdict:
    """The verdict when no reported hypothesis is the true one."""
    survivors = int(solution.statistics.get("survivors", len(solution.hypotheses)))
    held = (
        None
        if solution.correspondence is None
        else summary_holds(solution.correspondence, truth.assignment, set(named))
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
                f"truth check: the true correspondence is not among the "
                f"{len(solution.hypotheses)} reported of {survivors} survivors (raise "
                "--max-hypotheses to see it)"
            ],
        )
    if solution.complete:
        return TruthVerdict(
            False, ["truth check: the true correspondence is not among the survivors"]
        )
    return TruthVerdict(
        True,
        [
            "truth check: the true correspondence is not among the survivors found before "
            "the search stopped on its budget (the search was incomplete; raise --time-budget)"
        ],
    )
