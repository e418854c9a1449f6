"""Online solving: guaranteed boxes as the robot drives (``cuikslam follow``).

:class:`Session` takes a log's records one at a time and gives each pose's box when the
pose is finished (:class:`PoseEstimate`), narrowing incrementally on a graph that grows
(:mod:`.growing`).
"""

from cuikslam.online.estimate import PoseEstimate
from cuikslam.online.session import Session

__all__ = ["PoseEstimate", "Session"]
