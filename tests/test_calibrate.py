"""``cuikslam calibrate``: bounds measured on a part of a run hold on that part; their file
round-trips into the importer; bad bounds files are refused in one line."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, replace
from pathlib import Path

import pytest

from cuikslam.cli.main import main
from cuikslam.datasets.calibrate import (
    calibrate_mrclam,
    count_outside,
    read_bounds_file,
    write_bounds_file,
)
from cuikslam.datasets.mrclam import MrclamBounds
from cuikslam.datasets.mrclam_files import read_mrclam_tables
from cuikslam.errors import InputFileError
from test_mrclam import _real, write_dataset


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("mrclam") / "d", duration=30.0)


def test_calibrated_bounds_hold_every_measurement_of_their_part(folder: Path) -> None:
    base = replace(MrclamBounds(), range=0.0)  # the range bound all relative
    calibration = calibrate_mrclam(folder, 1, duration=15.0, base=base)
    # The synthetic ranges err by 0.05 sin(k) and bearings by 0.03 cos(k) (k = 0, 1, ...).
    assert calibration.errors["bearing"]["max"] <= calibration.bounds.bearing < 0.0301
    needed = calibration.errors["range_per_metre_needed"]["max"]
    assert 0 < needed <= calibration.bounds.range_per_metre < needed * 1.01
    assert calibration.bounds.range == 0.0
    outside = calibration.outside
    assert outside.observations_checked > 10 and outside.moves_checked >= 20
    assert (outside.ranges, outside.bearings, outside.moves) == (0, 0, 0)
    # Checked on the rest of the run: some sightings err more there, each one listed.
    later = count_outside(folder, 1, calibration.bounds, start=15.0)
    assert later.observations_checked > 10 and later.ranges + later.bearings > 0
    assert len(later.details) == later.ranges + later.bearings + later.moves


def test_a_quantile_below_one_leaves_that_share_outside(folder: Path) -> None:
    tables = read_mrclam_tables(folder, 1)
    base = replace(MrclamBounds(), range=0.0)
    calibration = calibrate_mrclam(tables, 1, quantile=0.8, base=base)
    outside = calibration.outside
    assert 0 < outside.ranges <= math.ceil(0.2 * outside.observations_checked)
    full = calibrate_mrclam(tables, 1, base=base)
    assert calibration.bounds.range_per_metre < full.bounds.range_per_metre


def test_the_bounds_file_round_trips_into_the_importer(folder: Path, tmp_path: Path) -> None:
    calibration = calibrate_mrclam(folder, 1, duration=15.0)
    path = tmp_path / "bounds.json"
    write_bounds_file(calibration, path)
    assert read_bounds_file(path) == asdict(calibration.bounds)
    out = tmp_path / "r.jsonl"
    args = ["import", "mrclam", str(folder), "--robot", "1", "-o", str(out), "-q"]
    assert main([*args, "--bounds", str(path)]) == 0
    from cuikslam.log import read_log_file

    obs = read_log_file(out).observations[5]
    assert obs.bearing[1] - obs.bearing[0] == pytest.approx(2 * calibration.bounds.bearing)
    assert main([*args, "--bounds", str(path), "--bearing-bound", "0.2"]) == 0  # overrides
    obs = read_log_file(out).observations[5]
    assert obs.bearing[1] - obs.bearing[0] == pytest.approx(0.4)


def test_cli_calibrates_and_checks(folder: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "b.json"
    args = ["calibrate", "mrclam", str(folder), "--robot", "1", "--duration", "15", "-o", str(out)]
    assert main([*args, "--check-start", "15"]) == 0
    err = capsys.readouterr().err
    assert "the calibration part: 0 ranges and 0 bearings" in err and "checked on robot 1" in err
    doc = json.loads(out.read_text())
    assert doc["calibrated_on"]["checked_on"]["start"] == 15.0
    assert main([*args, "--quantile", "2"]) == 2
    assert "--quantile 2.0: must be at most 1" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("doc", "problem"),
    [
        ("{", "malformed JSON"),
        ('{"bounds": {}}', "not a cuikslam bounds file"),
        ('{"cuikslam_bounds": 1, "dataset": "woods", "bounds": {}}', "bounds of dataset 'woods'"),
        ('{"cuikslam_bounds": 1, "dataset": "mrclam", "bounds": {"rnge": 1}}', "unknown bound"),
        ('{"cuikslam_bounds": 1, "dataset": "mrclam", "bounds": {"range": -1}}', "finite and >= 0"),
        (
            '{"cuikslam_bounds": 1, "dataset": "mrclam", "bounds": {"range": "1"}}',
            "must be a number",
        ),
    ],
)
def test_bad_bounds_files_are_refused(
    folder: Path, tmp_path: Path, capsys, doc: str, problem: str
) -> None:
    path = tmp_path / "bounds.json"
    path.write_text(doc)
    with pytest.raises(InputFileError, match=problem):
        read_bounds_file(path)
    out = tmp_path / "r.jsonl"
    assert main(["import", "mrclam", str(folder), "--robot", "1", "-o", str(out),
                 "--bounds", str(path)]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "bounds.json" in err and problem in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.slow
def test_real_robot_1_first_half_bounds_on_the_second_half() -> None:
    calibration = calibrate_mrclam(_real(), 1, duration=370.0)
    assert (calibration.outside.ranges, calibration.outside.bearings) == (0, 0)
    assert calibration.outside.moves == 0
    later = count_outside(_real(), 1, calibration.bounds, start=370.0)
    # measured: 5 of 934 ranges, no bearing and no move outside
    assert later.observations_checked > 900 and later.ranges + later.bearings < 20


def test_check_lists_what_misses_the_truth(folder: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "r.jsonl"
    args = ["import", "mrclam", str(folder), "--robot", "1", "-o", str(out), "-q"]
    assert main([*args, "--bearing-bound", "0.001"]) == 0  # the bearings err by 0.03 cos k
    report = tmp_path / "check.json"
    truth = str(tmp_path / "r.truth.json")
    assert main(["calibrate", "check", str(out), "--truth", truth, "--json", str(report)]) == 0
    printed = capsys.readouterr().out
    doc = json.loads(report.read_text())
    assert doc["ranges_outside"] == 0 and doc["moves_outside"] == 0
    assert doc["bearings_outside"] == len(doc["outside_observations"]) > 20
    assert f"0 ranges and {doc['bearings_outside']} bearings of" in printed
    assert "bearing misses" in doc["details"][0] and "(line " in doc["details"][0]
    (tmp_path / "short.truth.json").write_text(
        json.dumps({**json.loads(Path(truth).read_text()), "assignment": []})
    )
    short = ["calibrate", "check", str(out), "--truth", str(tmp_path / "short.truth.json")]
    assert main(short) == 2
    assert "assigns 0 observations" in capsys.readouterr().err
