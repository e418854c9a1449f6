"""Consistency levels: how hard to narrow beyond the fixpoint of the factors' operators.

- ``hull``: the fixpoint of the narrowing operators (local, hull consistency). Fastest;
  boxes forget that consecutive poses are correlated, so they grow along the chain.
- ``lp``: ``hull`` then sweeps of the polytope-hull operator (:mod:`.relaxation`) over
  overlapping windows of consecutive poses, forward then backward along the chain, each
  followed by propagation, until a sweep shrinks the boxes by less than 0.5 %. A bound
  whose LP stopped moving it is not solved again until its window's boxes have shrunk.
  Each pose is bounded by the window where it sits in the middle; a window's LPs are
  solved as one sequence (:func:`.lp_bounds.certified_bounds`: HiGHS, then a compiled
  simplex from its basis); on long logs the sweeps from the 4th reuse the last LPs'
  multipliers instead of solving LPs (``REUSE_FROM``). Correlation-aware, so it removes
  most of the wrapping effect: within 1.31x of the exact hull on the seed's experiment.
  Its cost grows linearly with the log (every window has a bounded size), so ``auto`` is
  ``lp`` at any length.
- ``lp-split``: ``lp``, then the widest headings are bisected one after the other; each
  half is narrowed at level ``lp`` and the hull of the halves is kept. The linearisations
  are tighter on half the heading interval. About 2.5 times the cost of ``lp``, for
  boxes within 1.22x of the exact hull on the seed's experiment.

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
from cuikslam.budget import expired
from cuikslam.graph.encoding import (
    KIND,
    OBSERVATION,
    ODOMETRY,
    RELATIVE,
    ROTATION,
    TA,
    TB,
    XA,
    XB,
)
from cuikslam.narrowing._factors import fresh_memory
from cuikslam.narrowing._propagate import propagate_buffered
from cuikslam.narrowing.propagation import Arrays, Propagation, Status, narrow
from cuikslam.narrowing.relaxation import LpStatistics, WarmStarts, tighten

__all__ = [
    "BUDGET_SUFFIX",
    "DEFAULT_LEVEL",
    "LEVELS",
    "Arrays",
    "StrengthenReport",
    "resolve_level",
    "strengthen",
    "warm_up_lp",
]

LEVELS = ("hull", "lp", "lp-split")
DEFAULT_LEVEL = "auto"
"""``lp``, whatever the length of the log (see :func:`resolve_level`)."""
WINDOW_POSES = 10
"""Poses per window of the polytope-hull operator."""
WINDOW_OVERLAP = 5
"""Poses shared by consecutive windows."""
LOCAL_SPAN = 4
"""Before a window's LPs, its factors are propagated, with at most this many operator
applications per factor of the window (the LPs' relaxation is tighter on narrower boxes;
the cap keeps the cost of a window independent of the log's length)."""
MAX_LP_ROUNDS = 12
MIN_GAIN = 0.005
"""Stop after a sweep that shrinks the total width by less than this fraction."""
CENTRAL_ONLY = True
"""Each pose is bounded by one window per sweep (see ``_central``)."""
REUSE_FROM = 3
"""From this sweep on (counting from 0), no LP is solved: each bound is the safe bound of
the multipliers of its last LP over the window's new relaxation (see
``lp_bounds.certified_bounds(reuse=True)``). It follows the neighbours' narrowing while
the LP's optimal basis stays optimal; on the octagon the LPs of the 4th and 5th sweeps
gained 1 % for a third of the LPs."""
REUSE_MIN_WINDOWS = 8
"""Logs with fewer windows solve every sweep's LPs: there the later sweeps gain from the
relaxation of narrower boxes, not only from the neighbours (on the seed's experiment, one
window, reusing multipliers took the worst box from 1.30 to 1.57 times the inner hull)."""
FULL_ROUND_EVERY = 3
"""Every this many sweeps, stale bounds are solved again all the same."""
UNSTALE_SHRINK = 0.02
"""A window's stale bounds are solved again once the widths of its variables have shrunk
by about this fraction since its last LPs (in the mean of their logarithms)."""
STALE_GAIN = 0.01
"""A bound whose LP moved it by less than this fraction of its width is left alone (see
``_polytope_rounds``)."""
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


def resolve_level(level: str, n_poses: int) -> str:
    """The level to run: ``auto`` becomes ``lp`` (whatever ``n_poses``; kept as a parameter
    so that callers need not change if the choice ever depends on the log again).

    The ``lp`` sweeps cost about the same per pose on short and long logs (see
    ``benchmarks/bench_long_logs.py``); the time budget of a solve, not the level, is what
    bounds a long log's run time.
    """
    if level == "auto":
        return "lp"
    if level not in LEVELS:
        raise ValueError(f"unknown consistency level {level!r}; choose auto or one of {LEVELS}")
    return level


@dataclass
class _Window:
    """A window of consecutive poses: its factors (indices and rows) and the variables it
    narrows (positions and headings of its poses, positions of the landmarks they see)."""

    indices: np.ndarray
    rows: np.ndarray
    targets: np.ndarray
    """Every variable of the window's poses and landmarks (sorted)."""
    headings: np.ndarray
    bounded: np.ndarray
    """The variables whose bounds this window's LPs compute, x coordinates first, then y,
    then headings, each in the order of the chain: consecutive LPs then have nearby
    optima, so each starts close to the last one's basis."""


def _windows(factors: np.ndarray) -> list[_Window]:
    """Overlapping windows of consecutive poses, in the order of the chain.

    A window holds every odometry factor between two of its poses and every observation
    from one of them; built in time linear in the number of factors.
    """
    kept = np.flatnonzero(np.isin(factors[:, KIND], (ODOMETRY, OBSERVATION, RELATIVE, ROTATION)))
    rows = factors[kept]
    if len(rows) == 0:
        return []
    odo = np.isin(rows[:, KIND], (ODOMETRY, RELATIVE, ROTATION))  # pose to pose
    turns = np.isin(rows[:, KIND], (ODOMETRY, ROTATION))  # with a heading tb
    poses = np.unique(np.concatenate([rows[:, XA], rows[odo, XB]]))
    first = np.searchsorted(poses, rows[:, XA])
    last = np.where(odo, np.searchsorted(poses, np.where(odo, rows[:, XB], rows[:, XA])), first)
    first, last = np.minimum(first, last), np.maximum(first, last)
    if len(poses) <= WINDOW_POSES:
        starts = [0]
    else:
        starts = list(range(0, len(poses) - WINDOW_OVERLAP, WINDOW_POSES - WINDOW_OVERLAP))
    order = np.argsort(first, kind="stable")
    sorted_first = first[order]
    landmark_x = np.unique(rows[rows[:, KIND] == OBSERVATION, XB])
    windows = []
    for start in starts:
        end = start + WINDOW_POSES
        span = np.searchsorted(sorted_first, [start, end])
        candidates = order[span[0] : span[1]]
        inside = np.sort(candidates[last[candidates] < end])
        selected, selected_turns = rows[inside], turns[inside]
        b = selected[:, XB]
        targets = [selected[:, XA], selected[:, XA] + 1, selected[:, TA], b, b + 1]
        targets.append(selected[selected_turns, TB])
        headings = np.unique(np.concatenate([selected[:, TA], selected[selected_turns, TB]]))
        targets = np.unique(np.concatenate(targets))
        low, high = _central(start, end, len(poses))
        seen = selected[:, KIND] == OBSERVATION
        landmarks = np.concatenate([selected[seen, XB], selected[seen, XB] + 1])
        bounded = _bounded(targets, poses, low, high, landmarks, landmark_x)
        windows.append(_Window(kept[inside], selected, targets, headings, bounded))
    return windows


def _central(start: int, end: int, n_poses: int) -> tuple[int, int]:
    """The positions of the poses a window bounds: with ``CENTRAL_ONLY``, its middle
    ``WINDOW_POSES - WINDOW_OVERLAP`` (the first and last windows reach the ends of the
    chain), so each pose is bounded by the one window where it has the most neighbours on
    both sides."""
    if not CENTRAL_ONLY:
        return start, end
    margin = WINDOW_OVERLAP // 2
    low = start + margin if start > 0 else 0
    high = end - (WINDOW_OVERLAP - margin) if end < n_poses else n_poses
    return low, high


def _bounded(
    targets: np.ndarray,
    poses: np.ndarray,
    low: int,
    high: int,
    landmarks: np.ndarray,
    landmark_x: np.ndarray,
) -> np.ndarray:
    """The ``targets`` a window bounds, in LP order (see ``_Window.bounded``): the
    coordinates of its poses at positions ``low`` to ``high - 1`` and of the ``landmarks``.
    """
    k = np.searchsorted(poses, targets, side="right") - 1
    offset = targets - poses[np.maximum(k, 0)]
    is_pose = (k >= 0) & (offset <= 2)  # x, y, theta of a pose are consecutive variables
    kind = np.where(is_pose, offset, np.where(np.isin(targets, landmark_x), 0, 1))
    keep = np.where(is_pose, (k >= low) & (k < high), np.isin(targets, landmarks))
    order = np.lexsort((targets, kind))
    return targets[order[keep[order]]]


def _signature(lo: np.ndarray, hi: np.ndarray, variables: np.ndarray) -> float:
    """Mean of the logarithms of the finite, non-zero widths: it drops by about g when
    every variable shrinks by the fraction g."""
    with np.errstate(invalid="ignore", divide="ignore"):
        logs = np.log(hi[variables] - lo[variables])
    logs = logs[np.isfinite(logs)]
    return float(np.mean(logs)) if logs.size else 0.0


def _total_width(lo: np.ndarray, hi: np.ndarray, variables: np.ndarray) -> float:
    with np.errstate(invalid="ignore"):
        widths = hi[variables] - lo[variables]
    return float(np.sum(widths[np.isfinite(widths)]))


def strengthen(
    arrays: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    level: str,
    rtol: float,
    max_rounds: int,
    progress: Callable[[int, int], None] | None = None,
    *,
    deadline: float | None = None,
    report: StrengthenReport | None = None,
) -> Propagation:
    """Narrow ``lo``/``hi`` in place beyond the fixpoint, to the given consistency level.

    Parameters
    ----------
    arrays : Arrays
        The graph.
    lo, hi : numpy.ndarray
        Bounds of every variable, already at the fixpoint of the factors; narrowed in place.
    level : str
        One of ``LEVELS``.
    rtol : float
        Relative gain below which propagation stops requeueing a factor.
    max_rounds : int
        Propagation rounds at most (per propagation).
    progress : callable, optional
        ``progress(done, total)`` after each window's LPs, ``total`` counting the most
        rounds the level may run.
    deadline : float, optional
        A :func:`time.perf_counter` value: no LP starts after it, and running LPs stop (at
        most ``lp_bounds.LP_TIME_LIMIT`` later). The boxes are then whatever sound
        narrowing reached, propagated back to the fixpoint. None: no time limit (each LP
        still has its own iteration and time limits).
    report : StrengthenReport, optional
        Filled in with the level reached and LP counts.

    Returns
    -------
    Propagation
        Holding ``lo`` and ``hi`` themselves and the operator applications of the level's
        propagations; ``Status.INCONSISTENT`` is a proof (whatever the deadline, an empty
        box is never a guess), otherwise ``Status.CONSISTENT``.
    """
    ensure_round_to_nearest()
    if level not in LEVELS:
        raise ValueError(f"unknown consistency level {level!r}; choose one of {', '.join(LEVELS)}")
    report = report if report is not None else StrengthenReport()
    report.level = "hull"
    if level == "hull":
        return Propagation(lo, hi, Status.CONSISTENT, 0)
    if expired(deadline):
        report.budget_exhausted = True
        return Propagation(lo, hi, Status.CONSISTENT, 0)
    solved_before = report.lp.solved
    status, applications, finished = _polytope_rounds(
        arrays, lo, hi, rtol, max_rounds, progress, deadline, report
    )
    if finished:
        report.level = "lp"
    elif report.lp.solved > solved_before:
        report.level = "lp" + BUDGET_SUFFIX
    if not finished:
        report.budget_exhausted = True
    if status is Status.INCONSISTENT or level == "lp" or not finished:
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
                status, count, finished = _polytope_rounds(
                    arrays, half_lo, half_hi, rtol, max_rounds, None, deadline, report
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


class _Propagator:
    """Propagation over the whole graph with work arrays allocated once (a call costs what
    it touches, not the size of the graph)."""

    def __init__(self, arrays: Arrays, rtol: float, max_rounds: int) -> None:
        n = arrays.factors.shape[0]
        self.arrays, self.rtol, self.max_rounds = arrays, rtol, max_rounds
        self.queue = np.empty(n + 1, dtype=np.int64)
        self.state = np.zeros(n, dtype=np.int8)
        self.memory = fresh_memory(n)
        self.applied = np.empty(n, dtype=np.int64)

    def __call__(
        self, lo: np.ndarray, hi: np.ndarray, touched: np.ndarray, max_applications: int = 2**62
    ) -> tuple[Status, int]:
        a = self.arrays
        status, count, _ = propagate_buffered(
            lo, hi, a.factors, a.head, a.entry_factor, a.entry_next, touched, self.rtol,
            self.max_rounds, max_applications, self.queue, self.state, self.memory,
            self.applied,
        )  # fmt: skip
        return Status(status), count


def _polytope_rounds(
    arrays: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    rtol: float,
    max_rounds: int,
    progress: Callable[[int, int], None] | None,
    deadline: float | None,
    report: StrengthenReport,
) -> tuple[Status, int, bool]:
    """Sweeps of the polytope-hull operator along the chain, forward then backward, until
    they stall.

    Before a window's LPs its factors are propagated (capped, see ``LOCAL_SPAN``), so each
    window starts from what the previous one found. A bound whose last LP moved it by less
    than ``STALE_GAIN`` of its width is *stale*: not solved again until its window's boxes
    have shrunk by ``UNSTALE_SHRINK`` since that window's last LPs, or the next full sweep
    (every ``FULL_ROUND_EVERY``-th). After each sweep the whole graph is propagated. Returns
    ``(status, applications, finished)``; ``finished`` is False when the deadline cut the
    sweeps short (the boxes are then propagated to the fixpoint all the same).
    """
    windows = _windows(arrays.factors)
    if not windows:
        return Status.CONSISTENT, 0, True
    propagate = _Propagator(arrays, rtol, max_rounds)
    everything = np.arange(arrays.factors.shape[0], dtype=np.int64)
    applications = 0
    targets = np.unique(np.concatenate([w.targets for w in windows]))
    width = _total_width(lo, hi, targets)
    stale_lo = np.zeros(len(lo), dtype=bool)
    stale_hi = np.zeros(len(lo), dtype=bool)
    warm = [WarmStarts() for _ in windows]
    signature = np.full(len(windows), -np.inf)
    total = MAX_LP_ROUNDS * len(windows)
    for round_index in range(MAX_LP_ROUNDS):
        full = round_index % FULL_ROUND_EVERY == 0
        if full:
            stale_lo[:] = False
            stale_hi[:] = False
        skipped = report.lp.skipped
        cut = False
        order = range(len(windows)) if round_index % 2 == 0 else range(len(windows) - 1, -1, -1)
        for step, w in enumerate(order):
            window = windows[w]
            if progress is not None:
                progress(round_index * len(windows) + step, total)
            if _signature(lo, hi, window.targets) < signature[w] - UNSTALE_SHRINK:
                stale_lo[window.targets] = False
                stale_hi[window.targets] = False
            reuse = round_index >= REUSE_FROM and len(windows) >= REUSE_MIN_WINDOWS
            if reuse:
                lower, upper = window.bounded, window.bounded[::-1]
            else:
                lower = window.bounded[~stale_lo[window.bounded]]
                upper = window.bounded[~stale_hi[window.bounded]][::-1]
            if lower.size == 0 and upper.size == 0:
                continue
            if expired(deadline):
                cut = True
                break
            status, count = propagate(lo, hi, window.indices, LOCAL_SPAN * len(window.indices))
            applications += count
            if status is Status.INCONSISTENT:
                return Status.INCONSISTENT, applications, True
            old_lo, old_hi = lo[window.targets], hi[window.targets]
            tightened = tighten(
                window.rows, lo, hi, lower, warm[w], deadline=deadline,
                statistics=report.lp, upper_targets=upper, reuse=reuse,
            )  # fmt: skip
            if tightened.is_empty:
                return Status.INCONSISTENT, applications, True
            with np.errstate(invalid="ignore"):
                slack = STALE_GAIN * (old_hi - old_lo)
                moved_lo = (lo[window.targets] - old_lo > slack) | (
                    np.isinf(slack) & (lo[window.targets] > old_lo)
                )
                moved_hi = (old_hi - hi[window.targets] > slack) | (
                    np.isinf(slack) & (hi[window.targets] < old_hi)
                )
            stale_lo[lower] = ~moved_lo[np.searchsorted(window.targets, lower)]
            stale_hi[upper] = ~moved_hi[np.searchsorted(window.targets, upper)]
            signature[w] = _signature(lo, hi, window.targets)
        report.lp_rounds += 1
        cut = cut or report.lp.skipped > skipped
        status, count = propagate(lo, hi, everything)
        applications += count
        if status is Status.INCONSISTENT:
            return Status.INCONSISTENT, applications, True
        if cut:
            return Status.CONSISTENT, applications, False
        new_width = _total_width(lo, hi, targets)
        if new_width > width * (1.0 - MIN_GAIN):
            break
        if expired(deadline) and round_index + 1 < MAX_LP_ROUNDS:
            return Status.CONSISTENT, applications, False
        width = new_width
    return Status.CONSISTENT, applications, True
