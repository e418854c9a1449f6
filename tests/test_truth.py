"""Truth files in both layouts, kept exact, and the exact truth check (``check_truth``).

The reproducers' truth files hold decimal strings of up to 60 digits: a box bound equal to
the nearest float of such a value may still miss it, and only an exact comparison tells.
"""

from __future__ import annotations

import json
import subprocess
import sys
from decimal import Decimal
from fractions import Fraction
from pathlib import Path

import mpmath
import numpy as np
import pytest

from _exact import MP, TWO_PI, angle_inside, mpf
from cuikslam.errors import InputFileError
from cuikslam.interval.angles import _pi_enclosure
from cuikslam.log import parse_log_lines
from cuikslam.log.reader import read_log_file
from cuikslam.results.solution import Hypothesis, Solution, check_truth
from cuikslam.simulate.truth import (
    GroundTruth,
    TruthMisfit,
    TruthMismatchError,
    _truth_from_json,
    check_truth_fits,
    read_truth_file,
    truth_misfit,
)

DATA = Path(__file__).parent / "data"
REPRO = DATA / "repro"


def hypothesis(pose_box: list[list[float]], landmark_box: list[list[float]]) -> Hypothesis:
    """One pose (id 0) and one landmark ("L0") with the given boxes."""
    return Hypothesis(
        assignment=["L0"],
        pose_ids=[0],
        poses=np.array([pose_box], float),
        landmark_ids=["L0"],
        landmark_classes=["c"],
        landmarks=np.array([landmark_box], float),
    )


def log_name(truth_path: Path) -> str:
    return truth_path.name.removesuffix(".truth.json") + ".jsonl"


def below(x: float) -> float:
    return float(np.nextafter(x, -np.inf))


def above(x: float) -> float:
    return float(np.nextafter(x, np.inf))


# --- reading ---------------------------------------------------------------------------


@pytest.mark.parametrize("path", sorted(REPRO.glob("*.truth.json")), ids=lambda p: p.name)
def test_repro_truth_files_are_read_exactly(path: Path) -> None:
    doc = json.loads(path.read_text(encoding="utf-8"))
    truth = read_truth_file(path)
    assert truth.pose_ids == [int(k) for k in doc["poses"]]
    assert truth.landmark_ids == list(doc["landmarks"])
    assert truth.landmark_classes == [v[2] for v in doc["landmarks"].values()]
    assert truth.assignment == doc["obs_truth"]
    for row, exact, text in zip(
        truth.poses_xyt, truth.exact_poses(), doc["poses"].values(), strict=True
    ):
        assert list(exact) == [Fraction(Decimal(t)) for t in text]
        assert list(row) == [float(Decimal(t)) for t in text]  # nearest floats
    for lid, (x, y, _cls) in doc["landmarks"].items():
        assert truth.exact_landmark(lid) == (Fraction(Decimal(x)), Fraction(Decimal(y)))
        np.testing.assert_array_equal(truth.landmark_xy(lid), [float(x), float(y)])


def test_numbers_and_strings_mix_and_the_assignment_has_three_names(tmp_path: Path) -> None:
    poses = {"3": [1, "0.1", 0.1], "7": ["-2.5e-3", "1E2", "-0"]}
    landmarks = {"A": ["1", 2.0, "door"], "B": {"class": "door", "x": "0.3", "y": 4}}
    for key in ("assignment", "obs_truth", "observation_landmark"):
        path = tmp_path / f"{key}.json"
        path.write_text(json.dumps({"poses": poses, "landmarks": landmarks, key: ["B", "A"]}))
        truth = read_truth_file(path)
        assert truth.assignment == ["B", "A"]
        assert truth.pose_ids == [3, 7]
        # the string "0.1" is the decimal 1/10; the JSON number 0.1 is the double 0.1
        assert truth.exact_poses()[0] == (1, Fraction(1, 10), Fraction(0.1))
        assert truth.exact_poses()[1] == (Fraction(-25, 10_000), 100, 0)
        assert truth.exact_landmark("B") == (Fraction(3, 10), 4)
        assert truth.landmark_class("A") == "door"
        assert truth.poses_xyt[0, 1] == 0.1


