"""The Victoria Park importer: on small folders in its format that the tests write (a car on
a circle among trees, exact readings), and on the real data set (skipped with a reason when
absent; ``CUIKSLAM_DATA`` points elsewhere)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cuikslam.cli.main import main
from cuikslam.datasets import data_dir
from cuikslam.datasets.calibrate import read_bounds_file
from cuikslam.datasets.victoria_park import (
    LASER_A,
    LASER_B,
    WHEEL_OFFSET,
    WHEELBASE,
    GpsReference,
    VictoriaParkBounds,
    car_motion,
    gps_inside,
    read_victoria_park,
)
from cuikslam.errors import InputFileError
from cuikslam.log import read_log_file
from cuikslam.motion import compose_relative

V, PHI = 2.0, 0.1  # the rear axle's true speed [m/s] and the steering angle [rad]
OMEGA = V * math.tan(PHI) / WHEELBASE
TREES = np.array([[10.0, 8.0], [-5.0, 12.0], [3.0, 25.0], [15.0, 20.0], [-12.0, 3.0]])
START = (1.0, -2.0, 0.3)


def true_pose(t: np.ndarray | float) -> np.ndarray:
    """The rear axle on its circle: (x, y, theta) at time t."""
    x0, y0, th0 = START
    th = th0 + OMEGA * np.asarray(t, dtype=float)
    r = V / OMEGA
    return np.stack(
        [x0 + r * (np.sin(th) - math.sin(th0)), y0 - r * (np.cos(th) - math.cos(th0)), th], -1
    )


def laser(p: np.ndarray) -> np.ndarray:
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    return np.stack(
        [p[..., 0] + LASER_A * c - LASER_B * s, p[..., 1] + LASER_A * s + LASER_B * c], -1
    )


def write_folder(folder: Path, duration: float = 40.0) -> Path:
    """A Victoria Park folder of exact readings: inputs 40 Hz, scans 5 Hz, GPS at the laser."""
    folder.mkdir(parents=True, exist_ok=True)
    t_in = np.round(np.arange(0.0, duration, 0.025), 3)
    wheel = V * (1 - WHEEL_OFFSET / WHEELBASE * math.tan(PHI))
    (folder / "inputs.dat").write_text("".join(f"{t:10.3f} {wheel:.6f} {PHI:.6f}\n" for t in t_in))
    lines = []
    for t in np.round(np.arange(0.1, duration - 0.5, 0.2), 3):
        p = true_pose(t)
        lx, ly = laser(p)
        for tx, ty in TREES:
            r = math.hypot(tx - lx, ty - ly)
            b = (math.atan2(ty - ly, tx - lx) - p[2] + math.pi / 2 + math.pi) % (
                2 * math.pi
            ) - math.pi
            if 0 < b < math.pi and r < 40:
                lines.append(f"{t:10.3f} {r:.6f} {b:.6f} 0.300\n")
    (folder / "measurements.dat").write_text("".join(lines))
    t_gps = np.round(np.arange(0.0, duration, 0.2), 3)
    g = laser(true_pose(t_gps))
    (folder / "gps.dat").write_text(
        "".join(f"{t:10.3f} {x:.4f} {y:.4f}\n" for t, (x, y) in zip(t_gps, g, strict=True))
    )
    return folder


def _real_folder() -> Path:
    folder = data_dir()
    path = folder / "victoria-park" if folder else None
    if path is None or not (path / "inputs.dat").is_file():
        pytest.skip(
            "real dataset not found: set CUIKSLAM_DATA to the folder holding "
            "victoria-park/inputs.dat, measurements.dat and gps.dat"
        )
    return path


def _inside(value: float, bounds: tuple[float, float]) -> bool:
    return bounds[0] <= value <= bounds[1]


def test_synthetic_moves_and_observations_hold_the_truth(tmp_path):
    log, reference = read_victoria_park(write_folder(tmp_path / "vp"), keyframe=1.0)
    assert log.has_unknown_correspondence and {o.landmark_class for o in log.observations} == {
        "tree"
    }
    times = dict(zip(reference.pose_ids, reference.times, strict=True))
    assert len(times) == len(log.pose_ids)  # GPS everywhere in this folder
    truth = {p: true_pose(t) for p, t in times.items()}
    prior = log.priors[0]
    assert all(
        _inside(v, b) for v, b in zip(truth[0], (prior.x, prior.y, prior.theta), strict=True)
    )
    for move in log.relative_poses:
        a, b = truth[move.source], truth[move.target]
        c, s = math.cos(a[2]), math.sin(a[2])
        dx, dy = b[0] - a[0], b[1] - a[1]
        assert _inside(c * dx + s * dy, move.dx) and _inside(-s * dx + c * dy, move.dy)
        assert _inside(b[2] - a[2], move.dtheta)
    assert log.observations
    for obs in log.observations:
        p = truth[obs.pose]
        lx, ly = laser(p)
        assert obs.offset == ((LASER_A, LASER_A), (LASER_B, LASER_B), (0.0, 0.0))
        ranges = np.hypot(TREES[:, 0] - lx, TREES[:, 1] - ly)
        bearings = np.arctan2(TREES[:, 1] - ly, TREES[:, 0] - lx) - p[2]
        bearings = (bearings + math.pi) % (2 * math.pi) - math.pi
        assert any(
            _inside(r, obs.range) and _inside(b, obs.bearing)
            for r, b in zip(ranges, bearings, strict=True)
        )


def test_every_scan_and_max_range(tmp_path):
    folder = write_folder(tmp_path / "vp", duration=12.0)
    keyframes, _ = read_victoria_park(folder, keyframe=1.0)
    every, _ = read_victoria_park(folder, keyframe=1.0, every_scan=True)
    near, _ = read_victoria_park(folder, keyframe=1.0, every_scan=True, max_range=12.0)
    assert len(every.observations) > 3 * len(keyframes.observations)
    assert 0 < len(near.observations) < len(every.observations)
    assert all(o.range[0] < 12.0 for o in near.observations)
    assert any(o.offset[0][1] > LASER_A for o in every.observations)  # motion since the keyframe


@settings(max_examples=40, deadline=None)
@given(
    v=st.floats(0.0, 6.0),
    phi=st.floats(-0.55, 0.55),
    duration=st.floats(0.01, 3.0),
    th0=st.floats(-3.0, 3.0),
)
def test_car_motion_encloses_the_arc(v, phi, duration, th0):
    """Constant wheel speed and steering: the exact Ackermann arc lies in the enclosure."""
    t = np.arange(0.0, duration + 0.1, 0.025)
    wheel = v * (1 - WHEEL_OFFSET / WHEELBASE * math.tan(phi))
    bounds = VictoriaParkBounds(speed_scale_min=1.0, speed_scale_max=1.0, speed=0.0, steering=0.0)
    dx, dy, dth = car_motion(t, np.full(t.size, wheel), np.full(t.size, phi), 0.0, duration, bounds)
    w = v * math.tan(phi) / WHEELBASE
    turn = w * duration
    if abs(w) < 1e-12:
        ex, ey = v * duration, 0.0
    else:
        ex, ey = v / w * math.sin(turn), v / w * (1 - math.cos(turn))
    tol = 1e-9
    assert dx[0] - tol <= ex <= dx[1] + tol and dy[0] - tol <= ey <= dy[1] + tol
    assert dth[0] - tol <= turn <= dth[1] + tol


def test_gps_inside_maps_the_box_to_the_antenna():
    reference = GpsReference(
        [0, 1], [0.0, 1.0], np.array([[LASER_A, LASER_B], [LASER_A + 5.0, LASER_B]])
    )
    point = ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    inside, compared, misses = gps_inside({0: point, 1: point}, reference, 1.0)
    assert (inside, compared) == (1, 2) and misses[0][0] == 1
    assert misses[0][1] == pytest.approx(4.0)


@pytest.mark.parametrize(
    ("name", "text", "where", "problem"),
    [
        ("inputs.dat", "0.0 1.0 0.0\n0.1 1.0\n", "inputs.dat:2:", "expected 3 numbers"),
        (
            "measurements.dat",
            "0.1 5.0 1.0 0.2\n0.2 -5.0 1.0 0.2\n",
            "measurements.dat:2:",
            "negative",
        ),
        ("measurements.dat", "0.1 5.0 4.0 0.2\n", "measurements.dat:1:", "0..pi"),
        ("gps.dat", "0.0 1.0 2.0\n0.5 x 2.0\n", "gps.dat:2:", "not a number"),
        ("inputs.dat", "0.0 1.0 0.0\n0.1 1.0 2.0\n", "inputs.dat:2:", "steering"),
    ],
)
def test_bad_files_name_file_and_line(tmp_path, name, text, where, problem):
    folder = write_folder(tmp_path / "vp", duration=5.0)
    (folder / name).write_text(text)
    with pytest.raises(InputFileError) as err:
        read_victoria_park(folder)
    assert where in str(err.value) and problem in str(err.value)


def test_missing_file_and_window_without_gps(tmp_path):
    folder = write_folder(tmp_path / "vp", duration=5.0)
    (folder / "gps.dat").unlink()
    with pytest.raises(InputFileError, match=r"gps\.dat: no such file \(is this a Victoria Park"):
        read_victoria_park(folder)
    folder = write_folder(tmp_path / "vp2", duration=5.0)
    with pytest.raises(InputFileError, match="no GPS fix"):
        read_victoria_park(folder, start=100.0)


def test_cli_import_and_calibrate_synthetic(tmp_path, capsys):
    folder = write_folder(tmp_path / "vp", duration=40.0)
    out = tmp_path / "vp.jsonl"
    assert main(["import", "victoria-park", str(folder), "-o", str(out), "--minutes", "0.5"]) == 0
    log = read_log_file(out)
    assert log.has_unknown_correspondence and len(log.priors) == 1
    reference = json.loads((tmp_path / "vp.gps.json").read_text())
    assert reference["cuikslam_gps_reference"] == 1 and len(reference["poses"]) == len(log.pose_ids)
    bounds = tmp_path / "b.json"
    code = main([
        "calibrate", "victoria-park", str(folder), "-o", str(bounds), "--duration", "20",
        "--window", "10", "--check-duration", "20", "--gps-error", "0.5",
        "--window-heading", "0.02",
    ])  # fmt: skip
    assert code == 0
    values = read_bounds_file(bounds, "victoria-park", VictoriaParkBounds.names())
    assert values["steering"] <= VictoriaParkBounds().steering  # exact readings: small margins
    assert "checked on 20..40 s: 2 of 2 windows hold" in capsys.readouterr().err
    again = tmp_path / "again.jsonl"
    assert (
        main(
            [
                "import",
                "victoria-park",
                str(folder),
                "-o",
                str(again),
                "--bounds",
                str(bounds),
                "-q",
            ]
        )
        == 0
    )


def test_real_first_five_minutes_import():
    folder = _real_folder()
    log, reference = read_victoria_park(folder, duration=300.0, keyframe=1.0, max_range=30.0)
    assert 250 <= len(log.pose_ids) <= 320 and len(log.relative_poses) == len(log.pose_ids) - 1
    assert len(log.observations) > 1000 and log.has_unknown_correspondence
    assert {o.landmark_class for o in log.observations} == {"tree"}
    assert all(o.range[1] < 31.0 for o in log.observations)
    assert len(reference.pose_ids) > 100
    # the first pose's box holds the rear axle under the first GPS fix (the car stands still)
    prior = log.priors[0]
    x, y, _ = compose_relative(
        [(prior.x, prior.y, prior.theta), ((LASER_A,) * 2, (LASER_B,) * 2, (0.0, 0.0))]
    )
    g = reference.xy[0]
    assert x[0] <= g[0] <= x[1] and y[0] <= g[1] <= y[1]


def test_scan_consistency_of_exact_readings(tmp_path):
    from cuikslam.datasets.victoria_park_calibrate import scan_consistency
    from cuikslam.datasets.victoria_park_files import read_victoria_park_tables

    tables = read_victoria_park_tables(write_folder(tmp_path / "vp", duration=10.0))
    found = scan_consistency(tables, 0.0, 10.0)
    assert found["pairs"] > 20
    assert found["range_max"] < 0.01 and found["bearing_max"] < 1e-3
