"""The row multipliers each column's last LP leaves, kept small, and the safe bounds they
give without solving an LP (:func:`~cuikslam.narrowing.lp_bounds.certified_bounds` with
``reuse``): valid for any multipliers (:mod:`.safe_bound`), and close to the LP's bound
while its optimal basis stays optimal. Moved unchanged out of :mod:`.lp_bounds`, which
imports these helpers.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy import sparse

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.narrowing.safe_bound import safe_bounds_of_columns

if TYPE_CHECKING:
    from cuikslam.narrowing.lp_bounds import WarmStarts

__all__: list[str] = []


def _sparse(y: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """``y`` to keep for :func:`_reused`, small: its nonzero entries in single precision
    (any multipliers give a safe bound; these move it by about 1e-7 of its terms, and
    those beyond single precision's range are clipped to it rather than made infinite)."""
    nonzero = np.flatnonzero(y)
    index = nonzero.astype(np.int16 if len(y) < 2**15 else np.int32)
    top = float(np.finfo(np.float32).max)
    return len(y), index, np.clip(y[nonzero], -top, top).astype(np.float32)


def _keep_sparse(
    warm: WarmStarts,
    order: np.ndarray,
    senses: np.ndarray,
    duals: np.ndarray,
    q: int,
    at: int,
) -> None:
    """:func:`_sparse` of ``duals[q:at]`` into ``warm.duals``, the run at once."""
    if at <= q:
        return
    m = duals.shape[1]
    block = duals[q:at]
    which, nonzero = np.nonzero(block)
    index = nonzero.astype(np.int16 if m < 2**15 else np.int32)
    top = float(np.finfo(np.float32).max)
    values = np.clip(block[which, nonzero], -top, top).astype(np.float32)
    ends = np.searchsorted(which, np.arange(at - q + 1))
    for k in range(at - q):
        a, b = ends[k], ends[k + 1]
        warm.duals[int(order[q + k]), bool(senses[q + k] > 0)] = (
            m,
            index[a:b].copy(),
            values[a:b].copy(),
        )


def _reused(
    csc: sparse.csc_matrix,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    box: np.ndarray,
    columns: list[int],
    upper_columns: list[int],
    warm: WarmStarts,
) -> tuple[list[float], list[float]]:
    """Safe bounds from the multipliers of each column's last LP (no LP solved): valid for
    any multipliers, and close to the LP's bound while its optimal basis stays optimal."""
    ensure_round_to_nearest()
    m = csc.shape[0]
    box_lo, box_hi = np.ascontiguousarray(box[:, 0]), np.ascontiguousarray(box[:, 1])
    order = np.array(list(columns) + list(upper_columns), dtype=np.int64)
    senses = np.concatenate([np.ones(len(columns)), -np.ones(len(upper_columns))])
    duals = np.zeros((len(order), m))
    known = np.zeros(len(order), dtype=bool)
    for r, j in enumerate(order.tolist()):
        stored = warm.duals.get((j, bool(senses[r] > 0)))
        if stored is not None and stored[0] == m:
            duals[r, stored[1]] = stored[2]
            known[r] = True
    bounds = np.full(len(order), -math.inf)
    safe_bounds_of_columns(
        csc.indptr, csc.indices, csc.data, row_lo, row_hi, order, senses, duals, 0,
        len(order), box_lo, box_hi, bounds,
    )  # fmt: skip
    bounds = senses * np.where(known, bounds, -math.inf)
    k = len(columns)
    return bounds[:k].tolist(), bounds[k:].tolist()