def test_json_numbers_are_doubles_unless_longer(tmp_path: Path) -> None:
    """A number printed as a double's shortest decimal is that double; a longer one is exact."""
    long = "0.4963798642739724717198527465614949627954107281141256669848"
    path = tmp_path / "truth.json"
    path.write_text(
        '{"poses": {"1": [-0.39269908169872414, 1e-05, ' + long + '], "2": [5e-324, 2, 1.5]},'
        ' "landmarks": {}, "obs_truth": []}'
    )
    truth = read_truth_file(path)
    assert truth.exact_poses()[0] == (
        Fraction(-0.39269908169872414),
        Fraction(1e-05),
        Fraction(Decimal(long)),
    )
    assert truth.exact_poses()[1] == (Fraction(5e-324), 2, Fraction(3, 2))
    assert truth.poses_xyt[0, 2] == float(long)


def test_own_truth_files_check_exactly_against_their_floats(tmp_path: Path) -> None:
    """A file written by write_truth_file reads back as the very same doubles."""
    from cuikslam.simulate import simulate_paper
    from cuikslam.simulate.truth import write_truth_file

    truth = simulate_paper(0)[1]
    write_truth_file(truth, tmp_path / "t.json")
    back = read_truth_file(tmp_path / "t.json")
    assert back.exact_poses() == [tuple(Fraction(float(v)) for v in row) for row in truth.poses_xyt]


@pytest.mark.parametrize(
    ("doc", "problem"),
    [
        ({"poses": {}, "landmarks": {}}, "assignment"),
        ({"poses": {}, "landmarks": {}, "obs_truth": [], "assignment": []}, "both"),
        ({"poses": {"1": [0, 0, "nan"]}, "landmarks": {}, "obs_truth": []}, "finite"),
        ({"poses": {"1": [0, 0, "Infinity"]}, "landmarks": {}, "obs_truth": []}, "finite"),
        ({"poses": {"1": [0, 0, "0x10"]}, "landmarks": {}, "obs_truth": []}, "finite"),
        ({"poses": {"1": [0, 0, "1_0"]}, "landmarks": {}, "obs_truth": []}, "finite"),
        ({"poses": {"1": [0, 0, ""]}, "landmarks": {}, "obs_truth": []}, "finite"),
        ({"poses": {"1": [0, 0, "1e400"]}, "landmarks": {}, "obs_truth": []}, "float range"),
        ({"poses": {"1": [0, 0, "1e-99999999"]}, "landmarks": {}, "obs_truth": []}, "range"),
        ({"poses": {"1": [0, 0, "1" * 3000]}, "landmarks": {}, "obs_truth": []}, "finite"),
        ({"poses": {"1": [0, 0, None]}, "landmarks": {}, "obs_truth": []}, "finite"),
        ({"poses": {}, "landmarks": {"L0": ["1", "2"]}, "obs_truth": []}, "class"),
        ({"poses": {}, "landmarks": {"L0": ["1", "2", 3]}, "obs_truth": []}, "class"),
        ({"poses": {}, "landmarks": {"L0": ["x", "2", "c"]}, "obs_truth": []}, "finite"),
        ({"poses": {}, "landmarks": {}, "obs_truth": ["L9"]}, "obs_truth"),
        ({"poses": {}, "landmarks": {}, "obs_truth": "L0"}, "list"),
    ],
)
def test_malformed_truth_files_name_the_problem(tmp_path: Path, doc: dict, problem: str) -> None:
    path = tmp_path / "truth.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputFileError, match=problem) as caught:
        read_truth_file(path)
    assert caught.value.path == str(path)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ('{"poses": {"1": [0, 0, 1e400]}, "landmarks": {}, "obs_truth": []}', "float range"),
        ('{"poses": {"1": [0, 0, NaN]}, "landmarks": {}, "obs_truth": []}', "finite"),
        ('{"poses": {"1": [0, 0, ' + "9" * 5000 + ']}, "landmarks": {}, "obs_truth": []}', "JSON"),
    ],
)
def test_malformed_json_numbers(tmp_path: Path, text: str, problem: str) -> None:
    path = tmp_path / "truth.json"
    path.write_text(text)
    with pytest.raises(InputFileError, match=problem):
        read_truth_file(path)


