"""One correspondence hypothesis solved as known correspondence: the log with each
observation labelled by the landmark the hypothesis gives it.

The search narrows its survivors as nodes of its tree. A survivor it did not keep for the
report, and that the ranking then reports (:func:`~.witness.fit.fit_hypotheses`), has no
node: its boxes come from this labelled log instead. The labelled log keeps the odometry,
the observations, the priors and the class regions; it leaves out the observations the
hypothesis takes as outliers, the sensor's negative information and the classes'
separations and counts. Fewer constraints only widen the boxes, so they hold the
hypothesis' worlds all the same, and an empty box is still a proof that the hypothesis is
impossible. A log that declares outliers is refused: its named observations may be
outliers too, and the labelled log would make them hard constraints.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from cuikslam.budget import Budget
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.log.records import Log, Observation
from cuikslam.narrowing.consistency import StrengthenReport, strengthen
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, Arrays, propagate
from cuikslam.options import Level
from cuikslam.outcome.solution import OUTLIER, Hypothesis
from cuikslam.outliers import log_without_observations

__all__ = ["has_labelled_logs", "hypothesis_from_graph", "labelled_log", "solve_labelled"]


def has_labelled_logs(log: Log) -> bool:
    """Whether the hypotheses of ``log`` have labelled logs: not when it declares outliers
    (see the module's docstring)."""
    return not log.outlier_bounds


def hypothesis_from_graph(
    graph: KinematicGraph,
    lo: np.ndarray,
    hi: np.ndarray,
    assignment: list[str],
    consistency: str = "",
) -> Hypothesis:
    """Package a graph's narrowed bounds as a :class:`Hypothesis`."""
    return Hypothesis(
        assignment=list(assignment),
        pose_ids=list(graph.pose_ids),
        poses=graph.pose_boxes(lo, hi),
        landmark_ids=list(graph.landmark_ids),
        landmark_classes=list(graph.landmark_classes),
        landmarks=graph.landmark_boxes(lo, hi),
        consistency=consistency,
    )


def labelled_log(log: Log, assignment: list[str]) -> Log:
    """``log`` with the i-th observation labelled ``assignment[i]``, the observations it
    takes as outliers left out; ValueError for a log that declares outliers (see the
    module's docstring)."""
    if not has_labelled_logs(log):
        raise ValueError(
            "a log that declares outliers has no labelled log: its named "
            "observations may be outliers too"
        )
    drop = {i for i, a in enumerate(assignment) if a == OUTLIER}
    reduced = log_without_observations(log, drop)
    labels = iter([a for a in assignment if a != OUTLIER])
    records = [
        replace(r, landmark=next(labels)) if isinstance(r, Observation) else r
        for r in reduced.records
    ]
    return Log(records=records, path=log.path)


def solve_labelled(
    log: Log,
    assignment: list[str],
    level: Level | str = Level.HULL,
    rtol: float = 1e-3,
    deadline: Budget | None = None,
    threads: int | None = None,
) -> Hypothesis | None:
    """The boxes of the hypothesis ``assignment`` of ``log``, narrowed to ``level`` on its
    labelled log (:func:`labelled_log`) until ``deadline`` (the ``lp`` sweeps on
    ``threads``, see :func:`~cuikslam.narrowing.consistency.strengthen`); None when they
    contract to empty (a proof that it is impossible).

    Examples
    --------
    >>> from cuikslam.simulate import simulate_paper
    >>> log, _ = simulate_paper(seed=0, unknown=True)
    >>> known, _ = simulate_paper(seed=0)
    >>> h = solve_labelled(log, [o.landmark for o in known.observations])
    >>> h.consistency, sorted(h.landmark_ids)
    ('hull', ['L1', 'L2', 'L3', 'L4'])
    >>> solve_labelled(log, ["L1"] * len(log.observations)) is None  # one door all around
    True
    """
    graph = KinematicGraph.from_log(labelled_log(log, assignment))
    result = propagate(graph, rtol=rtol)
    if result.is_empty:
        return None
    lo, hi = result.lo, result.hi
    report = StrengthenReport(level=level)
    if strengthen(
        Arrays.of(graph),
        lo,
        hi,
        level,
        rtol,
        DEFAULT_ROUNDS,
        deadline=deadline,
        report=report,
        threads=threads,
    ).is_empty:
        return None
    return hypothesis_from_graph(graph, lo, hi, assignment, report.level)
