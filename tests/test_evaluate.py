"""``cuikslam evaluate``: containment, widths and association against small hand-made truths."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from cuikslam.cli.main import main
from cuikslam.results.evaluate import evaluate, evaluation_to_json
from cuikslam.results.io import write_result_file
from cuikslam.results.solution import Hypothesis, Solution
from cuikslam.simulate.truth import read_truth_file


def _hypothesis(
    assignment: list[str], landmark_ids: list[str], theta_hi: float = 0.1
) -> Hypothesis:
    poses = np.array(
        [
            [[-0.1, 0.1], [-0.1, 0.1], [-0.1, theta_hi]],
            [[0.9, 1.2], [-0.2, 0.2], [-0.2, 0.2]],
            [[1.8, 2.4], [-0.4, 0.4], [-0.3, 0.3]],
        ]
    )
    landmarks = np.array([[[2.0 + k, 4.0 + k], [0.5, 1.5]] for k in range(len(landmark_ids))])
    return Hypothesis(
        assignment=assignment,
        pose_ids=[0, 1, 2],
        poses=poses,
        landmark_ids=landmark_ids,
        landmark_classes=["post"] * len(landmark_ids),
        landmarks=landmarks.reshape(len(landmark_ids), 2, 2),
    )


def _truth_doc(poses: dict, assignment: list[str]) -> dict:
    return {
        "poses": poses,
        "landmarks": {
            "A": {"class": "post", "x": 3.0, "y": 1.0},
            "B": {"class": "post", "x": 4.5, "y": 1.0},
        },
        "assignment": assignment,
    }


def _write(tmp_path: Path, solution: Solution, truth: dict) -> tuple[str, str]:
    result, truth_path = tmp_path / "r.json", tmp_path / "t.truth.json"
    write_result_file(solution, result)
    truth_path.write_text(json.dumps(truth))
    return str(result), str(truth_path)


def test_partial_truth_counts_only_poses_with_truth_and_finds_the_miss(tmp_path: Path) -> None:
    # Pose 0's heading box ends at 0.1; its truth is 0.1 + 1e-20 as a decimal string: a miss
    # only an exact comparison sees. Pose 2 has no truth (a Vicon gap).
    truth = _truth_doc(
        {"0": [0, 0, "0.10000000000000000555111512312578270211815834045410157"], "1": [1, 0, 0]},
        ["A", "B"],
    )
    solution = Solution([_hypothesis(["A", "B"], ["A", "B"])], log_path="")
    result, truth_path = _write(tmp_path, solution, truth)
    ev = evaluate(solution, read_truth_file(truth_path))
    assert ev.pose_inside == [False, True, None]
    assert (ev.poses_with_truth, ev.poses_inside, ev.poses_without_truth) == (2, 1, 1)
    assert ev.misses == [
        "pose 0 theta=0.1000000000000000055511151 (decimal) not in [-0.1, 0.1] (mod 2pi)"
    ]
    assert (ev.landmarks_with_truth, ev.landmarks_inside) == (2, 2)
    assert ev.guarantee_held is False  # the sole survivor of a complete search misses
    out = tmp_path / "ev.json"
    assert main([
        "evaluate", result, "--truth", truth_path, "--json", str(out), "-q"
    ]) == 1  # fmt: skip
    doc = json.loads(out.read_text())
    assert doc["poses"] == {
        "total": 3,
        "with_truth": 2,
        "inside": 1,
        "share_inside": 0.5,
        "without_truth": 1,
        "truth_poses_not_in_result": 0,
    }
    assert doc["widths"]["x"] == {"median": 1.2 - 0.9, "p95": 2.4 - 1.8, "max": 2.4 - 1.8}


def test_widths_over_time_and_an_unbounded_box() -> None:
    h = _hypothesis(["A"], ["A"])
    h.poses[2, 0] = [-math.inf, math.inf]
    truth_doc = _truth_doc({"0": [0, 0, 0], "1": [1, 0, 0], "2": [2, 0, 0]}, ["A"])
    from cuikslam.simulate.truth import _truth_from_json

    ev = evaluate(Solution([h]), _truth_from_json(truth_doc))
    stats = ev.widths()
    assert stats["x"].max == math.inf and stats["x"].median == pytest.approx(0.3)
    assert [s["poses"] for s in ev.over_time()] == [1, 1, 1]
    doc = evaluation_to_json(ev)
    assert doc["widths"]["x"]["max"] is None  # JSON has no infinity
    assert doc["poses"]["inside"] == 3


def test_unknown_correspondence_rank_and_share_by_partition() -> None:
    # Truth: observations 0, 2 see A, observation 1 sees B. The best-ranked hypothesis
    # merges all three (observation 1 wrong: it follows #0 instead of being new, and
    # observation 2 follows #1 instead of #0); the second has the true partition under
    # other names.
    from cuikslam.simulate.truth import _truth_from_json

    truth = _truth_from_json(
        _truth_doc({"0": [0, 0, 0], "1": [1, 0, 0], "2": [2, 0, 0]}, ["A", "B", "A"])
    )
    wrong = _hypothesis(["L1", "L1", "L1"], ["L1"])
    right = _hypothesis(["L2", "L1", "L2"], ["L1", "L2"])
    ev = evaluate(Solution([wrong, right], statistics={"survivors": 2}), truth)
    assert (ev.true_rank, ev.evaluated_rank) == (2, 2)
    assert ev.correct_associations == 1
    # landmark L2 is A ([3, 5] x [0.5, 1.5] holds (3, 1)); L1 is B ([2, 4] misses 4.5)
    assert (ev.landmarks_with_truth, ev.landmarks_inside) == (2, 1)
    assert ev.guarantee_held is False


def test_named_landmarks_keep_their_names() -> None:
    # The log names A; a hypothesis that calls the landmark of observation 0 "B" (a new
    # landmark given the name B) and observation 1 "A" has the true partition but not the
    # true names.
    from cuikslam.simulate.truth import _truth_from_json

    truth = _truth_from_json(_truth_doc({"0": [0, 0, 0]}, ["A", "B"]))
    swapped = _hypothesis(["B", "A"], ["A", "B"])
    assert evaluate(Solution([swapped]), truth).true_rank == 1
    ev = evaluate(Solution([swapped], statistics={"survivors": 1}), truth, named={"A"})
    assert ev.true_rank is None and ev.correct_associations == 0
    assert ev.guarantee_held is False  # complete, every survivor reported, truth absent


def test_an_incomplete_search_without_the_truth_says_nothing() -> None:
    from cuikslam.simulate.truth import _truth_from_json

    truth = _truth_from_json(_truth_doc({"0": [0, 0, 0]}, ["A", "B"]))
    ev = evaluate(Solution([_hypothesis(["A", "A"], ["A"])], complete=False), truth)
    assert ev.true_rank is None and ev.guarantee_held is None


def test_cli_writes_tables_and_figure(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    truth = _truth_doc({"0": [0, 0, 0], "1": [1, 0, 0]}, ["A", "B"])
    result, truth_path = _write(tmp_path, Solution([_hypothesis(["A", "B"], ["A", "B"])]), truth)
    figure = tmp_path / "ev.png"
    assert main(["evaluate", result, "--truth", truth_path, "--figure", str(figure)]) == 0
    out = capsys.readouterr().out
    assert "2 of 2 (100.0 %)" in out and "poses without truth (not counted)" in out
    assert "pose x [m]" in out
    assert figure.stat().st_size > 10_000


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda r, t: Path(r).unlink(), "r.json: cannot read result file"),
        (lambda r, t: Path(t).write_text("{"), "t.truth.json:1: not valid JSON"),
        (
            lambda r, t: Path(t).write_text(json.dumps(_truth_doc({"0": [0, 0, 0]}, ["A"]))),
            "r.json: it assigns 1 observation, the result has 2",
        ),
        (
            lambda r, t: Path(t).write_text(json.dumps(_truth_doc({"7": [0, 0, 0]}, ["A", "B"]))),
            "r.json: it has 1 pose the result lacks (7)",
        ),
        (lambda r, t: Path(r).write_text('{"hypotheses": 3}'), "not a cuikslam result file"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_no_output(
    tmp_path: Path, capsys: pytest.CaptureFixture, make, expected: str
) -> None:
    truth = _truth_doc({"0": [0, 0, 0]}, ["A", "B"])
    result, truth_path = _write(tmp_path, Solution([_hypothesis(["A", "B"], ["A", "B"])]), truth)
    make(result, truth_path)
    out = tmp_path / "ev.json"
    assert main(["evaluate", result, "--truth", truth_path, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert expected in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_a_refuted_result_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    result, truth_path = _write(tmp_path, Solution([]), _truth_doc({"0": [0, 0, 0]}, []))
    assert main(["evaluate", result, "--truth", truth_path]) == 2
    assert "no hypothesis to evaluate" in capsys.readouterr().err


def test_the_pose_hull_over_every_survivor_is_checked_too() -> None:
    # The true correspondence is not reported (1 of 5 survivors shown), but the result's
    # pose hull over every survivor still holds each true pose; a hull that misses one is
    # a failure once the search is complete.
    from cuikslam.simulate.truth import _truth_from_json

    truth = _truth_from_json(
        _truth_doc({"0": [0, 0, 0], "1": [1, 0, 0], "2": [2, 0, 0]}, ["A", "B", "A"])
    )
    wrong = _hypothesis(["L1", "L1", "L1"], ["L1"])
    hull = wrong.poses.copy()
    stats = {"survivors": 5}
    ev = evaluate(Solution([wrong], statistics=stats, correspondence={"pose_hull": hull}), truth)
    assert (ev.true_rank, ev.hull_checked, ev.hull_inside) == (None, 3, 3)
    assert ev.guarantee_held is None  # the true one is among the 4 unreported
    hull[1, 0] = [1.5, 2.0]  # pose 1's truth x = 1 now misses the hull
    ev = evaluate(Solution([wrong], statistics=stats, correspondence={"pose_hull": hull}), truth)
    assert ev.hull_inside == 2 and ev.guarantee_held is False
    assert evaluation_to_json(ev)["pose_hull"] == {"with_truth": 3, "inside": 2}


def test_the_logs_named_landmarks_come_from_the_result_or_log(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # The log names landmark A on observation 1; the only survivor calls observation 0's
    # landmark "A" (a new landmark given that name) and observation 1's "B": the true
    # partition, but not with the log's names.
    log = tmp_path / "trip.jsonl"
    log.write_text(
        '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}\n'
        '{"type": "observation", "pose": 0, "class": "post", "range": [2, 3]}\n'
        '{"type": "observation", "pose": 0, "class": "post", "range": [2, 3], "landmark": "A"}\n'
    )
    truth = _truth_doc({"0": [0, 0, 0]}, ["B", "A"])
    solution = Solution([_hypothesis(["A", "B"], ["A", "B"])], log_path=str(log))
    result, truth_path = _write(tmp_path, solution, truth)
    out = tmp_path / "ev.json"
    assert main(["evaluate", result, "--truth", truth_path, "--json", str(out), "-q"]) == 1
    assert json.loads(out.read_text())["true_rank"] is None
    log.rename(tmp_path / "moved.jsonl")  # the result's log is gone: compared without names
    # Then the survivor is the true partition, and its landmark "A" (truly B at x = 4.5)
    # misses its box [2, 4]: the guarantee fails.
    assert main(["evaluate", result, "--truth", truth_path, "--json", str(out), "-q"]) == 1
    doc = json.loads(out.read_text())
    assert doc["true_rank"] == 1 and "is not there" in doc["notes"][0]
    assert doc["misses"] == ["landmark A x=4.5 not in [2.0, 4.0]"]
    args = ["evaluate", result, "--truth", truth_path, "--log", str(tmp_path / "moved.jsonl")]
    assert main([*args, "-q"]) == 1  # --log names it again
    assert main([*args[:-1], str(tmp_path / "nope.jsonl")]) == 2
    assert "nope.jsonl" in capsys.readouterr().err


def test_a_wrong_best_ranked_hypothesis_is_named_as_such(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """When the true correspondence is not reported, evaluate judges the best-ranked one and
    says it is not the true one, so that its boxes missing the truth read as expected, not
    as a broken guarantee (an adversarial tester's log, reported with --max-hypotheses 1)."""
    data = Path(__file__).parent / "data" / "adversary"
    log = data / "unchecked-outlier-unreported.jsonl"
    result = tmp_path / "r.json"
    assert main(["solve", str(log), "--max-hypotheses", "1", "--json", str(result), "-q"]) == 0
    capsys.readouterr()
    truth = data / "unchecked-outlier-unreported.truth.json"
    assert main(["evaluate", str(result), "--truth", str(truth)]) == 0
    out = capsys.readouterr().out
    assert "the best-ranked, not the true one" in " ".join(out.split())
    assert "miss the truth (of a hypothesis that is not the true one)" in " ".join(out.split())
    assert "the guarantee did not hold" not in out


def test_the_pose_hull_is_paired_with_poses_by_id_not_by_first_mention() -> None:
    """The pose hull is in increasing pose id; a hypothesis lists its poses as they first
    appear in the log. With pose 5 before pose 1, evaluate paired pose 5's truth with pose
    1's hull box and reported a failed guarantee (found by an adversarial helper)."""
    from cuikslam.log import parse_log_lines
    from cuikslam.simulate.truth import _truth_from_json
    from cuikslam.solver import solve

    log = parse_log_lines(
        [
            '{"type": "prior", "pose": 5, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
            '{"type": "observation", "pose": 5, "class": "a", "range": [2, 2.1], '
            '"bearing": [0.5, 0.6]}',
            '{"type": "odometry", "from": 5, "to": 1, "turn": [0, 0], "distance": [3, 3]}',
            '{"type": "observation", "pose": 1, "class": "a", "range": [1.5, 1.6], '
            '"bearing": [1.5, 1.7]}',
        ],
        path="hull.jsonl",
    )
    solution = solve(log, work_budget=7e6)
    assert solution.complete and solution.best.pose_ids == [5, 1]
    truth = _truth_from_json(
        {
            "poses": {"5": [0, 0, 0], "1": [3, 0, 0]},
            "landmarks": {
                "A": {"class": "a", "x": 1.7476752702219866, "y": 1.0715088193078513},
                "B": {"class": "a", "x": 2.9547407404330023, "y": 1.549339084714333},
            },
            "assignment": ["A", "B"],
        }
    )
    ev = evaluate(solution, truth)
    assert (ev.hull_checked, ev.hull_inside) == (2, 2)
    assert ev.guarantee_held is not False


LOG = (
    '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}\n'
    '{"type": "observation", "pose": 0, "class": "post", "range": [2, 4], "landmark": "A"}\n'
    '{"type": "odometry", "from": 0, "to": 1, "turn": [0, 0], "distance": [1, 1]}\n'
    '{"type": "observation", "pose": 1, "class": "post", "range": [1, 4]}\n'
)


@pytest.mark.parametrize(
    ("truth", "problem"),
    [
        pytest.param(
            _truth_doc({"0": [0, 0, 0], "1": [1, 0, 0], "2": [2, 0, 0]}, ["A", "B", "A"]),
            "it assigns 3 observations, the log has 2; it has 1 pose the log lacks (2)",
            id="bigger",
        ),
        pytest.param(
            _truth_doc({"0": [0, 0, 0]}, ["A"]),
            "it assigns 1 observation, the log has 2",
            id="smaller",
        ),
        pytest.param(
            {**_truth_doc({"0": [0, 0, 0]}, ["B", "B"]), "landmarks": {"B": [4.5, 1, "post"]}},
            "the log names 1 landmark it lacks (A)",
            id="renamed",
        ),
    ],
)
def test_the_truth_of_another_log_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture, truth: dict, problem: str
) -> None:
    """Against the log the result names, the log given with --log, or the result itself
    when its log is gone: one line naming both files, exit 2, no table, no output."""
    log = tmp_path / "trip.jsonl"
    log.write_text(LOG)
    hypothesis = _hypothesis(["A", "B"], ["A", "B"])
    solution = Solution([hypothesis], log_path=str(log))
    result, truth_path = _write(tmp_path, solution, truth)
    out, figure = tmp_path / "ev.json", tmp_path / "ev.png"
    args = ["evaluate", result, "--truth", truth_path, "--json", str(out), "--figure", str(figure)]
    for extra, against in (([], log), (["--log", str(log)], log)):
        assert main([*args, *extra]) == 2
        captured = capsys.readouterr()
        assert captured.out == "" and not out.exists() and not figure.exists()
        assert captured.err.splitlines() == [
            f"cuikslam: error: {truth_path} does not fit {against}: {problem}"
        ]
    if "log names" in problem:  # without the log, the names it gives are unknown
        return
    log.unlink()
    assert main(args) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and not out.exists() and not figure.exists()
    line = captured.err.splitlines()
    assert len(line) == 1 and f"{truth_path} does not fit {result}: it assigns" in line[0]


