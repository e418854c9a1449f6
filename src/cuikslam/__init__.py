"""cuikslam: guaranteed 2-D SLAM with bounded errors and unknown landmark correspondence."""

from cuikslam._fpu import ensure_round_to_nearest

# Some libraries (codac/IBEX) switch the process to rounding upward when imported; module
# constants of cuikslam must be parsed and computed in round-to-nearest mode.
ensure_round_to_nearest()

__version__ = "0.1.0"
