"""TUM and g2o files and ``cuikslam export``: written, read back, read by evo (no GTSAM needed).

The Gaussians they carry (:mod:`cuikslam.interop.gaussian`) are checked here too; that GTSAM
reads them the right way round is in ``test_interop_gtsam.py``.
"""

from __future__ import annotations

import importlib
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from _small_world import OFFSET, small_world
from cuikslam.errors import InputFileError
from cuikslam.interop.estimate import hypothesis_estimate, truth_estimate
from cuikslam.interop.g2o import g2o_lines, read_g2o_file, write_g2o_file
from cuikslam.interop.gaussian import move_gaussian, reading_gaussian
from cuikslam.interop.tum import read_tum_file, write_tum_file
from cuikslam.log.records import Observation, Odometry, RelativePose
from cuikslam.log.writer import write_log_file
from cuikslam.results.io import write_result_file
from cuikslam.results.solution import OUTLIER
from cuikslam.simulate.truth import write_truth_file
from cuikslam.solver import solve
from test_cli import assert_input_error, listing, run


@pytest.fixture(scope="module")
def solved():
    log, truth = small_world()
    return log, truth, solve(log)


@pytest.fixture(scope="module")
def files(solved, tmp_path_factory) -> Path:
    """A folder with the small world's log, truth and result."""
    log, truth, solution = solved
    folder = tmp_path_factory.mktemp("export")
    write_log_file(log, folder / "small.jsonl")
    write_truth_file(truth, folder / "small.truth.json")
    solution.log_path = str(folder / "small.jsonl")
    write_result_file(solution, folder / "result.json")
    return folder


# --------------------------------------------------------------------------- Gaussians
@pytest.mark.parametrize(
    "record",
    [
        Odometry(0, 1, (0.35, 0.45), (2.9, 3.1)),
        Odometry(0, 1, (-0.01, 0.01), (0.0, 0.0)),  # a turn in place, nothing exact but it
        RelativePose(0, 1, (1.9, 2.1), (0.4, 0.6), (0.2, 0.4)),
    ],
)
def test_move_covariances_are_symmetric_positive_definite(record) -> None:
    cov = move_gaussian(record).covariance
    assert np.array_equal(cov, cov.T)
    assert np.linalg.eigvalsh(cov).min() > 0


def test_odometry_mean_turns_then_drives() -> None:
    g = move_gaussian(Odometry(0, 1, (0.35, 0.45), (2.9, 3.1)))
    assert np.allclose(g.mean, [3 * math.cos(0.4), 3 * math.sin(0.4), 0.4])
    # distance along the new heading, turn across it and in the heading
    assert np.diag(g.covariance)[[0, 2]] == pytest.approx([0.1**2, 0.05**2], rel=1e-2)


def test_relative_pose_errors_are_turned_into_the_target_frame() -> None:
    g = move_gaussian(RelativePose(0, 1, (1.0, 3.0), (-0.1, 0.1), (math.pi / 2, math.pi / 2)))
    # dx (half-width 1) lies across the target turned by 90°, dy (0.1) along it
    assert np.allclose(np.diag(g.covariance), [0.1**2, 1.0, 1e-12])


def test_an_offset_reading_is_read_from_the_robots_centre() -> None:
    log, truth = small_world()
    (seen,) = [o for o in log.observations if o.offset is not None]
    reading = reading_gaussian(seen)
    xyt, point = truth.pose_xyt(seen.pose), truth.landmark_xy("B")
    dx, dy = point - xyt[:2]
    expected = [math.remainder(math.atan2(dy, dx) - xyt[2], 2 * math.pi), math.hypot(dx, dy)]
    assert reading.kind == "bearing-range"
    assert np.allclose(reading.mean, expected, atol=1e-12)
    plain = reading_gaussian(Observation(3, "door", seen.range, seen.bearing))
    # the offset's own errors and its lever arm only add uncertainty
    assert np.linalg.eigvalsh(reading.covariance - plain.covariance).min() > -1e-15
    assert OFFSET[2] != 0


def test_a_one_sided_reading_with_an_offset_is_refused() -> None:
    record = Observation(1, "door", None, (0.1, 0.2), offset=((0.1, 0.1), (0.0, 0.0), (0, 0)))
    with pytest.raises(ValueError, match="bearing-only reading with a sensor offset"):
        reading_gaussian(record)


def test_without_gtsam_the_gtsam_module_says_what_to_install(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "gtsam", None)  # as if it were not installed
    monkeypatch.delitem(sys.modules, "cuikslam.interop.gtsam", raising=False)
    with pytest.raises(ImportError, match=r'pip install "cuikslam\[interop\]"'):
        importlib.import_module("cuikslam.interop.gtsam")


