"""Finding a witness: local optimisation inside the measured intervals, then verification.

:func:`find_witness` minimises how far each check falls short of lying a little inside its
interval, from a few starting points, and keeps the first point that :mod:`.verify` proves.
It minimises in the world form (:mod:`._world`: poses and landmarks as parameters, a sparse
Jacobian, so an evaluation's cost grows with the log, not with its square) and verifies
the model's parameters read off that world.
:func:`~.certification.certify` runs that search on every hypothesis of a
:class:`~cuikslam.outcome.solution.Solution` and marks the proven ones.

The search has a budget: a deadline (checked at every evaluation of the residuals, so it
stops within one least-squares step of it) and a work limit (``MAX_EVALUATIONS`` residual
evaluations per hypothesis). When either runs out the hypothesis stays ``not refuted``:
only a verified point ever makes it ``proven consistent``. The search runs with one BLAS
thread (:func:`cuikslam.budget.blas_single_thread`): its dense matrices are small.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cuikslam.budget import COSTS, Budget, OutOfTime, blas_single_thread, expired, spend
from cuikslam.log.records import Log
from cuikslam.witness._levenberg import bounded_least_squares
from cuikslam.witness._numeric import finite, midpoint
from cuikslam.witness._world import WorldForm
from cuikslam.witness.model import (
    HypothesisModel,
    LandmarkBoxes,
    PoseBoxes,
    WitnessPoint,
)
from cuikslam.witness.verify import verified_box

_HOPELESS = 0.5
"""A hinge residual (in half-widths) beyond which aiming closer to the bounds is not tried."""
MAX_EVALUATIONS = 20_000
"""Residual evaluations (each with its Jacobian) one hypothesis' search may use at most."""
MAX_TOTAL_EVALUATIONS = 40_000
"""Residual evaluations one :func:`certify` may use for all its hypotheses together."""
CENTRE_EVALUATIONS = 50
"""Evaluations of the least-squares estimate that starts each local search."""
CENTRE_TOLERANCE = 1e-5
"""scipy's tolerances (cost, step, gradient) on that estimate, and on the fit that ranks
hypotheses (:mod:`.fit`): a starting point and a ranking need no more. On the Lost in the
Woods window (201 poses) survivors were proven after 9-60 evaluations instead of 10-100
with 1e-14, and the fit's costs agreed with 1e-8's to 1e-3."""
MARGIN_EVALUATIONS = 200
"""Evaluations of each hinge (aimed margins) least-squares run."""
MARGIN_SCALES = (0.1, 0.01, 0.001)
"""The hinge runs aim at these fractions of the aimed margins (``AIM_FRACTION`` of each
interval's half-width), one after the other while none verifies."""
VERIFY_EVERY = 10
"""The least squares' points are verified every this many evaluations (and at the end)."""


@dataclass
class WitnessStatistics:
    """How a witness search went (added up over the hypotheses of a :func:`certify`)."""

    starts: int = 0
    """Starting points tried."""
    evaluations: int = 0
    """Residual evaluations (the unit of work of the least-squares steps)."""
    out_of_time: bool = False
    """The deadline stopped a search before it had tried every start."""
    out_of_work: bool = False
    """``MAX_EVALUATIONS`` stopped a search before it had tried every start."""
    failed_starts: int = 0
    """Starts abandoned on a numerical error of the optimiser (never expected; counted)."""

    @property
    def budget_exhausted(self) -> bool:
        return self.out_of_time or self.out_of_work


class _OutOfWork(Exception):
    pass


class _OverQuota(Exception):
    """A start used the evaluations its round allowed (:meth:`WitnessSearch.run`)."""


class _Verified(Exception):
    """A point of a least-squares run verified: the run stops there."""

    def __init__(self, p: np.ndarray, box: np.ndarray) -> None:
        super().__init__()
        self.p, self.box = p, box


