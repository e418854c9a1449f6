"""Compiled chaotic iteration of narrowing operators (the seed's Section 4 algorithm).

A FIFO queue of factors; each factor popped is applied; every other factor sharing a
variable that shrank by more than ``rtol`` is queued again. At the fixpoint the queue is
empty. A factor with no solution proves the whole graph inconsistent.
"""

from __future__ import annotations

import numpy as np

from cuikslam._jit import jit
from cuikslam.graph.encoding import N_SLOTS
from cuikslam.narrowing._factors import (
    EMPTY_FACTOR,
    NOT_AT_FIXPOINT,
    fresh_memory,
    narrow_factor_memo,
)

CONSISTENT = 0
INCONSISTENT = 1
BUDGET_EXHAUSTED = 2


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
    capacity = n_factors + 1
    queue = np.empty(capacity, dtype=np.int64)
    queued = np.zeros(n_factors, dtype=np.bool_)
    head_q = 0
    size = 0
    for f in touched:
        if not queued[f]:
            queue[(head_q + size) % capacity] = f
            size += 1
            queued[f] = True
    memory = fresh_memory(n_factors)
    applications = 0
    while size > 0:
        if applications >= max_applications:
            return BUDGET_EXHAUSTED, applications
        f = queue[head_q]
        head_q = (head_q + 1) % capacity
        size -= 1
        queued[f] = False
        row = factors[f]
        mask = narrow_factor_memo(lo, hi, row, rtol, max_rounds, memory[f])
        applications += 1
        if mask == EMPTY_FACTOR:
            return INCONSISTENT, applications
        if mask == 0:
            continue
        if mask & NOT_AT_FIXPOINT and not queued[f]:
            # one application is not idempotent at max_rounds: apply this factor again
            queue[(head_q + size) % capacity] = f
            size += 1
            queued[f] = True
        for s in range(N_SLOTS):
            if (mask >> s) & 1 == 0:
                continue
            e = head[row[1 + s]]
            while e >= 0:
                g = entry_factor[e]
                e = entry_next[e]
                if g != f and not queued[g]:
                    queue[(head_q + size) % capacity] = g
                    size += 1
                    queued[g] = True
    return CONSISTENT, applications