# --------------------------------------------------------------------------- TUM
def test_tum_round_trip_by_pose_id(tmp_path: Path) -> None:
    _, truth = small_world()
    point = truth_estimate(truth)
    path = tmp_path / "truth.txt"
    write_tum_file(point, path, comments=["from a test"])
    text = path.read_text()
    assert text.startswith("# cuikslam trajectory: truth\n") and "# from a test\n" in text
    stamps, poses = read_tum_file(path)
    assert stamps.tolist() == [0.0, 1.0, 2.0, 3.0]
    assert np.allclose(poses, truth.poses_xyt, atol=1e-15)


def test_tum_reader_names_the_bad_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.txt"
    path.write_text("# header\n0 1 2 0 0 0 0 1\n1 1 2 0 0 0 1\n")
    with pytest.raises(InputFileError, match=r"bad.txt:3: expected 'timestamp tx"):
        read_tum_file(path)


def test_evo_reads_the_tum_export(solved, tmp_path: Path) -> None:
    file_interface = pytest.importorskip(
        "evo.tools.file_interface", reason="evo is in the extra (pip install 'cuikslam[interop]')"
    )
    _, _, solution = solved
    write_tum_file(hypothesis_estimate(solution.best), tmp_path / "traj.txt")
    trajectory = file_interface.read_tum_trajectory_file(str(tmp_path / "traj.txt"))
    assert trajectory.num_poses == 4
    assert trajectory.timestamps.tolist() == [0.0, 1.0, 2.0, 3.0]
    witness = solution.best.witness["poses_xyt"]
    assert np.allclose(trajectory.positions_xyz[:, :2], witness[:, :2], atol=1e-12)
    assert np.allclose(trajectory.positions_xyz[:, 2], 0.0)


# --------------------------------------------------------------------------- g2o
def test_g2o_graph_of_the_small_world(solved, tmp_path: Path) -> None:
    log, _, solution = solved
    best = solution.best
    point = hypothesis_estimate(best)
    lines = g2o_lines(log, point, best.assignment)
    tags = [line.split()[0] for line in lines]
    assert tags.count("VERTEX_SE2") == 4 and tags.count("VERTEX_XY") == 2
    assert tags.count("EDGE_SE2") == 4  # 3 odometry steps, 1 relative pose
    assert tags.count("EDGE_SE2_XY") == 6 and tags.count("EDGE_BEARING_SE2_XY") == 1
    assert tags.count("EDGE_PRIOR_SE2") == 1 and tags.count("EDGE_PRIOR_XY") == 1
    first_comment = tags.index("#")
    assert set(tags[first_comment:]) == {"#"}  # GTSAM's readG2o stops at a comment
    assert "# left out: range-only observation at pose 2 of A" in lines
    assert "# landmarks are vertices 4..5: A=4, B=5" in lines

    path = tmp_path / "graph.g2o"
    write_g2o_file(log, point, best.assignment, path)
    graph = read_g2o_file(path)
    assert graph.vertices[1].tolist() == point.poses_xyt[1].tolist()
    assert graph.vertices[5].tolist() == point.landmarks_xy[1].tolist()
    step = next(e for e in graph.edges if e[0] == "EDGE_SE2" and e[1] == (0, 1))
    expected = move_gaussian(log.odometry[0])
    assert np.allclose(step[2], expected.mean)
    assert np.allclose(step[3], np.linalg.inv(expected.covariance), rtol=1e-12)


def test_g2o_leaves_out_observations_taken_as_outliers(solved) -> None:
    log, _, solution = solved
    assignment = [OUTLIER, *solution.best.assignment[1:]]
    lines = g2o_lines(log, hypothesis_estimate(solution.best), assignment)
    assert sum(line.startswith("EDGE_SE2_XY 0 ") for line in lines) == 1  # was 2
    assert "# left out: observation at pose 0 taken as an outlier" in lines


def test_g2o_refuses_an_assignment_of_another_log(solved) -> None:
    log, _, solution = solved
    with pytest.raises(ValueError, match="7 observations assigned, the log"):
        g2o_lines(log, hypothesis_estimate(solution.best), solution.best.assignment[:-1])


def test_g2o_reader_names_the_bad_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.g2o"
    path.write_text("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0\n")
    with pytest.raises(InputFileError, match=r"bad.g2o:2: EDGE_SE2 needs 2 vertex"):
        read_g2o_file(path)


