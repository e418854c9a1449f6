"""Lanes that agree on their future, walked once: the joined walk of the search.

An ambiguity can stay open for hundreds of readings: a few neighbouring readings may see
one landmark or another, and the robot comes back to that corner only much later. Depth
first, the search then walks the readings in between once per combination (*lane*) that
survives, and every walk makes the same decisions. When the lanes below a branching node
have agreed on every decision for :data:`JOIN_AGREE` readings, they are *joined*: one node
whose box is the hull of theirs and whose constraints are those every lane holds walks
their common future once. Its constraints are a subset of every lane's and its box a
superset, so what refutes it refutes every lane with the same future; a leaf of the joined
walk (a *suffix*) is then checked against each lane in turn (:func:`combine`): the lane's
box met with the leaf's (which holds every solution of every lane with that suffix), the
suffix's constraints added, narrowed once, and the leaf's bisection.

A landmark that only some lanes hold (one lane's new landmark is another lane's known
one) keeps in the joined walk only the constraints every lane holds (its slot is where
its reading puts it, in every lane) and those of the suffixes that name it (a lane that
does not hold it is not a lane of such a suffix): negative information, the class priors'
separation and their counts apply to the landmarks every lane holds, and to the rest when
a suffix is checked against a lane. An unexplored joined node stands for each of
its lanes with its suffix (:func:`lane_paths`), and its boxes hold each of theirs.
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import replace

import numpy as np

from cuikslam.budget import COSTS, spend
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.tree import Lanes, Node, SearchLimit

__all__ = [
    "JOIN_AGREE",
    "JOIN_MAX_EXPANSIONS",
    "JOIN_MAX_LANES",
    "combine",
    "join",
    "joined_children",
    "joined_leaves",
    "joined_paths",
    "lane_paths",
    "leave_where_partial",
    "look_ahead",
]

JOIN_AGREE = 16
"""Consecutive decisions on which every lane below a branching node must agree (one child
each, the same landmark) before the lanes are joined."""
JOIN_MAX_LANES = 256
"""Lanes a look-ahead follows at most; more, and the search goes on depth first (seed 6 of
the 200-pose sparse worlds: 140 lanes at reading 418, 14 left when they are joined at
585)."""
JOIN_MAX_EXPANSIONS = 20_000
"""Expansions a look-ahead makes at most before the search goes on depth first (the
nodes it made are pushed on the stack, so no work is lost: only the order changes)."""


def landmark_key(node: Node, number: int, n_named: int) -> Hashable:
    """What landmark ``number`` of ``node`` is, whatever the numbering: a named landmark,
    or the decision that created it."""
    if number < n_named:
        return ("named", number)
    return ("made", node.blocks[number - n_named])


def can_join(explorer: Explorer, nodes: list[Node]) -> bool:
    """Whether ``nodes`` (of one depth) may be joined: plain nodes, no outliers, and a scan
    starts at their depth (a scan's readings see distinct landmarks, a rule on the whole
    scan)."""
    p = explorer.problem
    depth = nodes[0].depth
    if p.outlier is not None or depth == 0 or depth >= len(p.decisions):
        return False
    if p.decisions[depth].scan == p.decisions[depth - 1].scan:
        return False
    return all(n.lanes is None and n.depth == depth for n in nodes)


def join(explorer: Explorer, nodes: list[Node]) -> Node:
    """The joined node of ``nodes`` (:func:`can_join`): the hull of their boxes, every
    variable's over every lane (a lane that does not hold a landmark still bounds its
    slot, where its reading puts what it sees: a constraint of the root), and the
    constraints they all hold."""
    graph, n_named = explorer.graph, explorer.n_named
    blocks = tuple(sorted({k for n in nodes for k in n.blocks}))
    boxes = [graph.materialize(n.overlay) for n in nodes]
    lo = np.minimum.reduce([b[0] for b in boxes])
    hi = np.maximum.reduce([b[1] for b in boxes])
    common = set(range(n_named))
    common.update(n_named + j for j, k in enumerate(blocks) if all(k in n.blocks for n in nodes))
    rows = nodes[0].overlay.rows
    for n in nodes[1:]:
        rows = np.intersect1d(rows, n.overlay.rows, assume_unique=True)
    counts: dict[str, int] = {}
    for n in nodes:
        held: dict[str, int] = {}
        for number in range(n_named + len(n.blocks)):
            cls = explorer.landmark_class(n, number)
            held[cls] = held.get(cls, 0) + 1
        for cls in {*counts, *held}:
            counts[cls] = min(counts.get(cls, held.get(cls, 0)), held.get(cls, 0))
    lanes = Lanes(tuple(nodes), nodes[0].depth, blocks, frozenset(common), counts)
    explorer.stats.joins += 1
    explorer.stats.joined_lanes += len(nodes)
    return Node(
        nodes[0].depth,
        graph.overlay_of(lo, hi, rows),
        blocks,
        None,
        share=sum(n.share for n in nodes),
        lp_depth=max(n.lp_depth for n in nodes),
        lp_gap=min(n.lp_gap for n in nodes),
        lanes=lanes,
    )


def _lane_number(lanes: Lanes, lane: Node, number: int, n_named: int) -> int | None:
    """Joined-node landmark ``number`` in ``lane``'s numbering; None when the lane does
    not hold it."""
    if number < n_named:
        return number
    m = number - n_named
    if m >= len(lanes.blocks):  # made after the join: after the lane's own
        return n_named + len(lane.blocks) + m - len(lanes.blocks)
    k = lanes.blocks[m]
    return n_named + lane.blocks.index(k) if k in lane.blocks else None


def _suffix_in(lanes: Lanes, lane: Node, suffix: list[int], n_named: int) -> list[int] | None:
    out = []
    for number in suffix:
        mine = _lane_number(lanes, lane, number, n_named)
        if mine is None:
            return None
        out.append(mine)
    return out


def lane_paths(node: Node, n_named: int) -> list[list[int]]:
    """Every decision of each hypothesis prefix that ``node`` stands for, in that prefix's
    own numbering: ``node``'s own for a plain node, one per lane (that holds every landmark
    its suffix names) for a joined one."""
    if node.lanes is None:
        return [node.decisions()]
    suffix = node.decisions()
    out = []
    for lane in node.lanes.nodes:
        mine = _suffix_in(node.lanes, lane, suffix, n_named)
        if mine is not None:
            out.append(lane.decisions() + mine)
    return out


def joined_paths(node: Node, n_named: int) -> list[list[int]]:
    """As :func:`lane_paths`, in ``node``'s numbering (whose boxes they then read)."""
    if node.lanes is None:
        return [node.decisions()]
    lanes, suffix = node.lanes, node.decisions()
    index = {k: n_named + j for j, k in enumerate(lanes.blocks)}
    out = []
    for lane in lanes.nodes:
        if _suffix_in(lanes, lane, suffix, n_named) is None:
            continue
        prefix = [n if n < n_named else index[lane.blocks[n - n_named]] for n in lane.decisions()]
        out.append(prefix + suffix)
    return out


