"""``outliers`` records from the command line and in the log reader: one clear line with
file and line for a bad record, the proven outliers listed by ``solve``, counted truth by
``evaluate``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cuikslam.errors import InputFileError
from cuikslam.log import parse_log_lines
from cuikslam.log.writer import log_to_lines
from test_cli import assert_input_error, run

PRIOR = '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}'
MARK = '{"type": "landmark", "id": "A", "class": "post", "x": [4.9, 5.1], "y": [-0.1, 0.1]}'
MOVE = '{"type": "odometry", "from": 0, "to": 1, "turn": [-0.01, 0.01], "distance": [1, 1.1]}'


def sighting(pose: int, lo: float, hi: float) -> str:
    return (
        f'{{"type": "observation", "pose": {pose}, "class": "post", "landmark": "A", '
        f'"range": [{lo}, {hi}], "bearing": [-0.05, 0.05]}}'
    )


@pytest.mark.parametrize(
    ("record", "fragment"),
    [
        ('{"type": "outliers"}', 'outliers record is missing field "at_most"'),
        ('{"type": "outliers", "at_most": -1}', 'field "at_most" must be a whole number >= 0'),
        ('{"type": "outliers", "at_most": 1.0}', 'field "at_most" must be a whole number >= 0'),
        ('{"type": "outliers", "at_most": true}', 'field "at_most" must be a whole number >= 0'),
        ('{"type": "outliers", "at_most": 1, "window": 0}', 'field "window" must be a whole'),
        ('{"type": "outliers", "at_most": 1, "window": "5"}', 'field "window" must be a whole'),
        ('{"type": "outliers", "at_most": 1, "windows": 5}', 'did you mean "window"?'),
    ],
)
def test_a_bad_outliers_record_names_file_and_line(record: str, fragment: str) -> None:
    with pytest.raises(InputFileError) as caught:
        parse_log_lines([PRIOR, record], path="trip.jsonl")
    assert str(caught.value).startswith("trip.jsonl:2: ")
    assert fragment in str(caught.value)


@pytest.mark.parametrize("window", ["", ', "window": 4'])
def test_a_second_declaration_of_one_scope_is_refused(window: str) -> None:
    one = f'{{"type": "outliers", "at_most": 1{window}}}'
    with pytest.raises(InputFileError, match=r"trip\.jsonl:3: a second outliers record .* line 2"):
        parse_log_lines([PRIOR, one, one], path="trip.jsonl")


def test_one_declaration_per_scope_reads_and_writes_back() -> None:
    lines = [
        PRIOR,
        '{"type": "outliers", "at_most": 3}',
        '{"type": "outliers", "at_most": 1, "window": 20, "time": 4.5}',
    ]
    log = parse_log_lines(lines)
    assert [(b.at_most, b.window, b.line) for b in log.outlier_bounds] == [(3, None, 2), (1, 20, 3)]
    assert log_to_lines(log)[1:] == [
        '{"type": "outliers", "at_most": 3}',
        '{"type": "outliers", "at_most": 1, "window": 20, "time": 4.5}',
    ]


def _write(folder: Path, *lines: str) -> Path:
    path = folder / "trip.jsonl"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_solve_lists_the_proven_outlier_and_evaluate_counts_the_truth(tmp_path: Path) -> None:
    _write(
        tmp_path,
        PRIOR,
        '{"type": "outliers", "at_most": 1}',
        MARK,
        MOVE,
        sighting(0, 4.8, 5.2),
        sighting(1, 9.0, 9.5),
    )
    truth = {
        "poses": {"0": [0, 0, 0], "1": [1.05, 0, 0]},
        "landmarks": {"A": {"class": "post", "x": 5, "y": 0}},
        "assignment": ["A", "A"],
    }
    (tmp_path / "trip.truth.json").write_text(json.dumps(truth), encoding="utf-8")
    result = run("solve", "trip.jsonl", "--json", "r.json", "--consistency", "hull", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "declared outliers: at most 1 in all; 1 observation(s) proven" in result.stdout
    assert "outlier: line 6, pose 1 sees A" in result.stdout
    document = json.loads((tmp_path / "r.json").read_text(encoding="utf-8"))
    assert document["outliers"]["proven"] == [
        {"observation": 1, "line": 6, "pose": 1, "landmark": "A"}
    ]
    assert document["outliers"]["declared"] == [{"at_most": 1, "window": None, "line": 2}]
    evaluated = run(
        "evaluate", "r.json", "--truth", "trip.truth.json", "--json", "e.json", cwd=tmp_path
    )
    assert evaluated.returncode == 0, evaluated.stderr
    figures = json.loads((tmp_path / "e.json").read_text(encoding="utf-8"))
    assert figures["guarantee_held"] is True
    assert (figures["poses"]["inside"], figures["landmarks"]["inside"]) == (2, 1)
    assert figures["notes"][0].startswith("the log declares outliers (at most 1 in all) and 1 were")


def test_more_outliers_than_declared_exits_1(tmp_path: Path) -> None:
    _write(tmp_path, PRIOR, '{"type": "outliers", "at_most": 0}', MARK, sighting(0, 9.0, 9.5))
    result = run("solve", "trip.jsonl", "--consistency", "hull", cwd=tmp_path)
    assert result.returncode == 1
    assert "inconsistent with its outliers declaration (at most 0 in all)" in result.stdout


def test_outlier_named_landmark_with_unknown_correspondence_exit_2(tmp_path: Path) -> None:
    """With unknown correspondence "outlier" marks outliers in assignments: a landmark of
    that name is refused, naming its line."""
    _write(
        tmp_path,
        PRIOR,
        '{"type": "outliers", "at_most": 1}',
        '{"type": "observation", "pose": 0, "class": "post", "range": [2, 2.1]}',
        '{"type": "observation", "pose": 0, "class": "post", "range": [3, 3.1], '
        '"landmark": "outlier"}',
    )
    result = run("solve", "trip.jsonl", cwd=tmp_path)
    assert_input_error(result, "trip.jsonl:4:", 'landmark id "outlier" is reserved')


def test_outlier_named_landmark_is_refused_in_any_log(tmp_path: Path) -> None:
    """Without an outliers record and with known correspondence too: the witness search and
    the fit leave out observations marked "outlier", so a landmark of that name was proven
    consistent without its constraints (found by an adversarial helper)."""
    _write(
        tmp_path,
        PRIOR,
        '{"type": "observation", "pose": 0, "class": "post", "range": [2, 2.1], '
        '"bearing": [0, 0.1], "landmark": "A"}',
        '{"type": "landmark", "id": "outlier", "class": "post", "x": [1, 2], "y": [0, 1]}',
    )
    result = run("solve", "trip.jsonl", "--json", "out.json", cwd=tmp_path)
    assert_input_error(result, "trip.jsonl:3:", 'landmark id "outlier" is reserved')
    assert not (tmp_path / "out.json").exists()


def test_a_log_built_in_code_with_the_reserved_id_is_refused_by_solve() -> None:
    from cuikslam.log.records import LandmarkPrior, Log, PosePrior
    from cuikslam.solver import solve

    log = Log(
        records=[
            PosePrior(pose=0, x=(0.0, 0.0), y=(0.0, 0.0), theta=(0.0, 0.0), line=1),
            LandmarkPrior(landmark="outlier", landmark_class="post", x=(1.0, 2.0),
                          y=(0.0, 1.0), line=2),
        ]
    )  # fmt: skip
    with pytest.raises(InputFileError, match='landmark id "outlier" is reserved'):
        solve(log, work_budget=3.5e6)


def test_a_bad_outliers_record_exits_2(tmp_path: Path) -> None:
    _write(tmp_path, PRIOR, '{"type": "outliers", "at_most": -2}')
    result = run("solve", "trip.jsonl", cwd=tmp_path)
    assert_input_error(result, "trip.jsonl:2:", '"at_most" must be a whole number >= 0')


def test_every_key_of_the_outliers_is_documented() -> None:
    import re

    from cuikslam.results.io import solution_to_json
    from cuikslam.solver import solve
    from test_result_doc import DOC, _keys

    log = parse_log_lines(
        [PRIOR, '{"type": "outliers", "at_most": 1}', MARK, MOVE, sighting(1, 9.0, 9.5)]
    )
    document = solution_to_json(solve(log, consistency="hull", work_budget=None))
    assert document["outliers"]["proven"]  # every key of a proven outlier is seen
    named = set(re.findall(r"[`\"]([a-z_]+)[`\"]", DOC.read_text(encoding="utf-8")))
    keys = _keys({"outliers": document["outliers"], "statistics": document["statistics"]})
    assert "outliers_proven" in keys
    assert keys - named == set()


def test_calibrate_check_says_whether_the_declaration_holds(tmp_path: Path) -> None:
    _write(
        tmp_path,
        PRIOR,
        '{"type": "outliers", "at_most": 1}',
        '{"type": "outliers", "at_most": 0, "window": 1}',
        MARK,
        MOVE,
        sighting(0, 4.8, 5.2),
        sighting(1, 9.0, 9.5),
    )
    truth = {
        "poses": {"0": [0, 0, 0], "1": [1.05, 0, 0]},
        "landmarks": {"A": {"class": "post", "x": 5, "y": 0}},
        "assignment": ["A", "A"],
    }
    (tmp_path / "t.json").write_text(json.dumps(truth), encoding="utf-8")
    result = run(
        "calibrate", "check", "trip.jsonl", "--truth", "t.json", "--json", "c.json", cwd=tmp_path
    )
    assert result.returncode == 0, result.stderr
    assert (
        "declared outliers: at most 1 in all: 1 outside (holds); at most 0 per 1 poses: 1 in "
        "the worst block (BROKEN): the guarantee does not hold"
    ) in result.stdout
    assert json.loads((tmp_path / "c.json").read_text())["declaration_holds"] is False


def test_import_mrclam_declares_outliers(tmp_path: Path, capsys) -> None:
    from cuikslam.cli.main import main
    from cuikslam.log import read_log_file
    from test_mrclam import write_dataset

    folder = write_dataset(tmp_path / "d")
    out = tmp_path / "r.jsonl"
    base = ["import", "mrclam", str(folder), "--robot", "1", "-o", str(out), "-q"]
    assert main([*base, "--outliers", "2", "--outliers-window", "1", "5"]) == 0
    log = read_log_file(out)
    assert [(b.at_most, b.window, b.line) for b in log.outlier_bounds] == [(2, None, 1), (1, 5, 2)]
    from cuikslam.solver import solve

    solution = solve(log, consistency="hull", work_budget=None)  # and it solves with them
    assert solution.outliers["declared"][1] == {"at_most": 1, "window": 5, "line": 2}
    capsys.readouterr()
    assert main([*base, "--unknown", "--outliers", "2"]) == 0  # the search's outlier option
    assert [b.at_most for b in read_log_file(out).outlier_bounds] == [2]
    assert main([*base, "--outliers-window", "1", "0"]) == 2
    assert "W must be at least 1 pose" in capsys.readouterr().err
