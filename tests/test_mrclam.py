"""The MRCLAM importer: on small synthetic dataset folders the tests write, and on the real one."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cuikslam.cli.main import main
from cuikslam.datasets import data_dir
from cuikslam.datasets.mrclam import MrclamBounds, read_mrclam
from cuikslam.datasets.mrclam_files import keyframe_times, lagged_command_hulls, velocity_steps
from cuikslam.errors import InputFileError

T0 = 1248444187.0
HEADER = "# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset\n# synthetic\n#\n#\n"
V, W = 0.2, 0.15  # the true forward and angular velocity of robot 1 (a circle)
LANDMARKS = {6: (3.0, 1.0), 7: (-1.0, 3.5), 8: (0.5, 4.5)}
BARCODES = {1: 5, 2: 14, 3: 41, 4: 32, 5: 23, 6: 63, 7: 81, 8: 7}


def true_pose(t: np.ndarray | float) -> np.ndarray:
    """Robot 1 drives a circle from (0, 0) heading 0."""
    th = W * (np.asarray(t, dtype=float) - T0)
    return np.stack([V / W * np.sin(th), V / W * (1 - np.cos(th)), th], axis=-1)


def other_pose(t: np.ndarray | float) -> np.ndarray:
    """Robot 2 stands still at (2, -1)."""
    t = np.asarray(t, dtype=float)
    return np.stack([2.0 + 0 * t, -1.0 + 0 * t, 0 * t], axis=-1)


def _table(rows: list[list[float]], fmt: str) -> str:
    return HEADER + "".join(fmt.format(*row) + "\n" for row in rows)


def write_dataset(folder: Path, *, duration: float = 20.0, vicon_gap: tuple | None = None) -> Path:
    """A MRCLAM-format folder: robot 1 (commands jittering around its true velocities,
    measurements of landmarks, of robot 2, of an unknown barcode, and a duplicate), robot 2."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "Barcodes.dat").write_text(_table([[s, b] for s, b in BARCODES.items()], "{} {}"))
    (folder / "Landmark_Groundtruth.dat").write_text(
        _table([[s, x, y, 0.0, 0.0] for s, (x, y) in LANDMARKS.items()], "{} {} {} {} {}")
    )
    cmd_t = T0 + np.round(np.arange(0, duration, 1 / 67), 3)
    jitter = 0.03 * np.sin(np.arange(cmd_t.size))  # within the 0.07 m/s and 0.5 rad/s bounds
    (folder / "Robot1_Odometry.dat").write_text(
        _table(
            [[t, V + j, W - 2 * j] for t, j in zip(cmd_t, jitter, strict=True)],
            "{:.3f} {:.6f} {:.6f}",
        )
    )
    gt_t = T0 + np.round(np.arange(0, duration + 0.5, 0.01), 3)
    if vicon_gap is not None:
        gt_t = gt_t[(gt_t < T0 + vicon_gap[0]) | (gt_t > T0 + vicon_gap[1])]
    (folder / "Robot1_Groundtruth.dat").write_text(
        _table([[t, *true_pose(t)] for t in gt_t], "{:.3f} {:.17g} {:.17g} {:.17g}")
    )
    (folder / "Robot2_Groundtruth.dat").write_text(
        _table([[t, *other_pose(t)] for t in gt_t], "{:.3f} {:.17g} {:.17g} {:.17g}")
    )
    rows = []
    for k, t in enumerate(T0 + np.arange(0.5, duration - 0.5, 0.7).round(3)):
        pose = true_pose(t)
        subjects = [6 + k % 3, 2] if k % 2 else [6 + k % 3]
        for s in subjects:
            xy = LANDMARKS[s] if s in LANDMARKS else other_pose(t)[:2]
            dx, dy = xy[0] - pose[0], xy[1] - pose[1]
            rng = math.hypot(dx, dy) + 0.05 * math.sin(k)
            bearing = math.remainder(math.atan2(dy, dx) - pose[2], 2 * math.pi)
            rows.append([t, BARCODES[s], rng, bearing + 0.03 * math.cos(k)])
        if k == 3:
            rows.append([t, 99, 2.0, 0.1])  # a barcode in no table
            rows.append([t, BARCODES[6 + k % 3], 2.0, 0.1])  # a second detection
    (folder / "Robot1_Measurement.dat").write_text(_table(rows, "{:.3f} {} {:.17g} {:.17g}"))
    return folder


