"""Bounds of Lost in the Woods calibrated against Vicon (``cuikslam calibrate
lost-in-the-woods``): on a small synthetic ``.mat`` the tests write, and on the real
recording (skipped with a reason when absent; ``CUIKSLAM_DATA`` points elsewhere)."""

from __future__ import annotations

import json
import math
import os

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from _exact import angle_inside, mpf
from _litw import LASER, moves_hold_the_truth, write_synthetic
from cuikslam.cli.main import main
from cuikslam.datasets import read_lost_in_the_woods
from cuikslam.datasets.lost_in_the_woods_bounds import (
    _fit,
    calibrate_lost_in_the_woods,
    count_outside_lost_in_the_woods,
)
from cuikslam.log import read_log_file
from test_datasets import _dataset


def _sightings_hold_the_truth(log, truth) -> int:
    """Assert the range and bearing of every keyframe observation (the laser at its mount,
    no motion in between) hold the truth; return how many were checked."""
    pose = dict(zip(truth.pose_ids, truth.poses_xyt.tolist(), strict=True))
    mark = dict(zip(truth.landmark_ids, truth.landmarks_xy.tolist(), strict=True))
    checked = 0
    for obs, lid in zip(log.observations, truth.assignment, strict=True):
        if obs.pose not in pose:
            continue
        x, y, th = pose[obs.pose]
        sx, sy = x + LASER * math.cos(th), y + LASER * math.sin(th)
        px, py = mark[lid]
        assert obs.range[0] <= math.hypot(px - sx, py - sy) <= obs.range[1]
        assert angle_inside(*obs.bearing, mpf(math.atan2(py - sy, px - sx) - th))
        checked += 1
    return checked


def test_calibrated_bounds_hold_every_move_and_sighting_of_their_part(tmp_path):
    path = tmp_path / "small.mat"
    write_synthetic(path)
    calibration = calibrate_lost_in_the_woods(path, keyframe=10)
    assert calibration.outside.moves == 0 and calibration.outside.moves_checked > 50
    assert calibration.outside.ranges == calibration.outside.bearings == 0
    # the importer builds its intervals from the same model: checked independently
    log, truth = read_lost_in_the_woods(
        path, unknown=False, bounds=calibration.bounds, every_observation=False
    )
    assert moves_hold_the_truth(log, truth) == 9
    assert _sightings_hold_the_truth(log, truth) > 10
    # tighter than three standard deviations per sample composed over a keyframe
    default, _ = read_lost_in_the_woods(path, unknown=False, every_observation=False)
    width = lambda m: m.dtheta[1] - m.dtheta[0]  # noqa: E731
    assert sum(map(width, log.relative_poses)) < sum(map(width, default.relative_poses))


def test_a_quantile_leaves_out_at_most_its_share(tmp_path):
    path = tmp_path / "small.mat"
    write_synthetic(path, n=300, gap=(200, 210))
    every = calibrate_lost_in_the_woods(path, keyframe=10)
    most = calibrate_lost_in_the_woods(path, keyframe=10, quantile=0.8)
    b, e = most.bounds, every.bounds
    assert b.range <= e.range and b.bearing <= e.bearing
    out = most.outside
    assert b.motion(1.0, 1.0) == e.motion(1.0, 1.0)  # moves: quantile 1 unless asked
    assert out.moves == 0
    moves = calibrate_lost_in_the_woods(path, keyframe=10, motion_quantile=0.8).outside
    assert 0 < moves.moves <= 3 * 0.2 * moves.moves_checked  # each of x, y, theta leaves 20 %
    assert out.ranges <= 0.2 * out.sightings_checked
    assert out.bearings <= 0.2 * out.sightings_checked
    assert out.ranges + out.bearings > 0  # the share left out is really left out
    # a part of the run checked with them counts against the same intervals
    rest = count_outside_lost_in_the_woods(path, every.bounds, start=150)
    assert rest.moves == 0 and rest.ranges == rest.bearings == 0


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-1, 1), st.floats(0, 5)), min_size=1, max_size=60),
    st.sampled_from([1.0, 0.95, 0.8, 0.5]),
)
def test_fitted_model_covers_its_share(pairs, quantile):
    error = np.array([p[0] for p in pairs])
    scale = np.array([p[1] for p in pairs])
    a, c = _fit(error, scale, quantile)
    covered = np.abs(error) <= a + c * scale
    assert covered.sum() >= math.ceil(quantile * len(pairs) - 1e-9)


