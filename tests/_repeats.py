"""Property checks that skip a world they already passed on.

Hypothesis draws some worlds again: the mutations it makes of earlier examples often give
back one it had (in the default runs of ``test_guarantee.py``, 7 to 15 of every 60 to 100
examples, and often the costly ones, since it mutates the examples that took the most
choices). The checks are deterministic (node limits and work budgets, never the clock), so
a repeat of a world that passed proves nothing new: :func:`once_per_world` runs a check once
per distinct world and arguments, :func:`once_per_log` once per distinct log of a world
(a mixed log that names no observation is the unnamed one). A world that failed is never
recorded, so Hypothesis still replays and shrinks it.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Hashable
from typing import Any, TypeVar

__all__ = ["DESCRIPTIONS", "frozen", "once_per_log", "once_per_world"]

Check = TypeVar("Check", bound=Callable[..., None])
DESCRIPTIONS = frozenset({"notes"})
"""Fields of a world that only describe it for Hypothesis' report (the error bounds drawn,
say, of which the log may use none): left out of its key."""


def frozen(value: Any) -> Hashable:
    """``value`` (a world: dataclasses, dicts, lists, sets, floats, exact reals) as a
    hashable key, equal only for equal values (but for the :data:`DESCRIPTIONS` of a
    dataclass), and telling apart what float equality does not: ``-0.0`` and ``0.0``
    (compared by their hex form).

    Examples
    --------
    >>> frozen([0.0]) == frozen([-0.0]), frozen({"x": (1.5, "a")}) == frozen({"x": (1.5, "a")})
    (False, True)
    """
    if isinstance(value, float):
        return ("float", value.hex())
    if isinstance(value, dict):
        return ("dict", tuple((frozen(k), frozen(v)) for k, v in value.items()))
    if isinstance(value, list | tuple):
        return (type(value).__name__, tuple(frozen(v) for v in value))
    if isinstance(value, set | frozenset):
        return ("set", frozenset(frozen(v) for v in value))
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = [f.name for f in dataclasses.fields(value) if f.name not in DESCRIPTIONS]
        return (type(value).__name__, tuple(frozen(getattr(value, name)) for name in fields))
    hash(value)  # str, int, bool, None, an exact real: anything else must say so here
    return value


def once_per_world(check: Check) -> Check:
    """``check(world, *args, **kwargs)``, run once for each distinct ``world`` and arguments
    that pass.

    Parameters
    ----------
    check : callable
        A deterministic check of a world (a dataclass), raising on failure.

    Returns
    -------
    callable
        The same check, returning at once for a world and arguments it passed before.
    """
    passed: set[Hashable] = set()

    @functools.wraps(check)
    def checked(world: Any, *args: Any, **kwargs: Any) -> None:
        key = (frozen(world), frozen(args), frozen(kwargs))
        if key not in passed:
            check(world, *args, **kwargs)
            passed.add(key)

    return checked  # type: ignore[return-value]


def once_per_log(check: Check) -> Check:
    """``check(world, naming, *args, **kwargs)``, run once for each distinct log that
    ``world`` gives with ``naming`` (its ``lines(naming)``), world and arguments that pass.

    Which observations a world *could* name (its ``named``) is left out of the key: the
    log itself says which it does, so a mixed log that names none is checked once with the
    unnamed log of the same world.

    Parameters
    ----------
    check : callable
        A deterministic check of the log of a world (a dataclass with ``lines(naming)``
        and ``named``), raising on failure.

    Returns
    -------
    callable
        The same check, returning at once for a log, world and arguments it passed before.
    """
    passed: set[Hashable] = set()

    @functools.wraps(check)
    def checked(world: Any, naming: str, *args: Any, **kwargs: Any) -> None:
        unnamed = dataclasses.replace(world, named=[])
        key = (tuple(world.lines(naming)), frozen(unnamed), frozen(args), frozen(kwargs))
        if key not in passed:
            check(world, naming, *args, **kwargs)
            passed.add(key)

    return checked  # type: ignore[return-value]