def test_a_fitting_truth_with_or_without_assignment_is_evaluated(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    log = tmp_path / "trip.jsonl"
    log.write_text(LOG)
    solution = Solution([_hypothesis(["A", "B"], ["A", "B"])], log_path=str(log))
    for assignment in (["A", "B"], []):
        result, truth_path = _write(tmp_path, solution, _truth_doc({"0": [0, 0, 0]}, assignment))
        assert main(["evaluate", result, "--truth", truth_path, "-q"]) == 0
        assert capsys.readouterr().err == ""


def test_evaluate_and_the_solve_overview_print_one_median() -> None:
    """An even number of poses: `cuikslam evaluate` and `cuikslam solve` (the overview) take
    the same median of the widths (the mean of the two middle ones), not two."""
    from cuikslam.results.overview import box_statistics

    h = _hypothesis(["A"], ["A"])
    h.poses = np.concatenate([h.poses, [[[3.0, 3.9], [-0.5, 0.5], [-0.4, 0.4]]]])
    h.pose_ids = [0, 1, 2, 3]
    truth_doc = _truth_doc(
        {"0": [0, 0, 0], "1": [1, 0, 0], "2": [2, 0, 0], "3": [3.5, 0, 0]}, ["A"]
    )
    from cuikslam.simulate.truth import _truth_from_json

    widths = evaluate(Solution([h]), _truth_from_json(truth_doc)).widths()
    overview = box_statistics(h.poses, h.pose_ids, ("x", "y", "θ"))
    assert [widths[k].median for k in ("x", "y", "theta")] == overview.median.tolist()
    assert widths["x"].median == pytest.approx((0.3 + 0.6) / 2)  # widths 0.2, 0.3, 0.6, 0.9
