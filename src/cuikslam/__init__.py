"""cuikslam: guaranteed 2-D SLAM with bounded errors and unknown landmark correspondence.

The main names are importable from here; each loads its module on first use, so
``import cuikslam`` stays fast.

Examples
--------
>>> import cuikslam
>>> log, truth = cuikslam.simulate_paper(seed=0)
>>> solution = cuikslam.solve(log, consistency="hull", time_budget=None)
>>> best = solution.best
>>> cuikslam.check_truth(best, truth.pose_ids, truth.exact_poses()).ok
True

The narrowing steps one by one, as a GTSAM or Codac user builds them: a graph, its
fixpoint (:func:`propagate`), then a stronger level on the same bounds
(:func:`strengthen`); every step returns a :class:`Propagation`, which answers by pose
and landmark id:

>>> graph = cuikslam.KinematicGraph.from_log(log)
>>> result = cuikslam.propagate(graph)
>>> result.status
<Status.CONSISTENT: 0>
>>> result.pose_box(graph.pose_ids[0]).shape, result.landmark_box(graph.landmark_ids[0]).shape
((3, 2), (2, 2))
>>> stronger = cuikslam.strengthen(graph, result.lo, result.hi, level="lp")
>>> stronger.is_empty, stronger.lo is result.lo
(False, True)
>>> stronger.pose_box(graph.pose_ids[0]).shape
(3, 2)
"""

import importlib
from typing import Any

from cuikslam._fpu import ensure_round_to_nearest

# Some libraries (codac/IBEX) switch the process to rounding upward when imported; module
# constants of cuikslam must be parsed and computed in round-to-nearest mode.
ensure_round_to_nearest()

__version__ = "0.1.0"

_HOMES: dict[str, str] = {
    # reading and writing logs
    "Log": "cuikslam.log.records",
    "read_log_file": "cuikslam.log.reader",
    "parse_log_lines": "cuikslam.log.reader",
    "write_log_file": "cuikslam.log.writer",
    "InputFileError": "cuikslam.errors",
    # solving
    "solve": "cuikslam.solver",
    "SolveOptions": "cuikslam.options",
    "Level": "cuikslam.options",
    "KinematicGraph": "cuikslam.graph.kinematic_graph",
    "propagate": "cuikslam.narrowing.propagation",
    "narrow": "cuikslam.narrowing.propagation",
    "Arrays": "cuikslam.narrowing.propagation",
    "Propagation": "cuikslam.narrowing.propagation",
    "Status": "cuikslam.narrowing.propagation",
    "strengthen": "cuikslam.narrowing.consistency",
    "StrengthenReport": "cuikslam.narrowing.consistency",
    "tighten": "cuikslam.narrowing.polytope",
    # online
    "Session": "cuikslam.online.session",
    "PoseEstimate": "cuikslam.online.estimate",
    # results
    "Solution": "cuikslam.outcome.solution",
    "Hypothesis": "cuikslam.outcome.solution",
    "check_truth": "cuikslam.outcome.solution",
    "check_estimate": "cuikslam.interop.check",
    "read_result_file": "cuikslam.results.io",
    "write_result_file": "cuikslam.results.io",
    "summarize": "cuikslam.outcome.summary",
    "evaluate": "cuikslam.results.evaluate",
    "Evaluation": "cuikslam.results.evaluate",
    # simulation
    "simulate_paper": "cuikslam.simulate.paper",
    "simulate_random_world": "cuikslam.simulate.random_world",
    "GroundTruth": "cuikslam.simulate.truth",
    "read_truth_file": "cuikslam.simulate.truth",
    "write_truth_file": "cuikslam.simulate.truth",
}

__all__ = sorted(_HOMES)


def __getattr__(name: str) -> Any:
    """One of the main names, from its module (imported on first use)."""
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_HOMES[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOMES})
