"""How the MRCLAM importer turns commanded velocities into one move between poses.

:func:`relative_pose_motion` is the importer's default
:data:`~cuikslam.datasets.mrclam.MotionModel`: the steps between two poses become one
``relative_pose`` record (the later pose in the frame of the earlier one), enclosed by
:func:`cuikslam.motion.compose_steps` from each step's velocity intervals, then widened
by the slack of :class:`~cuikslam.datasets.mrclam.MrclamBounds` (``move_xy``, ``move_theta``). Every
bound is rounded outward by the interval kernel.
"""

from __future__ import annotations

import numpy as np

from cuikslam.interval._arith import add
from cuikslam.log.records import Record, RelativePose
from cuikslam.motion import compose_steps

__all__ = ["relative_pose_motion"]


def relative_pose_motion(
    source: int, target: int, v: np.ndarray, omega: np.ndarray, times: np.ndarray, bounds
) -> list[Record]:
    """One ``relative_pose`` record from pose ``source`` to ``target`` (a MotionModel).

    ``v`` and ``omega`` hold each step's velocity intervals, ``times`` the n + 1 step
    boundaries; ``bounds`` is a :class:`~cuikslam.datasets.mrclam.MrclamBounds`.
    """
    dx, dy, dtheta = compose_steps(v, omega, times)
    xy, th = bounds.move_xy, bounds.move_theta
    return [
        RelativePose(
            source,
            target,
            add(dx[0], dx[1], -xy, xy),
            add(dy[0], dy[1], -xy, xy),
            add(dtheta[0], dtheta[1], -th, th),
        )
    ]