def _inside(value: float, box: tuple[float, float]) -> bool:
    return box[0] <= value <= box[1]


def _relative(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return c * dx + s * dy, -s * dx + c * dy, b[2] - a[2]


def test_every_interval_holds_the_exact_truth(tmp_path: Path) -> None:
    log, truth, report = read_mrclam(write_dataset(tmp_path / "d"), 1, keyframe_gap=0.5)
    # The window starts 1 s (the lag) after the first command: the first image is left out.
    assert report.dropped == {
        "barcodes in no table": 1,
        "outside the window": 1,
        "second detections of a subject in one image": 1,
        "sightings of other robots": 14,
    }
    assert report.kept == len(log.observations) == 27 and report.measurements == 44
    # Pose times: the start, the measurement times (1.2 s, then every 0.7 s), and one
    # fill-in between two measurements (gaps of at most 0.5 s).
    assert report.poses == len(truth.pose_ids) == 2 + 2 * 26
    exact = {p: true_pose(T0 + (1.2 + 0.35 * (p - 1) if p else 1.0)) for p in truth.pose_ids}
    for p, xyt in zip(truth.pose_ids, truth.poses_xyt, strict=True):
        assert np.allclose(xyt, exact[p], atol=1e-6)  # Vicon interpolated at the pose time
    prior = log.priors[0]
    assert _inside(exact[0][0], prior.x) and _inside(exact[0][2], prior.theta)
    assert len(log.relative_poses) == report.poses - 1
    for move in log.relative_poses:
        dx, dy, dth = _relative(exact[move.source], exact[move.target])
        assert _inside(dx, move.dx) and _inside(dy, move.dy) and _inside(dth, move.dtheta)
    for obs, lid in zip(log.observations, truth.assignment, strict=True):
        assert obs.landmark == lid and obs.landmark_class == "landmark"
        p, mark = exact[obs.pose], LANDMARKS[int(lid[1:])]
        rng = math.hypot(mark[0] - p[0], mark[1] - p[1])
        bearing = math.remainder(math.atan2(mark[1] - p[1], mark[0] - p[0]) - p[2], 2 * math.pi)
        assert _inside(rng, obs.range) and _inside(bearing, obs.bearing)


def test_robots_kept_as_a_class_and_unknown_ids(tmp_path: Path) -> None:
    log, truth, _ = read_mrclam(write_dataset(tmp_path / "d"), 1, robots="class", unknown=True)
    robots = [o for o in log.observations if o.landmark_class == "robot"]
    assert len(robots) == 14 and len({o.landmark for o in robots}) == 14
    assert all(o.landmark.startswith("R2@") for o in robots)
    landmarks = [o for o in log.observations if o.landmark_class == "landmark"]
    assert landmarks and all(o.landmark is None for o in landmarks)
    for obs, lid in zip(log.observations, truth.assignment, strict=True):
        if obs.landmark_class == "robot":
            assert obs.landmark == lid and np.allclose(truth.landmark_xy(lid), (2.0, -1.0))
    # A robot sighting is named by its row in the file: the same name in any window.
    window, _, _ = read_mrclam(tmp_path / "d", 1, robots="class", start=8.0, duration=5.0)
    named = {o.landmark for o in window.observations if o.landmark_class == "robot"}
    assert named and named <= {o.landmark for o in robots}


def test_a_vicon_gap_leaves_poses_without_truth(tmp_path: Path) -> None:
    _, truth, report = read_mrclam(write_dataset(tmp_path / "d", vicon_gap=(5.0, 6.0)), 1)
    missing = sorted(set(range(report.poses)) - set(truth.pose_ids))
    assert report.poses_without_truth == len(missing) > 0
    times = keyframe_times(np.arange(0.5, 19.5, 0.7).round(3) + T0, report.start, report.end, 1.0)
    assert all(5.0 < times[p] - T0 < 6.0 for p in missing)


def test_a_window(tmp_path: Path) -> None:
    _, truth, report = read_mrclam(write_dataset(tmp_path / "d"), 1, start=5.0, duration=5.0)
    assert report.start == T0 + 5.0 and report.end <= T0 + 10.0
    assert report.dropped["outside the window"] > 0
    assert truth.pose_ids[0] == 0 and np.allclose(truth.poses_xyt[0], true_pose(T0 + 5.0))


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: (d / "Robot1_Odometry.dat").unlink(), "Robot1_Odometry.dat: no such file"),
        (
            lambda d: _append(d / "Robot1_Measurement.dat", "1248444300.000 63 2.0\n"),
            "Robot1_Measurement.dat:9: expected 4 numbers, got 3",
        ),
        (
            lambda d: _append(d / "Robot1_Odometry.dat", "1248444100.000 0.1 0.1\n"),
            "time 1248444100.000 goes back",
        ),
        (
            lambda d: _append(d / "Barcodes.dat", "9 1.5\n"),
            "Barcodes.dat:13: barcode 1.5 is not an integer",
        ),
        (lambda d: _append(d / "Robot1_Groundtruth.dat", "x 1 2 3\n"), "not a number in 'x 1 2 3'"),
    ],
)
def test_bad_files_name_file_and_line(tmp_path: Path, capsys, edit, message: str) -> None:
    folder = write_dataset(tmp_path / "d", duration=3.0)
    edit(folder)
    with pytest.raises(InputFileError, match=re.escape(message)):
        read_mrclam(folder, 1)
    out = tmp_path / "r.jsonl"
    assert main(["import", "mrclam", str(folder), "--robot", "1", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists() and not (tmp_path / "r.truth.json").exists()


def _append(path: Path, text: str) -> None:
    path.write_text(path.read_text() + text)


def test_cli_writes_log_and_truth_that_read_back(tmp_path: Path, capsys) -> None:
    from cuikslam.log import read_log_file
    from cuikslam.simulate.truth import read_truth_file

    folder = write_dataset(tmp_path / "d")
    out = tmp_path / "r.jsonl"
    args = ["import", "mrclam", str(folder), "--robot", "1", "-o", str(out), "--range-bound", "0.3",
            "--range-per-metre-bound", "0"]  # fmt: skip
    assert main(args) == 0
    assert "27 of 44 measurements kept" in capsys.readouterr().err
    log = read_log_file(out)
    truth = read_truth_file(tmp_path / "r.truth.json")
    assert len(truth.assignment) == len(log.observations) == 27
    assert all(o.range[1] - o.range[0] == pytest.approx(0.6) for o in log.observations)
    assert main([*args[:-4], "--start", "100"]) == 2
    assert "holds no command" in capsys.readouterr().err


def test_velocity_steps_clip_the_commands() -> None:
    odometry = np.array([[0.0, 1.0, 0.0], [1.0, 2.0, 0.5], [3.0, 3.0, -0.5]])
    rows, times = velocity_steps(odometry, 0.5, 3.5)
    assert rows.tolist() == [0, 1, 2]
    assert times.tolist() == [0.5, 1.0, 3.0, 3.5]
    rows, times = velocity_steps(odometry, 1.0, 2.0)
    assert rows.tolist() == [1] and times.tolist() == [1.0, 2.0]
    rows, times = velocity_steps(odometry, 0.5, 3.0)
    assert rows.tolist() == [0, 1] and times.tolist() == [0.5, 1.0, 3.0]
    with pytest.raises(ValueError, match="no command before"):
        velocity_steps(odometry, -1.0, 2.0)


def _real() -> Path:
    folder = data_dir()
    path = folder / "mrclam-6" if folder else None
    if path is None or not (path / "Robot1_Odometry.dat").is_file():
        pytest.skip("MRCLAM dataset 6 not found: set CUIKSLAM_DATA to the folder holding mrclam-6/")
    return path


def test_real_robot_1_moves_and_landmark_sightings_hold_the_vicon_truth() -> None:
    log, truth, report = read_mrclam(_real(), 1)
    assert report.dropped["sightings of other robots"] == 407
    pose = dict(zip(truth.pose_ids, truth.poses_xyt, strict=True))
    moves = [m for m in log.relative_poses if m.source in pose and m.target in pose]
    assert len(moves) > 1500
    misses = 0
    for move in moves:
        dx, dy, dth = _relative(pose[move.source], pose[move.target])
        misses += not (_inside(dx, move.dx) and _inside(dy, move.dy) and _inside(dth, move.dtheta))
    assert misses <= 2  # measured with the default bounds: 2 moves miss by < 3 mm
    misses = 0
    for obs, lid in zip(log.observations, truth.assignment, strict=True):
        p, mark = pose.get(obs.pose), truth.landmark_xy(lid)
        if p is None:
            continue
        rng = math.hypot(mark[0] - p[0], mark[1] - p[1])
        bearing = math.remainder(math.atan2(mark[1] - p[1], mark[0] - p[0]) - p[2], 2 * math.pi)
        misses += not (_inside(rng, obs.range) and _inside(bearing, obs.bearing))
    assert misses == 0  # robot 1 has no gross outlier (robots 3 and 5 have)


def test_real_bounds_are_checked() -> None:
    with pytest.raises(ValueError, match="bound range must be a finite number >= 0"):
        MrclamBounds(range=-1.0)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.tuples(st.floats(0.001, 0.5), st.floats(-1, 1), st.floats(-1, 1)), min_size=1),
    st.floats(0.0, 2.0),
)
def test_lagged_hulls_are_the_commands_in_force_within_the_lag(rows, lag: float) -> None:
    t = np.cumsum([0.0] + [r[0] for r in rows[:-1]])
    odometry = np.column_stack((t, [r[1] for r in rows], [r[2] for r in rows]))
    hulls = lagged_command_hulls(odometry, lag)
    for i in range(len(t)):
        ends = np.append(t[1:], np.inf)
        force = [j for j in range(i + 1) if ends[j] > t[i] - lag]
        assert force  # the command itself is always in force
        v, w = odometry[force, 1], odometry[force, 2]
        assert hulls[i].tolist() == [v.min(), v.max(), w.min(), w.max()]


