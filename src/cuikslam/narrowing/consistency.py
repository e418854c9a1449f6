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
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.graph.encoding import KIND, OBSERVATION, ODOMETRY, TA, TB, XA, XB
from cuikslam.narrowing._propagate import CONSISTENT, INCONSISTENT, propagate_arrays
from cuikslam.narrowing.relaxation import WarmStarts, tighten

__all__ = ["DEFAULT_LEVEL", "LEVELS", "Arrays", "resolve_level", "strengthen"]

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
    rows = factors[np.isin(factors[:, KIND], (ODOMETRY, OBSERVATION))]
    if len(rows) == 0:
        return []
    odo = rows[:, KIND] == ODOMETRY
    poses = np.unique(np.concatenate([rows[:, XA], rows[odo, XB]]))
    if len(poses) <= WINDOW_POSES:
        groups = [poses]
    else:
        step = WINDOW_POSES // 2
        groups = [poses[i : i + WINDOW_POSES] for i in range(0, len(poses) - step, step)]
    windows = []
    for group in groups:
        inside = np.isin(rows[:, XA], group) & (~odo | np.isin(rows[:, XB], group))
        selected, selected_odo = rows[inside], odo[inside]
        b = selected[:, XB]
        targets = [selected[:, XA], selected[:, XA] + 1, selected[:, TA], b, b + 1]
        targets.append(selected[selected_odo, TB])
        windows.append((selected, np.unique(np.concatenate(targets))))
    return windows


def _total_width(lo: np.ndarray, hi: np.ndarray, variables: np.ndarray) -> float:
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
) -> tuple[int, int]:
    """Narrow ``lo``/``hi`` in place beyond the fixpoint, to the given consistency level.

    Call it on boxes already at the fixpoint. Returns ``(status, operator applications)``
    with status CONSISTENT or INCONSISTENT (a proof). ``progress(done, total)`` is called
    after each window's LPs, ``total`` counting the most rounds the level may run.
    """
    ensure_round_to_nearest()
    if level not in LEVELS:
        raise ValueError(f"unknown consistency level {level!r}; choose one of {', '.join(LEVELS)}")
    if level == "hull":
        return CONSISTENT, 0
    status, applications = _polytope_rounds(arrays, lo, hi, rtol, max_rounds, progress)
    if status == INCONSISTENT or level == "lp":
        return status, applications
    headings = np.unique(arrays.factors[arrays.factors[:, KIND] == ODOMETRY][:, [TA, TB]])
    for _ in range(SPLIT_HEADINGS):
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
                status, count = _polytope_rounds(arrays, half_lo, half_hi, rtol, max_rounds)
                applications += count
            if status != INCONSISTENT:
                halves.append((half_lo, half_hi))
        if not halves:
            return INCONSISTENT, applications
        lo[:] = np.min([h[0] for h in halves], axis=0)
        hi[:] = np.max([h[1] for h in halves], axis=0)
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
    progress: Callable[[int, int], None] | None = None,
) -> tuple[int, int]:
    """Rounds of the polytope-hull operator, each followed by propagation, until they stall."""
    everything = np.arange(arrays.factors.shape[0], dtype=np.int64)
    applications = 0
    windows = _windows(arrays.factors)
    if not windows:
        return CONSISTENT, 0
    targets = np.unique(np.concatenate([t for _, t in windows]))
    width = _total_width(lo, hi, targets)
    active = np.ones(len(lo), dtype=bool)
    warm = [WarmStarts() for _ in windows]
    for round_index in range(MAX_LP_ROUNDS):
        before = hi - lo
        if round_index % FULL_ROUND_EVERY == 0:
            active[:] = True
        for w, ((rows, window_targets), bases) in enumerate(zip(windows, warm, strict=True)):
            if progress is not None:
                progress(round_index * len(windows) + w, MAX_LP_ROUNDS * len(windows))
            chosen = window_targets[active[window_targets]]
            if chosen.size == 0:
                continue
            new_lo, new_hi, feasible = tighten(rows, lo, hi, chosen, bases)
            if not feasible:
                return INCONSISTENT, applications
            lo[:] = new_lo
            hi[:] = new_hi
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
            return INCONSISTENT, applications
        new_width = _total_width(lo, hi, targets)
        if new_width > width * (1.0 - MIN_GAIN) and round_index % FULL_ROUND_EVERY == 0:
            break
        width = new_width
        with np.errstate(invalid="ignore"):
            active = (hi - lo) < before * (1.0 - ACTIVE_GAIN)
    return CONSISTENT, applications
