"""What every survivor of a search contributes to its summary, reported in detail or not:
its assignment (for the correspondence summary, up to ``MAX_TALLIED`` of them) and its boxes
(joined into the :class:`~.envelope.Envelope`, with those of the subtrees left unexplored)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cuikslam.hypotheses.envelope import Envelope
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.outlier_option import OUTLIER
from cuikslam.hypotheses.tree import Node
from cuikslam.outcome.naming import new_mark, partition
from cuikslam.outcome.solution import OUTLIER as OUTLIER_MARK

__all__ = ["MAX_TALLIED", "Tally"]

MAX_TALLIED = 100_000
"""Survivors whose assignments the correspondence summary holds at most."""


class Tally:
    """What every survivor contributes to the summary, reported in detail or not."""

    def __init__(self, explorer: Explorer, on_survivor: Callable[[list[str]], None] | None):
        self.explorer = explorer
        self.on_survivor = on_survivor
        self.assignments: list[list[str] | None] = []
        self.new_mark = new_mark(explorer.problem.named)
        """Prefix of the landmarks a hypothesis adds (longer if a log id starts with it)."""
        self._position: dict[tuple[int, ...], int] = {}
        self.envelope = Envelope(explorer)
        """Every survivor's boxes, and those of the subtrees left unexplored."""

    def add(self, node: Node) -> None:
        self.add_assignment(node.decisions())
        self.envelope.add(node)

    def add_assignment(self, decisions: list[int]) -> None:
        """A survivor's assignment, given by its decisions (landmark numbers)."""
        p = self.explorer.problem
        tallied = len(self.assignments) < MAX_TALLIED
        if tallied or self.on_survivor is not None:
            assignment = [""] * p.n_observations
            for position, n in p.named_assignment.items():
                assignment[position] = p.named[n]
            n_named, mark = len(p.named), self.new_mark
            for d, n in zip(p.decisions, decisions, strict=True):
                # new landmarks are numbered in the order the log first sees them
                assignment[d.position] = (
                    OUTLIER_MARK
                    if n == OUTLIER
                    else p.named[n]
                    if n < n_named
                    else f"{mark}{n - n_named + 1}"
                )
            if self.on_survivor is not None:
                self.on_survivor(assignment)
            if tallied:
                self._position[tuple(decisions)] = len(self.assignments)
                self.assignments.append(assignment)

    def add_boxes(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Flat envelope boxes of survivors (:meth:`.Envelope.boxes_of`), joined in."""
        self.envelope.join(lo, hi)

    def discard(self, node: Node) -> None:
        """Forget a survivor proven impossible after the search (its pose boxes stay in the
        hull, which remains a sound outer bound)."""
        where = self._position.pop(tuple(node.decisions()), None)
        if where is not None:
            self.assignments[where] = None

    def discard_assignment(self, assignment: list[str]) -> None:
        """Forget a survivor given by its assignment (one the search did not keep as a
        node; its new landmarks named in any way), proven impossible after the search."""
        named = set(self.explorer.problem.named)
        wanted = partition(assignment, named)
        for k, tallied in enumerate(self.assignments):
            if tallied is not None and partition(tallied, named) == wanted:
                self.assignments[k] = None
                return

    def found(self) -> list[tuple[int, ...]] | None:
        """The decisions of every survivor found (None when more than ``MAX_TALLIED``:
        then they are not all held)."""
        if len(self.assignments) >= MAX_TALLIED:
            return None
        return list(self._position)

    def kept(self) -> list[list[str]]:
        """The assignments of the survivors not discarded."""
        return [a for a in self.assignments if a is not None]

    def poses(self) -> np.ndarray:
        """Every pose's envelope box (survivors and unexplored subtrees), shape
        (n_poses, 3, 2)."""
        n = len(self.envelope.pose_cols)
        return np.stack([self.envelope.lo[:n], self.envelope.hi[:n]], axis=-1).reshape(-1, 3, 2)
