"""cuikslam: guaranteed 2-D SLAM with bounded errors and unknown landmark correspondence."""

__version__ = "0.1.0"
