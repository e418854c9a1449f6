"""Results: hypotheses and their boxes, result files, tables and figures."""

from cuikslam.outcome.solution import Hypothesis, Solution, check_truth
from cuikslam.results.io import read_result_file, write_result_csv, write_result_file

__all__ = [
    "Hypothesis",
    "Solution",
    "check_truth",
    "read_result_file",
    "write_result_csv",
    "write_result_file",
]
