"""The least-squares fit of each hypothesis: how well its best world explains the readings.

Hypotheses with as many outliers and landmarks differ in which readings they pair up.
The truth pairs readings whose errors are spread inside their intervals; a wrong pairing
leans on errors near the bounds (that is why narrowing finds it nearer to contradiction,
with smaller boxes). So :func:`fit_hypotheses` gives each hypothesis the cost of its
least-squares estimate (:meth:`~.model.HypothesisModel.fit_residuals`: each measured
value's distance from its interval's centre, in half-widths, squared and summed: what a
least-squares back end minimises with those as standard deviations; with a ``sensor``
record of finite range, for a hypothesis without outliers, plus each pose's violations
of the negative information, squared, in the median half-widths of the ranges and
bearings), and
:attr:`~cuikslam.outcome.solution.Hypothesis.rank_key` ranks by it after parsimony. On Lost in the
Woods (2,000 samples, every id dropped, the surveyed map, 176 survivors) the truth ranks
first by it (cost 45.5, the next 48.1); by smallest boxes it ranked last. A wrong "new
landmark" explanation fits the readings as well as the truth (it has one landmark to
place freely) but puts a landmark the robot would have seen where it saw none; without
the sensor term the dense 30-pose world of seed 9 ranked the truth last of 4 (48.1
against 47.1–47.8), with it first (the others 48.6–49.0).

When more survive than are reported, the search keeps those with the smallest boxes for
the report; the others (``Solution.unreported``) are fitted too, and those that fit better
are reported in place of worse ones, with the boxes of a known-correspondence solve.

The fit only orders the report: every reported hypothesis stays possible or undecided,
whatever its cost, and the guarantee does not depend on it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from cuikslam.budget import Budget, OutOfTime, blas_single_thread, expired
from cuikslam.log.records import Log
from cuikslam.outcome.naming import display_names, named_landmarks
from cuikslam.outcome.solution import OUTLIER, Hypothesis, Solution
from cuikslam.outliers import log_without_observations
from cuikslam.witness._dense import (
    dense_least_squares,
    evaluation_cost,
    param_bounds,
    tr_solver_for,
)
from cuikslam.witness.find import (
    CENTRE_TOLERANCE,
    WitnessStatistics,
    _Meter,
    _OutOfWork,
)
from cuikslam.witness.model import HypothesisModel

__all__ = ["FIT_EVALUATIONS", "FIT_MAX_HYPOTHESES", "fit_cost", "fit_hypotheses"]

FIT_EVALUATIONS = 30
"""Residual evaluations of one hypothesis' least squares at most (on the 200-pose Lost in
the Woods window it stops after 8 from the boxes' centres, 5 from a neighbour's
minimiser)."""
FIT_SENSOR_SLACK = 2.0
"""Metres beyond the sensor's range within which a (pose, landmark) pair of the start's
world enters the fit's negative information."""
FIT_MAX_HYPOTHESES = 1000
"""Hypotheses fitted at most, in rank order (the rest rank by box size after them)."""


