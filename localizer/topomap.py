"""The topological map of the paper's Algorithm 4, with ports.

A node per junction, numbered 0, 1, 2, ... in first-visit order; an edge between
two consecutively visited junctions, labelled 1, 2, 3, ... in the order the edges
are first traversed. Traversing an edge again adds nothing.

Nodes have *ports* when the robot reported the junction's pipes (see
:mod:`localizer.ports`): their angles in the node's first-visit frame, port 0 the
pipe behind the robot then, the rest clockwise. An edge then joins two ends, (node,
port) and (node, port): the map says which pipe of a junction leads where, and two
pipes between the same two junctions are two edges. A pipe end joins one other end
only; a traversal that would join an end already joined elsewhere is a *conflict*
(the map and the robot's path disagree: a false merge or a false new node
somewhere). It is recorded on the visit and adds no edge: the map keeps the first.

A port can be *blocked*: the robot left by it, could not get through its pipe (a
deposit it could not pass) and came back (:meth:`TopoMap.block`). A blocked port is
neither untraversed (nothing is left to explore there) nor routable (no route
leaves or enters by it); the map document marks it ``"blocked": true``.

Without ports (image folders, older logs) an edge joins two junctions, as in the
paper: the map records adjacency. Two consecutive visits of one junction add a
self-loop; the localizer makes them only under the paper's rule
(``LocalizerConfig.distinct_consecutive`` off), since a pipe joins two different
junctions.

Node ids can come from a pool shared by competing maps (:mod:`localizer.hypotheses`):
one map may take a visit as a new junction where another takes it as a known one,
and the id the first gives it stays *unused* in the second. :meth:`visit` then
takes an id past :attr:`node_count`, and the ids between are unused: no ports, no
pipes, listed in the map document as ``{"id": n, "unused": true, "ports": []}`` and
left out of :attr:`graph` and :attr:`used_node_count`.

When a visit is lost (its sweep was in a damaged part of a log), the robot's path
is broken there: :meth:`TopoMap.new_traversal` makes the next visit add no edge,
since the junctions either side of the lost one need not be neighbours.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["MapEdge", "MapVisit", "TopoMap"]

_DECIMALS = 6


def _round(value: float | None) -> float | None:
    if value is None:
        return None
    rounded = round(float(value), _DECIMALS)
    return 0.0 if rounded == 0 else rounded  # no "-0.0"


@dataclass(frozen=True)
class MapEdge:
    """An edge of the map: its two junctions (in first-traversal order), its label,
    the port at either end (``None`` when unknown) and the distance the robot drove
    along it the first time (``None`` when unknown)."""

    u: int
    v: int
    label: int
    u_port: int | None = None
    v_port: int | None = None
    length_m: float | None = None

    def other(self, node: int, port: int | None) -> tuple[int, int | None]:
        """The far end seen from ``(node, port)``."""
        if (self.u, self.u_port) == (node, port):
            return self.v, self.v_port
        return self.u, self.u_port


@dataclass(frozen=True)
class MapVisit:
    """One visit: its node, the port it arrived by and left by (``None`` when
    unknown, or the run's first visit), and the conflict its arrival met, if any."""

    node: int
    arrival_port: int | None = None
    departure_port: int | None = None
    conflict: str | None = None


class TopoMap:
    """A growing topological map. :meth:`visit` is Algorithm 4's update step;
    :meth:`depart` says which port the robot left by.

    It keeps its own edge list; networkx (0.09 s to import) is loaded only when
    :attr:`graph` is asked for.
    """

    def __init__(self) -> None:
        self._ports: list[tuple[float, ...] | None] = []
        #: Pool ids this map leaves unused (another map's new junctions).
        self._unused: set[int] = set()
        self._edges: dict[Any, MapEdge] = {}
        self._ends: dict[tuple[int, int], MapEdge] = {}
        self._traversed: set[tuple[int, int]] = set()
        self._blocked: set[tuple[int, int]] = set()
        self._visits: list[MapVisit] = []
        self._odometer: list[float | None] = []
        #: Index in ``_visits`` where the current traversal began.
        self._traversal_start = 0

    # -- reading ---------------------------------------------------------------------

    @property
    def graph(self) -> nx.MultiGraph:
        """A copy of the map as a networkx multigraph: nodes carry ``ports`` (a string
        of angles, GraphML has no lists) and, when any is blocked, ``blocked`` (a
        string of port numbers), edges ``label``, ``u_port``, ``v_port`` and
        ``length_m`` (absent when unknown)."""
        import networkx as nx

        graph = nx.MultiGraph()
        for n in range(self.node_count):
            if n in self._unused:
                continue
            ports = self._ports[n]
            text = "" if ports is None else " ".join(f"{_round(a)}" for a in ports)
            blocked = self.blocked(n)
            if blocked:
                graph.add_node(n, ports=text, blocked=" ".join(str(p) for p in blocked))
            else:
                graph.add_node(n, ports=text)
        for e in self._edges.values():
            attrs: dict[str, Any] = {"label": e.label}
            if e.u_port is not None:
                attrs["u_port"] = e.u_port
            if e.v_port is not None:
                attrs["v_port"] = e.v_port
            if e.length_m is not None:
                attrs["length_m"] = _round(e.length_m)
            graph.add_edge(e.u, e.v, key=e.label, **attrs)
        return graph

    @property
    def visits(self) -> tuple[int, ...]:
        """The node of every visit, in order."""
        return tuple(v.node for v in self._visits)

    @property
    def visit_records(self) -> tuple[MapVisit, ...]:
        """Every visit with its ports, in order."""
        return tuple(self._visits)

    @property
    def visit_count(self) -> int:
        """Number of visits so far (``len(visit_records)`` without copying them)."""
        return len(self._visits)

    @property
    def last_visit(self) -> MapVisit | None:
        """The last visit (``visit_records[-1]`` without copying them), ``None`` before
        the first."""
        return self._visits[-1] if self._visits else None

    @property
    def edge_count(self) -> int:
        """Number of edges (``len(edges())`` without listing them)."""
        return len(self._edges)

    @property
    def node_count(self) -> int:
        """Number of node ids in the map: its junctions and the ids it leaves unused
        (the next new junction's id)."""
        return len(self._ports)

    @property
    def used_node_count(self) -> int:
        """Number of junctions in the map (:attr:`node_count` but the unused ids)."""
        return len(self._ports) - len(self._unused)

    def unused(self, node: int) -> bool:
        """Whether id ``node`` is one this map leaves unused (another map's junction,
        or one past its own: the pool may be ahead of it)."""
        return node in self._unused or node >= len(self._ports)

    @property
    def previous(self) -> int | None:
        """The node of the last visit of the current traversal (``None`` at its start)."""
        if len(self._visits) > self._traversal_start:
            return self._visits[-1].node
        return None

    @property
    def last_length_m(self) -> float | None:
        """The distance driven from the visit before the last to the last (``None``:
        unknown, or the last visit began a traversal)."""
        if len(self._visits) - self._traversal_start < 2:
            return None
        before, after = self._odometer[-2], self._odometer[-1]
        return None if before is None or after is None else after - before

    def ports(self, node: int) -> tuple[float, ...] | None:
        """The angles of ``node``'s ports in its first-visit frame (``None``: unknown)."""
        return self._ports[node]

    @property
    def has_ports(self) -> bool:
        """Every node has its ports (and there is at least one node)."""
        used = [p for n, p in enumerate(self._ports) if n not in self._unused]
        return bool(used) and all(p is not None for p in used)

    def untraversed(self, node: int) -> list[int]:
        """The ports of ``node`` the robot has neither arrived nor left by, nor found
        blocked, in order."""
        ports = self._ports[node]
        if ports is None:
            return []
        done = self._traversed | self._blocked
        return [p for p in range(len(ports)) if (node, p) not in done]

    def blocked(self, node: int) -> list[int]:
        """The ports of ``node`` whose pipe the robot gave up as blocked, in order."""
        ports = self._ports[node]
        return [p for p in range(len(ports or ())) if (node, p) in self._blocked]

    def is_blocked(self, node: int, port: int | None) -> bool:
        """Whether port ``port`` of ``node`` is blocked."""
        return port is not None and (node, port) in self._blocked

    def edge_at(self, node: int, port: int) -> MapEdge | None:
        """The edge that joins port ``port`` of ``node``, if known."""
        return self._ends.get((node, port))

    def edges(self) -> list[MapEdge]:
        """Edges in label order, each as first traversed."""
        return list(self._edges.values())

    def copy(self) -> TopoMap:
        """An independent copy (its edges and visits are immutable records, shared)."""
        other = TopoMap()
        other._ports = list(self._ports)
        other._unused = set(self._unused)
        other._edges = dict(self._edges)
        other._ends = dict(self._ends)
        other._traversed = set(self._traversed)
        other._blocked = set(self._blocked)
        other._visits = list(self._visits)
        other._odometer = list(self._odometer)
        other._traversal_start = self._traversal_start
        return other

    # -- growing ---------------------------------------------------------------------

    def visit(
        self,
        node: int,
        ports: tuple[float, ...] | None = None,
        arrival_port: int | None = None,
        odometer_m: float | None = None,
        *,
        pooled: bool = False,
    ) -> MapEdge | None:
        """Record that the robot is at ``node``; returns the edge it added, if any.

        ``node`` must be a known node or the next new one (``node_count``); with
        ``pooled`` (competing maps draw new junctions' ids from one pool) also an
        unused id or one past ``node_count``, the ids between then unused. A new
        node takes ``ports`` (angles in this visit's frame, in port order).
        ``arrival_port`` is the port the robot came in by; the edge joins it to the
        port the previous visit left by. ``odometer_m`` (distance driven so far)
        gives the edge its length.
        """
        if node < 0 or (not pooled and (node > self.node_count or node in self._unused)):
            raise ValueError(f"node {node} is neither known nor the next new node")
        while self.node_count < node:
            self._unused.add(self.node_count)
            self._ports.append(None)
        if node == self.node_count:
            self._ports.append(None if ports is None else tuple(ports))
        elif node in self._unused:
            self._unused.discard(node)
            self._ports[node] = None if ports is None else tuple(ports)
        known_ports = self._ports[node]
        if arrival_port is not None and (
            known_ports is None or not 0 <= arrival_port < len(known_ports)
        ):
            raise ValueError(f"node {node} has no port {arrival_port}")
        added = None
        conflict = None
        previous = self.previous
        if previous is not None:
            last = self._visits[-1]
            length = None
            odometer_before = self._odometer[-1]
            if odometer_m is not None and odometer_before is not None:
                length = odometer_m - odometer_before
            added, conflict = self._join(previous, last.departure_port, node, arrival_port, length)
        if arrival_port is not None:
            self._traversed.add((node, arrival_port))
        self._visits.append(MapVisit(node, arrival_port, None, conflict))
        self._odometer.append(odometer_m)
        return added

    def _join(
        self, u: int, u_port: int | None, v: int, v_port: int | None, length: float | None
    ) -> tuple[MapEdge | None, str | None]:
        if u_port is None or v_port is None:
            key: Any = ("nodes", frozenset((u, v)))
            if key in self._edges:
                return None, None
            edge = MapEdge(u, v, len(self._edges) + 1, u_port, v_port, length)
            self._edges[key] = edge
            return edge, None
        key = ("ends", frozenset(((u, u_port), (v, v_port))))
        if key in self._edges:
            return None, None
        for here, there in (((u, u_port), (v, v_port)), ((v, v_port), (u, u_port))):
            joined = self._ends.get(here)
            if joined is not None:
                far = joined.other(*here)
                return None, (
                    f"port {here[1]} of node {here[0]} already leads to port {far[1]} of "
                    f"node {far[0]}, not to port {there[1]} of node {there[0]}"
                )
        edge = MapEdge(u, v, len(self._edges) + 1, u_port, v_port, length)
        self._edges[key] = edge
        self._ends[(u, u_port)] = edge
        self._ends[(v, v_port)] = edge
        return edge, None

    def depart(self, port: int | None) -> None:
        """Record that the robot leaves the current junction by ``port`` (``None``:
        unknown)."""
        if not self._visits:
            raise ValueError("no visit to depart from")
        last = self._visits[-1]
        if port is not None:
            known = self._ports[last.node]
            if known is None or not 0 <= port < len(known):
                raise ValueError(f"node {last.node} has no port {port}")
            self._traversed.add((last.node, port))
        self._visits[-1] = MapVisit(last.node, last.arrival_port, port, last.conflict)

    def block(self) -> int | None:
        """The robot came back to the current junction through the port it left by:
        that port is blocked, and the robot has left by none. Returns the port
        (``None``: it was not known, and nothing is marked)."""
        if not self._visits:
            raise ValueError("no visit whose departure was blocked")
        last = self._visits[-1]
        port = last.departure_port
        if port is not None:
            self._blocked.add((last.node, port))
        self._visits[-1] = MapVisit(last.node, last.arrival_port, None, last.conflict)
        return port

    def new_traversal(self) -> None:
        """The next visit does not follow the last one (the robot was carried, or a
        new run starts on this map): no edge joins them."""
        self._traversal_start = len(self._visits)

    # -- output ----------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Nodes in id order and edges in label order, as plain JSON-ready data."""
        return {
            "nodes": [
                {"id": n, "unused": True, "ports": []}
                if n in self._unused
                else {
                    "id": n,
                    "ports": [
                        {"port": p, "angle_rad": _round(a)}
                        | ({"blocked": True} if (n, p) in self._blocked else {})
                        for p, a in enumerate(ports or ())
                    ],
                }
                for n, ports in enumerate(self._ports)
            ],
            "edges": [
                {
                    "u": e.u,
                    "u_port": e.u_port,
                    "v": e.v,
                    "v_port": e.v_port,
                    "label": e.label,
                    "length_m": _round(e.length_m),
                }
                for e in self.edges()
            ],
        }

    @classmethod
    def from_dict(cls, doc: Any) -> TopoMap:
        """The map of a map document's ``nodes`` and ``edges`` (its visits are not
        read). Raises ``ValueError`` naming the first thing that is wrong."""
        if not isinstance(doc, dict):
            raise ValueError("not a map document (a JSON object with nodes and edges)")
        nodes, edges = doc.get("nodes"), doc.get("edges")
        if not isinstance(nodes, list) or not isinstance(edges, list):
            raise ValueError("not a map document: no list of nodes and list of edges")
        m = cls()
        for i, node in enumerate(nodes):
            if not isinstance(node, dict) or node.get("id") != i:
                raise ValueError(f"node {i}: expected {{'id': {i}, ...}} in id order")
            ports = node.get("ports", [])
            if not isinstance(ports, list):
                raise ValueError(f"node {i}: ports is not a list")
            if node.get("unused", False) not in (True, False):
                raise ValueError(f"node {i}: unused is not true or false")
            if node.get("unused", False):
                if ports:
                    raise ValueError(f"node {i}: an unused id has no ports")
                m._unused.add(i)
                m._ports.append(None)
                continue
            angles = []
            for k, port in enumerate(ports):
                angle = port.get("angle_rad") if isinstance(port, dict) else None
                if (
                    not isinstance(port, dict)
                    or port.get("port") != k
                    or not isinstance(angle, int | float)
                    or isinstance(angle, bool)
                    or not -4.0 < angle < 4.0
                ):
                    raise ValueError(f"node {i}: port {k} is not {{'port': {k}, 'angle_rad': A}}")
                if port.get("blocked", False) not in (True, False):
                    raise ValueError(f"node {i}: port {k}: blocked is not true or false")
                if port.get("blocked", False):
                    m._blocked.add((i, k))
                angles.append(float(angle))
            m._ports.append(tuple(angles) if angles else None)
        for k, edge in enumerate(edges):
            m._load_edge(k, edge)
        return m

    def _load_edge(self, k: int, edge: Any) -> None:
        if not isinstance(edge, dict):
            raise ValueError(f"edge {k}: not an object")
        ends = []
        for end in ("u", "v"):
            node, port = edge.get(end), edge.get(f"{end}_port")
            if not isinstance(node, int) or isinstance(node, bool):
                raise ValueError(f"edge {k}: {end} is not a node id")
            if not 0 <= node < self.node_count or node in self._unused:
                raise ValueError(f"edge {k}: names node {node}, which the map does not have")
            if port is not None:
                ports = self._ports[node]
                if not isinstance(port, int) or ports is None or not 0 <= port < len(ports):
                    raise ValueError(f"edge {k}: node {node} has no port {port!r}")
            ends.append((node, port))
        label = edge.get("label")
        if not isinstance(label, int) or isinstance(label, bool):
            raise ValueError(f"edge {k}: label is not an integer")
        length = edge.get("length_m")
        if length is not None and (not isinstance(length, int | float) or length < 0):
            raise ValueError(f"edge {k}: length_m is not a distance")
        (u, u_port), (v, v_port) = ends
        added = MapEdge(u, v, label, u_port, v_port, None if length is None else float(length))
        if u_port is None or v_port is None:
            key: Any = ("nodes", frozenset((u, v)))
        else:
            key = ("ends", frozenset(((u, u_port), (v, v_port))))
            for joined in ((u, u_port), (v, v_port)):
                if joined in self._ends:
                    raise ValueError(
                        f"edge {k}: port {joined[1]} of node {joined[0]} is joined twice"
                    )
            self._ends[(u, u_port)] = added
            self._ends[(v, v_port)] = added
        if key in self._edges:
            raise ValueError(f"edge {k}: joins the same ends as edge {self._edges[key].label}")
        self._edges[key] = added

    def to_json(self) -> str:
        """Deterministic JSON of :meth:`to_dict`: the same map gives the same bytes."""
        return json.dumps(self.to_dict(), indent=2) + "\n"