@dataclass
class _Meter:
    """Counts evaluations and raises when the search's time or work budget is spent."""

    deadline: Budget | None
    limit: int
    stats: WitnessStatistics
    cost: float = 0.0
    """Work units of one evaluation (see :data:`cuikslam.budget.COSTS`)."""
    used: int = 0
    quota_end: int | None = None
    """``used`` beyond which the current start is over its round's quota."""

    def tick(self) -> None:
        self.used += 1
        self.stats.evaluations += 1
        spend(self.deadline, self.cost)
        if expired(self.deadline):
            raise OutOfTime
        if self.used > self.limit:
            raise _OutOfWork
        if self.quota_end is not None and self.used > self.quota_end:
            raise _OverQuota

    def spend(self, units: float) -> None:
        """Work beside the evaluations (an iterative step's products); raises
        :class:`OutOfTime` once the budget is spent."""
        spend(self.deadline, units)
        if expired(self.deadline):
            raise OutOfTime


def _polish_equalities(model: HypothesisModel, p: np.ndarray, iterations: int = 4) -> np.ndarray:
    """A few Gauss-Newton steps on the closure equalities (minimum-norm, free parameters)."""
    if len(model.equality_rows) == 0:
        return p
    free = model.free
    p = p.copy()
    for _ in range(iterations):
        f, J = model.equalities(p, jacobian=True)
        assert J is not None
        if np.max(np.abs(f)) < 1e-15:
            break
        step, *_ = np.linalg.lstsq(finite(J[:, free], nan=0.0), -finite(f), rcond=None)
        if not np.all(np.isfinite(step)):
            break
        p[free] += step
        p = np.clip(p, model.param_lo, model.param_hi)
    return p


def _shortfall(model: HypothesisModel, p: np.ndarray) -> float:
    """The largest hinge residual of the model's parameters ``p`` at the aimed margins."""
    res = model.margin_residuals(p)[0]
    return float(np.max(np.abs(res))) if len(res) else 0.0


