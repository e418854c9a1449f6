"""Reading logs: the example parses, and every kind of bad input names its line and problem."""

from __future__ import annotations

import json
import math
import os
import pickle
from pathlib import Path

import pytest

from cuikslam.log import (
    InputFileError,
    LandmarkPrior,
    Observation,
    Odometry,
    PosePrior,
    parse_log_lines,
    read_log_file,
)

PRIOR = '{"type": "prior", "pose": 0, "x": [15, 15], "y": [5, 5], "theta": [-0.3927, -0.3927]}'
ODOMETRY = (
    '{"type": "odometry", "from": 0, "to": 1, "turn": [0.70, 0.87], "distance": [7.40, 7.90]}'
)
OBSERVATION = (
    '{"type": "observation", "pose": 1, "class": "door", "range": [4.98, 5.03], '
    '"bearing": [-1.19, -1.17], "landmark": "L0"}'
)
LANDMARK = '{"type": "landmark", "id": "L0", "class": "door", "x": [14, 16], "y": [-1, 1]}'
EXAMPLE = [PRIOR, ODOMETRY, OBSERVATION, LANDMARK]


def record(**fields: object) -> str:
    return json.dumps(fields)


def prior(pose: object = 0, **override: object) -> str:
    fields = {"type": "prior", "pose": pose, "x": [0, 1], "y": [0, 1], "theta": [0, 0.1]}
    return record(**{**fields, **override})


def odometry(source: object = 0, target: object = 1, **override: object) -> str:
    fields = {"type": "odometry", "from": source, "to": target, "turn": [0, 0.1]}
    return record(**{**fields, "distance": [1, 2], **override})


def observation(pose: object = 0, **override: object) -> str:
    fields = {"type": "observation", "pose": pose, "class": "door", "range": [1, 2]}
    return record(**{**fields, "bearing": [0, 0.1], **override})


def landmark(ident: object = "L0", **override: object) -> str:
    fields = {"type": "landmark", "id": ident, "class": "door", "x": [0, 1], "y": [0, 1]}
    return record(**{**fields, **override})


def fails(lines: list[str], line: int | None, *fragments: str) -> InputFileError:
    with pytest.raises(InputFileError) as caught:
        parse_log_lines(lines, path="trip.jsonl")
    err = caught.value
    assert err.path == "trip.jsonl"
    assert err.line == line, str(err)
    for fragment in fragments:
        assert fragment in err.problem, str(err)
    where = "trip.jsonl" if line is None else f"trip.jsonl:{line}"
    assert str(err) == f"{where}: {err.problem}"
    assert "\n" not in str(err)
    return err


# --- valid input -------------------------------------------------------------------------


def test_example_parses_into_records_with_lines() -> None:
    log = parse_log_lines(EXAMPLE)
    assert log.path == "<memory>"
    assert log.records == [
        PosePrior(0, (15.0, 15.0), (5.0, 5.0), (-0.3927, -0.3927), line=1),
        Odometry(0, 1, (0.70, 0.87), (7.40, 7.90), line=2),
        Observation(1, "door", (4.98, 5.03), (-1.19, -1.17), "L0", line=3),
        LandmarkPrior("L0", "door", (14.0, 16.0), (-1.0, 1.0), line=4),
    ]
    assert all(isinstance(v, float) for v in log.priors[0].x)


def test_comments_and_blank_lines_are_skipped_but_counted() -> None:
    log = parse_log_lines(["# a trip", "", "   ", PRIOR, "  # later", ODOMETRY])
    assert [r.line for r in log.records] == [4, 6]


def test_time_field_is_accepted_and_ignored() -> None:
    log = parse_log_lines([prior(time=0.5), odometry(time=3)])
    assert log.records[0] == PosePrior(0, (0.0, 1.0), (0.0, 1.0), (0.0, 0.1), line=1)


def test_range_only_bearing_only_and_null_optionals() -> None:
    log = parse_log_lines(
        [
            prior(),
            observation(bearing=None),
            record(type="observation", pose=0, **{"class": "tree"}, bearing=[1, 2]),
            observation(range=None, landmark=None),
        ]
    )
    first, second, third = log.observations
    assert first.bearing is None and first.range == (1.0, 2.0)
    assert second.range is None and second.bearing == (1.0, 2.0)
    assert third.range is None and third.landmark is None


def test_angles_may_be_unwrapped_and_wider_than_two_pi() -> None:
    log = parse_log_lines([prior(theta=[-20, 20]), odometry(turn=[7, 100])])
    assert log.priors[0].theta == (-20.0, 20.0)
    assert log.odometry[0].turn[1] - log.odometry[0].turn[0] > 2 * math.pi


