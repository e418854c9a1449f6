"""The helper that skips worlds a property check already passed on (:mod:`_repeats`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest

from _exact import MP
from _repeats import frozen, once_per_log, once_per_world


@dataclass
class Box:
    bounds: list[float]
    truth: dict[str, object] = field(default_factory=dict)
    tags: set[str] = field(default_factory=set)
    notes: str = ""


def test_a_passing_world_is_checked_once_per_arguments() -> None:
    seen: list[tuple[list[float], str]] = []

    @once_per_world
    def check(world: Box, level: str) -> None:
        seen.append((world.bounds, level))

    for world, level in [(Box([1.0, 2.0]), "hull"), (Box([1.0, 2.0]), "hull"),
                         (Box([1.0, 2.0]), "lp"), (Box([1.0, 2.5]), "hull")]:  # fmt: skip
        check(world, level)
    assert seen == [([1.0, 2.0], "hull"), ([1.0, 2.0], "lp"), ([1.0, 2.5], "hull")]


def test_keyword_arguments_count_too() -> None:
    seen: list[bool] = []

    @once_per_world
    def check(world: Box, level: str, certify: bool) -> None:
        seen.append(certify)

    for certify in (True, True, False):
        check(Box([1.0]), "hull", certify=certify)
    assert seen == [True, False]


def test_a_failing_world_is_checked_again() -> None:
    calls: list[int] = []

    @once_per_world
    def check(world: Box) -> None:
        calls.append(1)
        raise AssertionError("the truth is outside")

    for _ in range(2):
        with pytest.raises(AssertionError):
            check(Box([0.0, 1.0]))
    assert len(calls) == 2


@pytest.mark.parametrize(
    ("a", "b"),
    [
        (Box([0.0, 1.0]), Box([-0.0, 1.0])),  # equal as floats, not as data
        (Box([1.0], {"x": MP.mpf(1) / 3}), Box([1.0], {"x": MP.mpf(1) / 3 + MP.mpf(2) ** -1000})),
        (Box([1.0], tags={"a"}), Box([1.0], tags={"b"})),
        (Box([1.0], {"x": [1.0]}), Box([1.0], {"x": (1.0,)})),
    ],
)
def test_worlds_that_differ_anywhere_are_different(a: Box, b: Box) -> None:
    assert frozen(a) != frozen(b)
    assert frozen(a) == frozen(Box(list(a.bounds), dict(a.truth), set(a.tags)))


def test_an_unhashable_leaf_is_refused() -> None:
    with pytest.raises(TypeError):
        frozen(Box([1.0], {"x": bytearray(b"1")}))


def test_notes_only_describe_a_world() -> None:
    assert frozen(Box([1.0], notes="errors 0.2")) == frozen(Box([1.0], notes="errors 0.05"))


@dataclass
class Named:
    """A world whose log names the observations ``named`` says (of ``names``)."""

    names: list[str]
    named: list[bool]

    def lines(self, naming: str) -> list[str]:
        keep = {"all": [True] * len(self.names), "none": [False] * len(self.names)}
        kept = keep.get(naming, self.named)
        return [n if k else "?" for n, k in zip(self.names, kept, strict=True)]


def test_a_log_is_checked_once_whatever_naming_gave_it() -> None:
    seen: list[tuple[str, ...]] = []

    @once_per_log
    def check(world: Named, naming: str) -> None:
        seen.append(tuple(world.lines(naming)))

    check(Named(["A", "B"], [False, False]), "none")
    check(Named(["A", "B"], [False, False]), "mixed")  # names none: the same log
    check(Named(["A", "B"], [True, False]), "none")  # the same log again
    check(Named(["A", "B"], [True, False]), "mixed")
    check(Named(["A", "C"], [False, False]), "none")
    assert seen == [("?", "?"), ("A", "?"), ("?", "?")]
