"""What ``cuikslam solve`` prints for a person, and the exit status of ``--truth``.

Long results get an overview (counts, median and widest boxes, the worst poses, where
every box went) instead of one row per pose; ``--table`` asks for every row; short
results print every row; nothing from a third-party library reaches stdout; a complete
search that lost the true correspondence exits with status 1.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from cuikslam.cli.main import main
from cuikslam.cli.solve import TABLE_MAX_POSES, report_truth
from cuikslam.results.overview import box_statistics, overview_lines, worst_poses
from cuikslam.results.solution import Hypothesis, Solution
from cuikslam.results.summary import summarize, summary_holds, summary_to_json
from cuikslam.simulate.truth import GroundTruth

TABLE_ROW = re.compile(r"^\s*│ r \d+ ")  # a pose row of a rich table: "│ r 12  │ ..."
LONG = TABLE_MAX_POSES + 20


def run_main(capfd: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    """``cuikslam ARGV`` in this process; exit status, stdout and stderr (file descriptors,
    so that a C library printing on them is seen too)."""
    capfd.readouterr()
    status = main([str(a) for a in argv])
    out, err = capfd.readouterr()
    return status, out, err


@pytest.fixture(scope="module")
def long_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A random known-correspondence world with more poses than the table threshold."""
    folder = tmp_path_factory.mktemp("long")
    log = folder / "long.jsonl"
    assert main(["simulate", "random", "--poses", str(LONG), "-o", str(log), "-q"]) == 0
    return log


def pose_rows(text: str) -> list[str]:
    return [line for line in text.splitlines() if TABLE_ROW.match(line)]


def test_long_result_prints_an_overview(capfd, long_log: Path, tmp_path: Path) -> None:
    out_json = tmp_path / "result.json"
    status, out, _ = run_main(capfd, "solve", long_log, "--json", out_json)
    assert status == 0
    assert pose_rows(out) == []
    assert f"{LONG:,} poses" in out
    for fragment in ("pose box widths, median", "pose box widths, widest", "widest pose boxes"):
        assert fragment in out, fragment
    assert f"every box: {out_json}; --table prints them all here" in out
    assert len(out.splitlines()) < 30
    doc = json.loads(out_json.read_text(encoding="utf-8"))
    assert len(doc["hypotheses"][0]["poses"]) == LONG  # the file still holds every box


def test_overview_without_output_files_says_how_to_get_them(capfd, long_log: Path) -> None:
    status, out, _ = run_main(capfd, "solve", long_log)
    assert status == 0
    assert "every box: no file (give --json or --csv); --table prints them all here" in out


def test_table_flag_prints_every_pose(capfd, long_log: Path) -> None:
    status, out, _ = run_main(capfd, "solve", long_log, "--table")
    assert status == 0
    rows = pose_rows(out)
    assert len(rows) == LONG
    assert "pose box widths" not in out


def test_json_is_the_same_with_or_without_tables(capfd, long_log: Path, tmp_path: Path) -> None:
    docs = []
    for flag in ("--table", "--no-table"):
        path = tmp_path / f"{flag.strip('-')}.json"
        argv = ("solve", long_log, flag, "--json", path, "--consistency", "hull")  # no budget cut
        assert run_main(capfd, *argv)[0] == 0
        docs.append(json.loads(path.read_text(encoding="utf-8")))
    assert docs[0]["hypotheses"] == docs[1]["hypotheses"]


def test_short_result_prints_every_row_and_nothing_from_highs(capfd, tmp_path: Path) -> None:
    log = tmp_path / "paper.jsonl"
    assert main(["simulate", "paper", "-o", str(log), "-q"]) == 0
    status, out, err = run_main(capfd, "solve", log, "--consistency", "lp", "--time-budget", "none")
    assert status == 0
    assert [row.split()[1:3] for row in pose_rows(out)] == [["r", str(p)] for p in range(1, 10)]
    assert "pose box widths" not in out
    for banner in ("HiGHS", "Highs", "Copyright", "Running"):
        assert banner not in out and banner not in err, banner


def test_no_table_on_a_short_result_gives_the_overview(capfd, tmp_path: Path) -> None:
    log = tmp_path / "paper.jsonl"
    assert main(["simulate", "paper", "-o", str(log), "-q"]) == 0
    status, out, _ = run_main(capfd, "solve", log, "--consistency", "hull", "--no-table")
    assert status == 0
    assert pose_rows(out) == []
    assert "9 poses, 4 landmarks, level hull" in out


