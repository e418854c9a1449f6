"""What a solve may be asked: the consistency levels and every option with its default.

The one source of the solve options. The command line builds one :class:`SolveOptions`
from its flags (its choices and defaults come from here) and the object travels whole:
:func:`cuikslam.solver.solve` hands it to the correspondence search
(:func:`cuikslam.hypotheses.solve_unknown`, or its cluster twin) and the search to its
explorer and its workers; the level travels as a :class:`Level`. The public functions
also take the fields as keywords (``solve(log, consistency="hull")``), turned into an
object at once (:meth:`SolveOptions.merged`), so a level's name is checked in one place.
Importing this module loads nothing compiled, so ``cuikslam --help`` stays fast.

Examples
--------
>>> options = SolveOptions(consistency="hull")
>>> options.consistency is Level.HULL, options.max_hypotheses
(True, 100)
>>> options.replace(max_hypotheses=5).max_hypotheses
5
>>> [str(level) for level in Level]
['hull', 'lp', 'lp-split']
>>> Level.parse("auto") is Level.LP  # an older name of the default
True
"""

from __future__ import annotations

import dataclasses
import difflib
import enum
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal

from cuikslam.budget import walk_reserve_for, work_budget_for

__all__ = ["AMBIGUITY_LP_MIN_DECISIONS", "Level", "SolveOptions", "check_option_names"]

AMBIGUITY_LP_MIN_DECISIONS = 64
"""Searches of fewer decisions do without the ``lp`` level on ambiguous nodes, whatever
``strengthen_during``: their hull boxes have not grown far and their trees are small (on a
12-pose world the level cost 8 times the search and refuted nothing more). Used by
:mod:`cuikslam.hypotheses.explorer`; here so that the command line's help can say it."""


class Level(enum.StrEnum):
    """How hard the boxes are narrowed (a string: ``Level.LP == "lp"``).

    ``"auto"`` (the default of earlier versions) is accepted as a name of ``lp``, which
    is the default at any length: see ``docs/concepts/levels.md``.
    """

    HULL = "hull"
    """The fixpoint of the narrowing operators (fastest)."""
    LP = "lp"
    """``hull``, then rounds of the rigorous polytope-hull operator (much tighter)."""
    LP_SPLIT = "lp-split"
    """``lp``, then the widest headings bisected (tighter, and slower than ``lp``)."""
    AUTO = "lp"
    """Another name of ``lp`` (``Level.AUTO is Level.LP``), kept for earlier callers."""

    @classmethod
    def _missing_(cls, value: object) -> Level | None:
        return cls.LP if value == "auto" else None

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
        The level applied to the boxes (a level's name is accepted too; default ``lp``).
    max_hypotheses : int
        Survivors of the correspondence search reported in detail (the best-ranked); the
        search explores and counts all of them.
    strengthen_limit : int
        The level is applied to every reported hypothesis (in rank order) when at most
        this many are reported, else to the best-ranked one.
    strengthen_during : int or None
        Nodes of the unknown-correspondence search that would branch are first narrowed to
        level ``lp`` (briefly, see :meth:`cuikslam.hypotheses.explorer.Explorer.children`)
        during its first ``strengthen_during`` decisions (None: all of them; 0: off). Only
        a search of at least :data:`AMBIGUITY_LP_MIN_DECISIONS` (64) decisions does so: a
        shorter one has narrow boxes and a small tree, where the level cost more than it
        refuted.
    certify_limit : int or None
        Best-ranked hypotheses that get a witness search (None: every reported one).
    rtol : float
        Relative shrink below which propagation stops requeueing an operator.
    work_budget : float, "auto" or None
        Work units the whole solve may spend (see :mod:`cuikslam.budget`): the same log,
        options and version then give the same result on any machine and at any load.
        ``"auto"``: :func:`~cuikslam.budget.work_budget_for` the log's poses (more per
        pose when a correspondence search runs); None: no limit.
    time_budget : float or None
        An optional wall-clock cap, in seconds, on top of the work budget (None: none).
        When it binds, the result says so, and may differ from run to run.
    threads : int or None
        Threads the ``lp`` sweeps of a long log may use (None: the cores that other
        processes are not already using, from the CPU affinity and the load average), with
        known or unknown correspondence (there, the sweeps of the reported hypotheses). The
        boxes are the same for any number.
    max_nodes : int or None
        Node expansions after which the correspondence search stops, incomplete (None: no
        limit but the budget). Unknown correspondence only.
    local_frame : bool
        The correspondence search also narrows windows of poses in a frame fixed at one of
        them (:mod:`cuikslam.hypotheses.local`); off only to measure what that prunes.
        Unknown correspondence only.
    """

    consistency: Level = Level.LP
    max_hypotheses: int = 100
    strengthen_limit: int = 100
    strengthen_during: int | None = None
    certify_limit: int | None = None
    rtol: float = 1e-3
    work_budget: float | Literal["auto"] | None = "auto"
    time_budget: float | None = None
    threads: int | None = None
    max_nodes: int | None = None
    local_frame: bool = True

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
        if self.max_nodes is not None and self.max_nodes < 0:
            raise ValueError(f"max_nodes must be >= 0 (or None), got {self.max_nodes}")

    @classmethod
    def merged(
        cls,
        options: SolveOptions | None,
        overrides: dict[str, Any],
        caller: str,
        refused: dict[str, str] | None = None,
    ) -> SolveOptions:
        """``options`` (the defaults for None) with the keyword ``overrides`` of a public
        function's call: the entry point's one conversion.

        Parameters
        ----------
        options : SolveOptions or None
            The options given.
        overrides : dict
            Fields given as keywords, replacing those of ``options``.
        caller : str
            The function called, named in the errors (e.g. ``"solve"``).
        refused : dict, optional
            Fields ``caller`` does not use, each with why (a TypeError names it).

        Examples
        --------
        >>> SolveOptions.merged(None, {"consistency": "hull"}, "solve").consistency
        <Level.HULL: 'hull'>
        >>> SolveOptions.merged(None, {"work_budget": 1}, "f", {"work_budget": "pass deadline="})
        Traceback (most recent call last):
        ...
        TypeError: f() does not take work_budget: pass deadline=
        """
        check_option_names(overrides, caller)
        for name in overrides:
            if refused and name in refused:
                raise TypeError(f"{caller}() does not take {name}: {refused[name]}")
        return (options or cls()).replace(**overrides) if overrides else options or cls()

    def work_for(self, n_poses: int, search: bool = False) -> float | None:
        """The work budget of a log of ``n_poses`` poses (``"auto"`` resolved; ``search``:
        some of its readings lack their landmark id)."""
        if self.work_budget == "auto":
            return work_budget_for(n_poses, search)
        return None if self.work_budget is None else float(self.work_budget)

    def walk_reserve_for(self, n_poses: int, search: bool = False) -> float:
        """The work only the search's walk may spend beyond its share: with the ``"auto"``
        budget and a search, :func:`~cuikslam.budget.walk_reserve_for` the log's poses;
        none with a budget given (it bounds the whole solve)."""
        return walk_reserve_for(n_poses) if self.work_budget == "auto" and search else 0.0

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