# --- does the truth fit its log ------------------------------------------------------------

LOG_LINES = [
    '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
    '{"type": "landmark", "id": "M", "class": "post", "x": [4, 6], "y": [0, 1]}',
    '{"type": "odometry", "from": 0, "to": 1, "turn": [0, 0], "distance": [1, 1]}',
    '{"type": "observation", "pose": 0, "class": "post", "range": [2, 3], "landmark": "A"}',
    '{"type": "observation", "pose": 1, "class": "post", "range": [1, 2]}',
]


def truth_of(poses: list[int], landmarks: list[str], assignment: list[str]) -> GroundTruth:
    return _truth_from_json(
        {
            "poses": {str(p): [p, 0, 0] for p in poses},
            "landmarks": {m: {"class": "post", "x": 2, "y": 0} for m in landmarks},
            "assignment": assignment,
        }
    )


@pytest.mark.parametrize(
    ("truth", "expected"),
    [
        pytest.param(truth_of([0, 1], ["A", "M"], ["A", "A"]), TruthMisfit(2, 2), id="fits"),
        pytest.param(truth_of([1], ["A", "M"], ["A", "M"]), TruthMisfit(2, 2), id="vicon-gap"),
        pytest.param(
            truth_of([0, 1, 2, 3], ["A", "M"], ["A", "A", "M"]),
            TruthMisfit(3, 2, count_differs=True, extra_poses=(2, 3)),
            id="bigger",
        ),
        pytest.param(
            truth_of([0], ["A", "M"], ["A"]), TruthMisfit(1, 2, count_differs=True), id="smaller"
        ),
        pytest.param(
            truth_of([0, 1], ["B"], ["B", "B"]),
            TruthMisfit(2, 2, missing_landmarks=("A", "M")),
            id="other-names",
        ),
        pytest.param(
            truth_of([0, 1], ["A", "M"], []), TruthMisfit(0, 2, count_differs=True), id="unassigned"
        ),
    ],
)
def test_truth_misfit_finds_what_does_not_fit_the_log(
    truth: GroundTruth, expected: TruthMisfit
) -> None:
    log = parse_log_lines(LOG_LINES, path="trip.jsonl")
    named = {"A", "M"}
    misfit = truth_misfit(truth, log.pose_ids, len(log.observations), named)
    assert misfit == expected
    assert bool(misfit) is (expected != TruthMisfit(2, 2))
    if misfit:
        with pytest.raises(TruthMismatchError) as caught:
            check_truth_fits(truth, "t.truth.json", log)
        assert isinstance(caught.value, InputFileError)
        assert caught.value.misfit == expected
        assert str(caught.value) == f"t.truth.json does not fit trip.jsonl: {misfit.describe()}"
        assert "\n" not in str(caught.value)
    else:
        check_truth_fits(truth, "t.truth.json", log)


def test_a_truth_without_assignment_fits_where_it_may() -> None:
    log = parse_log_lines(LOG_LINES, path="trip.jsonl")
    unassigned = truth_of([0, 1], ["A", "M"], [])
    check_truth_fits(unassigned, "t.truth.json", log, assignment_optional=True)
    short = truth_of([0, 1], ["A", "M"], ["A"])
    with pytest.raises(TruthMismatchError, match=r"it assigns 1 observation, the log has 2$"):
        check_truth_fits(short, "t.truth.json", log, assignment_optional=True)


def test_a_truth_is_held_against_a_result_when_its_log_is_not_at_hand() -> None:
    result = Solution([hypothesis([[0, 0], [0, 0], [0, 0]], [[1, 3], [-1, 1]])])
    check_truth_fits(truth_of([0], ["Z"], ["Z"]), "t.truth.json", result, "r.json")
    with pytest.raises(TruthMismatchError) as caught:
        check_truth_fits(truth_of([0, 5], ["Z"], ["Z", "Z"]), "t.truth.json", result, "r.json")
    assert str(caught.value) == (
        "t.truth.json does not fit r.json: it assigns 2 observations, the result has 1; "
        "it has 1 pose the result lacks (5)"
    )


