"""Logs from an adversarial round on relative poses, sensor offsets and declared outliers.

See tests/data/adversary/README.md for what each log broke.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from cuikslam.log import read_log_file
from cuikslam.results.measurement_check import check_log
from cuikslam.simulate.truth import read_truth_file

FOUND = Path(__file__).parent / "data" / "adversary"


def test_a_truth_exactly_on_a_bound_is_not_outside() -> None:
    """The true dtheta of the move is exactly the point interval [-0.13, -0.13] (the true
    headings are doubles that differ by it), but the truth's floats subtracted again give
    -0.13 + 1 ulp: the float comparison counted the move outside its interval."""
    log = read_log_file(FOUND / "truth-on-bound.jsonl")
    truth = read_truth_file(FOUND / "truth-on-bound.truth.json")
    found = check_log(log, truth)
    assert found.moves == 0, found.details
    assert found.moves_checked == 1
    assert found.outside_observations == []


def test_a_truth_on_a_bound_keeps_the_guarantee_of_a_declaration() -> None:
    """With an outliers record, a move counted outside made ``solve --truth`` print "no
    guarantee applies" on a log whose every interval holds the truth, and a box missing
    the truth would then not have failed the check (exit 0)."""
    log, truth = FOUND / "truth-on-bound.jsonl", FOUND / "truth-on-bound.truth.json"
    run = [sys.executable, "-m", "cuikslam.cli.main", "solve", str(log), "--truth", str(truth)]
    done = subprocess.run([*run, "-q", "--work-budget", "2e7"], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "no guarantee applies" not in done.stdout
    assert "the true correspondence survived" in done.stdout


def test_an_unreported_true_hypothesis_with_an_unchecked_outlier_is_not_a_failure() -> None:
    """The only observation is an outlier made from an uncertain sensor offset (the truth
    file cannot check it), and the true hypothesis (taking it as an outlier) is the second
    of two survivors, not reported with ``--max-hypotheses 1``. The truth check looked for
    the truth's own landmark in the correspondence summary, not for the hypothesis taking
    the unchecked observation as an outlier, and said "the true correspondence is not among
    the 2 survivors" (exit 1); a 6-pose world at ``lp-split`` (1,335 survivors) did the same
    with the default 100 reported."""
    log = FOUND / "unchecked-outlier-unreported.jsonl"
    truth = FOUND / "unchecked-outlier-unreported.truth.json"
    run = [sys.executable, "-m", "cuikslam.cli.main", "solve", str(log), "--truth", str(truth)]
    done = subprocess.run([*run, "-q", "--max-hypotheses", "1"], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "not among the 1 reported of 2 survivors" in done.stdout
    everything = subprocess.run([*run, "-q"], capture_output=True, text=True)
    assert everything.returncode == 0, everything.stdout + everything.stderr
    assert "the true correspondence survived (hypothesis 2 of 2)" in everything.stdout
