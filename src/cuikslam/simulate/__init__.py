"""Simulated logs with known ground truth: the seed paper's experiment and random worlds."""

from cuikslam.simulate.paper import (
    PAPER_SURVIVORS,
    paper_survivors,
    paper_table1,
    paper_truth,
    simulate_paper,
)
from cuikslam.simulate.random_world import WorldSpec, simulate_random_world, simulate_world
from cuikslam.simulate.truth import (
    GroundTruth,
    TruthMisfit,
    TruthMismatchError,
    check_truth_fits,
    noisy_interval,
    read_truth_file,
    truth_misfit,
    truth_to_json,
    wrap_angle,
    write_truth_file,
)

__all__ = [
    "PAPER_SURVIVORS",
    "GroundTruth",
    "TruthMisfit",
    "TruthMismatchError",
    "WorldSpec",
    "check_truth_fits",
    "noisy_interval",
    "paper_survivors",
    "paper_table1",
    "paper_truth",
    "read_truth_file",
    "simulate_paper",
    "simulate_random_world",
    "simulate_world",
    "truth_misfit",
    "truth_to_json",
    "wrap_angle",
    "write_truth_file",
]