def _witness_of(
    model: HypothesisModel, world: WorldForm, w: np.ndarray, deadline: Budget | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """The model's parameters of the world point ``w`` (closures polished), and a verified
    box around them or None. Verification is tried only when every check holds in
    floating point: it could not succeed otherwise (each counted: ``world.check_cost``,
    ``world.verify_cost``)."""
    spend(deadline, world.check_cost)
    p = _polish_equalities(model, world.to_params(w))
    if not world.holds(p):
        return p, None
    spend(deadline, world.verify_cost)
    return p, verified_box(model, p)


def _solve_margins(
    model: HypothesisModel,
    world: WorldForm,
    x0: np.ndarray,
    meter: _Meter,
    centre: bool = True,
    poses_xyt: np.ndarray | None = None,
) -> tuple[np.ndarray, float, np.ndarray | None]:
    """Least squares in the world form from the world of parameters ``x0`` (its robot
    poses at ``poses_xyt`` where given): the centre estimate (when ``centre``), then the
    hinge residuals at ``MARGIN_SCALES`` of the aimed margins; returns (params, largest
    hinge residual of the model, verified box or None). Every ``VERIFY_EVERY``-th point
    evaluated is tried too: the first that verifies ends the search."""
    free = world.free
    lb, ub = world.bounds()
    fixed = world.from_params(x0, poses_xyt)

    def full(z: np.ndarray) -> np.ndarray:
        w = fixed.copy()
        w[free] = z
        return w

    seen = [0]

    def run(scale: float | None, z: np.ndarray, max_nfev: int, tol: float) -> np.ndarray:
        def both(zz: np.ndarray) -> tuple[np.ndarray, Any]:
            meter.tick()
            seen[0] += 1
            if seen[0] % VERIFY_EVERY == 0:
                q, box = _witness_of(model, world, full(zz), meter.deadline)
                if box is not None:
                    raise _Verified(q, box)
            return world.residuals(full(zz), True, scale)

        ordering, work = world.ordering()
        spend(meter.deadline, work)
        return bounded_least_squares(both, z, lb, ub, max_nfev, tol, factorised, ordering)

    def factorised(multiply_adds: float) -> None:
        spend(meter.deadline, COSTS["factor_flop"] * multiply_adds)

    def shortfall(p: np.ndarray) -> float:
        spend(meter.deadline, world.check_cost)
        return _shortfall(model, p)

    z = np.clip(fixed[free], lb, ub)
    try:
        p, box = _witness_of(model, world, full(z), meter.deadline)
        if box is not None or not np.any(free):
            return p, shortfall(p), box
        if centre:
            z = run(None, z, CENTRE_EVALUATIONS, CENTRE_TOLERANCE)
        candidates = []
        for scale in MARGIN_SCALES:
            z = run(scale, z, MARGIN_EVALUATIONS, 1e-14)
            p, box = _witness_of(model, world, full(z), meter.deadline)
            if box is not None:
                return p, shortfall(p), box
            candidates.append((shortfall(p), p))
            spend(meter.deadline, world.check_cost)
            if float(np.max(world.residuals(full(z), False, scale)[0], initial=0.0)) > _HOPELESS:
                break  # far outside some interval: smaller margins will not help
    except _Verified as found:
        return found.p, shortfall(found.p), found.box
    residual, best = min(candidates, key=lambda c: c[0])
    return best, residual, None


class WitnessSearch:
    """One hypothesis' witness search, resumable so that :func:`~.certification.certify`
    can share its budget round-robin: the boxes' centres first, then the interval
    midpoints, then random points of the parameter intervals. The first two start with the
    least-squares estimate of the centre; the random ones go straight to the margins, since
    the centre estimate would pull them all back to one basin (a thin solution set far from
    the box centres, e.g. a new landmark beside a look-alike, is found only from a varied
    start)."""

    def __init__(
        self,
        model: HypothesisModel,
        poses_box: PoseBoxes,
        landmarks_box: LandmarkBoxes,
        seed: int,
        deadline: Budget | None,
        max_evaluations: int,
        statistics: WitnessStatistics,
    ) -> None:
        self.model = model
        self.poses_box = poses_box
        self.landmarks_box = landmarks_box
        self.rng = np.random.default_rng(seed)
        self.deadline = deadline
        self.stats = statistics
        model.focus_sensor(poses_box, landmarks_box)
        self.world = WorldForm(model)
        spend(deadline, self.world.build_cost)
        self.meter = _Meter(deadline, max_evaluations, statistics, self.world.evaluation_cost)
        self.tried = 0
        self.best: tuple[float, np.ndarray] | None = None
        self.point: WitnessPoint | None = None
        self.box: np.ndarray | None = None
        self.finished = bool(model.problems)
        if poses_box is None and landmarks_box is None:
            self.tried = 1  # no box centres to start from

    def _start(self, k: int) -> tuple[np.ndarray, bool, np.ndarray | None]:
        """Start ``k``: parameters, whether to begin with the centre estimate, and the
        robot poses to put the world's at (the boxes' centres, for the first)."""
        m = self.model
        if k == 0:
            boxes = m.pose_boxes(self.poses_box)
            centres = None if boxes is None else midpoint(boxes[..., 0], boxes[..., 1])
            params = m.initial_params(self.poses_box, self.landmarks_box, deadline=self.deadline)
            return params, True, centres
        if k == 1:
            return m.initial_params(deadline=self.deadline), True, None
        params = m.initial_params(None, self.landmarks_box, rng=self.rng, deadline=self.deadline)
        return params, False, None

    def run(self, starts: int, quota: int | None = None) -> None:
        """Try up to ``starts`` more starting points (fewer when it succeeds or a budget
        runs out, which finishes the search). With ``quota``, a start that needs more
        residual evaluations than that is abandoned and the run ends: the next run tries
        that start again (from its beginning; a random one is drawn anew)."""
        try:
            self._run(starts, quota)
        finally:
            self.model.release()

    def _run(self, starts: int, quota: int | None) -> None:
        stats, model, meter = self.stats, self.model, self.meter
        with blas_single_thread(), np.errstate(all="ignore"):
            for _ in range(starts):
                if self.finished:
                    return
                if expired(self.deadline):
                    stats.out_of_time = self.finished = True
                    return
                stats.starts += 1
                self.tried += 1
                meter.quota_end = None if quota is None else meter.used + quota
                try:
                    spend(self.deadline, self.world.start_cost)
                    meter.tick()  # a start counts as an evaluation, even one that fails
                    x0, centre, poses = self._start(self.tried - 1)
                    p, residual, box = _solve_margins(model, self.world, x0, meter, centre, poses)
                except _OverQuota:
                    stats.starts -= 1
                    self.tried -= 1
                    return
                except OutOfTime:
                    stats.out_of_time = self.finished = True
                    return
                except _OutOfWork:
                    stats.out_of_work = self.finished = True
                    return
                except (ValueError, ArithmeticError, np.linalg.LinAlgError):
                    # a numerical failure of the optimiser (it only proposes points): try the
                    # next start; the hypothesis at worst stays 'not refuted'
                    stats.failed_starts += 1
                    continue
                if box is not None:
                    self.point, self.box, self.finished = model.point(p, residual), box, True
                    return
                if self.best is None or residual < self.best[0]:
                    self.best = (residual, p)

    def unverified(self) -> WitnessPoint | None:
        """The best point when it meets every aimed margin in floating point."""
        if self.best is not None and self.best[0] <= 1e-12:
            return self.model.point(self.best[1], self.best[0])
        return None


def find_point(
    model: HypothesisModel,
    poses_box: PoseBoxes,
    landmarks_box: LandmarkBoxes,
    seed: int,
    restarts: int,
    *,
    deadline: Budget | None = None,
    max_evaluations: int = MAX_EVALUATIONS,
    statistics: WitnessStatistics | None = None,
) -> tuple[WitnessPoint | None, np.ndarray | None]:
    """The search of :func:`find_witness` on a built model.

    Parameters
    ----------
    model : HypothesisModel
        The hypothesis.
    poses_box, landmarks_box
        Boxes whose centres give the first start (or None).
    seed : int
        Seed of the random starts.
    restarts : int
        Random starts after the box centres and the interval midpoints.
    deadline : Budget, optional
        :func:`time.perf_counter` value at which the search stops.
    max_evaluations : int
        Residual evaluations at most.
    statistics : WitnessStatistics, optional
        Counts are added here (and whether a budget ran out).

    Returns
    -------
    tuple
        (point, verified parameter box), or (unverified point, None), or (None, None).
    """
    stats = statistics if statistics is not None else WitnessStatistics()
    search = WitnessSearch(model, poses_box, landmarks_box, seed, deadline, max_evaluations, stats)
    search.run(2 + restarts)
    if search.point is not None:
        return search.point, search.box
    return search.unverified(), None


def find_witness(
    log: Log,
    assignment: Sequence[str],
    poses_box: PoseBoxes = None,
    landmarks_box: LandmarkBoxes = None,
    seed: int = 0,
    *,
    restarts: int = 3,
    use_sensor: bool = True,
    deadline: Budget | None = None,
) -> WitnessPoint | None:
    """Look for a solution point of the hypothesis ``(log, assignment)``.

    Minimises, over the parameters (within their intervals), how far each check falls short
    of lying 10 % of its half-width inside its interval (at least 1e-9), plus the closure
    equalities and the sensor's negative information. Starts from the centres of
    ``poses_box`` / ``landmarks_box`` when given (mappings by id, or arrays in the kinematic
    graph's order: a Hypothesis' ``poses`` / ``landmarks``), then from interval midpoints,
    then from ``restarts`` random points (``numpy.random.default_rng(seed)``).

    Returns the first point that :func:`verify_witness` accepts; failing that, a point that
    meets every aimed margin in floating point (unverified), or None. The search stops at
    ``deadline`` (a :func:`time.perf_counter` value) or after ``MAX_EVALUATIONS``.
    """
    model = HypothesisModel(log, assignment, use_sensor=use_sensor)
    point, _ = find_point(model, poses_box, landmarks_box, seed, restarts, deadline=deadline)
    return point
