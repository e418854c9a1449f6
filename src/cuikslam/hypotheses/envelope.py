"""The envelope of a search: boxes that hold the truth whatever the correspondence, and
whatever stopped the search.

Every pose's box is the hull of the pose's box in every survivor and at the node of every
subtree a budget left unexplored; each observation's box holds the landmark it sees: in a
survivor, the box of the landmark the survivor assigns it; at an unexplored node, the
landmark's box when the node's path decides the observation, else the box where the node's
pose, bearing and range boxes put what it sees (interval arithmetic; unbounded without a
range). The true correspondence is a survivor or lies under an unexplored node (no proof
cuts it), and every box of that node holds the truth, so the hull does. Survivors refuted
after the search stay in the hull: it is wider than needed, never wrong.

An observation a hypothesis takes as an outlier sees nothing the log's intervals bound: its
box is unbounded (so is every undecided observation's, with an ``outliers`` declaration).
"""

from __future__ import annotations

import numpy as np

from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.joined import joined_paths
from cuikslam.hypotheses.outlier_option import OUTLIER
from cuikslam.hypotheses.tree import Node
from cuikslam.outcome.solution import Envelope as EnvelopeBoxes

__all__ = ["Envelope"]


class Envelope:
    """The hull, over survivors and unexplored nodes, of pose and observation boxes.

    The boxes are kept flat: ``lo`` and ``hi`` hold (x, y, theta) of every pose (by
    increasing id), then (x, y) of every observation (in log order).
    """

    def __init__(self, explorer: Explorer) -> None:
        self.explorer = explorer
        p = explorer.problem
        self.pose_ids = sorted(p.pose_x)
        xs = np.array([p.pose_x[q] for q in self.pose_ids], dtype=np.int64)
        self.pose_cols = (xs[:, None] + np.arange(3)).ravel()
        self.n_obs = p.n_observations
        size = len(self.pose_cols) + 2 * self.n_obs
        self.lo = np.full(size, np.inf)
        self.hi = np.full(size, -np.inf)
        self._named_pos = np.array(sorted(p.named_assignment), dtype=np.int64)
        self._named_x = np.array(
            [p.named_x[p.named_assignment[i]] for i in self._named_pos.tolist()], dtype=np.int64
        )
        self._dec_pos = np.array([d.position for d in p.decisions], dtype=np.int64)
        self._dec_cols = np.array(
            [[d.sensor_x, d.sensor_x + 1, d.sensor_x + 2, d.bearing_var, d.range_var]
             for d in p.decisions],
            dtype=np.int64,
        ).reshape(-1, 5)  # fmt: skip
        self.root: tuple[np.ndarray, np.ndarray] | None = None
        """The root node's boxes (see :meth:`set_root`)."""

    def join(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Join flat boxes (as :meth:`boxes_of` gives them) into the hull."""
        np.minimum(self.lo, lo, out=self.lo)
        np.maximum(self.hi, hi, out=self.hi)

    def add(self, node: Node) -> None:
        """Join a survivor's, or an unexplored node's, boxes (a joined node's, as each
        hypothesis prefix it stands for: :func:`.joined.joined_paths`)."""
        for numbers in joined_paths(node, self.explorer.n_named):
            self.join(*self.boxes_of(node, numbers))

    def set_root(self, root: Node | None) -> None:
        """Keep the root's boxes, the fallback for unexplored subtrees whose nodes are not
        at hand (its constraints hold whatever the correspondence)."""
        self.root = None if root is None else self.boxes_of(root)

    def cover_root(self) -> None:
        """Join the root's boxes: sound for any subtree left unexplored."""
        if self.root is not None:
            self.join(*self.root)

    def boxes_of(
        self, node: Node, decisions: list[int] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """``node``'s flat boxes: its poses, and where each observation's landmark lies (by
        ``decisions``, every decision made in ``node``'s numbering: its own by default)."""
        ex, p = self.explorer, self.explorer.problem
        n_poses = len(self.pose_cols)
        numbers = np.array(node.decisions() if decisions is None else decisions, dtype=np.int64)
        decided = numbers != OUTLIER
        landmark_xs = ex.landmark_xs(node)
        lm_pos = np.concatenate([self._named_pos, self._dec_pos[: node.depth][decided]])
        lm_x = np.concatenate([self._named_x, landmark_xs[numbers[decided]]]).astype(np.int64)
        open_cols = self._dec_cols[node.depth :]
        cols = np.concatenate([self.pose_cols, lm_x, lm_x + 1, open_cols.ravel()])
        lo_v, hi_v = ex.graph.values(node.overlay, cols)
        lo = np.full(len(self.lo), -np.inf)
        hi = np.full(len(self.hi), np.inf)
        lo[:n_poses], hi[:n_poses] = lo_v[:n_poses], hi_v[:n_poses]
        m = len(lm_x)
        at = n_poses + 2 * lm_pos
        lo[at], hi[at] = lo_v[n_poses : n_poses + m], hi_v[n_poses : n_poses + m]
        lo[at + 1] = lo_v[n_poses + m : n_poses + 2 * m]
        hi[at + 1] = hi_v[n_poses + m : n_poses + 2 * m]
        if len(open_cols) and p.outlier is None:  # else each may be an outlier: unbounded
            start = n_poses + 2 * m
            box = np.stack([lo_v[start:], hi_v[start:]], axis=-1).reshape(-1, 5, 2)
            xy = _sighted(box)
            at = n_poses + 2 * self._dec_pos[node.depth :]
            lo[at], hi[at] = xy[:, 0, 0], xy[:, 0, 1]
            lo[at + 1], hi[at + 1] = xy[:, 1, 0], xy[:, 1, 1]
        return lo, hi

    def boxes(self) -> EnvelopeBoxes | None:
        """The envelope as a result holds it; None when nothing was joined (a refuted log)."""
        n_poses = len(self.pose_cols)
        if n_poses and not np.all(self.lo[:n_poses] <= self.hi[:n_poses]):
            return None
        both = np.stack([self.lo, self.hi], axis=-1)
        return EnvelopeBoxes(
            list(self.pose_ids),
            both[:n_poses].reshape(-1, 3, 2).copy(),
            both[n_poses:].reshape(-1, 2, 2).copy(),
        )


def _sighted(box: np.ndarray) -> np.ndarray:
    """Where an observation puts what it sees, from boxes ``(x, y, theta, bearing, range)``
    of shape (n, 5, 2): ``(x, y) + range (cos, sin)(theta + bearing)`` in outward-rounded
    interval arithmetic, shape (n, 2, 2); unbounded where the range is."""
    from cuikslam import interval as ia

    reach = box[:, 4]
    # inf - inf in unbounded boxes (marked wild below); sums past 1e308 round out to inf,
    # and the sine and cosine of an angle that large are [-1, 1]: nothing to warn about
    with np.errstate(invalid="ignore", over="ignore"):
        angle = ia.add(box[:, 2], box[:, 3])
        out = np.stack(
            [
                ia.add(box[:, 0], ia.mul(reach, ia.cos(angle))),
                ia.add(box[:, 1], ia.mul(reach, ia.sin(angle))),
            ],
            axis=1,
        )
    wild = ~np.isfinite(reach).all(axis=-1) | ~np.isfinite(box[:, :2]).all(axis=(1, 2))
    wild |= np.isnan(out).any(axis=(1, 2))
    out[wild] = (-np.inf, np.inf)
    return out
