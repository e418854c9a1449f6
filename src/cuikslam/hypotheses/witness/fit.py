"""The least-squares fit of each hypothesis: how well its best world explains the readings.

Hypotheses with as many outliers and landmarks differ in which readings they pair up.
The truth pairs readings whose errors are spread inside their intervals; a wrong pairing
leans on errors near the bounds (that is why narrowing finds it nearer to contradiction,
with smaller boxes). So :func:`fit_hypotheses` gives each hypothesis the cost of its
least-squares estimate (:meth:`~.model.HypothesisModel.centre_residuals`: each measured
value's distance from its interval's centre, in half-widths, squared and summed: what a
least-squares back end minimises with those as standard deviations), and
:attr:`~cuikslam.results.Hypothesis.rank_key` ranks by it after parsimony. On Lost in the
Woods (2,000 samples, every id dropped, the surveyed map, 176 survivors) the truth ranks
first by it (cost 45.5, the next 48.1); by smallest boxes it ranked last.

The fit only orders the report: every reported hypothesis stays possible or undecided,
whatever its cost, and the guarantee does not depend on it.
"""

from __future__ import annotations

import math
import time

import numpy as np

from cuikslam.budget import OutOfTime, blas_single_thread, expired
from cuikslam.hypotheses.witness.find import (
    WitnessStatistics,
    _least_squares,
    _Meter,
    _OutOfWork,
    _param_bounds,
    tr_solver_for,
)
from cuikslam.hypotheses.witness.model import HypothesisModel
from cuikslam.log.records import Log
from cuikslam.outliers import log_without_observations
from cuikslam.results.solution import Hypothesis, Solution

__all__ = ["FIT_EVALUATIONS", "FIT_MAX_HYPOTHESES", "fit_cost", "fit_hypotheses"]

FIT_EVALUATIONS = 30
"""Residual evaluations of one hypothesis' least squares at most (on the 200-pose Lost in
the Woods window it stops after 8 from the boxes' centres, 5 from a neighbour's
minimiser)."""
FIT_MAX_HYPOTHESES = 1000
"""Hypotheses fitted at most, in rank order (the rest rank by box size after them)."""
FIT_TOLERANCE = 1e-5
"""scipy's tolerances on the cost, the step and the gradient: a ranking needs no more (the
witness search uses 1e-14; on Lost in the Woods the costs agree with 1e-8's to 1e-3)."""


def fit_cost(
    model: HypothesisModel,
    hypothesis: Hypothesis,
    deadline: float | None = None,
    max_evaluations: int = FIT_EVALUATIONS,
    start: np.ndarray | None = None,
) -> tuple[float, np.ndarray | None]:
    """The least-squares cost of ``model`` and its minimiser, from the centres of
    ``hypothesis``' boxes or from ``start`` (parameters of the same model, e.g. another
    hypothesis' minimiser), whichever costs less; (NaN, None) when the model has structural
    problems or the optimiser fails.

    Raises :class:`~cuikslam.budget.OutOfTime` when ``deadline`` passes first.

    Examples
    --------
    >>> from cuikslam.simulate import simulate_paper
    >>> from cuikslam.solver import solve
    >>> log, truth = simulate_paper(seed=0)
    >>> [h] = solve(log, certify_limit=0).hypotheses
    >>> cost, params = fit_cost(HypothesisModel(log, h.assignment), h)
    >>> 0 < cost < len(log.observations) + len(log.odometry)
    True
    """
    if model.problems:
        return math.nan, None
    poses_box = {pid: hypothesis.poses[k] for k, pid in enumerate(hypothesis.pose_ids)}
    marks_box = {lid: hypothesis.landmarks[k] for k, lid in enumerate(hypothesis.landmark_ids)}
    p0 = model.initial_params(poses_box, marks_box, deadline=deadline)
    free = model.free
    lb, ub = _param_bounds(model)
    if start is not None and start.shape == p0.shape:
        start = np.clip(start, lb, ub)
        start[~free] = p0[~free]
        p0 = min((p0, start), key=lambda q: _cost(model, q))
    if not np.any(free):
        return _cost(model, p0), p0
    lb, ub = lb[free], ub[free]

    def on_free(z: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        q = p0.copy()
        q[free] = z
        return model.centre_residuals(q, jacobian)

    meter = _Meter(deadline, max_evaluations, WitnessStatistics())
    z0 = np.clip(p0[free], lb, ub)
    try:
        with blas_single_thread(), np.errstate(all="ignore"):
            z = _least_squares(
                on_free, z0, meter, max_evaluations, free, (lb, ub),
                tr_solver=tr_solver_for(len(z0)), tol=FIT_TOLERANCE,
            )  # fmt: skip
    except _OutOfWork:  # counted one evaluation past the limit: keep the start's cost
        z = z0
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return math.nan, None
    p = p0.copy()
    p[free] = z
    return _cost(model, p), p


def _cost(model: HypothesisModel, p: np.ndarray) -> float:
    with np.errstate(all="ignore"):
        return float(np.sum(model.centre_residuals(p)[0] ** 2))


def fit_hypotheses(
    log: Log,
    solution: Solution,
    deadline: float | None = None,
    max_evaluations: int = FIT_EVALUATIONS,
) -> int:
    """Give every hypothesis of ``solution`` its least-squares ``fit``, in rank order, and
    rank them again (:attr:`~cuikslam.results.Hypothesis.rank_key`); returns how many got
    one.

    A hypothesis that takes observations as outliers is fitted on the log without them
    (an outlier explains nothing). Each least squares may also start from the minimiser of
    the last hypothesis with the same parameters: most differ in a few readings (on Lost in
    the Woods, 200 poses, 5 evaluations instead of 8; its 176 survivors took 88 s). At
    ``deadline`` (a :func:`time.perf_counter` value) the rest keep no fit (NaN: they rank
    after the fitted ones of their group) and ``solution.messages`` says how many; so do
    those beyond the first ``FIT_MAX_HYPOTHESES``.
    """
    started = time.perf_counter()
    fitted, tried = 0, 0
    minimisers: dict[tuple[str, ...], np.ndarray] = {}  # by the model's parameters
    for h in solution.hypotheses[:FIT_MAX_HYPOTHESES]:
        if expired(deadline):
            break
        reduced, assignment = _without_outliers(log, h)
        try:
            model = HypothesisModel(reduced, assignment)
            layout = tuple(model.param_names)
            h.fit, p = fit_cost(model, h, deadline, max_evaluations, minimisers.get(layout))
        except OutOfTime:
            break
        if p is not None:
            minimisers[layout] = p
        tried += 1
        fitted += math.isfinite(h.fit)
    solution.hypotheses.sort(key=lambda h: h.rank_key)
    solution.statistics["fitted_hypotheses"] = fitted
    solution.timings["fit_s"] = time.perf_counter() - started
    if 1 < len(solution.hypotheses) and tried < len(solution.hypotheses):
        solution.messages.append(
            f"the least-squares fit that ranks equally parsimonious hypotheses was computed "
            f"for {tried} of {len(solution.hypotheses)} "
            f"({'time budget' if tried < FIT_MAX_HYPOTHESES else 'the first ones only'}); "
            "the others rank after them, by box size"
        )
    return fitted


def _without_outliers(log: Log, h: Hypothesis) -> tuple[Log, list[str]]:
    """The log and assignment of ``h`` without the observations it takes as outliers."""
    drop = set(h.outliers)
    if not drop:
        return log, list(h.assignment)
    assignment = [a for i, a in enumerate(h.assignment) if i not in drop]
    return log_without_observations(log, drop), assignment