def test_zero_width_and_zero_range_are_fine() -> None:
    log = parse_log_lines([prior(), odometry(distance=[0, 0]), observation(range=[0, 0])])
    assert log.odometry[0].distance == (0.0, 0.0)


def test_loop_closure_odometry_to_a_known_pose_is_fine() -> None:
    log = parse_log_lines([prior(), odometry(0, 1), odometry(1, 0)])
    assert len(log.odometry) == 2


def test_pose_reached_by_odometry_can_be_observed_and_left() -> None:
    log = parse_log_lines([prior(), odometry(0, 1), observation(1), odometry(1, 2)])
    assert log.pose_ids == [0, 1, 2]


def test_same_landmark_from_different_poses_is_fine() -> None:
    log = parse_log_lines(
        [
            prior(),
            landmark(),
            observation(0, landmark="L0"),
            odometry(),
            observation(1, landmark="L0"),
        ]
    )
    assert len(log.observations) == 2


def test_a_single_string_is_split_into_lines() -> None:
    log = parse_log_lines("\n".join(EXAMPLE) + "\n")
    assert [r.line for r in log.records] == [1, 2, 3, 4]


def test_read_log_file(tmp_path: Path) -> None:
    path = tmp_path / "trip.jsonl"
    path.write_text("# header\r\n" + "\r\n".join(EXAMPLE) + "\r\n", encoding="utf-8")
    log = read_log_file(path)
    assert log.path == str(path)
    assert [r.line for r in log.records] == [2, 3, 4, 5]
    assert log.records == parse_log_lines(["#", *EXAMPLE]).records


def test_read_log_file_accepts_a_byte_order_mark(tmp_path: Path) -> None:
    path = tmp_path / "bom.jsonl"
    path.write_bytes(b"\xef\xbb\xbf" + "\n".join(EXAMPLE).encode())
    assert len(read_log_file(path).records) == 4


def test_error_attributes_and_pickling() -> None:
    err = InputFileError("a.jsonl", 3, "bad thing")
    assert isinstance(err, ValueError)
    assert (err.path, err.line, err.problem) == ("a.jsonl", 3, "bad thing")
    assert str(err) == "a.jsonl:3: bad thing"
    assert str(InputFileError(Path("a.jsonl"), None, "bad")) == "a.jsonl: bad"
    again = pickle.loads(pickle.dumps(err))
    assert (again.path, again.line, again.problem, str(again)) == (
        err.path,
        err.line,
        err.problem,
        str(err),
    )


# --- bad input, one test per case ----------------------------------------------------------


@pytest.mark.parametrize(
    "text",
    ['{"type": "prior", "pose": 0', "{'type': 'prior'}", "prior 0 1 2", '{"type": "prior"} x'],
)
def test_malformed_json(text: str) -> None:
    fails([prior(), text], 2, "malformed JSON", "column")


@pytest.mark.parametrize(
    ("text", "kind"),
    [("[1, 2]", "an array"), ('"prior"', "a string"), ("3", "a number"), ("null", "null")],
)
def test_record_not_an_object(text: str, kind: str) -> None:
    fails([prior(), text], 2, f"record is {kind}", "JSON object")


def test_missing_type() -> None:
    fails([prior(), '{"pose": 0}'], 2, 'no "type" field', '"prior", "odometry"')


@pytest.mark.parametrize("kind", ['"priors"', '"Prior"', "3", "null", "[1]"])
def test_unknown_type(kind: str) -> None:
    fails([prior(), f'{{"type": {kind}}}'], 2, "unknown record type", "expected one of")


@pytest.mark.parametrize(
    ("text", "missing"),
    [
        (record(type="prior", pose=0, x=[0, 1], y=[0, 1]), "theta"),
        (record(type="odometry", to=1, turn=[0, 1], distance=[0, 1]), "from"),
        (record(type="observation", pose=0, range=[1, 2]), "class"),
        (record(type="landmark", id="L0", x=[0, 1], y=[0, 1]), "class"),
    ],
)
def test_missing_field(text: str, missing: str) -> None:
    fails([prior(), text], 2, f'missing field "{missing}"', "required fields")


def test_unknown_field_names_it_and_suggests_the_right_one() -> None:
    text = record(type="prior", pose=0, x=[0, 1], y=[0, 1], thetaa=[0, 1])
    fails([prior(), text], 2, 'unknown field "thetaa"', 'did you mean "theta"', "allowed fields")


def test_unknown_field_without_a_close_match() -> None:
    fails([prior(), observation(colour="red")], 2, 'unknown field "colour"', "allowed fields")


