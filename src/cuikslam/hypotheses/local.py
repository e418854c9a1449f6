"""Relational refutation: a window of the graph, narrowed in the frame of one of its poses.

Absolute boxes grow along a trajectory (a pose far from its prior is known to metres),
while the geometry *between* neighbouring poses and the landmarks they see stays known to
centimetres. Box-against-box reasoning then misses contradictions that are plain in a
local frame: a "new" landmark where the previous pose saw one 10 m ahead, a landmark the
robot must still see from its next pose.

Every constraint of a kinematic graph except the priors is invariant under a rigid motion
of the whole world (odometry, range and bearing, and negative information are relative).
So if the constraints of a window (its odometry, observations and UNSEEN factors, no
priors) have a solution, they have one with the window's *anchor* pose at (0, 0, 0).
Narrowing the window from that start is therefore sound: an empty result proves the
whole hypothesis impossible. Measurement variables (turns, distances, ranges, bearings)
are invariant too, so the node's narrowed values may start them.
"""

from __future__ import annotations

import math

import numpy as np

from cuikslam._jit import jit
from cuikslam.graph.encoding import ODOMETRY, XA, XB, YB, factors_on
from cuikslam.hypotheses._shared import Overlay, SharedGraph, linked
from cuikslam.narrowing.propagation import narrow

__all__ = ["LocalCheck"]

WINDOWS = ((8, 0), (12, 0), (12, 6), (16, 0), (24, 12))
"""The windows tried, in order, until one refutes: (poses, anchor back). Each holds the
decided pose and the poses reached just before it; its anchor (fixed at the origin) is
that many poses back. The first is tried after every decision, the others once a pose's
scan is decided. Boxes grow away from the anchor, so a window anchored mid-way keeps
both ends tighter; a longer window holds more sightings of the landmarks a decision
involves, which is what refutes a reading taken for a post 1-2 m from the one it saw
(Lost in the Woods, every other reading known: of 22 such choices that 8 poses ending at
the reading leave, such windows refute 16)."""
MAX_APPLICATIONS = 20_000
"""Work budget of one window's narrowing (stopping early is sound, only weaker)."""


class LocalCheck:
    """Refutes nodes with a window of poses inconsistent in the frame of one of them."""

    def __init__(
        self,
        pose_x: dict[int, int],
        n_vars: int,
        rtol: float,
        rounds: int,
        sensor_x: dict[int, list[int]] | None = None,
    ) -> None:
        """``pose_x``: x variable of each pose, in the order the log reaches them;
        ``sensor_x``: x variables of each pose's sensor poses (offset observations), which
        move with their pose and belong to its windows."""
        sensors = sensor_x or {}
        self._windows: dict[int, list[tuple[np.ndarray, int]]] = {}
        """Each pose's distinct windows (pose x variables, anchor's x) in WINDOWS order:
        near the start of a log several hold the same poses and anchor."""
        order = list(pose_x)
        per_size = [(pose_windows(pose_x, sensors, n), back) for n, back in WINDOWS]
        for i, pose in enumerate(order):
            seen: set[tuple[bytes, int]] = set()
            mine = self._windows.setdefault(pose, [])
            for windows, back in per_size:
                key = (windows[pose].tobytes(), pose_x[order[max(0, i - back)]])
                if key not in seen:
                    seen.add(key)
                    mine.append((windows[pose], key[1]))
        self._is_pose = np.zeros(n_vars, dtype=np.bool_)
        for x in [*pose_x.values(), *(x for xs in sensors.values() for x in xs)]:
            self._is_pose[x : x + 3] = True
        self._in_window = np.zeros(n_vars, dtype=np.bool_)
        self._local_id = np.full(n_vars, -1, dtype=np.int64)
        self.rtol = rtol
        self.rounds = rounds
        self.checks = 0
        self.refuted = 0

    def refutes(self, graph: SharedGraph, overlay: Overlay, pose: int, every: bool) -> bool:
        """True when a window ending at ``pose`` is proven inconsistent in its frame: the
        first of :data:`WINDOWS`, or with ``every`` (a scan just decided) all of them.

        The windows' operator applications are added to ``graph.applications``, which
        the search spends from its budget: on a log of near-exact readings they are most
        of its work."""
        self.checks += 1
        windows = self._windows[pose]
        for window, anchor_x in windows if every else windows[:1]:
            if self._window_refutes(graph, overlay, window, anchor_x):
                self.refuted += 1
                return True
        return False

    def _window_refutes(
        self, graph: SharedGraph, overlay: Overlay, window: np.ndarray, anchor_x: int
    ) -> bool:
        local, variables, free = window_rows(
            window, graph.rows, graph.kinds, graph.in_base, overlay.rows, graph.head,
            graph.entry_factor, graph.entry_next, self._in_window, self._local_id,
            self._is_pose,
        )  # fmt: skip
        if len(local) == 0 or self._local_id[anchor_x] < 0:
            self._local_id[variables] = -1
            return False
        anchor = self._local_id[anchor_x : anchor_x + 3].copy()
        self._local_id[variables] = -1
        if np.any(anchor < 0):  # a heading no row of the window names: nothing to fix
            return False
        lo, hi = graph.values(overlay, variables)
        lo[free], hi[free] = -math.inf, math.inf
        lo[anchor], hi[anchor] = 0.0, 0.0
        arrays = linked(local, len(variables))
        result = narrow(arrays, lo, hi, None, self.rtol, self.rounds, MAX_APPLICATIONS)
        graph.applications += result.applications
        return result.is_empty