def test_many_missing_ids_are_shortened() -> None:
    misfit = TruthMisfit(3, 3, extra_poses=tuple(range(10, 200)), missing_landmarks=("B", "C"))
    assert misfit.describe() == (
        "it has 190 poses the log lacks (10, 11, 12, …, 199); the log names 2 landmarks it "
        "lacks (B, C)"
    )


@pytest.mark.parametrize(
    "path",
    sorted(p for p in DATA.rglob("*.truth.json") if p.with_name(log_name(p)).is_file()),
    ids=lambda p: p.name,
)
def test_every_truth_file_of_the_tests_fits_its_log(path: Path) -> None:
    check_truth_fits(read_truth_file(path), path, read_log_file(path.with_name(log_name(path))))


def test_cli_refuses_a_bad_truth_file_in_one_line(tmp_path: Path) -> None:
    log = tmp_path / "trip.jsonl"
    log.write_text((REPRO / "mixed-true-refuted.jsonl").read_text())
    bad = tmp_path / "bad.truth.json"
    bad.write_text('{"poses": {"0": ["1", "2", "three"]}, "landmarks": {}, "obs_truth": []}')
    result = subprocess.run(
        [sys.executable, "-m", "cuikslam.cli.main", "solve", str(log), "--truth", str(bad)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert str(bad) in lines[0] and "three" in lines[0]


# --- the exact check ---------------------------------------------------------------------


def test_pi_enclosure_holds_pi_tightly() -> None:
    lo, hi = _pi_enclosure()
    assert 0 < hi - lo < Fraction(1, 10**400)
    ctx = mpmath.MPContext()
    ctx.prec = 2000  # finer than the enclosure (1e-409 is about 2**-1359)
    assert ctx.mpf(lo.numerator) / lo.denominator < ctx.pi < ctx.mpf(hi.numerator) / hi.denominator


def test_a_decimal_truth_just_beyond_a_float_bound_is_a_miss() -> None:
    x = "0.496379864273972471719852746561494962795410728114125666984801"
    near = float(x)  # the float nearest to x: a bound equal to it may exclude x
    if Fraction(near) < Fraction(x):
        tight, wide = [below(near), near], [below(near), above(near)]
    else:
        tight, wide = [near, above(near)], [below(near), above(near)]
    h = hypothesis([tight, [0, 1], [0, 0]], [[0, 1], [0, 1]])
    report = check_truth(h, [0], [[x, "0.5", "0"]])
    assert len(report.misses) == 1
    assert report.misses[0].startswith("pose 0 x=0.49637986427397247171985")
    assert report.misses[0].endswith(f"not in {tight}")
    # with the nearest float the check passes: this is what the exact comparison adds
    assert check_truth(h, [0], [[near, 0.5, 0.0]]).ok
    h = hypothesis([wide, [0, 1], [0, 0]], [[0, 1], [0, 1]])
    assert check_truth(h, [0], [[x, "0.5", "0"]]).ok


def test_landmarks_are_compared_exactly_too() -> None:
    h = hypothesis([[0, 1], [0, 1], [0, 0]], [[0.1, 0.2], [0.1, 0.2]])
    # the float 0.1 is above the decimal 0.1: the decimal misses [0.1, 0.2], the float is in
    report = check_truth(h, [0], [[0, 0, 0]], {"L0": (Fraction(1, 10), 0.1)})
    assert report.misses == ["landmark L0 x=0.1 (decimal) not in [0.1, 0.2]"]
    assert report.checked == 5
    # the float 0.2 is 0.20000000000000001110...: a decimal just beyond it misses
    assert check_truth(h, [0], [[0, 0, 0]], {"L0": (0.1, "0.2")}).ok
    beyond = "0.200000000000000011103"
    assert check_truth(h, [0], [[0, 0, 0]], {"L0": (0.1, beyond)}).misses == [
        f"landmark L0 y={beyond} (decimal) not in [0.1, 0.2]"
    ]


@pytest.mark.parametrize(
    ("theta_box", "inside"),
    [
        (["2pi", "2pi"], False),  # fl(2π) < 2π: heading 0 is not in [fl(2π), fl(2π)]
        (["2pi", "2pi+"], True),
        (["-2pi", "-2pi"], False),  # -fl(2π) > -2π
        (["-2pi+", "-2pi"], True),
    ],
)
def test_headings_are_compared_modulo_an_exact_two_pi(theta_box: list, inside: bool) -> None:
    two_pi = float(TWO_PI)
    assert mpf(two_pi) < TWO_PI < mpf(above(two_pi))
    named = {"2pi": two_pi, "2pi+": above(two_pi), "-2pi": -two_pi, "-2pi+": -above(two_pi)}
    box = [named[b] for b in theta_box]
    assert angle_inside(box[0], box[1], mpf(0.0)) is inside  # the reference agrees
    h = hypothesis([[0, 0], [0, 0], box], [[0, 1], [0, 1]])
    report = check_truth(h, [0], [[0, 0, 0]])
    assert report.ok is inside
    if not inside:
        assert report.misses == [f"pose 0 theta=0.0 not in {box} (mod 2pi)"]


@pytest.mark.parametrize("k", [-(10**9), -3, -1, 1, 2, 7, 10**6, 10**9])
def test_headings_many_turns_away(k: int) -> None:
    """A heading k turns away: the box from mpmath's 2πk, one ulp each side, and beside it."""
    truth = "0.25"
    centre = MP.mpf("0.25") + k * TWO_PI
    lo = float(centre)
    lo = lo if mpf(lo) <= centre else below(lo)
    hi = above(lo)
    assert mpf(lo) <= centre <= mpf(hi)
    for box, inside in [([lo, hi], True), ([below(lo), below(below(lo))], False)]:
        box = sorted(box)
        assert angle_inside(box[0], box[1], MP.mpf("0.25")) is inside
        h = hypothesis([[0, 0], [0, 0], box], [[0, 1], [0, 1]])
        assert check_truth(h, [0], [[0, 0, truth]]).ok is inside


def test_wide_heading_boxes_contain_every_heading() -> None:
    h = hypothesis([[0, 0], [0, 0], [-3.1, 3.1]], [[0, 1], [0, 1]])  # misses (3.1, 2π - 3.1)
    assert not check_truth(h, [0], [[0, 0, "3.15"]]).ok
    assert check_truth(h, [0], [[0, 0, "3.2"]]).ok  # 3.2 - 2π = -3.083...
    assert check_truth(h, [0], [[0, 0, "-9.3"]]).ok  # -9.3 + 2π = -3.016...
    assert not check_truth(h, [0], [[0, 0, "-9.4"]]).ok  # -9.4 + 4π = 3.166...
    full = hypothesis([[0, 0], [0, 0], [0.0, 6.3]], [[0, 1], [0, 1]])
    assert check_truth(full, [0], [[0, 0, "12345.678"]]).ok
    empty = hypothesis([[0, 0], [0, 0], [1.0, 0.0]], [[0, 1], [0, 1]])
    assert not check_truth(empty, [0], [[0, 0, "0.5"]]).ok


def test_cli_truth_check_is_exact(tmp_path: Path) -> None:
    """``cuikslam solve --truth`` compares the exact truth: the decimal 0.1 is not in the box
    [0.1, 0.1] of the double 0.1 (a float comparison would call it inside)."""
    log = tmp_path / "trip.jsonl"
    log.write_text(
        '{"type": "prior", "pose": 0, "x": [0.1, 0.1], "y": [0.0, 0.0], "theta": [0.0, 0.0]}\n'
        '{"type": "odometry", "from": 0, "to": 1, "turn": [0.0, 0.0], "distance": [1.0, 1.0]}\n'
    )
    truth = tmp_path / "trip.truth.json"
    truth.write_text(
        '{"poses": {"0": ["0.1", "0", "0"], "1": ["1.1", "0", "0"]}, "landmarks": {},'
        ' "obs_truth": []}'
    )
    result = subprocess.run(
        [sys.executable, "-m", "cuikslam.cli.main", "solve", str(log), "--truth", str(truth)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert "Traceback" not in result.stderr, result.stderr
    assert result.returncode == 1, result.stdout[-1500:]
    assert "pose 0 x=0.1 (decimal) not in [0.1, 0.1]" in result.stdout
