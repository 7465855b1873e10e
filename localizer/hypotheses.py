"""Competing maps where appearance cannot tell junctions apart.

When a revisit fits several known junctions equally well (look-alike junctions:
``record --alike``) and nothing of the visit itself tells them apart, the localizer
does not bet the map on the best ranked one: it keeps a map per junction the visit
may be (:class:`Hypotheses`), each with a weight, and lets what appearance cannot
fake decide later. This is the multi-hypothesis topological mapping of Tully, Kantor
and Choset (2009), on the edge-ordered graph the map already is (ports in cyclic
order): the hypotheses differ in which known junction some visits were, and in
whether a visit was a known junction or a new one of the same look (a *new
branch*). New junctions take their ids from one pool (the matcher's): a map that
took a visit as known junction ``j`` where another took it as new junction ``n``
leaves ``n`` unused (:meth:`TopoMap.unused`) and reads every later visit of ``n``
as one of ``j``, its ports turned as that visit fitted them (:attr:`Hypothesis.aliases`).

The weight of a hypothesis is the product of the likelihoods of what it says:

* **Odometry** (at the visit that branches): the robot's dead reckoning against the
  junction's first-visit position, a Gaussian whose sigma is half the drift
  tolerance (:meth:`Localizer.localize`'s odometry check stays a gate around it).
* **Ports**: the misfit of the visit's exits with the junction's ports after the
  fit's turn, a Gaussian with sigma ``port_tolerance_rad``.
* **Graph consistency**: a later traversal that joins a pipe end its map already
  joins elsewhere (a port conflict, :class:`TopoMap`) multiplies the weight by
  ``CONFLICT_LIKELIHOOD``; a pipe driven again whose length differs from the first
  time by more than the odometry allows weighs by a Gaussian in the difference
  (sigma ``LENGTH_SIGMA_M`` plus ``LENGTH_SIGMA_PER_M`` of the pipe's length).

* **Planarity**: a buried network at one depth is planar, and the ports' clockwise
  order at every junction is a rotation system: a map whose graph, with each
  junction's pipes in that order, cannot be drawn in the plane without crossings
  (Euler's formula over its faces, :func:`embeds_in_plane`) is dropped while another
  can be (Tully, Kantor and Choset prune their tree of edge-ordered graphs by the
  same test).

Bounded: at most ``limit`` hypotheses live (the heaviest; ties keep the older), and
one whose weight falls below ``prune_ratio`` of the best is dropped. A visit whose
hypotheses disagree on its junction is *open*; it is *settled* when the survivors
agree, and the map the localizer shows is always the heaviest hypothesis's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pipemap.localizer.ports import PortMatch, nearest_exit, port_assignments
from pipemap.localizer.topomap import TopoMap

__all__ = [
    "CONFLICT_LIKELIHOOD",
    "Branch",
    "Hypotheses",
    "Hypothesis",
    "embeds_in_plane",
    "port_log_likelihood",
]

#: The exit straight behind the robot is the one it came in by, within half the
#: smallest angle between two pipes of a junction (as ``Localizer.depart``).
ARRIVAL_TOLERANCE_RAD = math.pi / 6.0
#: A map whose pipe end would lead to two places is this much less likely: one
#: conflict drops a hypothesis under the default prune ratio when another has none.
CONFLICT_LIKELIHOOD = 1e-3
#: Sigma of a pipe's length driven again against its first length: the explorer's
#: odometry is good to a few centimetres a metre (``ExploreConfig``).
LENGTH_SIGMA_M = 0.05
LENGTH_SIGMA_PER_M = 0.02


@dataclass(frozen=True)
class Branch:
    """One junction a visit may be: its node, the port it arrived by, the port of
    the node that each exit is, and the log-likelihood of what the visit itself
    says of it (odometry and ports)."""

    node: int
    arrival_port: int | None
    exit_ports: tuple[int, ...] | None
    log_likelihood: float = 0.0
    #: The visit is a junction not known before (an id new to every map).
    new: bool = False


@dataclass
class Hypothesis:
    """One map, its log weight, and the node of each visit that branched."""

    map: TopoMap
    log_weight: float = 0.0
    #: Visit index -> node, for the visits where the hypotheses branched.
    nodes: dict[int, int] = field(default_factory=dict)
    #: The last visit's exit ports under this hypothesis (for :meth:`Hypotheses.depart`).
    exit_ports: tuple[int, ...] | None = None
    #: Pool id another map gave a new junction -> this map's junction for it and, for
    #: each of that id's ports, this junction's port.
    aliases: dict[int, tuple[int, tuple[int, ...] | None]] = field(default_factory=dict)

    def read(self, branch: Branch) -> Branch:
        """``branch`` as this map reads it: an id it leaves unused (:attr:`aliases`) is
        its own junction, the ports turned to match."""
        if branch.node not in self.aliases:
            return branch
        node, turn = self.aliases[branch.node]
        if turn is None or branch.exit_ports is None:
            return Branch(node, None, None, branch.log_likelihood)
        arrival = None if branch.arrival_port is None else turn[branch.arrival_port]
        exits = tuple(turn[p] for p in branch.exit_ports)
        return Branch(node, arrival, exits, branch.log_likelihood)


class Hypotheses:
    """The live hypotheses, heaviest first after every update."""

    def __init__(self, topomap: TopoMap, limit: int, prune_ratio: float) -> None:
        self.limit = limit
        self.log_prune = math.log(prune_ratio) if prune_ratio > 0.0 else -math.inf
        self.live = [Hypothesis(topomap)]
        #: Visit index -> the nodes the live hypotheses give it, while they disagree.
        self.open: dict[int, tuple[int, ...]] = {}
        #: Whether more than one hypothesis was ever alive.
        self.branched = False

    @property
    def leader(self) -> Hypothesis:
        """The heaviest hypothesis (the oldest of equals)."""
        return self.live[0]

    def visit(
        self,
        branches: list[Branch],
        ports: tuple[float, ...] | None,
        odometer_m: float | None,
    ) -> tuple[tuple[int, int], ...]:
        """Add a visit to every live hypothesis, branching each into ``branches`` (one:
        no branching), weigh and prune. Returns the open visits this one settled,
        each as ``(visit index, node)``."""
        index = self.leader.map.visit_count
        grown: list[Hypothesis] = []
        new = next((b for b in branches if b.new), None)
        for h in self.live:
            # A map that leaves a branch's junction unused reads it as its own (and a
            # junction it has twice is one branch).
            readings: dict[int, tuple[Branch, Branch]] = {}
            for b in branches:
                readings.setdefault(h.read(b).node, (b, h.read(b)))
            for k, (branch, read) in enumerate(readings.values()):
                last = k == len(readings) - 1
                topomap = h.map if last else h.map.copy()
                nodes = h.nodes if last else dict(h.nodes)
                aliases = h.aliases if last else dict(h.aliases)
                weight = h.log_weight + branch.log_likelihood
                weight += _traversal_log_likelihood(topomap, read, ports, odometer_m)
                if len(branches) > 1:
                    nodes[index] = read.node
                if new is not None and not branch.new:
                    aliases[new.node] = (read.node, _turn(new.exit_ports, read.exit_ports))
                grown.append(Hypothesis(topomap, weight, nodes, read.exit_ports, aliases))
        if len(branches) > 1:
            self.branched = True
        return self._prune(grown)

    def _prune(self, grown: list[Hypothesis]) -> tuple[tuple[int, int], ...]:
        if len(grown) > 1:
            # A map that cannot be drawn in the plane is dropped, unless none can (the
            # network is then not what the rule assumes, and the weights decide).
            planar = [h for h in grown if embeds_in_plane(h.map)]
            grown = planar or grown
        best = max(h.log_weight for h in grown)
        # Stable: the hypothesis that came first (the best ranked branch) wins ties.
        kept = sorted(
            (h for h in grown if h.log_weight - best >= self.log_prune),
            key=lambda h: -h.log_weight,
        )[: self.limit]
        for h in kept:
            h.log_weight -= best
        self.live = kept
        settled = []
        candidates = set(self.open) | {i for h in kept for i in h.nodes}
        self.open = {}
        for i in sorted(candidates):
            nodes = tuple(dict.fromkeys(h.nodes.get(i, -1) for h in kept))
            if len(nodes) > 1:
                self.open[i] = nodes
            elif nodes[0] >= 0 and any(i in h.nodes for h in kept):
                settled.append((i, nodes[0]))
                for h in kept:
                    h.nodes.pop(i, None)
        return tuple(settled)

    def arrival_conflict(
        self, node: int, ports: PortMatch | None, exits: tuple[float, ...] | None
    ) -> str | None:
        """Why known junction ``node`` cannot be where a robot that came by a pipe the
        map has not driven arrives, its exits ``exits`` fitting ``node``'s ports as
        ``ports``: the pipe end it came in by (the exit straight behind) already leads
        elsewhere in the map, and a pipe has two ends (the edge-ordered graph). Only
        with one map alive (with more, a conflict weighs a map down instead: it may be
        another map's driven pipe) and competing maps on (with one, as before the
        rule). ``None`` when it can be, or the pipe was driven (the map's own junction
        is weighed, not ruled out)."""
        topomap = self.leader.map
        if not self._by_a_new_pipe():
            return None
        if ports is None or ports.exit_ports is None or exits is None:
            return None
        behind = nearest_exit(exits, math.pi, ARRIVAL_TOLERANCE_RAD)
        end = None if behind is None else ports.exit_ports[behind]
        edge = None if end is None else topomap.edge_at(node, end)
        if edge is None or end is None:
            return None
        far, far_port = edge.other(node, end)
        return (
            f"port {end} of node {node} already leads to port {far_port} of node {far}, "
            "not to the pipe the robot came by"
        )

    def arrival_conflict_at_every_turn(
        self, node: int, exits: tuple[float, ...] | None, tolerance_rad: float
    ) -> bool:
        """Whether :meth:`arrival_conflict` rejects known junction ``node`` at every
        assignment of the exits to its ports that a fit could agree with
        (:func:`localizer.ports.port_assignments`, within ``tolerance_rad``): then no
        fit makes it the visit's junction, and a fit that would only say so need not
        be made. ``False`` where the rule does not apply or nothing is compared."""
        ports = self.leader.map.ports(node)
        if ports is None or exits is None or not self._by_a_new_pipe():
            return False
        behind = nearest_exit(exits, math.pi, ARRIVAL_TOLERANCE_RAD)
        if behind is None:
            return False
        return all(
            self.leader.map.edge_at(node, exit_ports[behind]) is not None
            for _, exit_ports in port_assignments(ports, exits, tolerance_rad)
        )

    def _by_a_new_pipe(self) -> bool:
        """Whether :meth:`arrival_conflict` applies: one map alive, competing maps on,
        and the robot came by a pipe the map has not driven."""
        topomap = self.leader.map
        previous, last = topomap.previous, topomap.last_visit
        if self.limit < 2 or len(self.live) > 1 or previous is None or last is None:
            return False
        port = last.departure_port
        return port is None or topomap.edge_at(previous, port) is None

    def depart(self, exit_index: int | None) -> int | None:
        """Every hypothesis leaves by the exit ``exit_index`` of the last visit (each
        names it by its own port); returns the leader's port."""
        for h in self.live:
            port = None
            if exit_index is not None and h.exit_ports is not None:
                port = h.exit_ports[exit_index]
            h.map.depart(port)
        last = self.leader.map.last_visit
        return None if last is None else last.departure_port

    def block(self) -> int | None:
        """The last departure was blocked, in every hypothesis; returns the leader's port."""
        ports = [h.map.block() for h in self.live]
        return ports[0]

    def new_traversal(self) -> None:
        """The next visit does not follow the last, in every hypothesis."""
        for h in self.live:
            h.map.new_traversal()