def combine(explorer: Explorer, lane: Node, leaf: Node) -> Node | None:
    """The (partial) hypothesis of ``lane`` followed by the decisions of the joined walk's
    node ``leaf`` (a leaf, or a node the walk leaves): the lane's box met with ``leaf``'s
    (which carries what the walk's windows and ``lp`` narrowings proved), its constraints
    added and narrowed once, with the negative information of the scans they complete on
    what the lane alone holds; None when the lane does not hold a landmark they name, or
    when the constraints, negative information or a class prior refute it."""
    lanes, p, graph, n_named = leaf.lanes, explorer.problem, explorer.graph, explorer.n_named
    assert lanes is not None
    numbers = _suffix_in(lanes, lane, leaf.decisions(), n_named)
    if numbers is None:
        return None
    overlay = graph.met(lane.overlay, *graph.materialize(leaf.overlay))
    if overlay is not None:
        overlay = graph.add_rows(overlay, np.setdiff1d(leaf.overlay.rows, lane.overlay.rows))
    if overlay is None:
        explorer.stats.proven_empty += 1
        return None
    assigned = lane.assigned
    for number in numbers:
        assigned = (number, assigned)
    made = leaf.blocks[len(lanes.blocks) :]
    node = Node(
        leaf.depth, overlay, (*lane.blocks, *made), assigned, share=leaf.share / len(lanes.nodes),
        lp_depth=leaf.lp_depth, lp_gap=leaf.lp_gap,
    )  # fmt: skip
    if _breaks_prior(explorer, node, lane):
        explorer.stats.refuted_by_class_prior += 1
        return None
    own = [
        n_named + j
        for j, k in enumerate(lane.blocks)
        if n_named + lanes.blocks.index(k) not in lanes.common
    ]
    poses = [d.pose for d in p.decisions[lanes.depth : leaf.depth] if d.completes_scan]
    if p.has_sensor and own and poses:
        node = explorer.unseen_scans(node, poses, only=np.array(own, dtype=np.int64))
    return node


def joined_children(explorer: Explorer, kids: list[Node]) -> tuple[list[Node], float]:
    """The children ``kids`` of a joined node as the search pushes them
    (:func:`leave_where_partial`, then :func:`checked_lanes`), and the share of the tree
    that their lanes refuted decided."""
    before = sum(k.share for k in kids)
    out = [c for k in leave_where_partial(explorer, kids) for c in checked_lanes(explorer, k)]
    return out, before - sum(c.share for c in out)


def joined_leaves(explorer: Explorer, leaf: Node) -> list[Node]:
    """The hypotheses of a joined walk's ``leaf``: each lane followed by its suffix, those
    not refuted (:func:`combine`)."""
    assert leaf.lanes is not None
    out = [combine(explorer, lane, leaf) for lane in leaf.lanes.nodes]
    return [c for c in out if c is not None]