def test_tables_read_fast_and_slow_agree(tmp_path: Path) -> None:
    from cuikslam.datasets.mrclam_files import read_table_lines

    path = tmp_path / "t.dat"
    path.write_text("# a\n# b\n1.0 2 3\n\n2.5 -1 4e-3  # remark\n")
    table, lines = read_table_lines(path, 3)
    assert table.tolist() == [[1.0, 2.0, 3.0], [2.5, -1.0, 0.004]] and lines == [3, 5]
    path.write_text("# a\n1.0 2 3\n0.5 nan 3\n")
    with pytest.raises(InputFileError, match=r"t\.dat:3: a number is not finite"):
        read_table_lines(path, 3)
    path.write_text("# only a header\n")
    with pytest.raises(InputFileError, match="holds no data lines"):
        read_table_lines(path, 3)


def test_other_robots_vicon_is_read_only_when_kept(tmp_path: Path) -> None:
    folder = write_dataset(tmp_path / "d", duration=3.0)
    (folder / "Robot2_Groundtruth.dat").write_text("garbage\n")
    read_mrclam(folder, 1)  # robots dropped: robot 2's file is never read
    with pytest.raises(InputFileError, match=r"Robot2_Groundtruth\.dat:1"):
        read_mrclam(folder, 1, robots="class")


