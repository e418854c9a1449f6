"""The log layer: the JSON Lines log format (``docs/log-format.md``) to and from records."""

from cuikslam.errors import InputFileError
from cuikslam.log.reader import parse_log_lines, read_log_file
from cuikslam.log.records import (
    Bounds,
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    OutlierBound,
    PosePrior,
    Record,
    RelativePose,
    SensorModel,
)
from cuikslam.log.writer import log_to_lines, write_log_file

__all__ = [
    "Bounds",
    "InputFileError",
    "LandmarkPrior",
    "Log",
    "Observation",
    "Odometry",
    "OutlierBound",
    "PosePrior",
    "Record",
    "RelativePose",
    "SensorModel",
    "log_to_lines",
    "parse_log_lines",
    "read_log_file",
    "write_log_file",
]