# --------------------------------------------------------------------------- overview
def _hypothesis(poses: np.ndarray, landmarks: np.ndarray | None = None) -> Hypothesis:
    landmarks = np.zeros((0, 2, 2)) if landmarks is None else landmarks
    return Hypothesis(
        assignment=[],
        pose_ids=[10 + i for i in range(len(poses))],
        poses=poses,
        landmark_ids=[f"L{j}" for j in range(len(landmarks))],
        landmark_classes=["door"] * len(landmarks),
        landmarks=landmarks,
        consistency="hull",
    )


def test_box_statistics_median_and_widest() -> None:
    widths = np.array([[1.0, 4.0, 0.1], [3.0, 2.0, 0.3], [2.0, 8.0, 0.2]])
    boxes = np.stack([np.zeros_like(widths), widths], axis=-1)
    stats = box_statistics(boxes, ["a", "b", "c"], ("x", "y", "θ"))
    assert stats.median.tolist() == [2.0, 4.0, 0.2]
    assert stats.widest.tolist() == [3.0, 8.0, 0.3]
    assert stats.widest_at == ["b", "c", "b"]


def test_worst_poses_are_the_widest_positions_first() -> None:
    widths = np.array([[1.0, 1.0, 0.1], [5.0, 1.0, 0.1], [1.0, 7.0, 0.1], [5.0, 5.0, 0.9]])
    boxes = np.stack([-widths / 2, widths / 2], axis=-1)
    assert worst_poses(_hypothesis(boxes), 3) == [2, 3, 1]


def test_overview_counts_unknown_headings_and_unbounded_sides() -> None:
    boxes = np.array(
        [
            [[0.0, 1.0], [0.0, 1.0], [-math.inf, math.inf]],
            [[0.0, 2.0], [-math.inf, 1.0], [0.0, 7.0]],
            [[0.0, 3.0], [0.0, 1.0], [0.0, 0.5]],
        ]
    )
    landmarks = np.array([[[0.0, 0.5], [1.0, 1.25]]])
    text = "\n".join(overview_lines(_hypothesis(boxes, landmarks), "Hypothesis 1 of 1"))
    assert "2 of 3 headings are unknown" in text
    assert "y unbounded (r 11)" in text
    assert "x 3 m (r 12)" in text
    assert "landmark box widths, median: x 0.5 m, y 0.25 m" in text


# --------------------------------------------------------------------------- --truth
def _truth(assignment: list[str]) -> GroundTruth:
    ids = sorted(set(assignment))
    return GroundTruth(
        poses_xyt=np.zeros((1, 3)),
        pose_ids=[0],
        landmarks_xy=np.zeros((len(ids), 2)),
        landmark_ids=ids,
        landmark_classes=["door"] * len(ids),
        assignment=assignment,
    )


def _solution(survivors: list[list[str]], reported: int, complete: bool) -> Solution:
    hypotheses = [
        Hypothesis(
            assignment=a,
            pose_ids=[0],
            poses=np.array([[[-1.0, 1.0], [-1.0, 1.0], [-1.0, 1.0]]]),
            landmark_ids=sorted(set(a)),
            landmark_classes=["door"] * len(set(a)),
            landmarks=np.tile([[-1.0, 1.0]], (len(set(a)), 2, 1)),
        )
        for a in survivors[:reported]
    ]
    correspondence = {
        **summary_to_json(summarize(survivors)),
        "reported": reported,
        "survivors": len(survivors),
    }
    return Solution(
        hypotheses=hypotheses,
        complete=complete,
        statistics={"survivors": len(survivors)},
        correspondence=correspondence,
    )


class _Lines:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def print(self, text: str, **_: object) -> None:
        self.lines.append(str(text))


SURVIVORS = [["A", "A", "B"], ["A", "B", "B"], ["A", "B", "C"]]


@pytest.mark.parametrize("reported", [1, 3])
def test_complete_search_without_the_truth_fails(reported: int) -> None:
    console = _Lines()
    truth = _truth(["A", "B", "A"])  # observation 2 back on the first landmark: no survivor
    assert not report_truth(_solution(SURVIVORS, reported, complete=True), truth, console)
    assert "not among" in console.lines[-1]


@pytest.mark.parametrize("reported", [1, 3])
def test_incomplete_search_without_the_truth_is_not_a_failure(reported: int) -> None:
    console = _Lines()
    truth = _truth(["A", "B", "A"])
    assert report_truth(_solution(SURVIVORS, reported, complete=False), truth, console)