def checked_lanes(explorer: Explorer, node: Node) -> list[Node]:
    """A joined ``node`` whose walk is 16, 32, 64, ... decisions past its join, with the
    lanes that its decisions refute dropped (:func:`combine`): no lane left, nothing; one,
    that lane followed by the walk's decisions, searched depth first from there; else the
    joined node with fewer lanes (its box and constraints as they are: still a superset).
    Joined, a lane that would have died soon after the join walks on in the hull, and the
    walk costs more than the lanes apart (seed 7 of the 200-pose worlds: two lanes joined
    at reading 107, 69.6 s against 44.7 s depth first). Other nodes are returned as they
    are."""
    lanes = node.lanes
    if lanes is None:
        return [node]
    walked = node.depth - lanes.depth
    if walked < JOIN_AGREE or walked & (walked - 1):
        return [node]
    alive = [(lane, combine(explorer, lane, node)) for lane in lanes.nodes]
    alive = [(lane, c) for lane, c in alive if c is not None]
    if len(alive) < 2:
        return [replace(c, share=node.share) for _, c in alive]
    if len(alive) == len(lanes.nodes):
        return [node]
    return [replace(node, lanes=replace(lanes, nodes=tuple(lane for lane, _ in alive)))]


def leave_where_partial(explorer: Explorer, kids: list[Node]) -> list[Node]:
    """Children of a joined node, each child whose decision names a landmark that not every
    lane holds replaced by its lanes that hold it, each followed by the child's decisions
    (:func:`combine`): the joined walk cannot apply that landmark's negative information,
    and one lane's landmark is another's known one, whose hull of boxes is wide, so the
    joined walk branched on their readings (seed 4 of the 1,000-pose sparse worlds: 12,429
    expansions between readings 1,000 and 1,041, where the depth-first search goes
    through)."""
    out = []
    for kid in kids:
        lanes = kid.lanes
        assert lanes is not None
        number = kid.assigned[0] - explorer.n_named
        if not 0 <= number < len(lanes.blocks) or explorer.n_named + number in lanes.common:
            out.append(kid)
            continue
        plain = [c for c in (combine(explorer, lane, kid) for lane in lanes.nodes) if c]
        out.extend(replace(c, share=kid.share / len(plain)) for c in plain)
    return out


def _breaks_prior(explorer: Explorer, node: Node, lane: Node) -> bool:
    """The class priors the joined walk did not check on ``node`` (whose lane is ``lane``):
    each class's count, and the separations (the suffix's constraints may have narrowed any
    landmark)."""
    n_named = explorer.n_named
    counts: dict[str, int] = {}
    for number in range(n_named + len(node.blocks)):
        cls = explorer.landmark_class(node, number)
        counts[cls] = counts.get(cls, 0) + 1
    for cls, count in counts.items():
        prior = explorer.problem.class_priors.get(cls)
        if prior is not None and prior.at_most is not None and count > prior.at_most:
            return True
    return any(explorer.too_close(node, n) for n in range(n_named + len(node.blocks)))


def look_ahead(
    explorer: Explorer, kids: list[Node], limit: SearchLimit, expanded: int
) -> tuple[list[Node], int, float]:
    """Follow the children ``kids`` of a branching node breadth first, and join them
    (:func:`join`) once every lane has agreed on :data:`JOIN_AGREE` decisions in a row.

    Returns the nodes to push on the stack (one joined node, or the lanes reached: when
    one is left, when they are too many, when the look-ahead's expansions or ``limit`` are
    spent (the search made ``expanded`` before it), or at the leaves; only the order of
    the search changes then), the expansions made, and the share of the tree they decided.
    An interrupt leaves the branching node to be pushed back whole (:func:`.search._step`):
    what is pending then overlaps, which only widens what is left unexplored."""
    frontier, expansions, done, agreed = list(kids), 0, 0.0, 0
    n_named, n = explorer.n_named, len(explorer.problem.decisions)
    graph = explorer.graph
    while 1 < len(frontier) <= JOIN_MAX_LANES and frontier[0].depth < n:
        if agreed >= JOIN_AGREE and can_join(explorer, frontier):
            return [join(explorer, frontier)], expansions, done
        layer: list[Node] = []
        keys: set[Hashable] = set()
        alike = True
        for i, node in enumerate(frontier):
            if (
                expansions >= JOIN_MAX_EXPANSIONS
                or limit.exhausted(expanded + expansions) is not None
            ):
                return layer + frontier[i:], expansions, done
            applications = graph.applications
            children, options = explorer.children(node)
            spent = graph.applications - applications
            spend(limit.deadline, COSTS["node"] + COSTS["operator"] * spent)
            expansions += 1
            done += node.share * (options - len(children)) / options
            alike &= len(children) == 1
            keys.update(landmark_key(c, c.assigned[0], n_named) for c in children)
            layer.extend(children)
        frontier = layer
        agreed = agreed + 1 if alike and len(keys) == 1 else 0
    return frontier, expansions, done