def pose_windows(
    pose_x: dict[int, int], sensor_x: dict[int, list[int]], n_poses: int
) -> dict[int, np.ndarray]:
    """For each pose, the x variables of the window of the ``n_poses`` poses up to it (in
    the order the log reaches them), its sensors' poses included."""
    order = list(pose_x)
    windows = {}
    for i, pose in enumerate(order):
        xs = []
        for q in order[max(0, i - n_poses + 1) : i + 1]:
            xs += [pose_x[q], *sensor_x.get(q, ())]
        windows[pose] = np.array(xs, dtype=np.int64)
    return windows


@jit
def window_rows(
    window: np.ndarray,
    rows: np.ndarray,
    kinds: np.ndarray,
    in_base: np.ndarray,
    held: np.ndarray,
    head: np.ndarray,
    entry_factor: np.ndarray,
    entry_next: np.ndarray,
    in_window: np.ndarray,
    local_id: np.ndarray,
    is_pose: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The branch's rows whose poses all lie in ``window`` (pose x variables), renumbered.

    A branch holds the pool rows of the base set and the sorted rows ``held``. Returns the
    local rows, the global variable of each local one, and which local variables start
    free (poses and landmarks: not invariant under a rigid motion). ``in_window`` and
    ``local_id`` are scratch arrays, left as found except ``local_id`` of the returned
    variables (the caller resets them).
    """
    for x in window:
        in_window[x] = True
    on = factors_on(window, head, entry_factor, entry_next)
    found = np.empty(on.shape[0], dtype=np.int64)
    n_found = 0
    for f in on:
        if kinds[f] == ODOMETRY and not (in_window[rows[f, XA]] and in_window[rows[f, XB]]):
            continue  # a move to or from a pose outside the window
        if not in_base[f]:
            at = np.searchsorted(held, f)
            if at >= held.shape[0] or held[at] != f:
                continue  # another branch's row
        found[n_found] = f
        n_found += 1
    for x in window:
        in_window[x] = False
    picked = np.unique(found[:n_found])
    local = np.empty((picked.shape[0], rows.shape[1]), dtype=np.int64)
    variables = np.empty(picked.shape[0] * (rows.shape[1] - 1), dtype=np.int64)
    free = np.zeros(variables.shape[0], dtype=np.bool_)
    n = 0
    for i in range(picked.shape[0]):
        f = picked[i]
        local[i, 0] = kinds[f]
        for s in range(1, rows.shape[1]):
            v = rows[f, s]
            if v < 0:
                local[i, s] = -1
                continue
            if local_id[v] < 0:
                local_id[v] = n
                variables[n] = v
                landmark = kinds[f] != ODOMETRY and (s == XB or s == YB)
                free[n] = is_pose[v] or landmark
                n += 1
            local[i, s] = local_id[v]
    return local, variables[:n], free[:n]
