"""Consistency levels: how hard to narrow beyond the fixpoint of the factors' operators.

- ``hull``: the fixpoint of the narrowing operators (local, hull consistency). Fastest;
  boxes forget that consecutive poses are correlated, so they grow along the chain.
- ``lp``: ``hull`` then rounds of the polytope-hull operator (:mod:`.relaxation`) over
  windows of consecutive poses, each followed by propagation, until a round shrinks the
  boxes by less than 0.5 %. Correlation-aware, so it removes most of the wrapping effect:
  within 1.32x of the exact hull on the seed's experiment, in about half a second.
- ``lp-split``: ``lp``, then the widest headings are bisected one after the other; each
  half is narrowed at level ``lp`` and the hull of the halves is kept. The linearisations
  are tighter on half the heading interval. About 3.5 times the cost of ``lp``, for
  boxes within 1.16x of the exact hull on the seed's experiment.

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
from cuikslam.narrowing._propagate import CONSISTENT, INCONSISTENT, propagate_arrays
from cuikslam.narrowing.relaxation import LpStatistics, WarmStarts, tighten

__all__ = [
    "BUDGET_SUFFIX",
    "DEFAULT_LEVEL",
    "LEVELS",
    "Arrays",
    "StrengthenReport",
    "resolve_level",
    "strengthen",
]

LEVELS = ("hull", "lp", "lp-split")
DEFAULT_LEVEL = "auto"
"""``lp`` up to ``AUTO_LP_POSES`` poses, ``hull`` beyond (see :func:`resolve_level`)."""
AUTO_LP_POSES = 50
WINDOW_POSES = 10
"""Poses per window of the polytope-hull operator (windows overlap by half)."""
MAX_LP_ROUNDS = 12
MIN_GAIN = 0.005
"""Stop after a full round that shrinks the total width by less than this fraction."""
FULL_ROUND_EVERY = 3
ACTIVE_GAIN = 0.02
"""Between full rounds, only variables that shrank by this fraction last round are re-solved."""
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


@dataclass
class Arrays:
    """A graph as the compiled kernels see it (see :mod:`cuikslam.graph.encoding`)."""

    factors: np.ndarray
    head: np.ndarray
    entry_factor: np.ndarray
    entry_next: np.ndarray


def resolve_level(level: str, n_poses: int) -> str:
    """The level to run: ``auto`` becomes ``lp`` up to ``AUTO_LP_POSES`` poses, else ``hull``.

    The polytope-hull rounds take half a second on the seed's 9 poses, 3 s at 40-50
    poses and 19 s at 100 on random worlds dense with observations; ask for them
    explicitly on long logs.
    """
    if level == "auto":
        return "lp" if n_poses <= AUTO_LP_POSES else "hull"
    if level not in LEVELS:
        raise ValueError(f"unknown consistency level {level!r}; choose auto or one of {LEVELS}")
    return level


def _windows(factors: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Overlapping windows of consecutive poses: (factor rows, target variables) each."""
    rows = factors[np.isin(factors[:, KIND], (ODOMETRY, OBSERVATION, RELATIVE, ROTATION))]
    if len(rows) == 0:
        return []
    odo = np.isin(rows[:, KIND], (ODOMETRY, RELATIVE, ROTATION))  # pose to pose
    turns = np.isin(rows[:, KIND], (ODOMETRY, ROTATION))  # with a heading tb
    poses = np.unique(np.concatenate([rows[:, XA], rows[odo, XB]]))
    if len(poses) <= WINDOW_POSES:
        groups = [poses]
    else:
        step = WINDOW_POSES // 2
        groups = [poses[i : i + WINDOW_POSES] for i in range(0, len(poses) - step, step)]
    windows = []
    for group in groups:
        inside = np.isin(rows[:, XA], group) & (~odo | np.isin(rows[:, XB], group))
        selected, selected_turns = rows[inside], turns[inside]
        b = selected[:, XB]
        targets = [selected[:, XA], selected[:, XA] + 1, selected[:, TA], b, b + 1]
        targets.append(selected[selected_turns, TB])
        windows.append((selected, np.unique(np.concatenate(targets))))
    return windows


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
) -> tuple[int, int]:
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
    tuple of int
        ``(status, operator applications)``, status CONSISTENT or INCONSISTENT (a proof:
        whatever the deadline, an empty box is never a guess).
    """
    ensure_round_to_nearest()
    if level not in LEVELS:
        raise ValueError(f"unknown consistency level {level!r}; choose one of {', '.join(LEVELS)}")
    report = report if report is not None else StrengthenReport()
    report.level = "hull"
    if level == "hull":
        return CONSISTENT, 0
    if expired(deadline):
        report.budget_exhausted = True
        return CONSISTENT, 0
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
    if status == INCONSISTENT or level == "lp" or not finished:
        return status, applications
    turning = np.isin(arrays.factors[:, KIND], (ODOMETRY, ROTATION))
    headings = np.unique(arrays.factors[turning][:, [TA, TB]])
    for _ in range(SPLIT_HEADINGS):
        if expired(deadline):
            report.budget_exhausted = True
            report.level = "lp-split" + BUDGET_SUFFIX
            return CONSISTENT, applications
        widths = hi[headings] - lo[headings]
        if headings.size == 0 or not np.isfinite(widths).any() or widths.max() <= 0:
            break
        v = headings[np.argmax(np.where(np.isfinite(widths), widths, -1.0))]
        middle = 0.5 * (lo[v] + hi[v])
        halves = []
        for a, b in ((lo[v], middle), (middle, hi[v])):
            half_lo, half_hi = lo.copy(), hi.copy()
            half_lo[v], half_hi[v] = a, b
            status, count = propagate_arrays(
                half_lo, half_hi, arrays.factors, arrays.head, arrays.entry_factor,
                arrays.entry_next, _factors_of(arrays, v), rtol,
                max_rounds, 2**62,
            )  # fmt: skip
            applications += count
            if status != INCONSISTENT:
                # each half is narrowed as far as the deadline allows (at least propagated),
                # so the hull of the two halves is sound however early it stops
                status, count, finished = _polytope_rounds(
                    arrays, half_lo, half_hi, rtol, max_rounds, None, deadline, report
                )
                applications += count
                if not finished:
                    report.budget_exhausted = True
                    report.level = "lp-split" + BUDGET_SUFFIX
            if status != INCONSISTENT:
                halves.append((half_lo, half_hi))
        if not halves:
            return INCONSISTENT, applications
        lo[:] = np.min([h[0] for h in halves], axis=0)
        hi[:] = np.max([h[1] for h in halves], axis=0)
    if not report.budget_exhausted:
        report.level = "lp-split"
    return CONSISTENT, applications


def _factors_of(arrays: Arrays, variable: int) -> np.ndarray:
    found = []
    e = arrays.head[variable]
    while e >= 0:
        found.append(arrays.entry_factor[e])
        e = arrays.entry_next[e]
    return np.array(found, dtype=np.int64)


def _polytope_rounds(
    arrays: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    rtol: float,
    max_rounds: int,
    progress: Callable[[int, int], None] | None,
    deadline: float | None,
    report: StrengthenReport,
) -> tuple[int, int, bool]:
    """Rounds of the polytope-hull operator, each followed by propagation, until they stall.

    Returns ``(status, applications, finished)``; ``finished`` is False when the deadline
    cut the rounds short (the boxes are then propagated to the fixpoint all the same).
    """
    everything = np.arange(arrays.factors.shape[0], dtype=np.int64)
    applications = 0
    windows = _windows(arrays.factors)
    if not windows:
        return CONSISTENT, 0, True
    targets = np.unique(np.concatenate([t for _, t in windows]))
    width = _total_width(lo, hi, targets)
    active = np.ones(len(lo), dtype=bool)
    warm = [WarmStarts() for _ in windows]
    for round_index in range(MAX_LP_ROUNDS):
        with np.errstate(invalid="ignore"):  # inf - inf for unbounded variables
            before = hi - lo
        skipped = report.lp.skipped
        cut = False
        if round_index % FULL_ROUND_EVERY == 0:
            active[:] = True
        for w, ((rows, window_targets), bases) in enumerate(zip(windows, warm, strict=True)):
            if progress is not None:
                progress(round_index * len(windows) + w, MAX_LP_ROUNDS * len(windows))
            chosen = window_targets[active[window_targets]]
            if chosen.size == 0:
                continue
            if expired(deadline):
                cut = True
                break
            new_lo, new_hi, feasible = tighten(
                rows, lo, hi, chosen, bases, deadline=deadline, statistics=report.lp
            )
            if not feasible:
                return INCONSISTENT, applications, True
            lo[:] = new_lo
            hi[:] = new_hi
        report.lp_rounds += 1
        cut = cut or report.lp.skipped > skipped
        status, count = propagate_arrays(
            lo,
            hi,
            arrays.factors,
            arrays.head,
            arrays.entry_factor,
            arrays.entry_next,
            everything,
            rtol,
            max_rounds,
            2**62,
        )
        applications += count
        if status == INCONSISTENT:
            return INCONSISTENT, applications, True
        if cut:
            return CONSISTENT, applications, False
        new_width = _total_width(lo, hi, targets)
        if new_width > width * (1.0 - MIN_GAIN) and round_index % FULL_ROUND_EVERY == 0:
            break
        if expired(deadline) and round_index + 1 < MAX_LP_ROUNDS:
            return CONSISTENT, applications, False
        width = new_width
        with np.errstate(invalid="ignore"):
            active = (hi - lo) < before * (1.0 - ACTIVE_GAIN)
    return CONSISTENT, applications, True