def test_cli_calibrate_then_import(tmp_path, capsys):
    path = tmp_path / "small.mat"
    write_synthetic(path, n=300, gap=(200, 210))
    bounds = tmp_path / "b.json"
    assert main(["calibrate", "lost-in-the-woods", os.fspath(path), "-o", os.fspath(bounds)]) == 0
    doc = json.loads(bounds.read_text())
    assert doc["dataset"] == "lost-in-the-woods"
    assert doc["calibrated_on"]["end"] == 150 and doc["calibrated_on"]["checked_on"]["start"] == 150
    err = capsys.readouterr().err
    assert "checked on samples from 150" in err
    out = tmp_path / "w.jsonl"
    args = ["import", "lost-in-the-woods", os.fspath(path), "-o", os.fspath(out), "-q"]
    assert main([*args, "--bounds", os.fspath(bounds)]) == 0
    log = read_log_file(out)
    assert log.class_priors["post"].at_most == 5  # the synthetic map's posts, ids dropped
    assert main([*args, "--bounds", os.fspath(bounds), "--known"]) == 0
    assert read_log_file(out).class_priors == {}
    # longer keyframes than calibrated: refused, naming the options
    assert main([*args, "--bounds", os.fspath(bounds), "--keyframe", "20"]) != 0
    assert "calibrate with --keyframe 20" in capsys.readouterr().err
    # another dataset's bounds file is refused, naming it
    doc["dataset"] = "mrclam"
    bounds.write_text(json.dumps(doc))
    assert main([*args, "--bounds", os.fspath(bounds)]) != 0
    assert "b.json" in capsys.readouterr().err


# ---------------------------------------------------------------- the real recording


def test_real_first_half_calibrated_moves_hold_the_vicon_truth():
    path = _dataset()
    calibration = calibrate_lost_in_the_woods(path, steps=6304)
    assert calibration.outside.moves == 0
    log, truth = read_lost_in_the_woods(
        path, steps=6304, unknown=False, bounds=calibration.bounds, every_observation=False
    )
    assert moves_hold_the_truth(log, truth) > 600
    assert _sightings_hold_the_truth(log, truth) > 3000
    default, _ = read_lost_in_the_woods(path, steps=6304, every_observation=False)
    width = lambda m: m.dtheta[1] - m.dtheta[0]  # noqa: E731
    calibrated = np.median([width(m) for m in log.relative_poses])
    assert calibrated < np.median([width(m) for m in default.relative_poses]) / 2


def test_real_second_half_is_counted_and_a_margin_covers_more():
    path = _dataset()
    calibration = calibrate_lost_in_the_woods(path, steps=6304)
    rest = count_outside_lost_in_the_woods(path, calibration.bounds, start=6304)
    assert rest.moves_checked > 6000 and rest.sightings_checked > 29000
    assert len(rest.worst) == min(10, rest.moves) + min(10, rest.ranges + rest.bearings)
    wider = calibrate_lost_in_the_woods(path, steps=6304, motion_margin=2.0)
    b, w = calibration.bounds, wider.bounds
    assert all(a >= 2 * v for a, v in zip(w.motion(1.0, 1.0), b.motion(1.0, 1.0), strict=True))
    assert (w.range, w.bearing) == (b.range, b.bearing)
    assert count_outside_lost_in_the_woods(path, w, start=6304).moves < rest.moves


def test_calibrate_check_sees_the_laser_mount(tmp_path):
    """Readings made at a keyframe are checked from the laser, 0.219 m ahead of the pose
    (from the pose itself, ranges with a 6 cm bound would miss); readings between keyframes
    carry an uncertain offset and are counted apart."""
    from cuikslam.results.measurement_check import check_log

    path = tmp_path / "small.mat"
    write_synthetic(path)
    kw = {"unknown": False, "range_bound": 0.06, "bearing_bound": 0.06}
    log, truth = read_lost_in_the_woods(path, every_observation=False, **kw)
    found = check_log(log, truth)
    assert found.observations_checked == len(truth.assignment) - _without_truth(log, truth)
    assert found.ranges == found.bearings == found.observations_unchecked == 0
    log, truth = read_lost_in_the_woods(path, **kw)
    found = check_log(log, truth)
    assert found.observations_unchecked > 0 and found.ranges == found.bearings == 0


def _without_truth(log, truth) -> int:
    return sum(o.pose not in set(truth.pose_ids) for o in log.observations)