def test_truth_among_unreported_survivors_is_not_a_failure() -> None:
    console = _Lines()
    truth = _truth(["X", "Y", "Y"])  # the second survivor, up to renaming
    assert report_truth(_solution(SURVIVORS, 1, complete=True), truth, console)
    assert "raise --max-hypotheses" in console.lines[-1]


def test_summary_holds_exactly_the_survivors() -> None:
    doc = {**summary_to_json(summarize(SURVIVORS)), "survivors": len(SURVIVORS)}
    assert [summary_holds(doc, a, set()) for a in SURVIVORS] == [True, True, True]
    assert summary_holds(doc, ["A", "A", "A"], set()) is False
    assert summary_holds(doc, ["Q", "R", "Q"], set()) is False
    assert summary_holds({**doc, "survivors": 4}, ["A", "A", "A"], set()) is None


def test_cli_exits_1_when_a_complete_search_lost_the_truth(capfd, tmp_path: Path) -> None:
    log = tmp_path / "trip.jsonl"
    assert main(["simulate", "paper", "--unknown", "-o", str(log), "-q"]) == 0
    truth_path = tmp_path / "trip.truth.json"
    doc = json.loads(truth_path.read_text(encoding="utf-8"))
    n = len(doc["assignment"])
    doc["assignment"] = [f"X{i}" for i in range(n)]  # every sighting a landmark of its own
    doc["landmarks"].update({f"X{i}": {"class": "door", "x": 0.0, "y": 0.0} for i in range(n)})
    wrong = tmp_path / "wrong.truth.json"
    wrong.write_text(json.dumps(doc), encoding="utf-8")
    for extra in ([], ["--max-hypotheses", "1"]):
        argv = ("solve", log, "-q", "--truth", wrong, "--time-budget", "none", *extra)
        status, out, _ = run_main(capfd, *argv)
        assert status == 1, out
        assert "truth check: the true correspondence is not among" in out
    status, out, _ = run_main(capfd, "solve", log, "-q", "--truth", truth_path)
    assert status == 0, out


def test_check_truth_decides_floats_and_fractions_exactly() -> None:
    from fractions import Fraction

    from cuikslam.results.solution import check_truth

    lo, hi = 1.0, 2.0
    h = Hypothesis(
        assignment=[],
        pose_ids=[7, 3],
        poses=np.array([[[lo, hi], [lo, hi], [lo, hi]], [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]]),
        landmark_ids=[],
        landmark_classes=[],
        landmarks=np.zeros((0, 2, 2)),
    )
    tiny = Fraction(1, 10**30)
    inside = [(Fraction(lo), np.float64(hi), Fraction(3, 2)), (0.0, 0.0, 0.0)]
    assert check_truth(h, [7, 3], inside).ok
    outside = [(Fraction(lo) - tiny, Fraction(hi) + tiny, Fraction(hi) + tiny), (0.0, 0.0, 0.0)]
    report = check_truth(h, [7, 3], outside)
    assert len(report.misses) == 3 and report.checked == 6
    assert check_truth(h, [7, 3], [(1.5, 1.5, 1.5 + 2 * math.pi), (0.0, 0.0, 0.0)]).ok


def test_truth_file_with_a_pose_id_twice_is_refused(tmp_path: Path) -> None:
    from cuikslam.errors import InputFileError
    from cuikslam.simulate.truth import read_truth_file

    doc = {
        "poses": {str(i): [0.0, 0.0, 0.0] for i in range(3000)} | {"07": [1.0, 1.0, 0.0]},
        "landmarks": {},
        "assignment": [],
    }
    path = tmp_path / "t.truth.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(InputFileError, match="pose id '07' appears twice"):
        read_truth_file(path)
    del doc["poses"]["07"]
    path.write_text(json.dumps(doc), encoding="utf-8")
    assert read_truth_file(path).pose_ids == list(range(3000))


def test_a_long_message_stays_one_line_when_piped(capsys) -> None:
    """Piped or written to a file, a message longer than the console's width is printed
    whole on one line (a reader's pager wraps it), while tables keep their width."""
    from cuikslam.cli.commands import console

    message = "the search stopped " + "and went on " * 40 + "until the end"
    out = console()
    out.print(message, highlight=False, markup=False)
    assert capsys.readouterr().out == message + "\n"