def embeds_in_plane(topomap: TopoMap) -> bool:
    """Whether ``topomap``'s graph, with every junction's pipes in the clockwise order
    of its ports, is a plane drawing: Euler's formula (V - E + F = 2 in every
    component) holds over the faces its rotation system traces. A port with no pipe
    known yet leads to a dead end of its own, which changes no face and is left out.
    Loops and parallel pipes are traced like any other. A map without ports says
    nothing of the order: ``True``."""
    edges = topomap.edges()
    if not topomap.has_ports or any(e.u_port is None or e.v_port is None for e in edges):
        return True
    # A dart is a pipe end (node, port); its pipe's other end is its reverse.
    reverse: dict[tuple[int, int | None], tuple[int, int | None]] = {}
    for e in edges:
        reverse[(e.u, e.u_port)] = (e.v, e.v_port)
        reverse[(e.v, e.v_port)] = (e.u, e.u_port)
    # The next pipe end clockwise at the same node, skipping ports with no pipe.
    turn: dict[tuple[int, int | None], tuple[int, int | None]] = {}
    for node in range(topomap.node_count):
        ends: list[tuple[int, int | None]] = [
            (node, p) for p in range(len(topomap.ports(node) or ())) if (node, p) in reverse
        ]
        for k, end in enumerate(ends):
            turn[end] = ends[(k + 1) % len(ends)]
    faces = 0
    seen: set[tuple[int, int | None]] = set()
    for dart in reverse:
        if dart in seen:
            continue
        faces += 1
        while dart not in seen:  # a face: across the pipe, then the next pipe there
            seen.add(dart)
            dart = turn[reverse[dart]]
    # Components of the junctions that have a pipe (union-find over the pipes).
    parent = {node: node for node, _ in reverse}

    def root(node: int) -> int:
        while parent[node] != node:
            parent[node] = parent[parent[node]]
            node = parent[node]
        return node

    for e in edges:
        parent[root(e.u)] = root(e.v)
    components = len({root(node) for node in parent})
    return len(parent) - len(edges) + faces == 2 * components


