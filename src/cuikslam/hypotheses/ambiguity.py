"""The ``lp`` level on a node about to branch, on the window of poses that leads to it.

Hull pose boxes grow along a trajectory: on a dense world they are metres wide after a few
dozen poses, wide enough for a wrong association to pass the gate and survive hundreds of
decisions. The ``lp`` level (:mod:`cuikslam.narrowing.consistency`) keeps them far
tighter, but on a whole long graph it costs seconds. Before a node branches, the level is
applied to the subgraph of the last ``WINDOW_POSES`` poses up to its decision's pose (their
odometry, observations and negative information, in the global frame, started from the
node's bounds), within the schedule's ``branch_node_work`` units
(:meth:`cuikslam.budget.Schedule.branch_node`): dropping the other constraints is sound, so the
narrowed bounds hold for the whole hypothesis, and an empty window refutes it. The node's
children are then made from the tighter box (:meth:`.explorer.Explorer.children`).
"""

from __future__ import annotations

import numpy as np

from cuikslam.budget import SCHEDULE, Budget
from cuikslam.hypotheses._shared import Overlay, SharedGraph, linked
from cuikslam.hypotheses.local import pose_windows, window_rows
from cuikslam.narrowing.consistency import StrengthenReport, strengthen
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS

__all__ = ["AmbiguityLp"]

WINDOW_POSES = 60
"""Poses of the window: its decision's pose and those reached just before it."""


class AmbiguityLp:
    """Narrows a node's window to the ``lp`` level (see the module docstring)."""

    def __init__(
        self, pose_x: dict[int, int], n_vars: int, rtol: float, sensor_x: dict[int, list[int]]
    ) -> None:
        self._window = pose_windows(pose_x, sensor_x, WINDOW_POSES)
        self._in_window = np.zeros(n_vars, dtype=np.bool_)
        self._local_id = np.full(n_vars, -1, dtype=np.int64)
        self._is_pose = np.zeros(n_vars, dtype=np.bool_)
        self.rtol = rtol

    def narrow(
        self, graph: SharedGraph, overlay: Overlay, pose: int, deadline: Budget | None
    ) -> tuple[Overlay | None, int]:
        """The branch of ``overlay`` with the window ending at ``pose`` narrowed to ``lp``
        (within its share of ``deadline``: :meth:`~cuikslam.budget.Schedule.branch_node`);
        None when that proves it empty. Also returns the operator applications of the
        level's propagations."""
        local, variables, _ = window_rows(
            self._window[pose], graph.rows, graph.kinds, graph.in_base, overlay.rows,
            graph.head, graph.entry_factor, graph.entry_next, self._in_window,
            self._local_id, self._is_pose,
        )  # fmt: skip
        self._local_id[variables] = -1
        if len(local) == 0:
            return overlay, 0
        local = local[np.lexsort(local.T[::-1])]  # the LPs do not depend on the pool's order
        lo, hi = graph.values(overlay, variables)
        result = strengthen(
            linked(local, len(variables)), lo, hi, "lp", self.rtol,
            DEFAULT_ROUNDS, deadline=SCHEDULE.branch_node(deadline),
            report=StrengthenReport(),
        )  # fmt: skip
        if result.is_empty:
            return None, result.applications
        return graph.narrowed_to(overlay, variables, lo, hi), result.applications
