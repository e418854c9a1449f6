"""Expansions the dive made, kept for the exhaustive search that follows it.

The dive (:mod:`.dive`) and the exhaustive search (:func:`.search.explore`) expand nodes by
the same rules and in the same order of children, so the search's first descent goes down
the dive's path node by node: on a 200-pose sparse world, 1,569 expansions made twice. The
dive keeps each expansion here, keyed by the node object; the search takes it back when it
reaches *that same object* (a child the dive made), so its boxes are the dive's exactly and
the result is the one it would get expanding the node itself. The statistics the
expansion counted are counted again when it is taken back (the dive rolls its own back);
the work is not done twice. On the 200-pose sparse world of seed 42 (1,569 readings) the
whole solve takes 26.2 s of CPU against 31.3 s, with the same survivors.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from cuikslam.hypotheses.tree import Node, SearchStatistics

__all__ = ["MAX_KEPT", "Expansions"]

MAX_KEPT = 50_000
"""Expansions kept at most (each holds its children's overlays)."""
MAX_KEPT_BYTES = 1 << 30
"""Bytes of children's overlays kept at most: on the whole Victoria Park run (1,449 poses)
the dive's 15,860 expansions made the solve peak at 5.2 GB (680 MB before the dive kept
them); past this the search (and the dive, when it comes back to a node) expands the
nodes again: the same boxes, more work, so a budget that binds may stop elsewhere."""
COUNTED = [f.name for f in fields(SearchStatistics) if f.type in ("int", int)]


@dataclass
class _Kept:
    node: Node
    children: list[Node]
    options: int
    counts: dict[str, int]


class Expansions:
    """Node expansions (children, options considered, the statistics they counted), kept
    by node object."""

    def __init__(self) -> None:
        self._kept: dict[int, _Kept] = {}
        self._bytes = 0
        """Bytes of the kept children's overlays (shared arrays counted with each)."""

    def __len__(self) -> int:
        return len(self._kept)

    def keep(
        self,
        node: Node,
        children: list[Node],
        options: int,
        before: SearchStatistics,
        after: SearchStatistics,
    ) -> None:
        """Keep ``node``'s expansion; ``before`` and ``after`` are the statistics around it."""
        size = sum(c.overlay.nbytes for c in children)
        full = len(self._kept) >= MAX_KEPT or self._bytes + size > MAX_KEPT_BYTES
        if full or id(node) in self._kept:
            return
        self._bytes += size
        counts = {n: getattr(after, n) - getattr(before, n) for n in COUNTED}
        counted = {n: c for n, c in counts.items() if c}
        self._kept[id(node)] = _Kept(node, children, options, counted)

    def peek(self, node: Node) -> tuple[list[Node], int] | None:
        """``node``'s kept expansion, left kept (the dive's own later probes)."""
        kept = self._kept.get(id(node))
        return None if kept is None or kept.node is not node else (kept.children, kept.options)

    def take(self, node: Node, stats: SearchStatistics) -> tuple[list[Node], int] | None:
        """``node``'s kept expansion, no longer kept, its counts added to ``stats``; None
        when it was not kept."""
        kept = self._kept.get(id(node))
        if kept is None or kept.node is not node:
            return None
        del self._kept[id(node)]
        self._bytes -= sum(c.overlay.nbytes for c in kept.children)
        for name, count in kept.counts.items():
            setattr(stats, name, getattr(stats, name) + count)
        return kept.children, kept.options

    def nodes(self) -> list[Node]:
        """Every node the kept expansions hold (for :meth:`renamed`)."""
        return [n for k in self._kept.values() for n in (k.node, *k.children)]

    def renamed(self, new: dict[int, Node]) -> None:
        """The same expansions, each node replaced by ``new[id(node)]`` (the graph's
        maintenance re-expresses overlays: same boxes, new objects)."""
        kept = {}
        for k in self._kept.values():
            node = new[id(k.node)]
            children = [new[id(c)] for c in k.children]
            kept[id(node)] = replace(k, node=node, children=children)
        self._kept = kept
        self._bytes = sum(c.overlay.nbytes for k in kept.values() for c in k.children)

    def clear(self) -> None:
        self._kept.clear()
        self._bytes = 0
