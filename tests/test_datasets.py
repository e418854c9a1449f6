"""The Lost-in-the-Woods importer: on a small synthetic ``.mat`` the test writes, and on the
real recording (skipped with a reason when absent; ``CUIKSLAM_DATA`` points elsewhere)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from _exact import angle_inside, mpf
from _litw import moves_hold_the_truth
from _litw import write_synthetic as _synthetic
from cuikslam.cli.main import main
from cuikslam.datasets import data_dir, read_lost_in_the_woods
from cuikslam.errors import InputFileError
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.log import read_log_file
from cuikslam.log.writer import write_log_file
from cuikslam.narrowing.propagation import Status, propagate
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
    if angle:
        return angle_inside(lo, hi, mpf(value))
    return lo <= value <= hi


def test_synthetic_whole_run_holds_the_truth(tmp_path):
    path = tmp_path / "small.mat"
    _synthetic(path)
    log, truth = read_lost_in_the_woods(path, unknown=False, keyframe=10)
    # 120 samples: keyframes 0, 10, ..., 110 and the last sample; no truth in the gap
    assert len(log.relative_poses) == 12 and log.pose_ids == list(range(13))
    assert truth.pose_ids == [i for i in range(13) if not 4 <= i < 6]
    assert all(o.offset is not None for o in log.observations)
    assert moves_hold_the_truth(log, truth) == 9
    graph = KinematicGraph.from_log(log)
    result = propagate(graph)
    assert result.status is Status.CONSISTENT
    boxes = graph.pose_boxes(result.lo, result.hi)
    for i, pose in enumerate(truth.pose_ids):
        box = boxes[graph.pose_ids.index(pose)]
        x, y, th = truth.poses_xyt[i]
        assert _inside(x, box[0]) and _inside(y, box[1]) and _inside(th, box[2], angle=True)


def test_synthetic_window_starting_in_a_vicon_gap(tmp_path):
    """The window is imported all the same; the first pose gets a box around the posts and
    the first sample with a Vicon pose (a keyframe of its own) the small prior."""
    path = tmp_path / "small.mat"
    _synthetic(path)
    log, truth = read_lost_in_the_woods(path, start=45, steps=40, keyframe=10)
    first, second = log.priors
    assert first.pose == 0 and first.x[1] - first.x[0] > 40
    assert second.pose == 2 and second.x[1] - second.x[0] == pytest.approx(0.02)
    assert truth.pose_ids[0] == 2 and log.has_unknown_correspondence
    write_log_file(log, tmp_path / "w.jsonl")
    assert len(read_log_file(tmp_path / "w.jsonl").records) == len(log.records)


def test_keyframe_observations_only(tmp_path):
    path = tmp_path / "small.mat"
    _synthetic(path)
    every, _ = read_lost_in_the_woods(path)
    keyframes, _ = read_lost_in_the_woods(path, every_observation=False)
    assert 0 < len(keyframes.observations) < len(every.observations)


def test_bad_files_and_windows_are_log_format_errors(tmp_path, capsys):
    with pytest.raises(InputFileError, match="no such file"):
        read_lost_in_the_woods(tmp_path / "nope.mat")
    bad = tmp_path / "bad.mat"
    bad.write_text("not a mat file")
    with pytest.raises(InputFileError):
        read_lost_in_the_woods(bad)
    partial = tmp_path / "partial.mat"
    scipy.io.savemat(partial, {"t": np.zeros((3, 1))})
    with pytest.raises(InputFileError, match="lacks variable"):
        read_lost_in_the_woods(partial)
    path = tmp_path / "small.mat"
    _synthetic(path)
    with pytest.raises(InputFileError, match="leaves the recording"):
        read_lost_in_the_woods(path, start=100, steps=50)
    with pytest.raises(InputFileError, match="no valid Vicon pose"):
        read_lost_in_the_woods(path, start=41, steps=10)
    args = ["import", "lost-in-the-woods", os.fspath(tmp_path / "nope.mat")]
    assert main([*args, "-o", os.fspath(tmp_path / "o.jsonl")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert not (tmp_path / "o.jsonl").exists()


def test_cli_import_synthetic(tmp_path):
    path = tmp_path / "small.mat"
    _synthetic(path)
    out = tmp_path / "woods.jsonl"
    args = ["import", "lost-in-the-woods", os.fspath(path), "-o", os.fspath(out)]
    assert main([*args, "--keyframe", "5", "--known", "--range-bound", "0.1", "-q"]) == 0
    log = read_log_file(out)
    assert log.observations[0].landmark is not None and len(log.relative_poses) == 24
    assert (tmp_path / "woods.truth.json").is_file()


# ---------------------------------------------------------------- the real recording


def test_real_run_moves_hold_the_vicon_truth():
    log, truth = read_lost_in_the_woods(_dataset(), unknown=False)
    assert len(log.relative_poses) == 1261 and len(log.observations) == 61086
    assert len(truth.pose_ids) == 1229  # keyframes with a valid Vicon pose
    assert moves_hold_the_truth(log, truth) == 1210


def test_real_window_solved_boxes_contain_the_truth():
    from cuikslam.solver import solve

    log, truth = read_lost_in_the_woods(_dataset(), start=8174, steps=1182, unknown=False)
    solution = solve(log, consistency="hull", certify_limit=0)
    (hyp,) = solution.hypotheses
    report = check_truth(hyp, truth.pose_ids, truth.poses_xyt)
    assert report.ok, report.misses[:3]
    assert report.checked == 3 * len(truth.pose_ids)


@pytest.mark.slow
def test_real_whole_run_solved_boxes_contain_the_truth():
    from cuikslam.solver import solve

    log, truth = read_lost_in_the_woods(_dataset(), unknown=False)
    solution = solve(log, consistency="hull", certify_limit=0)
    (hyp,) = solution.hypotheses
    report = check_truth(hyp, truth.pose_ids, truth.poses_xyt)
    assert report.ok, report.misses[:3]


def test_synthetic_surveyed_map_is_matched_by_the_search(tmp_path):
    """``map_bound``: every post of the file's map becomes a landmark record holding its
    position; with the ids dropped the search, matching readings to those posts, keeps the
    true association."""
    from cuikslam import SolveOptions, solve
    from cuikslam.results.association import rank_of

    path = tmp_path / "small.mat"
    _synthetic(path)
    log, truth = read_lost_in_the_woods(
        path, unknown=True, keyframe=10, every_observation=False, map_bound=0.05
    )
    posts = scipy.io.loadmat(path)["l"]
    priors = log.landmark_priors
    assert [p.landmark for p in priors] == [f"P{j}" for j in range(len(posts))]
    for prior, (x, y) in zip(priors, posts, strict=True):
        assert _inside(x, prior.x) and _inside(y, prior.y)
        assert prior.x[1] - prior.x[0] < 0.1 + 1e-12
    solution = solve(log, SolveOptions(consistency="hull", work_budget=4e7))
    assert solution.complete
    assert rank_of(solution.hypotheses, truth.assignment) is not None
