"""The kinematic tree of a hypothesis: its steps, in floating point and in interval arithmetic.

A *frame* is a robot pose or a sensor's pose (a robot pose composed with an observation
offset). Frames are placed from anchors by :class:`Step` s, each driven by parameters of
:class:`~.model.HypothesisModel`:

* an ``odometry`` step ``(turn, distance)``: ``theta_c = theta_p + turn``, then ``distance``
  along ``theta_c`` (backward when only the record's target is placed);
* a ``relative`` step ``(dx, dy, dtheta)``: the child is the parent composed with the
  relative pose, ``(x, y)_c = (x, y)_p + R(theta_p) (dx, dy)`` and
  ``theta_c = theta_p + dtheta`` (backward: the parent is the child composed with it). A
  tree ``relative_pose`` record and a sensor's offset are both relative steps.

A ``relative_pose`` record that closes a loop between placed frames is checked instead
(:func:`relative_values`, :func:`relative_enclosure`): the pose of its target in the frame
of its source, three inequalities (the heading modulo 2 pi).

:func:`kinematics` evaluates the frames (and their Jacobian) in floating point for the
optimisers; :func:`interval_kinematics` encloses them in outward-rounded interval arithmetic
for :mod:`.verify`, which alone decides.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from cuikslam import interval as ia
from cuikslam.graph.variables import length_bounds
from cuikslam.log.records import Bounds, Odometry, PosePrior, RelativePose
from cuikslam.witness._numeric import cos_sin, midpoint, wrap_near


@dataclass
class Step:
    """One edge of the kinematic tree: ``child`` placed from ``parent`` (frame indices).

    ``params`` are the parameter indices, ``(turn, distance)`` for odometry, ``(dx, dy,
    dtheta)`` for a relative pose; ``forward`` is False when the record runs from the child
    to the parent (the parent is the record's target).
    """

    parent: int
    child: int
    params: tuple[int, ...]
    forward: bool
    relative: bool = False


Offset = tuple[Bounds, Bounds, Bounds]


@dataclass
class Tree:
    """The parameters (bounds and names, in order) and the tree they drive, as built.

    :meth:`grow` places the robot poses from anchors by the motion records;
    :meth:`add_sensors` places one sensor frame per (pose, offset) of the observations.
    """

    lo: list[float] = field(default_factory=list)
    hi: list[float] = field(default_factory=list)
    names: list[str] = field(default_factory=list)
    anchors: list[tuple[int, int]] = field(default_factory=list)
    """(frame, index of its first parameter) per anchor."""
    steps: list[Step] = field(default_factory=list)
    used: set[int] = field(default_factory=set)
    """The motion records (by position) that are tree steps; the others close loops."""
    sensor_frames: list[tuple[int, Offset]] = field(default_factory=list)
    """(robot pose index, offset) of each sensor frame, frames ``n, n + 1, ...``."""
    obs_frame: list[int] = field(default_factory=list)
    """The frame each observation is made from."""

    def new_param(self, name: str, bounds: tuple[float, float]) -> int:
        """A new parameter bounded by ``bounds``; its index."""
        self.lo.append(float(bounds[0]))
        self.hi.append(float(bounds[1]))
        self.names.append(name)
        return len(self.lo) - 1

    def grow(
        self,
        pose_ids: Sequence[int],
        pose_index: dict[int, int],
        order: Sequence[int],
        anchor_prior: dict[int, PosePrior],
        motions: Sequence[Odometry | RelativePose],
    ) -> None:
        """Place every robot pose: anchors taken in ``order`` (bounded by ``anchor_prior``,
        if any), each followed by the motions, in log order, that link a placed pose to an
        unplaced one, until none is left."""
        placed = [False] * len(pose_ids)
        for a in order:
            if placed[a]:
                continue
            prior = anchor_prior.get(pose_ids[a])
            box = [(-math.inf, math.inf)] * 3 if prior is None else [prior.x, prior.y, prior.theta]
            first = len(self.lo)
            for c, b in zip("xyt", box, strict=True):
                self.new_param(f"pose {pose_ids[a]} {c}", b)
            self.anchors.append((a, first))
            placed[a] = True
            changed = True
            while changed:
                changed = False
                for e, r in enumerate(motions):
                    s, t = pose_index[r.source], pose_index[r.target]
                    if e in self.used or placed[s] == placed[t]:
                        continue
                    params = self._motion_params(r)
                    relative = isinstance(r, RelativePose)
                    if placed[s]:
                        self.steps.append(Step(s, t, params, True, relative))
                    else:
                        self.steps.append(Step(t, s, params, False, relative))
                    placed[s] = placed[t] = True
                    self.used.add(e)
                    changed = True

    def _motion_params(self, r: Odometry | RelativePose) -> tuple[int, ...]:
        name = f"{r.source}->{r.target}"
        if isinstance(r, RelativePose):
            return tuple(
                self.new_param(f"{c} {name}", b)
                for c, b in (("dx", r.dx), ("dy", r.dy), ("dtheta", r.dtheta))
            )
        return (
            self.new_param(f"turn {name}", r.turn),
            self.new_param(f"distance {name}", length_bounds(r.distance)),
        )

    def add_sensors(
        self,
        pose_ids: Sequence[int],
        obs_robot: Sequence[int],
        obs_offset: Sequence[Offset | None],
    ) -> None:
        """One sensor frame per (pose, offset), placed from its pose by the offset's
        parameters (bounded by its intervals); ``obs_frame`` for every observation."""
        n = len(pose_ids)
        frame_of: dict[tuple[int, Offset], int] = {}
        for i, offset in zip(obs_robot, obs_offset, strict=True):
            if offset is None:
                self.obs_frame.append(i)
                continue
            if (i, offset) not in frame_of:
                frame_of[(i, offset)] = f = n + len(self.sensor_frames)
                self.sensor_frames.append((i, offset))
                params = tuple(
                    self.new_param(f"offset {pose_ids[i]} #{f - n} {c}", b)
                    for c, b in zip(("dx", "dy", "dtheta"), offset, strict=True)
                )
                self.steps.append(Step(i, f, params, True, True))
            self.obs_frame.append(frame_of[(i, offset)])


def kinematics(
    n_frames: int,
    n_params: int,
    anchors: list[tuple[int, int]],
    steps: list[Step],
    p: np.ndarray,
    jacobian: bool,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Frames (n_frames, 3) and, optionally, their Jacobian (n_frames, 3, n_params)."""
    P = np.empty((n_frames, 3))
    J = np.zeros((n_frames, 3, n_params)) if jacobian else None
    for a, k in anchors:
        P[a] = p[k : k + 3]
        if J is not None:
            J[a, 0, k] = J[a, 1, k + 1] = J[a, 2, k + 2] = 1.0
    for st in steps:
        if st.relative:
            _relative_step(st, P, J, p)
        else:
            _odometry_step(st, P, J, p)
    return P, J


def _odometry_step(st: Step, P: np.ndarray, J: np.ndarray | None, p: np.ndarray) -> None:
    x, y, t = P[st.parent]
    kt, kd = st.params
    d = p[kd]
    if st.forward:
        th = t + p[kt]
        c, s = cos_sin(th)
        P[st.child] = (x + d * c, y + d * s, th)
        if J is not None:
            jt = J[st.parent, 2].copy()
            jt[kt] += 1.0
            J[st.child, 2] = jt
            J[st.child, 0] = J[st.parent, 0] - d * s * jt
            J[st.child, 1] = J[st.parent, 1] + d * c * jt
            J[st.child, 0, kd] += c
            J[st.child, 1, kd] += s
    else:
        c, s = cos_sin(t)
        P[st.child] = (x - d * c, y - d * s, t - p[kt])
        if J is not None:
            jt = J[st.parent, 2]
            J[st.child, 2] = jt
            J[st.child, 2, kt] -= 1.0
            J[st.child, 0] = J[st.parent, 0] + d * s * jt
            J[st.child, 1] = J[st.parent, 1] - d * c * jt
            J[st.child, 0, kd] -= c
            J[st.child, 1, kd] -= s


def _relative_step(st: Step, P: np.ndarray, J: np.ndarray | None, p: np.ndarray) -> None:
    x, y, t = P[st.parent]
    ka, kb, kd = st.params
    a, b = p[ka], p[kb]
    sign = 1.0 if st.forward else -1.0
    th = t + sign * p[kd]
    # the rotation is by the source's heading: the parent's forward, the child's backward
    c, s = cos_sin(t if st.forward else th)
    u, v = a * c - b * s, a * s + b * c  # R(theta_source) (dx, dy)
    P[st.child] = (x + sign * u, y + sign * v, th)
    if J is not None:
        jt = J[st.parent, 2].copy()
        jt[kd] += sign
        j_src = J[st.parent, 2] if st.forward else jt
        J[st.child, 2] = jt
        J[st.child, 0] = J[st.parent, 0] - sign * v * j_src
        J[st.child, 1] = J[st.parent, 1] + sign * u * j_src
        J[st.child, 0, ka] += sign * c
        J[st.child, 0, kb] -= sign * s
        J[st.child, 1, ka] += sign * s
        J[st.child, 1, kb] += sign * c


def interval_kinematics(
    n_frames: int, anchors: list[tuple[int, int]], steps: list[Step], box: np.ndarray
) -> np.ndarray:
    """Frames (n_frames, 3, 2) enclosing those of every parameter in ``box`` (n_params, 2),
    by outward-rounded forward kinematics."""
    # the operations module itself: each attribute of the package is looked up by an
    # import, which took a third of a 13,795-frame log's verification
    from cuikslam.interval import ops as ia

    P = np.full((n_frames, 3, 2), np.nan)
    for a, k in anchors:
        P[a] = box[k : k + 3]
    for st in steps:
        parent = P[st.parent]
        if st.relative:
            ka, kb, kd = st.params
            a, b = box[ka], box[kb]
            if st.forward:
                th = ia.add(parent[2], box[kd])
                c, s = ia.cos(parent[2]), ia.sin(parent[2])
            else:
                th = ia.sub(parent[2], box[kd])
                c, s = ia.cos(th), ia.sin(th)
            u = ia.sub(ia.mul(a, c), ia.mul(b, s))
            v = ia.add(ia.mul(a, s), ia.mul(b, c))
            step = ia.add if st.forward else ia.sub
            P[st.child, 0] = step(parent[0], u)
            P[st.child, 1] = step(parent[1], v)
            P[st.child, 2] = th
            continue
        kt, kd = st.params
        d = box[kd]
        if st.forward:
            th = ia.add(parent[2], box[kt])
            c, s = ia.cos(th), ia.sin(th)
            P[st.child, 0] = ia.add(parent[0], ia.mul(d, c))
            P[st.child, 1] = ia.add(parent[1], ia.mul(d, s))
            P[st.child, 2] = th
        else:
            c, s = ia.cos(parent[2]), ia.sin(parent[2])
            P[st.child, 0] = ia.sub(parent[0], ia.mul(d, c))
            P[st.child, 1] = ia.sub(parent[1], ia.mul(d, s))
            P[st.child, 2] = ia.sub(parent[2], box[kt])
    return P


def step_from_world(
    st: Step,
    parent: np.ndarray,
    child: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
) -> list[float]:
    """The parameters of ``st`` that carry ``parent`` to ``child`` (floats, angles mod
    2 pi nearest their intervals' centres); NaN where the child's pose is not known."""
    if st.relative:
        src, dst = (parent, child) if st.forward else (child, parent)
        c, s = cos_sin(float(src[2]))
        ddx, ddy = dst[0] - src[0], dst[1] - src[1]
        dtheta = dst[2] - src[2]
        values = [c * ddx + s * ddy, -s * ddx + c * ddy, dtheta]
        angle = 2
    else:
        if st.forward:
            turn, heading, delta = child[2] - parent[2], child[2], child[:2] - parent[:2]
        else:
            turn, heading, delta = parent[2] - child[2], parent[2], parent[:2] - child[:2]
        u = cos_sin(float(heading))
        values = [turn, float(delta[0] * u[0] + delta[1] * u[1])]
        angle = 0
    k = st.params[angle]
    centre = midpoint(lo[k], hi[k], 0.0)
    values[angle] = float(wrap_near(np.array(values[angle]), np.array(centre)))
    return [float(v) for v in values]


def relative_values(
    P: np.ndarray, JP: np.ndarray | None, source: np.ndarray, target: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None]:
    """The pose of each ``target`` frame in the frame of its ``source`` (k, 3) in floating
    point, and optionally its Jacobian (k, 3, n_params)."""
    ddx = P[target, 0] - P[source, 0]
    ddy = P[target, 1] - P[source, 1]
    c, s = np.cos(P[source, 2]), np.sin(P[source, 2])
    rx = c * ddx + s * ddy
    ry = -s * ddx + c * ddy
    values = np.stack([rx, ry, P[target, 2] - P[source, 2]], axis=-1)
    if JP is None:
        return values, None
    jdx = JP[target, 0] - JP[source, 0]
    jdy = JP[target, 1] - JP[source, 1]
    jts = JP[source, 2]
    J = np.stack(
        [
            c[:, None] * jdx + s[:, None] * jdy + ry[:, None] * jts,
            -s[:, None] * jdx + c[:, None] * jdy - rx[:, None] * jts,
            JP[target, 2] - jts,
        ],
        axis=1,
    )
    return values, J


def relative_enclosure(P: np.ndarray, source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """An enclosure (k, 3, 2) of the pose of each ``target`` frame in the frame of its
    ``source``, from interval frames ``P`` (n, 3, 2): outward-rounded."""
    ddx = ia.sub(P[target, 0], P[source, 0])
    ddy = ia.sub(P[target, 1], P[source, 1])
    c, s = ia.cos(P[source, 2]), ia.sin(P[source, 2])
    rx = ia.add(ia.mul(c, ddx), ia.mul(s, ddy))
    ry = ia.sub(ia.mul(c, ddy), ia.mul(s, ddx))
    return np.stack([rx, ry, ia.sub(P[target, 2], P[source, 2])], axis=1)
