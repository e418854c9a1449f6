"""Compiled helpers of the shared graph (:mod:`._shared`): every per-branch step in one call.

Bounds are compared bit for bit (:func:`differs`), so an overlay reproduces a branch's
bounds exactly, signed zeros included. No interval arithmetic happens here: narrowing is
the propagation kernel's.
"""

from __future__ import annotations

import math

import numpy as np

from cuikslam._jit import jit
from cuikslam.graph.encoding import KIND, N_SLOTS, NO_FACTOR, link_factor
from cuikslam.narrowing._propagate import INCONSISTENT, propagate_buffered

EMPTY_SLOT = -1
"""An unused slot of the pool's hash table."""


@jit
def differs(a: float, b: float) -> bool:
    """Bitwise inequality of two bounds (0.0 and -0.0 differ; no NaN occurs)."""
    return a != b or math.copysign(1.0, a) != math.copysign(1.0, b)


@jit
def union(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Union of two sorted arrays of distinct integers, sorted."""
    out = np.empty(a.shape[0] + b.shape[0], dtype=np.int64)
    i = j = n = 0
    while i < a.shape[0] or j < b.shape[0]:
        if j == b.shape[0] or (i < a.shape[0] and a[i] < b[j]):
            out[n] = a[i]
            i += 1
        elif i == a.shape[0] or b[j] < a[i]:
            out[n] = b[j]
            j += 1
        else:
            out[n] = a[i]
            i += 1
            j += 1
        n += 1
    return out[:n]


# ------------------------------------------------------------------ the factor pool
@jit
def _hash(row: np.ndarray) -> int:
    h = np.uint64(14695981039346656037)
    for c in range(row.shape[0]):
        h = (h ^ np.uint64(row[c] & 0xFFFFFFFFFFFF)) * np.uint64(1099511628211)
    return int(h >> np.uint64(1))


@jit
def _same_row(rows: np.ndarray, kinds: np.ndarray, f: int, row: np.ndarray) -> bool:
    """Pool row ``f`` (whose kind column may read NO_FACTOR) equals ``row``."""
    if kinds[f] != row[KIND]:
        return False
    for c in range(1, row.shape[0]):
        if rows[f, c] != row[c]:
            return False
    return True


@jit
def rehash(rows: np.ndarray, kinds: np.ndarray, n_rows: int, size: int) -> np.ndarray:
    """A hash table (``size``, a power of two) of pool rows ``0..n_rows-1``."""
    table = np.full(size, EMPTY_SLOT, dtype=np.int64)
    mask = size - 1
    key = np.empty(rows.shape[1], dtype=np.int64)
    for f in range(n_rows):
        key[:] = rows[f]
        key[KIND] = kinds[f]
        h = _hash(key) & mask
        while table[h] != EMPTY_SLOT:
            h = (h + 1) & mask
        table[h] = f
    return table


@jit
def intern(
    new: np.ndarray,
    rows: np.ndarray,
    kinds: np.ndarray,
    n_rows: int,
    table: np.ndarray,
    head: np.ndarray,
    entry_factor: np.ndarray,
    entry_next: np.ndarray,
    n_entries: int,
) -> tuple[np.ndarray, int, int]:
    """Pool ids of the rows ``new``; rows not pooled yet are appended (switched off) and
    linked. The caller guarantees room for all of them and a table at most half full.
    Returns ``(ids, n_rows, n_entries)``."""
    mask = table.shape[0] - 1
    ids = np.empty(new.shape[0], dtype=np.int64)
    for k in range(new.shape[0]):
        row = new[k]
        h = _hash(row) & mask
        while table[h] != EMPTY_SLOT and not _same_row(rows, kinds, table[h], row):
            h = (h + 1) & mask
        if table[h] == EMPTY_SLOT:
            table[h] = n_rows
            rows[n_rows] = row
            rows[n_rows, KIND] = NO_FACTOR
            kinds[n_rows] = row[KIND]
            n_entries = link_factor(rows[n_rows], n_rows, head, entry_factor, entry_next, n_entries)
            n_rows += 1
        ids[k] = table[h]
    return ids, n_rows, n_entries


@jit
def link_rows(
    rows: np.ndarray,
    n_rows: int,
    head: np.ndarray,
    entry_factor: np.ndarray,
    entry_next: np.ndarray,
) -> int:
    """Link rows ``0..n_rows-1`` into an empty adjacency, in order; returns the entry count."""
    n_entries = 0
    for f in range(n_rows):
        n_entries = link_factor(rows[f], f, head, entry_factor, entry_next, n_entries)
    return n_entries


# ------------------------------------------------------------------ branches
@jit
def switch(
    lo: np.ndarray,
    hi: np.ndarray,
    saved_lo: np.ndarray,
    saved_hi: np.ndarray,
    base_lo: np.ndarray,
    base_hi: np.ndarray,
    old_idx: np.ndarray,
    new_idx: np.ndarray,
    new_lo: np.ndarray,
    new_hi: np.ndarray,
    rows: np.ndarray,
    kinds: np.ndarray,
    old_rows: np.ndarray,
    new_rows: np.ndarray,
) -> None:
    """Working arrays and switched-on rows: from base + old overlay to base + new overlay."""
    for v in old_idx:
        lo[v] = saved_lo[v] = base_lo[v]
        hi[v] = saved_hi[v] = base_hi[v]
    for k in range(new_idx.shape[0]):
        v = new_idx[k]
        lo[v] = saved_lo[v] = new_lo[k]
        hi[v] = saved_hi[v] = new_hi[k]
    for f in old_rows:
        rows[f, KIND] = NO_FACTOR
    for f in new_rows:
        rows[f, KIND] = kinds[f]


@jit
def _changed(
    rows: np.ndarray,
    applied: np.ndarray,
    n_applied: int,
    narrowed: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    saved_lo: np.ndarray,
    saved_hi: np.ndarray,
    mark: np.ndarray,
) -> np.ndarray:
    """Sorted variables, among those of the applied rows and ``narrowed``, whose bounds
    differ from the saved ones (``mark`` is scratch, left all False)."""
    candidates = np.empty(N_SLOTS * n_applied + narrowed.shape[0], dtype=np.int64)
    n = 0
    for k in range(n_applied):
        for s in range(N_SLOTS):
            v = rows[applied[k], 1 + s]
            if v >= 0 and not mark[v]:
                mark[v] = True
                candidates[n] = v
                n += 1
    for v in narrowed:
        if not mark[v]:
            mark[v] = True
            candidates[n] = v
            n += 1
    out = np.empty(n, dtype=np.int64)
    m = 0
    for k in range(n):
        v = candidates[k]
        mark[v] = False
        if differs(lo[v], saved_lo[v]) or differs(hi[v], saved_hi[v]):
            out[m] = v
            m += 1
    return np.sort(out[:m])


@jit
def _with_rows(held: np.ndarray, ids: np.ndarray, in_base: np.ndarray) -> np.ndarray:
    """Sorted ``held`` rows plus those of ``ids`` not in the base set."""
    extra = np.unique(ids)
    keep = np.zeros(extra.shape[0], dtype=np.bool_)
    for k in range(extra.shape[0]):
        keep[k] = not in_base[extra[k]]
    return union(held, extra[keep])


@jit
def apply(
    lo: np.ndarray,
    hi: np.ndarray,
    saved_lo: np.ndarray,
    saved_hi: np.ndarray,
    rows: np.ndarray,
    kinds: np.ndarray,
    in_base: np.ndarray,
    head: np.ndarray,
    entry_factor: np.ndarray,
    entry_next: np.ndarray,
    queue: np.ndarray,
    state: np.ndarray,
    memory: np.ndarray,
    applied: np.ndarray,
    mark: np.ndarray,
    held_idx: np.ndarray,
    held_rows: np.ndarray,
    ids: np.ndarray,
    touched: np.ndarray,
    narrowed: np.ndarray,
    rtol: float,
    max_rounds: int,
    keep: bool,
) -> tuple[int, int, int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Switch rows ``ids`` on for the checked-out branch (overlay ``held_idx``,
    ``held_rows``), propagate from ``touched`` (``narrowed`` variables were written by the
    caller), and return the resulting overlay.

    With ``keep`` the result stays in the working arrays (the branch itself changed);
    without, the working arrays and rows are put back (a trial child). Returns
    ``(status, applications, n_changed, idx, lo, hi, rows)``; on INCONSISTENT everything
    is put back and the arrays are empty.
    """
    switched = np.empty(ids.shape[0], dtype=np.int64)
    n_switched = 0
    for f in ids:
        if rows[f, KIND] == NO_FACTOR:
            rows[f, KIND] = kinds[f]
            switched[n_switched] = f
            n_switched += 1
    status, applications, n_applied = propagate_buffered(
        lo, hi, rows, head, entry_factor, entry_next, touched, rtol, max_rounds, 2**62,
        queue, state, memory, applied, False,
    )  # fmt: skip
    changed = _changed(rows, applied, n_applied, narrowed, lo, hi, saved_lo, saved_hi, mark)
    out_idx = union(held_idx, changed)
    out_lo, out_hi = lo[out_idx], hi[out_idx]
    out_rows = _with_rows(held_rows, ids, in_base)
    if status == INCONSISTENT or not keep:
        for v in changed:
            lo[v], hi[v] = saved_lo[v], saved_hi[v]
        for k in range(n_switched):
            rows[switched[k], KIND] = NO_FACTOR
    else:
        for v in changed:
            saved_lo[v], saved_hi[v] = lo[v], hi[v]
    if status == INCONSISTENT:
        empty = np.zeros(0, dtype=np.int64)
        return status, applications, 0, empty, np.zeros(0), np.zeros(0), empty
    return status, applications, changed.shape[0], out_idx, out_lo, out_hi, out_rows


@jit
def values(
    idx: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    base_lo: np.ndarray,
    base_hi: np.ndarray,
    variables: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of ``variables`` in the branch whose overlay is (idx, lo, hi)."""
    at = np.searchsorted(idx, variables)
    out_lo, out_hi = base_lo[variables], base_hi[variables]
    for k in range(variables.shape[0]):
        if at[k] < idx.shape[0] and idx[at[k]] == variables[k]:
            out_lo[k], out_hi[k] = lo[at[k]], hi[at[k]]
    return out_lo, out_hi


@jit
def width_correction(
    idx: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    base_lo: np.ndarray,
    base_hi: np.ndarray,
    ranked: np.ndarray,
    extra: np.ndarray,
) -> tuple[int, float]:
    """(infinite widths, sum of finite widths) of the branch over the ``extra`` variables,
    plus its difference from the base over the ``ranked`` (boolean mask) variables."""
    n_inf = 0
    total = 0.0
    for k in range(idx.shape[0]):
        v = idx[k]
        if not ranked[v]:
            continue
        mine, base = hi[k] - lo[k], base_hi[v] - base_lo[v]
        n_inf += (not math.isfinite(mine)) - (not math.isfinite(base))
        total += (mine if math.isfinite(mine) else 0.0) - (base if math.isfinite(base) else 0.0)
    extra_lo, extra_hi = values(idx, lo, hi, base_lo, base_hi, extra)
    for k in range(extra.shape[0]):
        width = extra_hi[k] - extra_lo[k]
        if math.isfinite(width):
            total += width
        else:
            n_inf += 1
    return n_inf, total


# ------------------------------------------------------------------ rebasing
@jit
def modes(var: np.ndarray, lo: np.ndarray, hi: np.ndarray, n_branches: int) -> np.ndarray:
    """For overlay entries sorted by (var, lo, hi) (bounds as bit patterns): the index of
    the first entry of each variable's most common bounds, where more branches have them
    than keep the base bounds."""
    out = np.empty(var.shape[0], dtype=np.int64)
    n_out = 0
    start = 0
    while start < var.shape[0]:
        stop = start
        best, best_count = -1, 0
        while stop < var.shape[0] and var[stop] == var[start]:
            group = stop
            while (
                stop < var.shape[0]
                and var[stop] == var[group]
                and lo[stop] == lo[group]
                and hi[stop] == hi[group]
            ):
                stop += 1
            if stop - group > best_count:
                best, best_count = group, stop - group
        if best_count > n_branches - (stop - start):
            out[n_out] = best
            n_out += 1
        start = stop
    return out[:n_out]


@jit
def rebased(
    idx: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    base_lo: np.ndarray,
    base_hi: np.ndarray,
    moved: np.ndarray,
    old_lo: np.ndarray,
    old_hi: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An overlay (idx, lo, hi) over the new base, where the sorted variables ``moved`` had
    the bounds ``old_lo/hi``: entries equal to the new base go, moved ones it lacked come."""
    n_out = idx.shape[0] + moved.shape[0]
    out_idx = np.empty(n_out, dtype=np.int64)
    out_lo = np.empty(n_out)
    out_hi = np.empty(n_out)
    i = j = n = 0
    while i < idx.shape[0] or j < moved.shape[0]:
        if j == moved.shape[0] or (i < idx.shape[0] and idx[i] <= moved[j]):
            v, vlo, vhi = idx[i], lo[i], hi[i]
            if j < moved.shape[0] and moved[j] == v:
                j += 1
            i += 1
        else:
            v, vlo, vhi = moved[j], old_lo[j], old_hi[j]
            j += 1
        if differs(vlo, base_lo[v]) or differs(vhi, base_hi[v]):
            out_idx[n], out_lo[n], out_hi[n] = v, vlo, vhi
            n += 1
    return out_idx[:n], out_lo[:n], out_hi[:n]