def _turn(new: tuple[int, ...] | None, known: tuple[int, ...] | None) -> tuple[int, ...] | None:
    """For each port of a new junction (its exits' clockwise order ``new``), the port
    of the known junction the same exits fitted as ``known``."""
    if new is None or known is None:
        return None
    turn = [0] * len(new)
    for exit_index, port in enumerate(new):
        turn[port] = known[exit_index]
    return tuple(turn)


def port_log_likelihood(ports: PortMatch | None, tolerance_rad: float) -> float:
    """The log-likelihood of a visit's exits fitting a junction's ports with their
    misfit: a Gaussian, sigma ``tolerance_rad`` (0 with nothing compared)."""
    if ports is None or ports.residual_rad is None:
        return 0.0
    return -0.5 * (ports.residual_rad / tolerance_rad) ** 2


def _traversal_log_likelihood(
    topomap: TopoMap, branch: Branch, ports: tuple[float, ...] | None, odometer_m: float | None
) -> float:
    """Visit ``branch`` on ``topomap`` and return the log-likelihood of the traversal
    that led there: a conflict, a pipe driven again at another length."""
    before = topomap.edge_count
    previous = topomap.previous
    last = topomap.last_visit
    departure = None if previous is None or last is None else last.departure_port
    topomap.visit(branch.node, ports, branch.arrival_port, odometer_m, pooled=True)
    record = topomap.last_visit
    assert record is not None
    if record.conflict is not None:
        return math.log(CONFLICT_LIKELIHOOD)
    if previous is None or topomap.edge_count != before:
        return 0.0
    if departure is not None:
        edge = topomap.edge_at(previous, departure)
    else:  # a map without ports: the edge joins the two junctions
        pair = {previous, branch.node}
        edge = next((e for e in topomap.edges() if {e.u, e.v} == pair and e.u_port is None), None)
    driven = topomap.last_length_m
    if edge is None or edge.length_m is None or driven is None:
        return 0.0
    sigma = LENGTH_SIGMA_M + LENGTH_SIGMA_PER_M * edge.length_m
    return -0.5 * ((driven - edge.length_m) / sigma) ** 2
