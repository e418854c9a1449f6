"""The fast JSON paths (orjson when installed) read and write what the strict ones do.

A log line decoded by orjson is used only when the strict decoder would give the same
object; every other line (duplicate keys, NaN, huge integers, malformed text) goes to the
strict reader, which words the error exactly as without orjson.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from cuikslam import _json
from cuikslam.errors import InputFileError
from cuikslam.log.reader import parse_log_lines
from cuikslam.results.io import read_result_file, write_result_file
from cuikslam.results.solution import Hypothesis, Solution

PRIOR = '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}'

needs_orjson = pytest.mark.skipif(not _json.HAVE_ORJSON, reason="orjson is not installed")


@pytest.fixture(params=["fast", "strict"])
def decoder(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Run a test with orjson (when installed) and with the standard library only."""
    if request.param == "strict":
        monkeypatch.setattr(_json, "orjson", None)
    elif not _json.HAVE_ORJSON:
        pytest.skip("orjson is not installed")
    return request.param


@needs_orjson
@pytest.mark.parametrize(
    "text",
    [
        '{"a": 1, "a": 2}',  # orjson keeps the last silently
        '{"a": 1, "a" : 2}',
        '{"a": 1,\t"a"\n:\r2}',
        '{"a": {"b": 1}}',  # nested: more key ends than keys
        '{"a": "x\\":"}',  # a string value holding ":
        '[{"a": 1}]',
        '{"a": NaN}',
        '{"a": 123456789012345678901234567890}',
        "{'a': 1}",
    ],
)
def test_fast_decoder_declines_what_it_cannot_vouch_for(text: str) -> None:
    assert _json.loads_object(text) is None


@needs_orjson
def test_fast_decoder_returns_plain_records() -> None:
    assert _json.loads_object(PRIOR) == json.loads(PRIOR)


@pytest.mark.parametrize(
    ("line", "fragment"),
    [
        ('{"type": "prior", "pose": 0, "pose": 1, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
         'field "pose" appears twice'),
        ('{"type": "prior", "pose": 0, "x": [NaN, 0], "y": [0, 0], "theta": [0, 0]}',
         "NaN is not allowed"),
        ('{"type": "prior", "pose": 0, "x": [1e400, 2e400], "y": [0, 0], "theta": [0, 0]}',
         "not a finite number"),
        ('{"type": "prior", "pose": 0, "x": [1.5, 0.5], "y": [0, 0], "theta": [0, 0]}',
         "with lo > hi"),
        ('{"type": "prior", "pose": 99999999999999999999999, "x": [0, 0], "y": [0, 0], '
         '"theta": [0, 0]}', None),
        ('{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]',
         "malformed JSON"),
        ('{"type": "odometry", "from": 0, "to": 1, "turn": [0.0, 0.1], "distance": [-0.5, 1.0]}',
         "cannot be negative"),
        ('{"type": "odometry", "from": 0, "to": 1, "turn": [0.0, true], "distance": [0.5, 1.0]}',
         "must be an interval"),
    ],
)  # fmt: skip
def test_same_verdict_with_and_without_orjson(decoder: str, line: str, fragment: str | None):
    text = f"{PRIOR}\n{line}\n"
    if fragment is None:  # a valid line: read alike either way
        assert parse_log_lines(text).records[1].pose == 99999999999999999999999
        return
    with pytest.raises(InputFileError) as caught:
        parse_log_lines(text, path="log.jsonl")
    assert caught.value.line == 2
    assert fragment in str(caught.value)


finite = st.floats(allow_nan=False, allow_infinity=False)


ordered = st.lists(finite, min_size=2, max_size=2).map(sorted)
lengths = st.lists(st.floats(min_value=0.0, allow_infinity=False), min_size=2, max_size=2).map(
    sorted
)


@given(turn=ordered, distance=lengths)
def test_odometry_read_alike_with_and_without_orjson(turn: list[float], distance: list[float]):
    (a, b), (c, d) = turn, distance
    line = json.dumps({"type": "odometry", "from": 0, "to": 1, "turn": [a, b], "distance": [c, d]})
    fast = parse_log_lines([PRIOR, line]).records[1]
    saved, _json.orjson = _json.orjson, None
    try:
        strict = parse_log_lines([PRIOR, line]).records[1]
    finally:
        _json.orjson = saved
    assert fast == strict
    assert fast.turn == (a, b) and fast.distance == (c, d)
    assert all(type(v) is float for v in (*fast.turn, *fast.distance))


def _solution(witness: dict | None = None, timing: float = 0.5) -> Solution:
    poses = np.array([[[0.1, 0.2], [-math.inf, 1.0], [-1.0, 1e300]]])
    h = Hypothesis(
        assignment=["L0"],
        pose_ids=[3],
        poses=poses,
        landmark_ids=["L0"],
        landmark_classes=["door"],
        landmarks=np.array([[[1 / 3, 2 / 3], [5.0, math.inf]]]),
        witness=witness,
    )
    return Solution(hypotheses=[h], statistics={"nodes": 7}, timings={"solve_s": timing})


@pytest.mark.parametrize(
    "solution",
    [
        _solution(),
        _solution(witness={"poses_xyt": [[0.15, 0.5, 0.0]], "landmarks_xy": [[0.5, math.nan]]}),
        _solution(timing=math.nan),
    ],
)
def test_result_file_reads_back_alike_with_and_without_orjson(decoder, tmp_path, solution):
    path = tmp_path / "result.json"
    write_result_file(solution, path)
    back = read_result_file(path)
    h, b = solution.hypotheses[0], back.hypotheses[0]
    np.testing.assert_array_equal(b.poses, h.poses)
    np.testing.assert_array_equal(b.landmarks, h.landmarks)
    if h.witness is not None:  # NaN stays NaN (the fast writer would have made it null)
        np.testing.assert_array_equal(b.witness["landmarks_xy"], h.witness["landmarks_xy"])
    assert back.statistics == solution.statistics
    assert math.isnan(back.timings["solve_s"]) == math.isnan(solution.timings["solve_s"])


def test_an_unbounded_pose_hull_is_written_as_null_and_read_back_infinite(
    decoder, tmp_path
) -> None:
    """JSON has no infinity: the pose hull over every survivor was written ``Infinity``
    (not JSON) where a move allowed 1.5e308 m twice (found by an adversarial helper)."""
    hull = [[[0.0, math.inf], [-math.inf, 0.0], [0.0, 0.0]]]
    solution = _solution()
    solution.correspondence = {"follows": [], "certain": [], "factors": [], "pose_hull": hull}
    path = tmp_path / "result.json"
    write_result_file(solution, path)

    def refuse(constant: str) -> None:
        raise ValueError(f"not JSON: {constant}")

    doc = json.loads(path.read_text(), parse_constant=refuse)
    assert doc["correspondence"]["pose_hull"] == [[[0.0, None], [None, 0.0], [0.0, 0.0]]]
    assert read_result_file(path).correspondence["pose_hull"] == hull
