"""The ``cuikslam`` command, run as a subprocess: happy paths, bad input, exit statuses.

Contract under test: bad input (a malformed or unreadable file, a bad output path) gives
exactly one line on stderr naming the file (and the line, for a problem in one record),
exit status 2, no traceback, and no output file touched; a result that reports a problem
(an inconsistent log, boxes missing the truth) gives exit status 1.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cuikslam.log.reader import read_log_file

TIMEOUT = 120
CLI = [sys.executable, "-m", "cuikslam.cli.main"]
CSV_HEADER = [
    "hypothesis",
    "kind",
    "id",
    "class",
    "x_lo",
    "x_hi",
    "y_lo",
    "y_hi",
    "theta_lo",
    "theta_hi",
]


def run(*args: object, cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run ``cuikslam ARGS`` in ``cwd``; a non-interactive, wide, colourless run."""
    env = {**os.environ, "COLUMNS": "220", "NO_COLOR": "1", "MPLBACKEND": "Agg"}
    return subprocess.run(
        [*CLI, *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        encoding="utf-8",
        timeout=TIMEOUT,
        env=env,
        check=False,
    )


def assert_input_error(result: subprocess.CompletedProcess[str], *fragments: str) -> str:
    """Exit status 2, one line on stderr holding every fragment, no traceback; the line."""
    assert "Traceback" not in result.stderr, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert result.returncode == 2, (result.returncode, result.stderr)
    line = lines[0]
    assert line.startswith("cuikslam: error: "), line
    for fragment in fragments:
        assert fragment in line, (fragment, line)
    return line


def listing(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too) with its bytes."""
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def load(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def check_bounds(pair: list, where: str) -> None:
    assert isinstance(pair, list) and len(pair) == 2, where
    lo = -math.inf if pair[0] is None else pair[0]
    hi = math.inf if pair[1] is None else pair[1]
    assert isinstance(lo, int | float) and isinstance(hi, int | float), where
    assert lo <= hi, (where, pair)


def check_result_contract(doc: dict, n_observations: int) -> None:
    """The stable keys of a result JSON, with every interval ``lo <= hi``."""
    assert isinstance(doc["complete"], bool)
    assert isinstance(doc["hypotheses"], list) and doc["hypotheses"]
    for h in doc["hypotheses"]:
        assert isinstance(h["assignment"], list) and len(h["assignment"]) == n_observations
        assert all(isinstance(a, str) for a in h["assignment"])
        assert h["poses"]
        for pose_id, box in h["poses"].items():
            int(pose_id)
            for key in ("x", "y", "theta"):
                check_bounds(box[key], f"pose {pose_id} {key}")
        assert set(h["assignment"]) <= set(h["landmarks"])
        for mark_id, box in h["landmarks"].items():
            assert isinstance(box["class"], str) and box["class"], mark_id
            for key in ("x", "y"):
                check_bounds(box[key], f"landmark {mark_id} {key}")


def check_csv(path: Path, doc: dict) -> None:
    with path.open(encoding="utf-8", newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == CSV_HEADER
    expected = sum(len(h["poses"]) + len(h["landmarks"]) for h in doc["hypotheses"])
    assert len(rows) - 1 == expected
    for row in rows[1:]:
        assert len(row) == len(CSV_HEADER)
        assert row[1] in ("pose", "landmark")
        numbers = [float(v) for v in row[4:] if v != ""]
        assert len(numbers) == (6 if row[1] == "pose" else 4)
        for lo, hi in zip(numbers[::2], numbers[1::2], strict=True):
            assert lo <= hi, row


def is_png(path: Path) -> bool:
    data = path.read_bytes()
    return len(data) > 1000 and data.startswith(b"\x89PNG\r\n\x1a\n")


def n_observations(log: Path) -> int:
    return sum('"observation"' in line for line in log.read_text(encoding="utf-8").splitlines())


# --------------------------------------------------------------------------- logs
def rec(**fields: object) -> str:
    return json.dumps(fields)


PRIOR = rec(type="prior", pose=0, x=[0, 0], y=[0, 0], theta=[0, 0])
ODOMETRY = rec(type="odometry", **{"from": 0, "to": 1}, turn=[0, 0.05], distance=[1, 1.1])
OBSERVATION = rec(
    type="observation", pose=1, **{"class": "door"}, range=[1, 1.1], bearing=[0, 0.1], landmark="L0"
)


def replace(line: str, **fields: object) -> str:
    return json.dumps({**json.loads(line), **fields})


def drop(line: str, field: str) -> str:
    doc = json.loads(line)
    del doc[field]
    return json.dumps(doc)


# (id, lines, line number of the problem, fragment of the message). Comments and blank
# lines count in line numbers, so several cases put the problem after some.
BAD_LOGS = [
    (
        "malformed-json",
        ["# trip", PRIOR, "", '{"type": "odometry", "from": 0,'],
        4,
        "malformed JSON",
    ),
    ("truncated-line", [PRIOR, ODOMETRY[:-5]], 2, "malformed JSON"),
    ("not-an-object", [PRIOR, "[1, 2]"], 2, "expected a JSON object"),
    ("missing-field", [PRIOR, drop(ODOMETRY, "distance")], 2, 'missing field "distance"'),
    ("missing-type", [PRIOR, drop(ODOMETRY, "type")], 2, '"type"'),
    ("unknown-field", ["# c", "# c", PRIOR, replace(ODOMETRY, distanse=[1, 2])], 4, '"distanse"'),
    ("unknown-type", [PRIOR, replace(ODOMETRY, type="odom")], 2, 'unknown record type "odom"'),
    ("duplicate-field", [PRIOR[:-1] + ', "x": [1, 1]}'], 1, 'field "x" appears twice'),
    ("lo-gt-hi", [PRIOR, ODOMETRY, replace(OBSERVATION, bearing=[0.5, 0.4])], 3, "lo > hi"),
    ("nan", [PRIOR, ODOMETRY.replace("[1, 1.1]", "[NaN, 1.1]")], 2, "NaN"),
    ("infinity", ["", PRIOR.replace('"y": [0, 0]', '"y": [-Infinity, 0]')], 2, "Infinity"),
    ("overflow", [PRIOR, ODOMETRY.replace("[1, 1.1]", "[1, 1e999]")], 2, "finite"),
    ("negative-range", [PRIOR, ODOMETRY, replace(OBSERVATION, range=[-0.1, 1])], 3, "negative"),
    ("negative-distance", [PRIOR, replace(ODOMETRY, distance=[-1, 1])], 2, "negative"),
    ("bad-pose-id", [PRIOR, replace(ODOMETRY, to=1.5)], 2, "pose id"),
    ("empty-class", [PRIOR, ODOMETRY, replace(OBSERVATION, **{"class": ""})], 3, "non-empty"),
    (
        "unreached-observation",
        [PRIOR, ODOMETRY, "# pose 7 was never reached", replace(OBSERVATION, pose=7)],
        4,
        "observation from pose 7, which no prior or earlier odometry reaches",
    ),
    (
        "unreached-odometry",
        [PRIOR, replace(ODOMETRY, **{"from": 5, "to": 6})],
        2,
        "odometry from pose 5",
    ),
    ("odometry-to-itself", [PRIOR, replace(ODOMETRY, to=0)], 2, "to itself"),
    (
        "class-conflict",
        [PRIOR, ODOMETRY, OBSERVATION, replace(OBSERVATION, pose=0, **{"class": "tree"})],
        4,
        'landmark "L0" has class "tree" here but class "door" on line 3',
    ),
    (
        "one-scan-twice",
        [PRIOR, ODOMETRY, OBSERVATION, replace(OBSERVATION, range=[2, 3])],
        4,
        'already observed landmark "L0" on line 3',
    ),
]

# Problems of the whole file: "FILE: PROBLEM", no line number.
BAD_FILES = [
    ("empty", b"", "the log is empty"),
    ("only-comments", b"# nothing was measured\n\n   \n", "the log is empty"),
    ("no-prior", (ODOMETRY + "\n").encode(), "no pose has a prior"),
    ("not-utf8", (PRIOR + "\n").encode() + b'{"type": "\xff"}\n', "not UTF-8"),
]


def fresh_outputs(folder: Path) -> tuple[Path, Path]:
    """Pre-existing --json and --csv targets, to check that they are left untouched."""
    out_json, out_csv = folder / "out.json", folder / "out.csv"
    out_json.write_text('{"old": true}\n', encoding="utf-8")
    out_csv.write_text("old,csv\n", encoding="utf-8")
    return out_json, out_csv


@pytest.mark.parametrize(
    ("lines", "line", "fragment"),
    [pytest.param(lines, line, fragment, id=name) for name, lines, line, fragment in BAD_LOGS],
)
def test_bad_log_record(tmp_path: Path, lines: list[str], line: int, fragment: str) -> None:
    log = tmp_path / "bad.jsonl"
    log.write_text("\n".join(lines) + "\n", encoding="utf-8")
    fresh_outputs(tmp_path)
    before = listing(tmp_path)
    result = run("solve", "bad.jsonl", "--json", "out.json", "--csv", "out.csv", cwd=tmp_path)
    message = assert_input_error(result, f"bad.jsonl:{line}: ", fragment)
    assert len(re.findall(r":\d+:", message)) == 1, message
    assert result.stdout == ""
    assert listing(tmp_path) == before


@pytest.mark.parametrize(
    ("content", "fragment"),
    [pytest.param(content, fragment, id=name) for name, content, fragment in BAD_FILES],
)
def test_bad_log_file(tmp_path: Path, content: bytes, fragment: str) -> None:
    (tmp_path / "bad.jsonl").write_bytes(content)
    fresh_outputs(tmp_path)
    before = listing(tmp_path)
    result = run("solve", "bad.jsonl", "--json", "out.json", "--csv", "out.csv", cwd=tmp_path)
    assert_input_error(result, "bad.jsonl: ", fragment)
    assert result.stdout == ""
    assert listing(tmp_path) == before


def test_bad_log_named_by_absolute_path(tmp_path: Path) -> None:
    log = tmp_path / "deep" / "trip.jsonl"
    log.parent.mkdir()
    log.write_text(f"{PRIOR}\n{replace(ODOMETRY, distance=[2, 1])}\n", encoding="utf-8")
    result = run("solve", log, cwd=tmp_path)
    assert_input_error(result, f"{log}:2: ", "lo > hi")


# --------------------------------------------------------------------------- paths
def test_missing_log(tmp_path: Path) -> None:
    before = listing(tmp_path)
    result = run("solve", "nowhere.jsonl", "--json", "out.json", cwd=tmp_path)
    assert_input_error(result, "nowhere.jsonl", "No such file")
    assert listing(tmp_path) == before


def test_directory_as_log(tmp_path: Path) -> None:
    (tmp_path / "trip.jsonl").mkdir()
    result = run("solve", "trip.jsonl", cwd=tmp_path)
    assert_input_error(result, "trip.jsonl", "directory")


@pytest.fixture(scope="module")
def small_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("small")
    log = folder / "small.jsonl"
    log.write_text("\n".join([PRIOR, ODOMETRY, OBSERVATION]) + "\n", encoding="utf-8")
    return log


@pytest.mark.parametrize(
    ("option", "target", "fragment"),
    [
        pytest.param("--json", "missing/out.json", "does not exist", id="json-no-folder"),
        pytest.param("--csv", "missing/sub/out.csv", "does not exist", id="csv-no-folder"),
        pytest.param("--json", "folder", "directory", id="json-is-a-directory"),
        pytest.param("--csv", "afile/out.csv", "not a folder", id="csv-under-a-file"),
    ],
)
def test_unwritable_output(
    tmp_path: Path, small_log: Path, option: str, target: str, fragment: str
) -> None:
    (tmp_path / "folder").mkdir()
    (tmp_path / "afile").write_text("x", encoding="utf-8")
    before = listing(tmp_path)
    result = run("solve", small_log, option, target, cwd=tmp_path)
    line = assert_input_error(result, target, fragment)
    assert ".tmp" not in line  # names the target, not the atomic write's temporary file
    assert listing(tmp_path) == before


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root writes anywhere")
def test_read_only_output_folder(tmp_path: Path, small_log: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        result = run("solve", small_log, "--json", "locked/out.json", cwd=tmp_path)
        assert_input_error(result, "locked/out.json", "permission")
        assert list(locked.iterdir()) == []
    finally:
        locked.chmod(0o700)


def test_simulate_into_missing_folder(tmp_path: Path) -> None:
    result = run("simulate", "paper", "-o", "missing/trip.jsonl", cwd=tmp_path)
    assert_input_error(result, "missing/trip.jsonl", "does not exist")
    assert listing(tmp_path) == {}


@pytest.mark.parametrize(
    "options",
    [
        pytest.param(["--poses", "0"], id="no-poses"),
        pytest.param(["--max-range", "-1"], id="negative-range"),
        pytest.param(["--max-range", "nan"], id="nan-range"),
        pytest.param(["--classes", "door,,post"], id="empty-class"),
    ],
)
def test_simulate_impossible_world(tmp_path: Path, options: list[str]) -> None:
    result = run("simulate", "random", "-o", "w.jsonl", *options, cwd=tmp_path)
    assert_input_error(result)
    assert listing(tmp_path) == {}


def test_unknown_figure_format(tmp_path: Path) -> None:
    result = run("paper", "--figure", "figure.jpg", cwd=tmp_path)
    assert_input_error(result, "figure.jpg", ".png")
    assert result.stdout == ""
    assert listing(tmp_path) == {}


def test_usage_error_exits_2(tmp_path: Path) -> None:
    result = run("solve", cwd=tmp_path)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert "usage:" in result.stderr


@pytest.mark.parametrize(
    ("option", "value", "fragment"),
    [
        ("--strengthen-during", "-1", "must be at least 0"),
        ("--max-hypotheses", "0", "--max-hypotheses"),
        ("--strengthen-limit", "x", "not an integer"),
    ],
)
def test_bad_numeric_option_exits_2(
    tmp_path: Path, small_log: Path, option: str, value: str, fragment: str
) -> None:
    result = run("solve", option, value, small_log, cwd=tmp_path)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert fragment in result.stderr


@pytest.mark.parametrize("command", [None, "paper", "solve", "simulate", "plot"])
def test_help(tmp_path: Path, command: str | None) -> None:
    result = run(*([command] if command else []), "--help", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "usage: cuikslam" in result.stdout
    assert result.stderr == ""


def test_console_script_version(tmp_path: Path) -> None:
    script = shutil.which("cuikslam") or shutil.which("cuikslam", path=Path(sys.executable).parent)
    if script is None:
        pytest.skip("the cuikslam console script is not installed")
    result = subprocess.run(
        [script, "--version"], capture_output=True, text=True, timeout=TIMEOUT, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("cuikslam ")


# --------------------------------------------------------------------------- happy paths
@pytest.fixture(scope="module")
def paper_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """``simulate paper`` then ``solve --json --csv --truth`` on it, once for the module."""
    folder = tmp_path_factory.mktemp("paper")
    sim = run("simulate", "paper", "-o", "trip.jsonl", cwd=folder)
    assert sim.returncode == 0, sim.stderr
    solved = run(
        "solve",
        "trip.jsonl",
        "--json",
        "result.json",
        "--csv",
        "result.csv",
        "--truth",
        "trip.truth.json",
        "--work-budget",
        "none",  # the assertions below need lp to finish
        cwd=folder,
    )
    assert solved.returncode == 0, solved.stdout + solved.stderr
    assert "Traceback" not in solved.stderr
    return folder, {"simulate": sim, "solve": solved}


def test_simulate_writes_log_and_truth(paper_run: tuple[Path, dict]) -> None:
    folder, runs = paper_run
    log, truth = folder / "trip.jsonl", folder / "trip.truth.json"
    lines = log.read_text(encoding="utf-8").splitlines()
    assert all(json.loads(line)["type"] for line in lines)
    doc = load(truth)
    assert {"poses", "landmarks", "assignment"} <= set(doc)
    assert len(doc["poses"]) == 9
    assert len(doc["assignment"]) == n_observations(log)
    assert "trip.truth.json" in runs["simulate"].stderr


def test_solve_prints_table_and_truth_check(paper_run: tuple[Path, dict]) -> None:
    out = paper_run[1]["solve"].stdout
    for row in ("description", "r 1", "r 5", "r 9", "l L1", "l L4"):
        assert re.search(rf"\b{row}\b", out), row
    assert re.search(r"truth check: the true correspondence survived.* all contain the truth", out)


def test_solve_writes_json_and_csv(paper_run: tuple[Path, dict]) -> None:
    folder = paper_run[0]
    doc = load(folder / "result.json")
    check_result_contract(doc, n_observations(folder / "trip.jsonl"))
    assert doc["complete"] is True
    assert len(doc["hypotheses"]) == 1
    h = doc["hypotheses"][0]
    truth = load(folder / "trip.truth.json")
    assert h["assignment"] == truth["assignment"]
    assert h["consistency"] == doc["consistency"] == "lp"
    assert set(h["poses"]) == set(truth["poses"])
    for pose_id, (x, y, _theta) in truth["poses"].items():
        box = h["poses"][pose_id]
        assert box["x"][0] <= x <= box["x"][1] and box["y"][0] <= y <= box["y"][1]
    for mark_id, mark in truth["landmarks"].items():
        assert h["landmarks"][mark_id]["class"] == mark["class"]
    check_csv(folder / "result.csv", doc)
    assert not [p for p in folder.iterdir() if p.name.startswith(".")]  # no temporary left


def test_plot_reads_solve_json(paper_run: tuple[Path, dict]) -> None:
    folder = paper_run[0]
    result = run("plot", "result.json", "-o", "boxes.png", "--truth", "trip.truth.json", cwd=folder)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert is_png(folder / "boxes.png")


def test_solve_truth_miss_exits_1(paper_run: tuple[Path, dict]) -> None:
    folder = paper_run[0]
    truth = load(folder / "trip.truth.json")
    pose = sorted(truth["poses"], key=int)[-1]
    truth["poses"][pose][0] += 100.0  # the last pose moved 100 m away: its box misses it
    (folder / "moved.truth.json").write_text(json.dumps(truth), encoding="utf-8")
    result = run("solve", "trip.jsonl", "-q", "--truth", "moved.truth.json", cwd=folder)
    assert result.returncode == 1, result.stdout + result.stderr
    assert "miss" in result.stdout
    assert "all contain the truth" not in result.stdout
    assert "Traceback" not in result.stderr


def test_paper(tmp_path: Path) -> None:
    result = run("paper", "--figure", "paper.png", "--json", "paper.json", cwd=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    out = result.stdout
    for pose in range(1, 10):
        assert re.search(rf"│ r {pose}\s", out), pose
    for mark in ("l L1", "l L2", "l L3", "l L4"):
        assert mark in out
    assert "(seed)" in out and "(cuikslam)" in out  # the seed's Table 1 beside ours
    assert "width ratio" in out
    assert re.search(r"\d\.\d\d / \d\.\d\d / \d\.\d\d", out)  # a pose row's three ratios
    assert re.search(r"truth check: the true correspondence survived.* all contain the truth", out)
    assert is_png(tmp_path / "paper.png")
    doc = load(tmp_path / "paper.json")
    check_result_contract(doc, len(doc["hypotheses"][0]["assignment"]))
    assert len(doc["hypotheses"][0]["poses"]) == 9


def test_simulate_random_then_solve_with_truth(tmp_path: Path) -> None:
    sim = run(
        "simulate", "random", "-o", "world.jsonl", "--seed", "3", "--poses", "20", cwd=tmp_path
    )
    assert sim.returncode == 0, sim.stderr
    assert (tmp_path / "world.truth.json").is_file()
    result = run("solve", "world.jsonl", "--truth", "world.truth.json", cwd=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert re.search(
        r"truth check: the true correspondence survived.* all contain the truth", result.stdout
    )
    assert "r 1" in result.stdout


# --------------------------------------------------------------------------- inconsistency
INCONSISTENT = [
    # Landmark L0 seen 1 m to the right, then 20 m straight ahead, then L0 1 m to the right
    # again: no position of L0 fits both, and narrowing proves it.
    PRIOR,
    rec(
        type="observation",
        pose=0,
        **{"class": "door"},
        range=[0.99, 1.01],
        bearing=[-1.58, -1.56],
        landmark="L0",
    ),
    rec(type="odometry", **{"from": 0, "to": 1}, turn=[-0.01, 0.01], distance=[19.9, 20.1]),
    rec(
        type="observation",
        pose=1,
        **{"class": "door"},
        range=[0.99, 1.01],
        bearing=[-1.58, -1.56],
        landmark="L0",
    ),
]


@pytest.mark.parametrize("quiet", [False, True], ids=["table", "quiet"])
def test_inconsistent_log_exits_1(tmp_path: Path, quiet: bool) -> None:
    (tmp_path / "twice.jsonl").write_text("\n".join(INCONSISTENT) + "\n", encoding="utf-8")
    args = ["solve", "twice.jsonl", "--json", "r.json", *(["-q"] if quiet else [])]
    result = run(*args, cwd=tmp_path)
    assert result.returncode == 1, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    said = result.stdout + result.stderr
    assert "inconsistent" in said and "proof" in said
    doc = load(tmp_path / "r.json")
    assert doc["hypotheses"] == []
    assert doc["refuted"] is True
    if not quiet:  # the refuted result has nothing to draw: plot refuses it cleanly
        plotted = run("plot", "r.json", "-o", "r.png", cwd=tmp_path)
        assert_input_error(plotted, "r.json", "no hypothesis")
        assert not (tmp_path / "r.png").exists()


# --------------------------------------------------------------------------- bad JSON inputs
@pytest.fixture(scope="module")
def good_result(paper_run: tuple[Path, dict]) -> dict:
    return load(paper_run[0] / "result.json")


def _lo_gt_hi(doc: dict) -> str:
    box = next(iter(doc["hypotheses"][0]["poses"].values()))
    box["x"] = [box["x"][1] + 1.0, box["x"][1]]
    return json.dumps(doc)


def _nan_bound(doc: dict) -> str:
    box = next(iter(doc["hypotheses"][0]["landmarks"].values()))
    box["y"] = [float("nan"), 1.0]
    return json.dumps(doc)  # Python writes NaN, which json.load accepts


def _no_poses(doc: dict) -> str:
    del doc["hypotheses"][0]["poses"]
    return json.dumps(doc)


BAD_RESULTS = [
    ("syntax", lambda doc: '{\n "complete": true,\n "hypotheses": [}\n', ["bad.json:3: "]),
    ("not-an-object", lambda doc: "[]", ["bad.json: "]),
    ("no-hypotheses", lambda doc: '{"complete": true}', ["hypotheses"]),
    ("no-poses", _no_poses, ["poses"]),
    ("lo-gt-hi", _lo_gt_hi, ["lo > hi"]),
    ("nan", _nan_bound, ["nan"]),
    ("not-utf8", None, ["UTF-8"]),
]


@pytest.mark.parametrize(
    ("make", "fragments"),
    [pytest.param(make, fragments, id=name) for name, make, fragments in BAD_RESULTS],
)
def test_plot_malformed_result(
    tmp_path: Path, good_result: dict, make: object, fragments: list[str]
) -> None:
    bad = tmp_path / "bad.json"
    if make is None:
        bad.write_bytes(b'{"complete": "\xff"}')
    else:
        bad.write_text(make(json.loads(json.dumps(good_result))), encoding="utf-8")
    before = listing(tmp_path)
    result = run("plot", "bad.json", "-o", "fig.png", cwd=tmp_path)
    assert_input_error(result, "bad.json", *fragments)
    assert listing(tmp_path) == before


@pytest.mark.parametrize(
    ("content", "fragments"),
    [
        pytest.param('{\n "poses": {\n', ["bad.truth.json:3: "], id="syntax"),
        pytest.param('{"poses": {}}', ["bad.truth.json: ", "landmarks"], id="missing-key"),
    ],
)
def test_malformed_truth(
    paper_run: tuple[Path, dict], tmp_path: Path, content: str, fragments: list[str]
) -> None:
    folder = paper_run[0]
    (tmp_path / "bad.truth.json").write_text(content, encoding="utf-8")
    shutil.copy(folder / "trip.jsonl", tmp_path)
    shutil.copy(folder / "result.json", tmp_path)
    fresh_outputs(tmp_path)
    before = listing(tmp_path)
    solved = run(
        "solve", "trip.jsonl", "--truth", "bad.truth.json", "--json", "out.json", cwd=tmp_path
    )
    assert_input_error(solved, *fragments)
    assert solved.stdout == ""
    plotted = run("plot", "result.json", "-o", "fig.png", "--truth", "bad.truth.json", cwd=tmp_path)
    assert_input_error(plotted, *fragments)
    assert listing(tmp_path) == before


def test_solve_streams_every_survivor_to_a_file(tmp_path: Path) -> None:
    """--survivors: one JSON line per survivor of the search, new landmarks as "+k"."""
    assert run("simulate", "paper", "--unknown", "-o", "trip.jsonl", cwd=tmp_path).returncode == 0
    result = run("solve", "trip.jsonl", "--survivors", "all.jsonl", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    lines = (tmp_path / "all.jsonl").read_text(encoding="utf-8").splitlines()
    rows = [json.loads(line)["assignment"] for line in lines]
    log = read_log_file(tmp_path / "trip.jsonl")
    assert len(rows) == 2
    assert all(len(row) == len(log.observations) for row in rows)
    assert all(name.startswith("+") for row in rows for name in row)
    assert sorted(len(set(row)) for row in rows) == [4, 5]
    bad = run("solve", "trip.jsonl", "--survivors", "missing/all.jsonl", "-q", cwd=tmp_path)
    assert bad.returncode == 2 and "missing/all.jsonl" in bad.stderr
    assert "Traceback" not in bad.stderr


def test_cli_defaults_match_the_library() -> None:
    """The CLI builds its solve options from SolveOptions; the search takes its defaults
    from it too."""
    import dataclasses

    from cuikslam.cli.main import build_parser
    from cuikslam.hypotheses.search import DEFAULT_MAX_HYPOTHESES
    from cuikslam.options import Level, SolveOptions

    parser = build_parser()
    args = parser.parse_args(["solve", "trip.jsonl"])
    defaults = SolveOptions()
    assert args.max_hypotheses == DEFAULT_MAX_HYPOTHESES == defaults.max_hypotheses
    for name in ("consistency", "strengthen_limit", "strengthen_during"):
        assert getattr(args, name) == getattr(defaults, name), name
    names = {f.name for f in dataclasses.fields(SolveOptions)}
    assert {"consistency", "max_hypotheses", "work_budget", "time_budget"} <= names
    for level in Level:
        parsed = parser.parse_args(["solve", "trip.jsonl", "--consistency", level.value])
        assert SolveOptions(consistency=parsed.consistency).consistency is level


def test_an_unknown_level_is_refused_with_the_choices() -> None:
    from cuikslam.options import SolveOptions

    with pytest.raises(ValueError, match="level 'box'; choose one of hull, lp, lp-split"):
        SolveOptions(consistency="box")
    with pytest.raises(TypeError, match=r"SolveOptions\.replace\(\) .* 'no_such_option'; the opt"):
        SolveOptions().replace(no_such_option=1)


def test_a_mistyped_option_of_solve_names_solve_and_the_close_option() -> None:
    """The error names the function the user called, not the dataclass behind it, and
    solves nothing."""
    import cuikslam

    log, _ = cuikslam.simulate_paper(seed=0)
    with pytest.raises(TypeError) as caught:
        cuikslam.solve(log, consistensy="hull")
    assert str(caught.value) == (
        "solve() got an unexpected keyword argument 'consistensy'; did you mean 'consistency'?"
    )
    with pytest.raises(TypeError, match=r"^solve\(\) .*'max_hypothesis'; did you mean 'max_hyp"):
        cuikslam.solve(log, max_hypothesis=3)


# --------------------------------------------------------------------------- a truth of another log
def walk(n_poses: int, folder: Path, name: str, *, landmark: str = "A") -> tuple[Path, Path]:
    """A log of ``n_poses`` poses 1 m apart along x, each seeing post A at (2, 3) (the first
    sighting names it), and its truth calling the post ``landmark``: ``NAME.jsonl`` and
    ``NAME.truth.json`` in ``folder``."""
    lines = ['{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}']
    for i in range(n_poses):
        if i:
            lines.append(
                f'{{"type": "odometry", "from": {i - 1}, "to": {i}, "turn": [-0.01, 0.01], '
                '"distance": [0.9, 1.1]}'
            )
        r, b = math.hypot(2 - i, 3), math.atan2(3, 2 - i)
        named = ', "landmark": "A"' if i == 0 else ""
        lines.append(
            f'{{"type": "observation", "pose": {i}, "class": "post", "range": [{r - 0.1}, '
            f'{r + 0.1}], "bearing": [{b - 0.05}, {b + 0.05}]{named}}}'
        )
    log, truth = folder / f"{name}.jsonl", folder / f"{name}.truth.json"
    log.write_text("\n".join(lines) + "\n", encoding="utf-8")
    doc = {
        "poses": {str(i): [i, 0, 0] for i in range(n_poses)},
        "landmarks": {landmark: {"class": "post", "x": 2, "y": 3}},
        "assignment": [landmark] * n_poses,
    }
    truth.write_text(json.dumps(doc), encoding="utf-8")
    return log, truth


@pytest.mark.parametrize(
    ("other", "fragments"),
    [
        pytest.param(
            {"n_poses": 9},
            [
                "it assigns 9 observations, the log has 3",
                "it has 6 poses the log lacks (3, 4, 5, …, 8)",
            ],
            id="bigger",
        ),
        pytest.param({"n_poses": 2}, ["it assigns 2 observations, the log has 3"], id="smaller"),
        pytest.param(
            {"n_poses": 3, "landmark": "B"}, ["the log names 1 landmark it lacks (A)"], id="renamed"
        ),
    ],
)
def test_solve_refuses_the_truth_of_another_log_before_solving(
    tmp_path: Path, other: dict, fragments: list[str]
) -> None:
    """The truth of a larger log crashed with an IndexError after the tables, that of a
    smaller one ran the whole solve to report a lost truth (issue 27): now one line naming
    both files, exit 2, no table (the solver never ran), no output file."""
    walk(3, tmp_path, "u")
    walk(**other, folder=tmp_path, name="other")
    before = listing(tmp_path)
    result = run(
        "solve", "u.jsonl", "--truth", "other.truth.json", "--json", "r.json", cwd=tmp_path
    )
    assert_input_error(result, "other.truth.json does not fit u.jsonl: ", *fragments)
    assert result.stdout == ""
    assert listing(tmp_path) == before


def test_a_truth_that_does_not_fit_never_reaches_the_solver(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """In process, with a stand-in solver that raises when called: the matching truth
    reaches it, the truth of another log does not."""
    import types

    from cuikslam.cli.main import main

    class Solved(Exception):
        pass

    def solve(*args: object, **kwargs: object) -> None:
        raise Solved

    monkeypatch.setitem(sys.modules, "cuikslam.solver", types.SimpleNamespace(solve=solve))
    log, truth = walk(3, tmp_path, "u")
    _, bigger = walk(4, tmp_path, "big")
    with pytest.raises(Solved):
        main(["solve", str(log), "--truth", str(truth), "-q"])
    assert main(["solve", str(log), "--truth", str(bigger), "-q"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.splitlines() == [
        f"cuikslam: error: {bigger} does not fit {log}: it assigns 4 observations, the log "
        "has 3; it has 1 pose the log lacks (3)"
    ]


def test_plot_and_calibrate_check_refuse_the_truth_of_another_log(tmp_path: Path) -> None:
    from cuikslam.results.io import write_result_file
    from cuikslam.results.solution import Hypothesis, Solution

    walk(3, tmp_path, "u")
    walk(5, tmp_path, "big")
    boxes = [[[i - 0.5, i + 0.5], [-0.5, 0.5], [-0.1, 0.1]] for i in range(3)]
    hypothesis = Hypothesis(
        assignment=["A"] * 3,
        pose_ids=[0, 1, 2],
        poses=np.array(boxes),
        landmark_ids=["A"],
        landmark_classes=["post"],
        landmarks=np.array([[[1.5, 2.5], [2.5, 3.5]]]),
    )
    write_result_file(Solution([hypothesis], log_path="u.jsonl"), tmp_path / "r.json")
    before = listing(tmp_path)
    plotted = run("plot", "r.json", "-o", "fig.png", "--truth", "big.truth.json", cwd=tmp_path)
    assert_input_error(
        plotted, "big.truth.json does not fit r.json: it assigns 5 observations, the result has 3"
    )
    checked = run(
        "calibrate", "check", "u.jsonl", "--truth", "big.truth.json", "--json", "c.json",
        cwd=tmp_path,
    )  # fmt: skip
    assert_input_error(checked, "big.truth.json does not fit u.jsonl: it assigns 5 observations")
    assert plotted.stdout == checked.stdout == ""
    assert listing(tmp_path) == before
    plotted = run("plot", "r.json", "-o", "fig.png", "--truth", "u.truth.json", cwd=tmp_path)
    assert plotted.returncode == 0, plotted.stderr
    assert is_png(tmp_path / "fig.png")


def test_the_walk_with_its_own_truth_solves_and_keeps_the_truth(tmp_path: Path) -> None:
    """The control for the tests above: the same log with its own truth is solved."""
    walk(3, tmp_path, "u")
    result = run("solve", "u.jsonl", "--truth", "u.truth.json", "--json", "r.json", cwd=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Hypothesis 1 of" in result.stdout
    assert "truth check: the true correspondence survived" in " ".join(result.stdout.split())
    assert (tmp_path / "r.json").is_file()


def test_values_near_the_largest_float_solve_without_warnings(tmp_path: Path) -> None:
    """Bounds of 1e308 (a bearing known only to lie in [-1e308, 1e308], a map box that
    wide) are valid input: the solve says nothing on stderr (an adversarial run saw
    numpy's overflow warnings there) and its boxes are those of the log."""
    lines = [
        {"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]},
        {"type": "odometry", "from": 0, "to": 1, "turn": [0, 0.1], "distance": [1, 1.1]},
        {"type": "observation", "pose": 0, "class": "post", "range": [3, 3.1],
         "bearing": [0.1, 0.2]},
        {"type": "observation", "pose": 1, "class": "post", "range": [2, 2.1],
         "bearing": [-1e308, 1e308]},
        {"type": "landmark", "id": "far", "class": "post", "x": [-1e308, 1e308],
         "y": [-1e308, 1e308]},
    ]  # fmt: skip
    (tmp_path / "huge.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    result = run("solve", "huge.jsonl", "--json", "huge.result.json", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert json.loads((tmp_path / "huge.result.json").read_text())["hypotheses"]