def test_duplicate_field() -> None:
    text = '{"type": "prior", "pose": 0, "x": [0, 1], "x": [2, 3], "y": [0, 1], "theta": [0, 0]}'
    fails([prior(), text], 2, 'field "x" appears twice')


@pytest.mark.parametrize(
    ("text", "field"),
    [
        (prior(x=[True, 1]), "x"),
        (prior(y=[0, False]), "y"),
        (prior(theta=["0", "1"]), "theta"),
        (odometry(turn=[None, 1]), "turn"),
        (observation(bearing=[{}, 1]), "bearing"),
    ],
)
def test_interval_with_non_numbers(text: str, field: str) -> None:
    fails([prior(), text], 2, f'field "{field}" must be an interval [lo, hi] of two numbers')


@pytest.mark.parametrize("value", [[1], [1, 2, 3], [], 1.5, "[1, 2]", {"lo": 1, "hi": 2}, True])
def test_interval_not_a_pair(value: object) -> None:
    fails([prior(), odometry(distance=value)], 2, 'field "distance" must be an interval')


def test_interval_lo_above_hi() -> None:
    fails([prior(), observation(bearing=[0.5, 0.4])], 2, 'field "bearing"', "lo > hi")


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity"])
def test_nan_and_infinity_tokens(token: str) -> None:
    text = f'{{"type": "prior", "pose": 0, "x": [0, {token}], "y": [0, 1], "theta": [0, 0]}}'
    fails([text], 1, f"{token} is not allowed", "finite")


@pytest.mark.parametrize("number", ["1e400", "1E999", "1" + "0" * 400])
def test_numbers_too_large_to_be_finite(number: str) -> None:
    text = f'{{"type": "prior", "pose": 0, "x": [0, 1], "y": [-{number}, 0], "theta": [0, 0]}}'
    fails([prior(), text], 2, 'field "y"', "not a finite number")


@pytest.mark.parametrize(
    ("text", "field"),
    [(observation(range=[-0.1, 1]), "range"), (odometry(distance=[-1, -0.5]), "distance")],
)
def test_negative_range_or_distance(text: str, field: str) -> None:
    fails([prior(), text], 2, f'field "{field}"', "cannot be negative")


@pytest.mark.parametrize("bad", [1.0, True, -1, "0", None, [0]])
@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda p: prior(pose=p), "pose"),
        (lambda p: odometry(source=p), "from"),
        (lambda p: odometry(target=p), "to"),
        (lambda p: observation(pose=p), "pose"),
    ],
)
def test_pose_id_not_a_non_negative_integer(make, field: str, bad: object) -> None:
    fails([prior(), make(bad)], 2, f'field "{field}" must be a non-negative integer pose id')


@pytest.mark.parametrize(
    ("text", "field"),
    [
        (observation(**{"class": ""}), "class"),
        (observation(**{"class": 3}), "class"),
        (observation(landmark=7), "landmark"),
        (observation(landmark=""), "landmark"),
        (landmark(ident=0), "id"),
        (landmark(**{"class": ["door"]}), "class"),
    ],
)
def test_names_must_be_non_empty_strings(text: str, field: str) -> None:
    fails([prior(), text], 2, f'field "{field}" must be a non-empty string')


@pytest.mark.parametrize("value", ["soon", True, None, [1]])
def test_time_must_be_a_number(value: object) -> None:
    fails([prior(), odometry(time=value)], 2, 'field "time" must be a number')


def test_time_must_be_finite() -> None:
    fails([prior(), odometry()[:-1] + ', "time": 1e999}'], 2, 'field "time"', "finite")


@pytest.mark.parametrize("extra", [{"range": None, "bearing": None}, {}])
def test_observation_without_range_and_bearing(extra: dict[str, object]) -> None:
    text = record(type="observation", pose=0, **{"class": "door"}, **extra)
    fails([prior(), text], 2, 'neither "range" nor "bearing"')


def test_odometry_from_pose_nothing_reaches() -> None:
    err = fails([prior(), odometry(0, 1), odometry(7, 8)], 3)
    assert err.problem == "odometry from pose 7, which no prior or earlier odometry reaches"


def test_odometry_before_the_prior_that_reaches_its_pose() -> None:
    fails([prior(0), odometry(5, 6), prior(5)], 2, "odometry from pose 5", "no prior")


def test_odometry_from_a_pose_reached_only_later() -> None:
    fails([prior(0), odometry(1, 2), odometry(0, 1)], 2, "odometry from pose 1")


def test_odometry_from_a_pose_to_itself() -> None:
    fails([prior(), odometry(0, 0)], 2, "from pose 0 to itself")


