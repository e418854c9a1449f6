"""What a solve may be asked: the consistency levels and every option with its default.

The one source of the solve options: :func:`cuikslam.solver.solve` takes a
:class:`SolveOptions` (or its fields as keywords), the search
(:func:`cuikslam.hypotheses.solve_unknown`) takes its defaults from it, and the command
line builds its choices and defaults from it. Importing this module loads nothing
compiled, so ``cuikslam --help`` stays fast.

Examples
--------
>>> options = SolveOptions(consistency="hull")
>>> options.consistency is Level.HULL, options.max_hypotheses
(True, 100)
>>> options.replace(max_hypotheses=5).max_hypotheses
5
>>> [str(level) for level in Level]
['auto', 'hull', 'lp', 'lp-split']
"""

from __future__ import annotations

import dataclasses
import difflib
import enum
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal

from cuikslam.budget import work_budget_for

__all__ = ["Level", "SolveOptions", "check_option_names"]


class Level(enum.StrEnum):
    """How hard the boxes are narrowed (a string: ``Level.LP == "lp"``)."""

    AUTO = "auto"
    """``lp``, whatever the length of the log."""
    HULL = "hull"
    """The fixpoint of the narrowing operators (fastest)."""
    LP = "lp"
    """``hull``, then rounds of the rigorous polytope-hull operator (much tighter)."""
    LP_SPLIT = "lp-split"
    """``lp``, then the widest headings bisected (tighter, and slower than ``lp``)."""

    @classmethod
    def parse(cls, value: str) -> Level:
        """The level named ``value``; ValueError naming the choices otherwise."""
        try:
            return cls(value)
        except ValueError:
            choices = ", ".join(level.value for level in cls)
            raise ValueError(
                f"unknown consistency level {value!r}; choose one of {choices}"
            ) from None


@dataclass(frozen=True)
class SolveOptions:
    """The options of a solve, each with its default.

    Attributes
    ----------
    consistency : Level
        The level applied to the boxes (a level's name is accepted too).
    max_hypotheses : int
        Survivors of the correspondence search reported in detail (the best-ranked); the
        search explores and counts all of them.
    strengthen_limit : int
        The level is applied to every reported hypothesis (in rank order) when at most
        this many are reported, else to the best-ranked one.
    strengthen_during : int or None
        Nodes of the unknown-correspondence search that would branch are first narrowed to
        level ``lp`` (briefly, see :meth:`cuikslam.hypotheses.explorer.Explorer.children`)
        during its first ``strengthen_during`` decisions (None: all of them; 0: off).
    certify_limit : int or None
        Best-ranked hypotheses that get a witness search (None: every reported one).
    rtol : float
        Relative shrink below which propagation stops requeueing an operator.
    work_budget : float, "auto" or None
        Work units the whole solve may spend (see :mod:`cuikslam.budget`): the same log,
        options and version then give the same result on any machine and at any load.
        ``"auto"``: :func:`~cuikslam.budget.work_budget_for` the log's poses; None: no
        limit.
    time_budget : float or None
        An optional wall-clock cap, in seconds, on top of the work budget (None: none).
        When it binds, the result says so, and may differ from run to run.
    threads : int or None
        Threads the ``lp`` sweeps of a long log may use (None: the cores that other
        processes are not already using, from the CPU affinity and the load average). The
        boxes are the same for any number.
    """

    consistency: Level = Level.AUTO
    max_hypotheses: int = 100
    strengthen_limit: int = 100
    strengthen_during: int | None = None
    certify_limit: int | None = None
    rtol: float = 1e-3
    work_budget: float | Literal["auto"] | None = "auto"
    time_budget: float | None = None
    threads: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "consistency", Level.parse(self.consistency))
        if self.work_budget != "auto" and self.work_budget is not None:
            if not isinstance(self.work_budget, int | float) or not self.work_budget >= 0:
                raise ValueError(
                    f"work_budget must be a number >= 0, 'auto' or None, got {self.work_budget!r}"
                )
        if self.time_budget is not None and not self.time_budget >= 0:
            raise ValueError(f"time_budget must be >= 0 seconds or None, got {self.time_budget}")
        if self.threads is not None and self.threads < 1:
            raise ValueError(f"threads must be at least 1 (or None), got {self.threads}")

    def work_for(self, n_poses: int) -> float | None:
        """The work budget of a log of ``n_poses`` poses (``"auto"`` resolved)."""
        if self.work_budget == "auto":
            return work_budget_for(n_poses)
        return None if self.work_budget is None else float(self.work_budget)

    def replace(self, **changes: Any) -> SolveOptions:
        """A copy with ``changes`` (TypeError on a name that is not an option)."""
        check_option_names(changes, "SolveOptions.replace")
        return dataclasses.replace(self, **changes)


def check_option_names(names: Iterable[str], caller: str) -> None:
    """Refuse a keyword that is not a field of :class:`SolveOptions`.

    Parameters
    ----------
    names : iterable of str
        The keywords given.
    caller : str
        The function they were given to, named in the error (e.g. ``"solve"``).

    Raises
    ------
    TypeError
        Naming ``caller``, the keyword and the closest option name (or every option name
        when none is close).

    Examples
    --------
    >>> check_option_names(["consistensy"], "solve")
    Traceback (most recent call last):
    ...
    TypeError: solve() got an unexpected keyword argument 'consistensy'; did you mean 'consistency'?
    """
    options = [f.name for f in dataclasses.fields(SolveOptions)]
    for name in names:
        if name in options:
            continue
        close = difflib.get_close_matches(name, options, n=1)
        hint = f"did you mean {close[0]!r}?" if close else f"the options are {', '.join(options)}"
        raise TypeError(f"{caller}() got an unexpected keyword argument {name!r}; {hint}")
