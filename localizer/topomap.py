"""The topological map of the paper's Algorithm 4.

A node per junction, numbered 0, 1, 2, ... in first-visit order; an edge between
two consecutively visited junctions, labelled 1, 2, 3, ... in the order the edges
are first traversed. Traversing an edge again adds nothing. Two different pipes
between the same pair of junctions are one edge: the map records adjacency. Two
consecutive visits of one junction add a self-loop; the localizer makes them only
under the paper's rule (``LocalizerConfig.distinct_consecutive`` off), since a pipe
joins two different junctions.

When a visit is lost (its sweep was in a damaged part of a log), the robot's path
is broken there: :meth:`TopoMap.lose_track` makes the next visit add no edge, since
the junctions either side of the lost one need not be neighbours.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["TopoMap", "MapEdge"]


@dataclass(frozen=True)
class MapEdge:
    """An edge of the map: its two junctions (in first-traversal order) and label."""

    u: int
    v: int
    label: int


class TopoMap:
    """A growing topological map. :meth:`visit` is Algorithm 4's update step.

    It keeps its own edge list; networkx (0.09 s to import) is loaded only when
    :attr:`graph` is asked for.
    """

    def __init__(self) -> None:
        self._nodes = 0
        self._edges: dict[frozenset[int], MapEdge] = {}
        self._visits: list[int] = []
        self._on_track = True

    @property
    def graph(self) -> nx.Graph:
        """A copy of the map as a networkx graph; edges carry ``label``."""
        import networkx as nx

        graph = nx.Graph()
        graph.add_nodes_from(range(self._nodes))
        for e in self._edges.values():
            graph.add_edge(e.u, e.v, label=e.label)
        return graph

    @property
    def visits(self) -> tuple[int, ...]:
        """The node of every visit, in order."""
        return tuple(self._visits)

    @property
    def previous(self) -> int | None:
        """The junction the robot came from directly, if the path is unbroken."""
        return self._visits[-1] if self._visits and self._on_track else None

    def lose_track(self) -> None:
        """A visit was lost: the next visit is not joined to the last one by an edge."""
        self._on_track = False

    @property
    def node_count(self) -> int:
        """Number of junctions in the map."""
        return self._nodes

    def visit(self, node: int) -> MapEdge | None:
        """Record that the robot is at ``node``; returns the edge it added, if any.

        ``node`` must be a known node or the next new one (``node_count``).
        """
        if not 0 <= node <= self._nodes:
            raise ValueError(f"node {node} is neither known nor the next new node")
        if node == self._nodes:
            self._nodes += 1
        added = None
        previous = self.previous
        if previous is not None:
            key = frozenset((previous, node))
            if key not in self._edges:
                added = MapEdge(previous, node, len(self._edges) + 1)
                self._edges[key] = added
        self._visits.append(node)
        self._on_track = True
        return added

    def edges(self) -> list[MapEdge]:
        """Edges in label order, each as first traversed."""
        return list(self._edges.values())

    def to_dict(self) -> dict[str, Any]:
        """Nodes in id order and edges in label order, as plain JSON-ready data."""
        return {
            "nodes": [{"id": n} for n in range(self._nodes)],
            "edges": [{"u": e.u, "v": e.v, "label": e.label} for e in self.edges()],
        }

    def to_json(self) -> str:
        """Deterministic JSON of :meth:`to_dict`: the same map gives the same bytes."""
        return json.dumps(self.to_dict(), indent=2) + "\n"
