"""Compiled chaotic iteration of narrowing operators (the seed's Section 4 algorithm).

A FIFO queue of factors; each factor popped is applied; every other factor sharing a
variable that shrank by more than ``rtol`` is queued again. At the fixpoint the queue is
empty. A factor with no solution proves the whole graph inconsistent. Rows whose kind is
``NO_FACTOR`` are never queued: a factor table may hold rows that are switched off.
"""

from __future__ import annotations

import numpy as np

from cuikslam._jit import jit
from cuikslam.graph.encoding import KIND, N_SLOTS, NO_FACTOR
from cuikslam.interval._rounding import INF
from cuikslam.narrowing._factors import (
    EMPTY_FACTOR,
    MEMORY_WIDTH,
    NOT_AT_FIXPOINT,
    fresh_memory,
    narrow_factor_memo,
)

CONSISTENT = 0
INCONSISTENT = 1
BUDGET_EXHAUSTED = 2

_QUEUED = 1
_APPLIED = 2


@jit
def propagate_arrays(
    lo: np.ndarray,
    hi: np.ndarray,
    factors: np.ndarray,
    head: np.ndarray,
    entry_factor: np.ndarray,
    entry_next: np.ndarray,
    touched: np.ndarray,
    rtol: float,
    max_rounds: int,
    max_applications: int,
) -> tuple[int, int]:
    """Narrow ``lo``/``hi`` in place to the fixpoint of the factors' operators.

    The factors of variable v are found by walking its adjacency list (see
    :func:`cuikslam.graph.encoding.link_factor`). ``touched`` lists the factors to apply
    first; only what they wake runs afterwards (incremental propagation). Returns
    ``(status, applications)`` where status is CONSISTENT, INCONSISTENT (a proof: no
    solution in the box) or BUDGET_EXHAUSTED (stopped early; the boxes are still sound,
    just not at the fixpoint).
    """
    n_factors = factors.shape[0]
    status, applications, _ = propagate_buffered(
        lo, hi, factors, head, entry_factor, entry_next, touched, rtol, max_rounds,
        max_applications, np.empty(n_factors + 1, dtype=np.int64),
        np.zeros(n_factors, dtype=np.int8), fresh_memory(n_factors),
        np.empty(n_factors, dtype=np.int64), False,
    )  # fmt: skip
    return status, applications


@jit
def propagate_buffered(
    lo: np.ndarray,
    hi: np.ndarray,
    factors: np.ndarray,
    head: np.ndarray,
    entry_factor: np.ndarray,
    entry_next: np.ndarray,
    touched: np.ndarray,
    rtol: float,
    max_rounds: int,
    max_applications: int,
    queue: np.ndarray,
    state: np.ndarray,
    memory: np.ndarray,
    applied: np.ndarray,
    keep_memory: bool,
) -> tuple[int, int, int]:
    """:func:`propagate_arrays` with caller-owned work arrays, for many small propagations.

    The work arrays cover at least ``factors.shape[0]`` factors: ``queue`` one more,
    ``state`` (int8) all zero, ``memory`` as :func:`fresh_memory`. They are left that way
    on return, whatever the status, so allocating them once serves every call: a call
    costs what it touches, not the size of the graph. Returns ``(status, applications,
    n_applied)``; ``applied[:n_applied]`` lists every factor applied, once each, so the
    caller knows which variables may have changed. When ``max_applications`` stopped the
    iteration, the factors still queued are left at the front of ``queue``, in queue
    order, ended by -1 (``queue[0]`` is -1 otherwise): a caller can resume from them.

    ``keep_memory`` leaves each applied factor's memory (its auxiliary intervals) as the
    call left it, for a caller whose bounds only ever shrink between calls (an online
    graph): each memory then stays an enclosure of its true value, and a propagation cut
    into several calls converges as one call does. Otherwise the memory is reset, as
    every caller that moves the bounds between calls needs.
    """
    capacity = queue.shape[0]
    head_q = 0
    size = 0
    n_applied = 0
    for f in touched:
        if state[f] & _QUEUED == 0 and factors[f, KIND] != NO_FACTOR:
            queue[(head_q + size) % capacity] = f
            size += 1
            state[f] |= _QUEUED
    status = CONSISTENT
    applications = 0
    while size > 0:
        if applications >= max_applications:
            status = BUDGET_EXHAUSTED
            break
        f = queue[head_q]
        head_q = (head_q + 1) % capacity
        size -= 1
        state[f] &= ~_QUEUED
        if state[f] & _APPLIED == 0:
            state[f] |= _APPLIED
            applied[n_applied] = f
            n_applied += 1
        row = factors[f]
        mask = narrow_factor_memo(lo, hi, row, rtol, max_rounds, memory[f])
        applications += 1
        if mask == EMPTY_FACTOR:
            status = INCONSISTENT
            break
        if mask == 0:
            continue
        if mask & NOT_AT_FIXPOINT and state[f] & _QUEUED == 0:
            # one application is not idempotent at max_rounds: apply this factor again
            queue[(head_q + size) % capacity] = f
            size += 1
            state[f] |= _QUEUED
        for s in range(N_SLOTS):
            if (mask >> s) & 1 == 0:
                continue
            e = head[row[1 + s]]
            while e >= 0:
                g = entry_factor[e]
                e = entry_next[e]
                if g != f and state[g] & _QUEUED == 0 and factors[g, KIND] != NO_FACTOR:
                    queue[(head_q + size) % capacity] = g
                    size += 1
                    state[g] |= _QUEUED
    left = np.empty(size if status == BUDGET_EXHAUSTED else 0, dtype=np.int64)
    for k in range(size):
        f = queue[(head_q + k) % capacity]
        state[f] = 0
        if status == BUDGET_EXHAUSTED:
            left[k] = f
    queue[: len(left)] = left  # what the limit kept from running, to resume from
    queue[len(left)] = -1
    for k in range(n_applied):
        f = applied[k]
        state[f] = 0
        if keep_memory:
            continue
        for j in range(MEMORY_WIDTH // 2):
            memory[f, 2 * j] = -INF
            memory[f, 2 * j + 1] = INF
    return status, applications, n_applied