def test_observation_from_pose_nothing_reaches() -> None:
    err = fails([prior(), odometry(0, 1), observation(2)], 3)
    assert err.problem == "observation from pose 2, which no prior or earlier odometry reaches"


def test_observation_before_the_odometry_that_reaches_its_pose() -> None:
    fails([prior(), observation(1), odometry(0, 1)], 2, "observation from pose 1")


def test_landmark_prior_reappearing_with_another_class() -> None:
    lines = [prior(), landmark("L0"), landmark("L1"), landmark("L0", **{"class": "tree"})]
    err = fails(lines, 4, 'landmark "L0"', '"tree"', '"door" on line 2')
    assert err.problem == 'landmark "L0" has class "tree" here but class "door" on line 2'


def test_landmark_prior_disagreeing_with_an_earlier_observation() -> None:
    lines = [prior(), observation(landmark="L3"), landmark("L3", **{"class": "tree"})]
    fails(lines, 3, 'landmark "L3" has class "tree" here but class "door" on line 2')


def test_observation_class_disagreeing_with_landmark_prior() -> None:
    lines = [prior(), landmark("L0"), observation(landmark="L0", **{"class": "window"})]
    fails(lines, 3, 'landmark "L0" has class "window" here but class "door" on line 2')


def test_observation_class_disagreeing_with_earlier_observation() -> None:
    lines = [
        prior(),
        observation(landmark="L0"),
        odometry(),
        observation(1, landmark="L0", **{"class": "tree"}),
    ]
    fails(lines, 4, 'landmark "L0" has class "tree"', "line 2")


def test_one_scan_cannot_see_the_same_landmark_twice() -> None:
    lines = [prior(), observation(landmark="L0"), observation(landmark="L0", range=[5, 6])]
    fails(lines, 3, 'pose 0 already observed landmark "L0" on line 2', "distinct landmarks")


@pytest.mark.parametrize("lines", [[], [""], ["# only a comment", "   "]])
def test_empty_log(lines: list[str]) -> None:
    err = fails(lines, None)
    assert err.problem == "the log is empty"


def test_no_prior() -> None:
    err = fails([odometry(0, 1), observation(1)], None)
    assert err.problem == (
        'no pose has a prior: every position would be relative; add a {"type": "prior", ...} record'
    )


def test_no_prior_with_only_landmark_priors() -> None:
    fails([landmark()], None, "no pose has a prior")


def test_record_errors_win_over_order_errors() -> None:
    fails([prior(), odometry(4, 5), "oops"], 3, "malformed JSON")


# --- files -------------------------------------------------------------------------------


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.jsonl"
    with pytest.raises(InputFileError) as caught:
        read_log_file(path)
    assert (caught.value.path, caught.value.line) == (str(path), None)
    assert "cannot read the log" in caught.value.problem
    assert "No such file" in caught.value.problem


def test_directory_instead_of_file(tmp_path: Path) -> None:
    with pytest.raises(InputFileError) as caught:
        read_log_file(tmp_path)
    assert caught.value.line is None
    assert "cannot read the log" in caught.value.problem


@pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root can read anything"
)
def test_unreadable_file(tmp_path: Path) -> None:
    path = tmp_path / "secret.jsonl"
    path.write_text(PRIOR)
    path.chmod(0)
    try:
        with pytest.raises(InputFileError) as caught:
            read_log_file(path)
    finally:
        path.chmod(0o600)
    assert caught.value.line is None
    assert "Permission denied" in caught.value.problem


def test_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "latin1.jsonl"
    path.write_bytes(PRIOR.encode() + b'\n{"type": "observation", "class": "caf\xe9"}\n')
    with pytest.raises(InputFileError) as caught:
        read_log_file(path)
    assert caught.value.line is None
    assert "not UTF-8" in caught.value.problem
    assert str(caught.value).startswith(f"{path}: ")


def test_file_errors_carry_file_name_and_line(tmp_path: Path) -> None:
    path = tmp_path / "trip.jsonl"
    path.write_text("\n".join([PRIOR, "# c", odometry(3, 4)]) + "\n")
    with pytest.raises(InputFileError, match=r"trip\.jsonl:3: odometry from pose 3"):
        read_log_file(path)


def test_one_error_type_for_every_input_file(tmp_path) -> None:
    from cuikslam.simulate.truth import read_truth_file

    bad = tmp_path / "trip.truth.json"
    bad.write_text("{", encoding="utf-8")
    with pytest.raises(InputFileError, match=r"trip\.truth\.json"):
        read_truth_file(bad)
