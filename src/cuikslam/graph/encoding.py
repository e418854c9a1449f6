"""How a kinematic graph is encoded as arrays for the compiled narrowing operators.

Variables are two float arrays ``lo`` and ``hi``. A factor is one int64 row
``(kind, xa, ya, ta, xb, yb, tb, angle, length)`` naming its variables (-1 for none):

- ``ODOMETRY``: pose a -> pose b; tb ≡ ta + turn (mod 2 pi) and
  (xb - xa, yb - ya) = distance (cos tb, sin tb); ``angle`` = turn, ``length`` = distance.
- ``OBSERVATION``: pose a sees landmark b at (xb, yb) (``tb = -1``);
  (xb - xa, yb - ya) = range (cos(ta + bearing), sin(ta + bearing)); ``angle`` = bearing,
  ``length`` = range. Range-only and bearing-only observations leave the missing
  quantity free ([-pi, pi] or [0, inf)).
- ``RELATIVE``: the translation of a relative pose (log record ``relative_pose``), pose a
  -> pose b (``tb = -1``): (xb - xa, yb - ya) = R(ta) (dx, dy), R(t) the rotation by t;
  ``angle`` = dx and ``length`` = dy, the displacement in the frame of pose a.
- ``ROTATION``: tb ≡ ta + angle (mod 2 pi), the heading change of a relative pose. Its
  row names both poses like an odometry row (so windows of poses find it), but its
  operator reads and narrows only ``ta``, ``tb`` and ``angle``.
- ``UNSEEN``: pose a did not see landmark b although it would have seen it within
  distance ``length`` and inside its field of view: |b - a| >= length, or the bearing of
  b lies in ``ta + angle``, where ``angle`` holds the bearings outside the field of view.

The factors of each variable are kept as singly linked lists (``head``, ``entry_factor``,
``entry_next``) so a graph grows one factor at a time in O(1).
"""

from __future__ import annotations

import numpy as np

from cuikslam._jit import jit

__all__ = [
    "ANGLE", "KIND", "LENGTH", "NO_FACTOR", "N_SLOTS", "OBSERVATION", "ODOMETRY", "RELATIVE",
    "ROTATION", "TA", "TB", "UNSEEN", "XA", "XB", "YA", "YB", "factors_on", "link_factor",
]  # fmt: skip

ODOMETRY = 0
OBSERVATION = 1
UNSEEN = 2
RELATIVE = 3
ROTATION = 4
NO_FACTOR = -1
"""Kind (and variable indices) of an unused row in a preallocated factor table."""

KIND, XA, YA, TA, XB, YB, TB, ANGLE, LENGTH = range(9)
N_SLOTS = 8
"""Variable slots of a factor row: columns 1..8."""


@jit
def link_factor(
    row: np.ndarray,
    f: int,
    head: np.ndarray,
    entry_factor: np.ndarray,
    entry_next: np.ndarray,
    n_entries: int,
) -> int:
    """Add factor ``f`` to the adjacency lists of its variables; returns the new entry count.

    ``head[v]`` is the first entry of variable v (-1 for none), ``entry_factor[e]`` the
    factor of entry e and ``entry_next[e]`` the next entry of the same variable.
    """
    for s in range(N_SLOTS):
        v = row[1 + s]
        if v < 0:
            continue
        entry_factor[n_entries] = f
        entry_next[n_entries] = head[v]
        head[v] = n_entries
        n_entries += 1
    return n_entries


@jit
def factors_on(
    variables: np.ndarray, head: np.ndarray, entry_factor: np.ndarray, entry_next: np.ndarray
) -> np.ndarray:
    """Every factor on one of ``variables`` (with repeats), by walking their adjacency lists."""
    n = 0
    for v in variables:
        e = head[v]
        while e >= 0:
            n += 1
            e = entry_next[e]
    found = np.empty(n, dtype=np.int64)
    n = 0
    for v in variables:
        e = head[v]
        while e >= 0:
            found[n] = entry_factor[e]
            n += 1
            e = entry_next[e]
    return found
