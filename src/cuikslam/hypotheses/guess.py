"""A first guess fast: whole scans decided at once, for the witness search to prove.

The dive (:mod:`.dive`) expands every node of its path by the search's rules: each
candidate landmark of each reading narrowed, "a new landmark" narrowed with its negative
information, windows checked in local frames, branching nodes narrowed to ``lp``. On a
long log that is a few milliseconds a reading, and most readings have one candidate:
on sparse worlds of 200 poses, 19 of 1,317 readings branch on the true path.

The guess walks the same tree a scan at a time. It assigns the scan's readings together
to distinct landmarks (of their class, not seen by the scan already, through the interval
gate), least sum of distances from where each reading puts its landmark to the
landmark's centre, a new landmark only where no known one passes the gate
(:func:`_choices`), and narrows the whole scan once: its observations, the negative information
of its new landmarks and of the scan, the class priors, and one window in a local frame.
Where that is proven empty, the scan is decided reading by reading with the search's own
expansion, depth first; where that fails too, the scans before it are decided again the
same way, up to ``MAX_BACK`` scans back.

A guess only proposes: its leaf counts for nothing until the witness search proves it
consistent (:func:`.dive.early_hypothesis`), and a proven hypothesis is one that every
sound search keeps. So nothing the guess skips can cut the truth or add a survivor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from cuikslam.budget import COSTS, spend
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.problem import observation_rows
from cuikslam.hypotheses.tree import Node, SearchLimit, aside

__all__ = ["MAX_BACK", "REPAIR_NODES", "RTOL", "Guess", "first_guess", "scans"]

MAX_BACK = 8
"""Scans a repair may go back, at most."""
REPAIR_NODES = 256
"""Node expansions of one repair (the search's own, reading by reading), at most."""
IMPOSSIBLE = 1e12
"""Cost of a landmark a reading cannot see (another class, seen by its scan already,
outside the gate) in a scan's assignment."""
NEW = 1e6
"""Cost of a new landmark in a scan's assignment: more than any distance, so that a
known landmark through the gate is preferred."""
RTOL = 0.05
"""The propagation of a scan's observations stops where variables shrink by less than
this share of their width (the search's ``rtol`` is 1e-3): a weaker fixpoint, as sound.
On a 1,000-pose sparse world (seed 0) it is 1,500 operator applications a scan instead
of 10,000, the guess 3.0 s instead of 6.1 s, and the same guess."""


@dataclass
class Guess:
    """What a guess reached and what it cost.

    Attributes
    ----------
    leaf : Node or None
        The full assignment guessed (None: a repair failed, or the budget stopped it).
    scans : int
        Scans decided at once.
    expansions : int
        Nodes expanded reading by reading (where a scan at once was proven empty).
    repairs : int
        Scans decided reading by reading.
    """

    leaf: Node | None = None
    scans: int = 0
    expansions: int = 0
    repairs: int = 0


def scans(explorer: Explorer) -> list[tuple[int, int]]:
    """The decisions of each scan, ``(first, end)``, in order: consecutive decisions of the
    same scan, up to the one that completes it."""
    decisions = explorer.problem.decisions
    out = []
    k = 0
    while k < len(decisions):
        j = k + 1
        while (
            j < len(decisions)
            and not decisions[j - 1].completes_scan
            and decisions[j].scan == decisions[k].scan
        ):
            j += 1
        out.append((k, j))
        k = j
    return out


def first_guess(explorer: Explorer, root: Node, limit: SearchLimit) -> Guess:
    """A full assignment from ``root``, a scan at a time (see the module's docstring).

    The explorer's statistics are left as they were. Logs with an ``outliers``
    declaration are not guessed (their leaf is None): the dive handles them.

    Parameters
    ----------
    explorer : Explorer
        Expands nodes by the search's rules where a scan at once fails.
    root : Node
        Where the guess starts.
    limit : SearchLimit
        Its budget; the guess stops with no leaf when it is spent.

    Returns
    -------
    Guess
        The leaf (or None) and the work done.
    """
    found = Guess()
    if explorer.problem.outlier is not None:
        return found
    with aside(explorer.stats, limit):
        found.leaf = _walk(explorer, root, limit, found)
    return found


def _walk(explorer: Explorer, root: Node, limit: SearchLimit, found: Guess) -> Node | None:
    """The leaf a scan at a time from ``root`` (None: a repair failed, or the budget
    stopped it), the work counted in ``found``."""
    ranges = scans(explorer)
    starts: list[Node] = []
    node, s = root, 0
    while s < len(ranges):
        if limit.exhausted(found.scans + found.expansions) is not None:
            return None
        starts[s:] = [node]
        first, end = ranges[s]
        made = _scan_at_once(explorer, node, first, end, limit)
        found.scans += 1
        if made is None:
            made, path = _repair(explorer, starts, ranges, s, limit, found)
            if made is None:
                return None
            starts[s + 1 - len(path) : s + 1] = path
        node, s = made, s + 1
    return node


def _scan_at_once(
    explorer: Explorer, node: Node, first: int, end: int, limit: SearchLimit
) -> Node | None:
    """``node`` with decisions ``first`` to ``end`` made at once (each reading's first
    candidate, or a new landmark), narrowed by the constraints the search would add
    reading by reading; None when one of them is proven empty."""
    p, graph = explorer.problem, explorer.graph
    applications = graph.applications
    made = _decided(explorer, node, first, end)
    d = p.decisions[end - 1]
    if made is not None and p.has_sensor and d.completes_scan:
        made = explorer.unseen_scans(made, [d.pose])
    if made is not None and explorer.local is not None:
        if explorer.local.refutes(graph, made.overlay, d.pose, False):
            made = None
    spend(limit.deadline, COSTS["node"] + COSTS["operator"] * (graph.applications - applications))
    return made


def _decided(explorer: Explorer, node: Node, first: int, end: int) -> Node | None:
    """The scan's choices (:func:`_choices`) and their constraints: observations, new
    landmarks (class prior, negative information), class separations."""
    p, graph = explorer.problem, explorer.graph
    all_xs = explorer.landmark_xs(node)
    classes = [explorer.landmark_class(node, n) for n in range(len(all_xs))]
    chosen = _choices(explorer, node, first, end, all_xs, classes)
    rows, new, numbers = [], [], []
    blocks, assigned = list(node.blocks), node.assigned
    for k, number in zip(range(first, end), chosen, strict=True):
        d = p.decisions[k]
        if number >= 0:
            rows.append(observation_rows(p, d, all_xs[[number]]))
        else:
            number = len(all_xs) + len(new)
            new.append((k, classes.count(d.landmark_class)))
            classes.append(d.landmark_class)
            blocks.append(k)
        numbers.append(number)
        assigned = (number, assigned)
    overlay = node.overlay
    if rows:
        overlay = graph.add_rows(overlay, graph.intern(np.concatenate(rows)), RTOL)
    for k, of_class in new:
        if overlay is None:
            return None
        overlay = explorer.new_landmark(overlay, k, of_class)
    if overlay is None:
        return None
    made = Node(end, overlay, tuple(blocks), assigned, lp_depth=node.lp_depth, lp_gap=node.lp_gap)
    return None if any(explorer.too_close(made, n) for n in numbers) else made


def _choices(
    explorer: Explorer,
    node: Node,
    first: int,
    end: int,
    all_xs: np.ndarray,
    classes: list[str],
) -> list[int]:
    """The landmark each reading of the scan sees (-1: a new one): the assignment of
    distinct landmarks through the interval gate whose distances (centre of where the
    reading puts its landmark to centre of the landmark) sum least, fewest new landmarks
    first. Reading by reading, the nearest first would swap two look-alike landmarks
    that a scan sees side by side (1,000-pose sparse world, seed 4: 35 readings)."""
    p, graph = explorer.problem, explorer.graph
    seen = explorer.seen_by(node, p.decisions[first].scan)
    n_readings, n_known = end - first, len(all_xs)
    cost = np.full((n_readings, n_known + n_readings), IMPOSSIBLE)
    cost[np.arange(n_readings), n_known + np.arange(n_readings)] = NEW
    for r, k in enumerate(range(first, end)):
        d = p.decisions[k]
        free = [n for n, c in enumerate(classes) if c == d.landmark_class and n not in seen]
        numbers = np.array(free, dtype=np.int64)
        passed = graph.gate(node.overlay, d.sensor_x, all_xs[numbers], d.bearing_var, d.range_var)
        numbers = numbers[passed]
        if len(numbers):
            cost[r, numbers] = np.minimum(explorer.gaps(node, d, all_xs[numbers]), NEW / 2)
    rows, cols = linear_sum_assignment(cost)
    chosen = [-1] * n_readings
    for r, c in zip(rows, cols, strict=True):
        chosen[r] = int(c) if c < n_known else -1
    return chosen


def _repair(
    explorer: Explorer,
    starts: list[Node],
    ranges: list[tuple[int, int]],
    s: int,
    limit: SearchLimit,
    found: Guess,
) -> tuple[Node | None, list[Node]]:
    """Scans ``s - b`` to ``s`` decided again reading by reading (depth first, the
    search's expansion), for b = 0, 1, ... ``MAX_BACK``: the node at the end of scan
    ``s`` and the nodes at the starts of scans ``s - b`` to ``s`` on its path (None
    when none reaches it)."""
    end = ranges[s][1]
    scan_start = {first: i for i, (first, _) in enumerate(ranges)}
    for back in range(min(MAX_BACK, s) + 1):
        begin = starts[s - back]
        stack: list[tuple[Node, tuple[Node, ...]]] = [(begin, ())]
        tried = 0
        while stack and tried < REPAIR_NODES:
            if limit.exhausted(found.scans + found.expansions) is not None:
                return None, []
            node, path = stack.pop()
            if node.depth == end:
                found.repairs += back + 1
                return node, list(path)
            if node.depth in scan_start:
                path = (*path, node)
            applications = explorer.graph.applications
            kids, _ = explorer.children(node, narrow=False)
            tried += 1
            found.expansions += 1
            spend(
                limit.deadline,
                COSTS["node"] + COSTS["operator"] * (explorer.graph.applications - applications),
            )
            stack.extend((kid, path) for kid in reversed(kids))
    return None, []
