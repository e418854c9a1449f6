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

from cuikslam.graph.encoding import KIND, N_SLOTS, ODOMETRY, XA, XB
from cuikslam.hypotheses import _kernels as k
from cuikslam.hypotheses._shared import Overlay, SharedGraph
from cuikslam.narrowing._propagate import INCONSISTENT, propagate_arrays

__all__ = ["LocalCheck"]

WINDOW_POSES = 8
"""Poses of a window: the anchor and the ones reached just before it."""
MAX_APPLICATIONS = 20_000
"""Work budget of one window's narrowing (stopping early is sound, only weaker)."""


class LocalCheck:
    """Refutes nodes whose window around a pose is inconsistent in that pose's frame."""

    def __init__(self, pose_x: dict[int, int], n_vars: int, rtol: float, rounds: int) -> None:
        order = list(pose_x)  # poses in the order the log reaches them
        self._window: dict[int, np.ndarray] = {}
        for i, pose in enumerate(order):
            xs = [pose_x[q] for q in order[max(0, i - WINDOW_POSES + 1) : i + 1]]
            self._window[pose] = np.array(xs, dtype=np.int64)
        self._is_pose = np.zeros(n_vars, dtype=np.bool_)
        for x in pose_x.values():
            self._is_pose[x : x + 3] = True
        self.rtol = rtol
        self.rounds = rounds
        self.checks = 0
        self.refuted = 0

    def refutes(self, graph: SharedGraph, overlay: Overlay, pose: int, pose_x: int) -> bool:
        """True when the window ending at ``pose`` is proven inconsistent in its frame."""
        self.checks += 1
        window = self._window[pose]
        rows = graph.rows_of(overlay)
        in_window = np.isin(rows[:, XA], window)
        odometry = rows[:, KIND] == ODOMETRY
        keep = in_window & (~odometry | np.isin(rows[:, XB], window))
        sub = rows[keep]
        if len(sub) == 0:
            return False
        slots = sub[:, 1:]
        variables = np.unique(slots[slots >= 0])
        local = sub.copy()
        local[:, 1:] = np.where(slots >= 0, np.searchsorted(variables, slots), -1)
        anchor_vars = np.arange(pose_x, pose_x + 3)
        if not np.all(np.isin(anchor_vars, variables)):
            return False
        lo, hi = graph.values(overlay, variables)
        free = self._is_pose[variables] | np.isin(variables, _landmark_vars(sub))
        lo[free], hi[free] = -math.inf, math.inf
        anchor = np.searchsorted(variables, anchor_vars)
        lo[anchor], hi[anchor] = 0.0, 0.0
        head = np.full(len(variables), -1, dtype=np.int64)
        entry_factor = np.zeros(N_SLOTS * len(local), dtype=np.int64)
        entry_next = np.zeros_like(entry_factor)
        k.link_rows(local, len(local), head, entry_factor, entry_next)
        status, _ = propagate_arrays(
            lo, hi, local, head, entry_factor, entry_next, np.arange(len(local)),
            self.rtol, self.rounds, MAX_APPLICATIONS,
        )  # fmt: skip
        if status == INCONSISTENT:
            self.refuted += 1
            return True
        return False


def _landmark_vars(rows: np.ndarray) -> np.ndarray:
    """x and y variables of the landmarks the (observation and UNSEEN) rows name."""
    lm = rows[rows[:, KIND] != ODOMETRY]
    return np.concatenate([lm[:, XB], lm[:, XB] + 1])
