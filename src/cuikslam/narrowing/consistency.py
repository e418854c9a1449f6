"""Consistency levels: how hard to narrow beyond the fixpoint of the factors' operators.

- ``hull``: the fixpoint of the narrowing operators (local, hull consistency). Fastest;
  boxes forget that consecutive poses are correlated, so they grow along the chain.
- ``lp``: ``hull`` then sweeps of the polytope-hull operator (:mod:`.polytope`) over
  overlapping windows of consecutive poses, forward then backward along the chain, each
  followed by propagation, until a sweep shrinks the boxes by less than 0.5 %. A bound
  whose LP stopped moving it is not solved again until its window's boxes have shrunk.
  Each pose is bounded by the window where it sits in the middle; a window's LPs are
  solved as one sequence (:func:`.lp_bounds.certified_bounds`: HiGHS, then a compiled
  simplex from its basis); on long logs the sweeps from the 4th reuse the last LPs'
  multipliers instead of solving LPs (``sweeps.REUSE_FROM``). Correlation-aware, so it removes
  most of the wrapping effect.
  Its cost grows linearly with the log (every window has a bounded size), so it is the
  default at any length (``auto``, an older name of the default, is ``lp``).
- ``lp-split``: ``lp``, then the widest headings are bisected one after the other; each
  half is narrowed at level ``lp`` and the hull of the halves is kept. The linearisations
  are tighter on half the heading interval. Tighter boxes than ``lp``, for a few times
  its cost.

How close each level comes to the exact hull, and at what cost, is measured in
``docs/concepts/levels.md`` and ``docs/benchmarks.md`` (``benchmarks/``), not here.

Every level is sound: the boxes still contain every solution, and an empty result is a
proof that the constraints have no solution.

The stronger levels have a time budget (``strengthen(..., deadline=...)``). When it runs
out, the LPs stop, the boxes are what sound narrowing reached so far (then propagated back
to the fixpoint of the factors), and the level reached is reported honestly
(:class:`StrengthenReport`): ``"lp (budget)"`` means hull-consistent boxes narrowed further
by some but not all ``lp`` rounds; ``"lp-split (budget)"`` means ``lp`` was reached and the
heading splits were cut short; ``"hull"`` means the budget ran out before any LP ran.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import Budget, expired
from cuikslam.graph.encoding import (
    KIND,
    OBSERVATION,
    ODOMETRY,
    ROTATION,
    TA,
    TB,
)
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.narrowing.polytope import LpStatistics, WarmStarts, tighten
from cuikslam.narrowing.propagation import (
    DEFAULT_ROUNDS,
    DEFAULT_RTOL,
    Arrays,
    Propagation,
    Status,
    narrow,
)
from cuikslam.narrowing.sweeps import polytope_rounds
from cuikslam.options import Level, SolveOptions

__all__ = [
    "BUDGET_SUFFIX",
    "DEFAULT_LEVEL",
    "LEVELS",
    "StrengthenReport",
    "strengthen",
    "warm_up_lp",
]

LEVELS = tuple(str(level) for level in Level)
"""The names of the levels :func:`strengthen` runs (:class:`~cuikslam.options.Level`)."""
DEFAULT_LEVEL = SolveOptions.consistency
"""``lp``, whatever the length of the log (the sweeps cost about the same per pose on
short and long logs, ``benchmarks/bench_long_logs.py``: the budget, not the level, bounds
a long log's run time)."""
SPLIT_HEADINGS = 2
"""Headings bisected by the ``lp-split`` level (the widest first)."""
BUDGET_SUFFIX = " (budget)"
"""Appended to a level whose rounds the time budget cut short (e.g. ``"lp (budget)"``)."""


@dataclass
class StrengthenReport:
    """What :func:`strengthen` reached: pass one as ``report=`` to have it filled in."""

    level: str = ""
    """The level the boxes reach: ``hull``, ``lp``, ``lp-split``, or a level followed by
    ``BUDGET_SUFFIX`` when the deadline cut it short (see the module docstring)."""
    budget_exhausted: bool = False
    """True when the deadline stopped the rounds before the level's own stopping rule."""
    lp_rounds: int = 0
    """Rounds of the polytope-hull operator run (over all windows, halves included)."""
    lp: LpStatistics = field(default_factory=LpStatistics)
    """LP counts: solved, optimal, stopped by a limit, retried, skipped at the deadline."""


def strengthen(
    graph: KinematicGraph | Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    level: Level | str = Level.LP,
    rtol: float = DEFAULT_RTOL,
    max_rounds: int = DEFAULT_ROUNDS,
    progress: Callable[[int, int], None] | None = None,
    *,
    deadline: Budget | None = None,
    report: StrengthenReport | None = None,
    threads: int | None = None,
) -> Propagation:
    """Narrow ``lo``/``hi`` in place beyond the fixpoint, to the given consistency level.

    Parameters
    ----------
    graph : KinematicGraph or Arrays
        The graph, or its arrays as the compiled kernels see them
        (:meth:`Arrays.of <cuikslam.narrowing.propagation.Arrays.of>`); given the graph,
        the result answers :meth:`~cuikslam.narrowing.propagation.Propagation.pose_box`
        and ``landmark_box`` by id.
    lo, hi : numpy.ndarray
        Bounds of every variable, already at the fixpoint of the factors (e.g. the ``lo``
        and ``hi`` of :func:`~cuikslam.narrowing.propagation.propagate`); narrowed in
        place.
    level : Level or str
        The level (``Level.LP`` by default; its name is accepted too).
    rtol : float
        Relative gain below which propagation stops requeueing a factor.
    max_rounds : int
        Propagation rounds at most (per propagation).
    progress : callable, optional
        ``progress(done, total)`` after each window's LPs, ``total`` counting the most
        rounds the level may run.
    deadline : Budget, optional
        A :func:`time.perf_counter` value: no LP starts after it, and running LPs stop (at
        most ``lp_bounds.LP_TIME_LIMIT`` later). The boxes are then whatever sound
        narrowing reached, propagated back to the fixpoint. None: no time limit (each LP
        still has its own iteration limit, and no time limit).
    report : StrengthenReport, optional
        Filled in with the level reached and LP counts.
    threads : int, optional
        Threads the sweeps of a long log may use (None: the cores not already busy, see
        :func:`.parts.default_threads`). The boxes are the same for any number.

    Returns
    -------
    Propagation
        Holding ``lo`` and ``hi`` themselves and the operator applications of the level's
        propagations; ``Status.INCONSISTENT`` is a proof (whatever the deadline, an empty
        box is never a guess), otherwise ``Status.CONSISTENT``.

    Examples
    --------
    >>> from cuikslam.graph import KinematicGraph
    >>> from cuikslam.narrowing.propagation import propagate
    >>> graph = KinematicGraph()
    >>> graph.add_pose_prior(0, x=(0, 0), y=(0, 0), theta=(0, 0))
    >>> _ = graph.add_odometry(0, 1, turn=(-0.1, 0.1), distance=(1, 2))
    >>> fixpoint = propagate(graph)
    >>> stronger = strengthen(graph, fixpoint.lo, fixpoint.hi, level="lp")
    >>> stronger.lo is fixpoint.lo, stronger.pose_box(1).shape
    (True, (3, 2))
    """
    level = Level.parse(level)
    if isinstance(graph, KinematicGraph):
        result = _strengthen(
            Arrays.of(graph), lo, hi, level, rtol, max_rounds, progress, deadline, report,
            threads,
        )  # fmt: skip
        result.graph = graph
        return result
    return _strengthen(graph, lo, hi, level, rtol, max_rounds, progress, deadline, report, threads)


def _strengthen(
    arrays: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    level: Level,
    rtol: float,
    max_rounds: int,
    progress: Callable[[int, int], None] | None,
    deadline: Budget | None,
    report: StrengthenReport | None,
    threads: int | None,
) -> Propagation:
    """:func:`strengthen` on the graph's arrays."""
    ensure_round_to_nearest()
    report = report if report is not None else StrengthenReport()
    report.level = "hull"
    if level is Level.HULL:
        return Propagation(lo, hi, Status.CONSISTENT, 0)
    if expired(deadline):
        report.budget_exhausted = True
        return Propagation(lo, hi, Status.CONSISTENT, 0)
    solved_before = report.lp.solved
    status, applications, finished = polytope_rounds(
        arrays, lo, hi, rtol, max_rounds, progress, deadline, report, threads
    )
    if finished:
        report.level = "lp"
    elif report.lp.solved > solved_before:
        report.level = "lp" + BUDGET_SUFFIX
    if not finished:
        report.budget_exhausted = True
    if status is Status.INCONSISTENT or level is Level.LP or not finished:
        return Propagation(lo, hi, status, applications)
    turning = np.isin(arrays.factors[:, KIND], (ODOMETRY, ROTATION))
    headings = np.unique(arrays.factors[turning][:, [TA, TB]])
    for _ in range(SPLIT_HEADINGS):
        if expired(deadline):
            report.budget_exhausted = True
            report.level = "lp-split" + BUDGET_SUFFIX
            return Propagation(lo, hi, Status.CONSISTENT, applications)
        widths = hi[headings] - lo[headings]
        if headings.size == 0 or not np.isfinite(widths).any() or widths.max() <= 0:
            break
        v = headings[np.argmax(np.where(np.isfinite(widths), widths, -1.0))]
        middle = 0.5 * (lo[v] + hi[v])
        halves = []
        for a, b in ((lo[v], middle), (middle, hi[v])):
            half_lo, half_hi = lo.copy(), hi.copy()
            half_lo[v], half_hi[v] = a, b
            halved = narrow(arrays, half_lo, half_hi, arrays.factors_of(v), rtol, max_rounds)
            applications += halved.applications
            status = halved.status
            if status is not Status.INCONSISTENT:
                # each half is narrowed as far as the deadline allows (at least propagated),
                # so the hull of the two halves is sound however early it stops
                status, count, finished = polytope_rounds(
                    arrays, half_lo, half_hi, rtol, max_rounds, None, deadline, report, threads
                )
                applications += count
                if not finished:
                    report.budget_exhausted = True
                    report.level = "lp-split" + BUDGET_SUFFIX
            if status is not Status.INCONSISTENT:
                halves.append((half_lo, half_hi))
        if not halves:
            return Propagation(lo, hi, Status.INCONSISTENT, applications)
        lo[:] = np.min([h[0] for h in halves], axis=0)
        hi[:] = np.max([h[1] for h in halves], axis=0)
    if not report.budget_exhausted:
        report.level = "lp-split"
    return Propagation(lo, hi, Status.CONSISTENT, applications)


def warm_up_lp() -> None:
    """Compile (or load from numba's cache) the kernels of the ``lp`` level: the interval
    operations of the relaxation, the safe bound and the LP sequence kernel, by bounding
    the variables of one odometry step and one observation (a solve calls it before its
    time budget starts)."""
    # variables: pose 0 (0-2), pose 1 (3-5), turn 6, distance 7, landmark 8-9, bearing 10,
    # range 11; columns KIND, XA, YA, TA, XB, YB, TB, ANGLE, LENGTH
    factors = np.array(
        [[ODOMETRY, 0, 1, 2, 3, 4, 5, 6, 7], [OBSERVATION, 3, 4, 5, 8, 9, -1, 10, 11]],
        dtype=np.int64,
    )
    lo = np.array([0.0, 0.0, 0.0, 0.9, -0.2, 0.0, 0.0, 1.0, 1.5, -1.0, -0.1, 1.0])
    hi = np.array([0.0, 0.0, 0.0, 1.2, 0.2, 0.1, 0.1, 1.1, 3.5, 1.0, 0.1, 1.1])
    tighten(factors, lo, hi, np.arange(len(lo)), WarmStarts())