@pytest.mark.slow
def test_real_default_bounds_leave_only_the_documented_outliers() -> None:
    from cuikslam.results.measurement_check import check_log

    folder = _real()
    found = {r: check_log(*read_mrclam(folder, r)[:2]) for r in range(1, 6)}
    # docs/real-data.md: 5 ranges and 9 bearings of 15,365 sightings, 2 of 11,966 moves
    assert sum(f.observations_checked for f in found.values()) == 15365
    assert sum(f.ranges for f in found.values()) == 5
    assert sum(f.bearings for f in found.values()) == 9
    assert sum(f.moves for f in found.values()) == 2


def test_the_surveyed_map_becomes_landmark_records_that_the_search_matches(tmp_path) -> None:
    """``map_bound``: each surveyed landmark's box holds its position with the bound's
    half-width; with the ids dropped the search matches every sighting to a surveyed
    landmark, and the true association survives."""
    from cuikslam import SolveOptions, solve
    from cuikslam.results.association import rank_of

    log, truth, _ = read_mrclam(write_dataset(tmp_path / "d"), 1, unknown=True, map_bound=0.02)
    priors = {p.landmark: p for p in log.landmark_priors}
    assert set(priors) == {f"L{s}" for s in LANDMARKS}
    for s, (x, y) in LANDMARKS.items():
        box = priors[f"L{s}"]
        assert _inside(x, box.x) and _inside(y, box.y)
        assert box.x[1] - box.x[0] == pytest.approx(0.04, rel=1e-9)
    solution = solve(log, SolveOptions(consistency="hull", work_budget=4e7))
    assert solution.complete
    assert rank_of(solution.hypotheses, truth.assignment) is not None
    assert all(a in priors for h in solution.hypotheses for a in h.assignment)
