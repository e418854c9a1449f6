"""The kinematic graph: interval variables for poses, landmarks and measurements, and factors."""

from cuikslam.graph.kinematic_graph import ANY_ANGLE, ANY_LENGTH, KinematicGraph

__all__ = ["ANY_ANGLE", "ANY_LENGTH", "KinematicGraph"]