def fit_cost(
    model: HypothesisModel,
    hypothesis: Hypothesis | None,
    deadline: Budget | None = None,
    max_evaluations: int = FIT_EVALUATIONS,
    start: np.ndarray | None = None,
) -> tuple[float, np.ndarray | None]:
    """The least-squares cost of ``model`` and its minimiser, from the centres of
    ``hypothesis``' boxes (None: the intervals' midpoints) or from ``start`` (parameters of
    the same model, e.g. another hypothesis' minimiser), whichever costs less; (NaN, None)
    when the model has structural problems or the optimiser fails.

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
    if hypothesis is None:
        p0 = model.initial_params(deadline=deadline)
    else:
        poses = {pid: hypothesis.poses[k] for k, pid in enumerate(hypothesis.pose_ids)}
        marks = {lid: hypothesis.landmarks[k] for k, lid in enumerate(hypothesis.landmark_ids)}
        p0 = model.initial_params(poses, marks, deadline=deadline)
    free = model.free
    lb, ub = param_bounds(model)
    if start is not None and start.shape == p0.shape:
        start = np.clip(start, lb, ub)
        start[~free] = p0[~free]
        p0 = min((p0, start), key=lambda q: _cost(model, q))
    _focus_sensor(model, p0)
    if not np.any(free):
        return _cost(model, p0), p0
    lb, ub = lb[free], ub[free]

    def on_free(z: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        q = p0.copy()
        q[free] = z
        return model.fit_residuals(q, jacobian)

    meter = _Meter(deadline, max_evaluations, WitnessStatistics(), evaluation_cost(model))
    z0 = np.clip(p0[free], lb, ub)
    try:
        with blas_single_thread(), np.errstate(all="ignore"):
            z = dense_least_squares(
                on_free, z0, meter.tick, max_evaluations, free, (lb, ub),
                tr_solver=tr_solver_for(len(z0)), tol=CENTRE_TOLERANCE, spend=meter.spend,
            )  # fmt: skip
    except _OutOfWork:  # counted one evaluation past the limit: keep the start's cost
        z = z0
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return math.nan, None
    p = p0.copy()
    p[free] = z
    return _cost(model, p), p


def _focus_sensor(model: HypothesisModel, p: np.ndarray) -> None:
    """Let the fit see the sensor pairs within ``max_range + FIT_SENSOR_SLACK`` of each
    other in the start's world (and the observed ones): the others cannot become visible
    in the few steps of the fit, and all pairs of a long log would not fit in memory."""
    if model.sensor is None:
        return
    poses, landmarks = model.poses(p)[0], model.landmarks(p)
    model.focus_sensor(
        np.stack([poses, poses], axis=-1), np.stack([landmarks, landmarks], axis=-1),
        slack=FIT_SENSOR_SLACK,
    )  # fmt: skip


def _cost(model: HypothesisModel, p: np.ndarray) -> float:
    """The fit's cost at ``p``, every sensor pair counted (the optimiser saw only the near
    ones), so that costs compare across hypotheses and starts."""
    model.see_all_sensor_pairs()
    with np.errstate(all="ignore"):
        return float(np.sum(model.fit_residuals(p)[0] ** 2))


class _Fitter:
    """Fits hypotheses of one log, each least squares started also from the minimiser of
    the last hypothesis with the same parameters: most differ in a few readings (on Lost
    in the Woods, 200 poses, 5 evaluations instead of 8)."""

    def __init__(self, log: Log, deadline: Budget | None, max_evaluations: int) -> None:
        self.log, self.deadline, self.max_evaluations = log, deadline, max_evaluations
        self.minimisers: dict[tuple[str, ...], np.ndarray] = {}  # by the model's parameters

    def fit(self, assignment: list[str], boxes: Hypothesis | None) -> float:
        """The fit of ``assignment`` (NaN: none); raises OutOfTime at the deadline.

        Observations it takes as outliers are left out of the log: an outlier explains
        nothing. Negative information counts only without outliers (the search does not
        apply it at a pose whose reading may be an outlier) and with a finite range (else
        every pair is near and the optimiser's Jacobian grows with all of them)."""
        drop = {i for i, a in enumerate(assignment) if a == OUTLIER}
        log = log_without_observations(self.log, drop) if drop else self.log
        sensor = self.log.sensor
        negative = not drop and sensor is not None and math.isfinite(sensor.max_range)
        model = HypothesisModel(log, [a for a in assignment if a != OUTLIER], negative)
        layout = tuple(model.param_names)
        cost, p = fit_cost(
            model, boxes, self.deadline, self.max_evaluations, self.minimisers.get(layout)
        )
        if p is not None:
            self.minimisers[layout] = p
        return cost


def fit_hypotheses(
    log: Log,
    solution: Solution,
    deadline: Budget | None = None,
    max_evaluations: int = FIT_EVALUATIONS,
    known: Callable[[list[str]], Hypothesis | None] | None = None,
) -> int:
    """Give every hypothesis of ``solution`` its least-squares ``fit``, in rank order, and
    rank them again (:attr:`~cuikslam.outcome.solution.Hypothesis.rank_key`); returns how many
    reported hypotheses have one.

    A hypothesis that takes observations as outliers is fitted on the log without them
    (an outlier explains nothing). On Lost in the Woods (200 poses) the 176 survivors took
    88 s. When ``deadline`` (a :class:`~cuikslam.budget.Budget`) is spent the rest keep no fit (NaN:
    they rank after the fitted ones of their group) and ``solution.messages`` says how
    many; so do those beyond the first ``FIT_MAX_HYPOTHESES``.

    With ``known`` (the boxes of a hypothesis given by its assignment, e.g. a
    known-correspondence solve; None when proven impossible), the survivors the search
    found but did not report (``solution.unreported``) are fitted too, within the same
    deadline, and those that rank before reported ones are reported in their place, with
    the boxes ``known`` gives (statistic ``promoted_hypotheses``): the report is chosen by
    smallest boxes, which on Lost in the Woods left the truth out of the 100 reported.
    """
    started = time.perf_counter()
    tried = 0
    fitter = _Fitter(log, deadline, max_evaluations)
    for h in solution.hypotheses[:FIT_MAX_HYPOTHESES]:
        if expired(deadline):
            break
        try:
            h.fit = fitter.fit(h.assignment, h)
        except OutOfTime:
            break
        tried += 1
    solution.hypotheses.sort(key=lambda h: h.rank_key)
    if known is not None and tried == len(solution.hypotheses):
        promoted = _promote(fitter, solution, known, FIT_MAX_HYPOTHESES - tried)
        solution.statistics["promoted_hypotheses"] = promoted
    fitted = sum(math.isfinite(h.fit) for h in solution.hypotheses)  # promoted ones too
    solution.statistics["fitted_hypotheses"] = fitted
    solution.timings["fit_s"] = time.perf_counter() - started
    if 1 < len(solution.hypotheses) and tried < len(solution.hypotheses):
        solution.messages.append(
            f"the least-squares fit that ranks equally parsimonious hypotheses was computed "
            f"for {tried} of {len(solution.hypotheses)} "
            f"({'budget' if tried < FIT_MAX_HYPOTHESES else 'the first ones only'}); "
            "the others rank after them, by box size"
        )
    return fitted


def _promote(
    fitter: _Fitter,
    solution: Solution,
    known: Callable[[list[str]], Hypothesis | None],
    most: int,
) -> int:
    """Fit up to ``most`` unreported survivors and report those that rank before reported
    ones in their place; returns how many."""
    reported = solution.hypotheses
    if not solution.unreported or not reported or most <= 0:
        return 0
    named = named_landmarks(fitter.log)
    better: list[tuple[tuple, float, list[str]]] = []
    for raw in solution.unreported[:most]:
        if expired(fitter.deadline):
            break
        assignment = display_names(raw, named)
        marks = {a for a in assignment if a != OUTLIER}
        worst = reported[-1].rank_key
        parsimony = (True, assignment.count(OUTLIER), len(named | marks))
        if parsimony > worst[:3]:
            continue  # ranks after every reported one whatever its fit
        try:
            fit = fitter.fit(assignment, None)
        except OutOfTime:
            break
        key = (*parsimony, round(fit, 6) if math.isfinite(fit) else math.inf)
        if key < worst[:4]:
            better.append((key, fit, assignment))
    promoted = 0
    for key, fit, assignment in sorted(better, key=lambda b: b[0]):
        if not key < reported[-1].rank_key[:4]:
            break
        h = known(assignment)
        if h is None:
            continue
        h.fit = fit
        reported[-1] = h
        reported.sort(key=lambda r: r.rank_key)
        promoted += 1
    if promoted:
        solution.messages.append(
            f"{promoted} survivors the search had not kept for the report fit the readings "
            "better than reported ones and are reported in their place (their boxes from a "
            "known-correspondence solve of the log labelled by their assignment)"
        )
    return promoted
