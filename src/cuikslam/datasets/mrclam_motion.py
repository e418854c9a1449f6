"""How the MRCLAM importer turns commanded velocities into one move between poses.

:func:`relative_pose_motion` is the importer's default
:data:`~cuikslam.datasets.mrclam.MotionModel`: the commands between two poses become one
``relative_pose`` record (the later pose in the frame of the earlier one), enclosed by
:func:`cuikslam.motion.compose_steps` from the intervals ``v ± velocity`` and
``ω ± turn_rate`` of each command, then widened by the slack of
:class:`~cuikslam.datasets.mrclam.MrclamBounds` (``move_xy``, ``move_theta``). Every
bound is rounded outward by the interval kernel.
"""

from __future__ import annotations

import numpy as np

from cuikslam import interval as ia
from cuikslam.interval._arith import add
from cuikslam.log.records import Record, RelativePose
from cuikslam.motion import compose_steps

__all__ = ["relative_pose_motion"]


def relative_pose_motion(
    source: int, target: int, commands: np.ndarray, times: np.ndarray, bounds
) -> list[Record]:
    """One ``relative_pose`` record from pose ``source`` to ``target`` (a MotionModel).

    ``commands`` holds the commanded (v, ω) of each step, ``times`` the n + 1 step
    boundaries; ``bounds`` is a :class:`~cuikslam.datasets.mrclam.MrclamBounds`.
    """
    v, w = commands[:, 0], commands[:, 1]
    v_box = ia.add(ia.interval(v, v), np.array([-bounds.velocity, bounds.velocity]))
    w_box = ia.add(ia.interval(w, w), np.array([-bounds.turn_rate, bounds.turn_rate]))
    dx, dy, dtheta = compose_steps(v_box, w_box, times)
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
