"""Writing logs: exact round trips, and atomic replacement that never leaves half a file."""

from __future__ import annotations

import dataclasses
import os
import stat
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cuikslam._atomic as atomic
import cuikslam.log.writer as writer
from cuikslam._atomic import atomic_open, atomic_write_text
from cuikslam.log import (
    InputFileError,
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
    Record,
    log_to_lines,
    parse_log_lines,
    read_log_file,
    write_log_file,
)

EXAMPLE = Log(
    [
        PosePrior(0, (15.0, 15.0), (5.0, 5.0), (-0.3927, -0.3927)),
        Odometry(0, 1, (0.70, 0.87), (7.40, 7.90)),
        Observation(1, "door", (4.98, 5.03), (-1.19, -1.17), "L0"),
        LandmarkPrior("L0", "door", (14.0, 16.0), (-1.0, 1.0)),
    ]
)
EXAMPLE_LINES = [
    '{"type": "prior", "pose": 0, "x": [15.0, 15.0], "y": [5.0, 5.0], "theta": [-0.3927, -0.3927]}',
    '{"type": "odometry", "from": 0, "to": 1, "turn": [0.7, 0.87], "distance": [7.4, 7.9]}',
    '{"type": "observation", "pose": 1, "class": "door", "range": [4.98, 5.03], '
    '"bearing": [-1.19, -1.17], "landmark": "L0"}',
    '{"type": "landmark", "id": "L0", "class": "door", "x": [14.0, 16.0], "y": [-1.0, 1.0]}',
]


def without_lines(records: list[Record]) -> list[Record]:
    return [dataclasses.replace(r, line=0) for r in records]


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


# --- strategies --------------------------------------------------------------------------

finite = st.floats(allow_nan=False, allow_infinity=False)
non_negative = st.floats(min_value=0.0, allow_nan=False, allow_infinity=False)
names = st.text(min_size=1, max_size=8)


def bounds(values: st.SearchStrategy[float] = finite) -> st.SearchStrategy[tuple[float, float]]:
    return st.tuples(values, values).map(lambda pair: (min(pair), max(pair)))


@st.composite
def logs(draw: st.DrawFn) -> Log:
    """Valid logs: a first prior, then records that respect reachability and classes."""
    reached = [draw(st.integers(0, 5))]
    records: list[Record] = [PosePrior(reached[0], draw(bounds()), draw(bounds()), draw(bounds()))]
    classes: dict[str, str] = {}
    scans: set[tuple[int, str]] = set()
    for kind in draw(st.lists(st.sampled_from("pOol"), max_size=12)):
        if kind == "p":
            pose = draw(st.integers(0, 2**40))
            records.append(PosePrior(pose, draw(bounds()), draw(bounds()), draw(bounds())))
            reached.append(pose)
        elif kind == "O":
            source = draw(st.sampled_from(reached))
            target = draw(st.integers(0, 2**40).filter(lambda t, s=source: t != s))
            records.append(Odometry(source, target, draw(bounds()), draw(bounds(non_negative))))
            reached.append(target)
        elif kind == "o":
            pose = draw(st.sampled_from(reached))
            landmark = draw(st.none() | names)
            if landmark is not None and (pose, landmark) in scans:
                continue
            cls = classes.get(landmark, draw(names)) if landmark is not None else draw(names)
            measured = draw(st.sampled_from(["range", "bearing", "both"]))
            records.append(
                Observation(
                    pose,
                    cls,
                    draw(bounds(non_negative)) if measured != "bearing" else None,
                    draw(bounds()) if measured != "range" else None,
                    landmark,
                )
            )
            if landmark is not None:
                classes[landmark] = cls
                scans.add((pose, landmark))
        else:
            landmark = draw(names)
            cls = classes.setdefault(landmark, draw(names))
            records.append(LandmarkPrior(landmark, cls, draw(bounds()), draw(bounds())))
    return Log(records)


# --- round trips -------------------------------------------------------------------------


def test_example_lines() -> None:
    assert log_to_lines(EXAMPLE) == EXAMPLE_LINES


def test_write_then_read_example(tmp_path: Path) -> None:
    path = tmp_path / "trip.jsonl"
    write_log_file(EXAMPLE, path)
    assert path.read_text(encoding="utf-8") == "\n".join(EXAMPLE_LINES) + "\n"
    log = read_log_file(path)
    assert without_lines(log.records) == EXAMPLE.records
    assert [r.line for r in log.records] == [1, 2, 3, 4]


def test_optional_observation_fields_are_omitted() -> None:
    log = Log([PosePrior(0, (0, 0), (0, 0), (0, 0)), Observation(0, "tree", None, (0.5, 0.6))])
    assert log_to_lines(log)[1] == (
        '{"type": "observation", "pose": 0, "class": "tree", "bearing": [0.5, 0.6]}'
    )


@settings(max_examples=200, deadline=None)
@given(logs())
def test_round_trip_through_lines(log: Log) -> None:
    again = parse_log_lines(log_to_lines(log))
    assert without_lines(again.records) == log.records
    assert [r.line for r in again.records] == list(range(1, len(log.records) + 1))
    assert log_to_lines(again) == log_to_lines(log)


@settings(max_examples=50, deadline=None)
@given(log=logs())
def test_round_trip_through_file(tmp_path_factory: pytest.TempPathFactory, log: Log) -> None:
    path = tmp_path_factory.mktemp("rt") / "log.jsonl"
    write_log_file(log, path)
    again = read_log_file(path)
    assert without_lines(again.records) == log.records
    for old, new in zip(log.records, again.records, strict=True):
        for name, value in dataclasses.asdict(old).items():
            if isinstance(value, tuple):
                assert [repr(v) for v in getattr(new, name)] == [repr(v) for v in value]


