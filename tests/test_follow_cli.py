"""``cuikslam follow``, run as a subprocess: one JSON line per pose, in order, that holds
the truth; standard input and growing files; bad input as one line and exit status 2."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from cuikslam.log.writer import log_to_lines
from cuikslam.simulate.random_world import simulate_random_world
from cuikslam.simulate.truth import write_truth_file
from test_cli import CLI, assert_input_error, run

KEYS = ["pose", "x", "y", "theta", "latency_s", "hypotheses"]


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> tuple[Path, Path, list[int]]:
    """A 40-pose random world: its log, its truth file and its poses in log order."""
    folder = tmp_path_factory.mktemp("follow")
    log, truth = simulate_random_world(seed=5, n_poses=40, n_landmarks=12)
    lines = log_to_lines(log)
    stamped = [line[:-1] + f', "time": {0.01 * k}}}' for k, line in enumerate(lines)]
    (folder / "world.jsonl").write_text("\n".join(stamped) + "\n", encoding="utf-8")
    write_truth_file(truth, folder / "world.truth.json")
    return folder / "world.jsonl", folder / "world.truth.json", list(log.pose_order())


def lines_of(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines()]


def test_one_line_per_pose_in_order_holding_the_truth(world, tmp_path) -> None:
    log, truth, poses = world
    result = run("follow", log, "--truth", truth, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    lines = lines_of(result.stdout)
    assert [line["pose"] for line in lines] == poses
    assert all(list(line) == KEYS and line["hypotheses"] == 1 for line in lines)
    assert f"truth: all {len(poses)} boxes with a true pose hold it" in result.stderr
    assert "\r" not in result.stderr  # no status line off a terminal


def widths(lines: list[dict]) -> np.ndarray:
    """The (poses, 3) widths of the boxes of JSON lines (an unbounded side: infinite)."""
    inf = float("inf")
    return np.array(
        [
            [(inf if hi is None else hi) - (-inf if lo is None else lo) for lo, hi in sides]
            for sides in ([line["x"], line["y"], line["theta"]] for line in lines)
        ]
    )


def test_the_lp_level_keeps_the_truth_and_narrows_beyond_hull(world, tmp_path) -> None:
    """``--consistency lp`` runs the window (:mod:`cuikslam.online.window`) end to end: its
    lines hold the truth, none is wider than at ``hull``, and most are narrower."""
    log, truth, poses = world
    lines = {}
    for level in ("hull", "lp"):
        result = run("follow", log, "--consistency", level, "--truth", truth, cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        assert f"truth: all {len(poses)} boxes with a true pose hold it" in result.stderr
        lines[level] = lines_of(result.stdout)
        assert [line["pose"] for line in lines[level]] == poses
    hull, lp = widths(lines["hull"]), widths(lines["lp"])
    assert np.all(lp <= hull)
    assert np.sum(lp < hull) > hull.size // 2
    assert lp[-1, 0] < 0.5 * hull[-1, 0]


def test_standard_input_and_an_output_file(world, tmp_path) -> None:
    log, _, poses = world
    out = tmp_path / "boxes.jsonl"
    result = subprocess.run(
        [*CLI, "follow", "-", "-o", out, "-q"],
        input=log.read_text(encoding="utf-8"),
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0 and result.stdout == "" and result.stderr == ""
    assert [line["pose"] for line in lines_of(out.read_text())] == poses


def test_a_bad_line_stops_with_its_line_and_whole_lines_written(world, tmp_path) -> None:
    log, _, poses = world
    lines = log.read_text(encoding="utf-8").splitlines()
    lines.insert(30, '{"type": "odometry", "from": 0, "to": 1, "turn": [0.2, 0.1]}')
    bad = tmp_path / "bad.jsonl"
    bad.write_text("\n".join(lines) + "\n", encoding="utf-8")
    out = tmp_path / "boxes.jsonl"
    result = run("follow", bad, "-o", out, cwd=tmp_path)
    assert_input_error(result, "bad.jsonl:31:", '"distance"')
    written = lines_of(out.read_text())  # every line whole: each one parses
    assert 0 < len(written) < len(poses)
    assert [line["pose"] for line in written] == poses[: len(written)]


def test_bad_input_before_any_pose_leaves_no_output_file(tmp_path) -> None:
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"type": "prior", "pose": 0}\n', encoding="utf-8")
    result = run("follow", bad, "-o", tmp_path / "boxes.jsonl", cwd=tmp_path)
    assert_input_error(result, "bad.jsonl:1:", '"x"')
    assert not (tmp_path / "boxes.jsonl").exists()


@pytest.mark.parametrize(
    ("arguments", "fragment"),
    [
        (["missing.jsonl"], "missing.jsonl: cannot read the log"),
        (["LOG", "-o", "no/such/folder/out.jsonl"], "does not exist"),
        (["LOG", "--truth", "missing.truth.json"], "missing.truth.json"),
    ],
)
def test_unreadable_input_and_unwritable_output(world, tmp_path, arguments, fragment) -> None:
    log, _, _ = world
    result = run("follow", *[log if a == "LOG" else a for a in arguments], cwd=tmp_path)
    assert_input_error(result, fragment)


def test_an_inconsistent_log_exits_1_with_the_proof(tmp_path) -> None:
    log = tmp_path / "inconsistent.jsonl"
    log.write_text(
        '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}\n'
        '{"type": "odometry", "from": 0, "to": 1, "turn": [0, 0], "distance": [1, 1]}\n'
        '{"type": "prior", "pose": 1, "x": [5, 6], "y": [0, 0], "theta": [0, 0]}\n',
        encoding="utf-8",
    )
    result = run("follow", log, cwd=tmp_path)
    assert result.returncode == 1, result.stderr
    assert [line["pose"] for line in lines_of(result.stdout)] == [0]
    assert "the log is inconsistent" in result.stderr and "Traceback" not in result.stderr


def test_a_truth_the_boxes_miss_exits_1(world, tmp_path) -> None:
    log, truth, _ = world
    moved = json.loads(truth.read_text())
    moved["poses"]["7"][0] += 100.0
    wrong = tmp_path / "wrong.truth.json"
    wrong.write_text(json.dumps(moved), encoding="utf-8")
    result = run("follow", log, "--truth", wrong, cwd=tmp_path)
    assert result.returncode == 1
    assert "pose 7" in result.stderr


def test_a_growing_file_is_followed_until_it_stops_growing(world, tmp_path) -> None:
    log, _, poses = world
    lines = log.read_text(encoding="utf-8").splitlines(keepends=True)
    growing = tmp_path / "growing.jsonl"
    growing.write_text("".join(lines[:10]), encoding="utf-8")
    command = subprocess.Popen(
        [*CLI, "follow", growing, "--wait", "3", "-q"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    with open(growing, "a", encoding="utf-8") as writer:
        for line in lines[10:]:
            half = len(line) // 2
            writer.write(line[:half])  # the reader must wait for the rest of the line
            writer.flush()
            time.sleep(0.005)
            writer.write(line[half:])
            writer.flush()
    stdout, stderr = command.communicate(timeout=120)
    assert command.returncode == 0, stderr
    assert [line["pose"] for line in lines_of(stdout)] == poses


def test_a_replay_at_the_recorded_rate_says_whether_it_kept_up(world, tmp_path) -> None:
    log, _, poses = world
    result = run("follow", log, "--rate", "4", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert len(lines_of(result.stdout)) == len(poses)
    assert "at 4x the recorded pace:" in result.stderr
