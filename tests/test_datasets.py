"""The Lost-in-the-Woods importer against the real recording and its Vicon truth."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from cuikslam.cli.main import main
from cuikslam.datasets import data_dir, read_lost_in_the_woods
from cuikslam.log import read_log_file
from cuikslam.log.errors import LogFormatError
from cuikslam.log.writer import write_log_file
from cuikslam.results.solution import check_truth


def _dataset() -> Path:
    folder = data_dir()
    path = folder / "lost-in-the-woods" / "dataset2.mat" if folder else None
    if path is None or not path.is_file():
        pytest.skip(
            "real dataset not found: set CUIKSLAM_DATA to the folder holding "
            "lost-in-the-woods/dataset2.mat"
        )
    return path


def _inside(value: float, bounds: tuple[float, float], *, angle: bool = False) -> bool:
    lo, hi = bounds
    if angle:  # shift value by 2π k next to the interval
        value = lo + (value - lo) % (2 * math.pi)
    return lo <= value <= hi


def test_every_interval_contains_the_vicon_truth():
    log, truth = read_lost_in_the_woods(_dataset(), unknown=False)
    assert len(log.odometry) == 2 * 45 and len(log.observations) > 100
    prior = log.priors[0]
    x, y, th = truth.pose_xyt(0)
    assert _inside(x, prior.x) and _inside(y, prior.y) and _inside(th, prior.theta)
    for odo in log.odometry:
        a, b = truth.pose_xyt(odo.source), truth.pose_xyt(odo.target)
        assert _inside(b[2] - a[2], odo.turn, angle=True), odo
        assert _inside(math.hypot(b[0] - a[0], b[1] - a[1]), odo.distance), odo
        heading = np.array([math.cos(b[2]), math.sin(b[2])])
        drive = np.array(b[:2] - a[:2])
        assert abs(drive[0] * heading[1] - drive[1] * heading[0]) < 1e-9  # along the heading
    for obs, lid in zip(log.observations, truth.assignment, strict=True):
        assert obs.landmark == lid
        p, post = truth.pose_xyt(obs.pose), truth.landmark_xy(lid)
        rng = math.hypot(*(post - p[:2]))
        bearing = math.atan2(post[1] - p[1], post[0] - p[0]) - p[2]
        assert _inside(rng, obs.range) and _inside(bearing, obs.bearing, angle=True), obs


def test_written_log_reads_back(tmp_path):
    log, _ = read_lost_in_the_woods(_dataset(), steps=300)
    assert log.has_unknown_correspondence
    write_log_file(log, tmp_path / "woods.jsonl")
    back = read_log_file(tmp_path / "woods.jsonl")
    assert [type(r) for r in back.records] == [type(r) for r in log.records]
    assert back.observations[0].range == log.observations[0].range


def test_solved_boxes_contain_the_truth():
    from cuikslam.solver import solve

    log, truth = read_lost_in_the_woods(_dataset(), steps=300, unknown=False)
    solution = solve(log, consistency="hull", certify_limit=0)
    (hyp,) = solution.hypotheses
    report = check_truth(hyp, truth.pose_ids, truth.poses_xyt)
    assert report.ok, report.misses[:3]
    assert report.checked == 3 * len(log.pose_ids)


def test_cli_import_writes_log_and_truth(tmp_path):
    out = tmp_path / "woods.jsonl"
    args = ["import", "lost-in-the-woods", os.fspath(_dataset()), "-o", os.fspath(out)]
    assert main([*args, "--steps", "100", "--known", "-q"]) == 0
    assert read_log_file(out).observations[0].landmark is not None
    assert (tmp_path / "woods.truth.json").is_file()


def test_missing_file_is_a_log_format_error(tmp_path, capsys):
    with pytest.raises(LogFormatError, match="no such file"):
        read_lost_in_the_woods(tmp_path / "nope.mat")
    bad = tmp_path / "bad.mat"
    bad.write_text("not a mat file")
    with pytest.raises(LogFormatError):
        read_lost_in_the_woods(bad)
    args = ["import", "lost-in-the-woods", os.fspath(tmp_path / "nope.mat")]
    assert main([*args, "-o", os.fspath(tmp_path / "o.jsonl")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