def test_numpy_like_values_are_normalised(tmp_path: Path) -> None:
    np = pytest.importorskip("numpy")
    log = Log([PosePrior(np.int64(3), (np.float64(0.1), 1), (0, 0), (np.float32(0.5), 1))])
    assert log_to_lines(log) == [
        '{"type": "prior", "pose": 3, "x": [0.1, 1.0], "y": [0.0, 0.0], "theta": [0.5, 1.0]}'
    ]


def test_non_finite_values_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "bad.jsonl"
    with pytest.raises(ValueError):
        write_log_file(Log([PosePrior(0, (0, float("nan")), (0, 0), (0, 0))]), path)
    assert not path.exists()
    assert leftovers(tmp_path) == []


def test_non_records_are_refused() -> None:
    with pytest.raises(TypeError, match="not a log record"):
        log_to_lines(Log(["prior"]))  # type: ignore[list-item]


# --- validation and atomicity --------------------------------------------------------------


def test_invalid_log_is_not_written_and_old_file_survives(tmp_path: Path) -> None:
    path = tmp_path / "trip.jsonl"
    path.write_text("old content\n")
    no_prior = Log([Odometry(0, 1, (0, 0), (1, 1))])
    with pytest.raises(InputFileError) as caught:
        write_log_file(no_prior, path)
    assert caught.value.path == str(path)
    assert "no pose has a prior" in caught.value.problem
    assert path.read_text() == "old content\n"
    assert leftovers(tmp_path) == []


def test_validation_error_names_the_line_in_the_written_file(tmp_path: Path) -> None:
    path = tmp_path / "trip.jsonl"
    log = Log([PosePrior(0, (0, 0), (0, 0), (0, 0)), Observation(0, "door", (2, 1), None)])
    with pytest.raises(InputFileError, match=r"trip\.jsonl:2: .*lo > hi"):
        write_log_file(log, path)
    assert not path.exists()


def test_validate_false_writes_anything_serialisable(tmp_path: Path) -> None:
    path = tmp_path / "empty.jsonl"
    write_log_file(Log([]), path, validate=False)
    assert path.read_text() == ""


def test_failure_midway_leaves_no_partial_file_and_old_file_intact(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "trip.jsonl"
    write_log_file(EXAMPLE, path)
    before = path.read_bytes()
    real = writer._record_to_line
    calls = []

    def flaky(record: Record) -> str:
        calls.append(record)
        if len(calls) == 3:
            raise RuntimeError("disk on fire")
        return real(record)

    monkeypatch.setattr(writer, "_record_to_line", flaky)
    bigger = Log([*EXAMPLE.records, *EXAMPLE.records[1:2]])
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_log_file(bigger, path)
    assert len(calls) == 3
    assert path.read_bytes() == before
    assert leftovers(tmp_path) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["trip.jsonl"]


def test_failure_midway_on_a_new_file_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(record: Record) -> str:
        raise RuntimeError("boom")

    monkeypatch.setattr(writer, "_record_to_line", broken)
    with pytest.raises(RuntimeError):
        write_log_file(EXAMPLE, tmp_path / "new.jsonl")
    assert list(tmp_path.iterdir()) == []


# --- the atomic helper ---------------------------------------------------------------------


def test_atomic_write_text_creates_and_replaces(tmp_path: Path) -> None:
    path = tmp_path / "out.txt"
    atomic_write_text(path, "one\r\ntwo\n")
    assert path.read_bytes() == b"one\r\ntwo\n"
    atomic_write_text(str(path), "three")
    assert path.read_text() == "three"
    assert leftovers(tmp_path) == []


def test_atomic_open_interrupted_keeps_old_content(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    path.write_text("old")
    with pytest.raises(KeyboardInterrupt), atomic_open(path) as file:
        file.write("half of the new")
        raise KeyboardInterrupt
    assert path.read_text() == "old"
    assert leftovers(tmp_path) == []


def test_atomic_open_binary(tmp_path: Path) -> None:
    path = tmp_path / "fig.png"
    with atomic_open(path, "wb") as file:
        file.write(b"\x89PNG")
    assert path.read_bytes() == b"\x89PNG"


def test_atomic_open_rejects_other_modes(tmp_path: Path) -> None:
    for mode in ("a", "r", "w+", "x"):
        with pytest.raises(ValueError, match="mode"), atomic_open(tmp_path / "f", mode):
            pass
    assert list(tmp_path.iterdir()) == []


def test_failed_replace_removes_the_temporary_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "out.txt"
    path.write_text("old")

    def refuse(src: str, dst: str) -> None:
        raise PermissionError("nope")

    monkeypatch.setattr(atomic.os, "replace", refuse)
    with pytest.raises(PermissionError):
        atomic_write_text(path, "new")
    assert path.read_text() == "old"
    assert leftovers(tmp_path) == []


def test_existing_permissions_are_kept(tmp_path: Path) -> None:
    path = tmp_path / "out.txt"
    path.write_text("old")
    path.chmod(0o640)
    atomic_write_text(path, "new")
    assert stat.S_IMODE(path.stat().st_mode) == 0o640


def test_new_file_gets_umask_permissions(tmp_path: Path) -> None:
    umask = os.umask(0o022)
    os.umask(umask)
    path = tmp_path / "out.txt"
    atomic_write_text(path, "new")
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


def test_missing_folder_raises_oserror(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        write_log_file(EXAMPLE, tmp_path / "no" / "such" / "trip.jsonl")