# --------------------------------------------------------------------------- cuikslam export
def test_export_tum_of_a_result_and_its_truth(files: Path) -> None:
    result = run("export", "result.json", "--format", "tum", "-o", "traj.txt", cwd=files)
    assert result.returncode == 0, result.stderr
    assert "wrote traj.txt: 4 poses (witness) of hypothesis 1" in result.stderr
    header = (files / "traj.txt").read_text().splitlines()[:3]
    assert header[0] == "# cuikslam trajectory: witness"
    assert header[2] == "# exported from hypothesis 1 (proven consistent) of result.json"
    result = run("export", "small.truth.json", "--format", "tum", "-o", "truth.txt", cwd=files)
    assert result.returncode == 0, result.stderr
    stamps, _ = read_tum_file(files / "truth.txt")
    assert stamps.tolist() == [0.0, 1.0, 2.0, 3.0]
    centres = run(
        "export", "result.json", "--format", "tum", "--point", "centres", "-o", "c.txt", cwd=files
    )
    assert centres.returncode == 0, centres.stderr
    assert (files / "c.txt").read_text().startswith("# cuikslam trajectory: box centres\n")


def test_evo_ape_compares_the_export_with_the_truth(files: Path) -> None:
    evo_ape = shutil.which("evo_ape", path=str(Path(sys.executable).parent))
    if evo_ape is None:
        pytest.skip("evo is in the extra (pip install 'cuikslam[interop]')")
    for name, out in (("result.json", "a.txt"), ("small.truth.json", "t.txt")):
        assert run("export", name, "--format", "tum", "-o", out, cwd=files).returncode == 0
    ape = subprocess.run(
        [evo_ape, "tum", "t.txt", "a.txt"], cwd=files, capture_output=True, text=True,
        timeout=120, check=False,
    )  # fmt: skip
    assert ape.returncode == 0, ape.stderr
    rmse = float(next(line.split()[1] for line in ape.stdout.splitlines() if "rmse" in line))
    # the witness satisfies every interval of a log centred on the truth: it is near it
    assert 0 <= rmse < 0.5


def test_export_g2o_reads_the_log_the_result_names(files: Path) -> None:
    result = run("export", "result.json", "--format", "g2o", "-o", "graph.g2o", cwd=files)
    assert result.returncode == 0, result.stderr
    graph = read_g2o_file(files / "graph.g2o")
    # 2 priors, 4 moves, 8 readings but the range-only one (no slam2d edge)
    assert len(graph.vertices) == 6 and len(graph.edges) == 13
    truth = run(
        "export", "small.truth.json", "--format", "g2o", "--log", "small.jsonl",
        "-o", "truth.g2o", cwd=files,
    )  # fmt: skip
    assert truth.returncode == 0, truth.stderr
    assert read_g2o_file(files / "truth.g2o").vertices[4].tolist() == [7.0, 5.0]


@pytest.mark.parametrize(
    "args, fragments",
    [
        (["missing.json", "--format", "tum", "-o", "x.txt"], ["missing.json", "cannot read"]),
        (["small.jsonl", "--format", "tum", "-o", "x.txt"], ["small.jsonl", "malformed JSON"]),
        (["result.json", "--format", "tum", "-o", "no/x.txt"], ["no/x.txt", "does not exist"]),
        (["result.json", "--format", "tum", "--hypothesis", "3", "-o", "x.txt"],
         ["result.json", "--hypothesis 3", "reports 1"]),
        (["small.truth.json", "--format", "g2o", "-o", "x.g2o"], ["small.truth.json", "--log"]),
        (["result.json", "--format", "g2o", "--log", "nothere.jsonl", "-o", "x.g2o"],
         ["nothere.jsonl"]),
    ],
)  # fmt: skip
def test_export_bad_input_says_one_line_and_writes_nothing(files: Path, args, fragments) -> None:
    before = listing(files)
    assert_input_error(run("export", *args, cwd=files), *fragments)
    assert listing(files) == before


def test_export_g2o_of_a_result_of_another_log(files: Path, tmp_path: Path) -> None:
    other, _ = small_world()
    other.records = [r for r in other.records if not isinstance(r, Observation) or r.pose != 0]
    write_log_file(other, tmp_path / "other.jsonl")
    result = run(
        "export", files / "result.json", "--format", "g2o", "--log", "other.jsonl",
        "-o", "x.g2o", cwd=tmp_path,
    )  # fmt: skip
    assert_input_error(result, "does not fit the log other.jsonl", "observations assigned")
    assert not (tmp_path / "x.g2o").exists()


def test_export_loads_no_heavy_package(files: Path, tmp_path: Path) -> None:
    from test_startup import loaded_after

    out = tmp_path / "graph.g2o"
    code = (
        "from cuikslam.cli.main import main\n"
        f"main(['export', {str(files / 'result.json')!r}, '--format', 'g2o', '-o', {str(out)!r}])"
    )
    assert loaded_after(code) == []
    assert out.is_file()
