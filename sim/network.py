"""The pipe network: nodes in the plane joined by straight pipes.

A node is any place where the pipe does more than go straight on: the open entry,
a dead end, a corner, a T or Y junction (three pipes) or a cross junction (four).
:class:`Network` refuses, with a :class:`~pipemap.errors.SimError` naming the bad
node or pipe, any layout the simulator could not build as pipe: crossings, pipes
that are too short or too close, junction angles under 60 degrees.
:func:`build_network` makes the preset layouts, seeded random ones included.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import networkx as nx
import numpy as np
from scipy.spatial import Delaunay, QhullError

from pipemap.errors import SimError

__all__ = [
    "Node",
    "Pipe",
    "NodeKind",
    "Network",
    "build_network",
    "wrap_rad",
    "MIN_JUNCTION_ANGLE_RAD",
    "MIN_PIPE_DIAMETERS",
]

#: Sharper than this, the junction fitting cannot be built around both pipes.
MIN_JUNCTION_ANGLE_RAD = math.radians(60.0)
#: A corner this close to straight is straight pipe, not a node.
STRAIGHT_TOLERANCE_RAD = math.radians(1.0)
#: Shortest pipe, in pipe diameters: the junction fittings at its ends need the room.
MIN_PIPE_DIAMETERS = 3.0
_EPS = 1e-9


@dataclass(frozen=True)
class Node:
    """A node of the network, at ``(x_m, y_m)`` in the plane."""

    label: str
    x_m: float
    y_m: float


@dataclass(frozen=True)
class Pipe:
    """A straight pipe between the nodes labelled ``a`` and ``b``."""

    a: str
    b: str

    def __str__(self) -> str:
        return f"{self.a}-{self.b}"


class NodeKind(Enum):
    """What the robot finds at a node, from its number of pipes."""

    ENTRY = "entry"
    DEAD_END = "dead_end"
    CORNER = "corner"
    TEE = "tee"
    CROSS = "cross"


def wrap_rad(angle_rad: float) -> float:
    """``angle_rad`` wrapped into (-pi, pi]."""
    wrapped = math.remainder(angle_rad, 2.0 * math.pi)
    return wrapped + 2.0 * math.pi if wrapped <= -math.pi else wrapped


def _heading_rad(x0: float, y0: float, x1: float, y1: float) -> float:
    return wrap_rad(math.atan2(y1 - y0, x1 - x0))


def _orient(p: tuple[float, float], q: tuple[float, float], r: tuple[float, float]) -> float:
    return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])


def _on_segment(p: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> bool:
    return (
        min(a[0], b[0]) - _EPS <= p[0] <= max(a[0], b[0]) + _EPS
        and min(a[1], b[1]) - _EPS <= p[1] <= max(a[1], b[1]) + _EPS
    )


def segments_touch(
    p1: tuple[float, float],
    p2: tuple[float, float],
    q1: tuple[float, float],
    q2: tuple[float, float],
) -> bool:
    """Whether the closed segments p1-p2 and q1-q2 share a point (collinear overlap too)."""
    o1, o2 = _orient(p1, p2, q1), _orient(p1, p2, q2)
    o3, o4 = _orient(q1, q2, p1), _orient(q1, q2, p2)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return (
        (abs(o1) <= _EPS and _on_segment(q1, p1, p2))
        or (abs(o2) <= _EPS and _on_segment(q2, p1, p2))
        or (abs(o3) <= _EPS and _on_segment(p1, q1, q2))
        or (abs(o4) <= _EPS and _on_segment(p2, q1, q2))
    )


def point_segment_distance_m(
    p: tuple[float, float], a: tuple[float, float], b: tuple[float, float]
) -> float:
    """Distance from point ``p`` to the closed segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length_sq = dx * dx + dy * dy
    t = 0.0 if length_sq == 0.0 else ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length_sq
    t = min(1.0, max(0.0, t))
    return math.hypot(p[0] - (a[0] + t * dx), p[1] - (a[1] + t * dy))


def _smallest_gap(headings: Mapping[str, float]) -> tuple[float, str, str]:
    """The smallest angle between two pipes of a node, and the two neighbours."""
    ordered = sorted(headings.items(), key=lambda kv: kv[1])
    best = (math.inf, "", "")
    for i, (label, h) in enumerate(ordered):
        next_label, next_h = ordered[(i + 1) % len(ordered)]
        gap = (next_h - h) % (2.0 * math.pi)
        if len(ordered) == 2:
            gap = min(gap, 2.0 * math.pi - gap)
        if gap < best[0]:
            best = (gap, label, next_label)
    return best


@dataclass(frozen=True)
class Network:
    """A validated planar pipe network; ``entry`` is the open end the robot comes in by."""

    nodes: tuple[Node, ...]
    pipes: tuple[Pipe, ...]
    entry: str
    diameter_m: float = 0.2
    _by_label: dict[str, Node] = field(init=False, repr=False, compare=False)
    _headings: dict[str, dict[str, float]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "nodes", tuple(self.nodes))
        object.__setattr__(self, "pipes", tuple(self.pipes))
        if not (math.isfinite(self.diameter_m) and self.diameter_m > 0):
            raise SimError(f"pipe diameter must be > 0 m, got {self.diameter_m}")
        by_label: dict[str, Node] = {}
        for n in self.nodes:
            if n.label in by_label:
                raise SimError(f"duplicate node label {n.label!r}")
            if not (math.isfinite(n.x_m) and math.isfinite(n.y_m)):
                raise SimError(f"node {n.label!r} has a non-finite position")
            by_label[n.label] = n
        headings: dict[str, dict[str, float]] = {label: {} for label in by_label}
        for p in self.pipes:
            for end in (p.a, p.b):
                if end not in by_label:
                    raise SimError(f"pipe {p} names unknown node {end!r}")
            if p.a == p.b:
                raise SimError(f"pipe {p} joins node {p.a!r} to itself")
            if p.b in headings[p.a]:
                raise SimError(f"duplicate pipe {p} between {p.a!r} and {p.b!r}")
            a, b = by_label[p.a], by_label[p.b]
            headings[p.a][p.b] = _heading_rad(a.x_m, a.y_m, b.x_m, b.y_m)
            headings[p.b][p.a] = _heading_rad(b.x_m, b.y_m, a.x_m, a.y_m)
        object.__setattr__(self, "_by_label", by_label)
        object.__setattr__(self, "_headings", headings)
        self._check_topology()
        self._check_geometry()

    def _check_topology(self) -> None:
        for label, nbrs in self._headings.items():
            if not nbrs:
                raise SimError(f"node {label!r} has no pipe")
            if len(nbrs) > 4:
                raise SimError(f"node {label!r} has {len(nbrs)} pipes (at most 4)")
        if self.entry not in self._by_label:
            raise SimError(f"entry {self.entry!r} is not a node")
        if len(self._headings[self.entry]) != 1:
            raise SimError(
                f"entry {self.entry!r} has {len(self._headings[self.entry])} pipes (must be 1)"
            )
        reached = {self.entry}
        stack = [self.entry]
        while stack:
            for nbr in self._headings[stack.pop()]:
                if nbr not in reached:
                    reached.add(nbr)
                    stack.append(nbr)
        unreached = [n.label for n in self.nodes if n.label not in reached]
        if unreached:
            raise SimError(f"network is disconnected: node {unreached[0]!r} is not reachable")

    def _check_geometry(self) -> None:
        d = self.diameter_m
        for p in self.pipes:
            if self.length_m(p.a, p.b) < MIN_PIPE_DIAMETERS * d - _EPS:
                raise SimError(
                    f"pipe {p} is {self.length_m(p.a, p.b):.3f} m long, shorter than "
                    f"{MIN_PIPE_DIAMETERS:g} diameters ({MIN_PIPE_DIAMETERS * d:.3f} m)"
                )
        for label, nbrs in self._headings.items():
            if len(nbrs) < 2:
                continue
            gap, u, v = _smallest_gap(nbrs)
            if gap < MIN_JUNCTION_ANGLE_RAD - _EPS:
                raise SimError(
                    f"node {label!r}: pipes to {u!r} and {v!r} are {math.degrees(gap):.1f} "
                    f"degrees apart (at least {math.degrees(MIN_JUNCTION_ANGLE_RAD):.0f})"
                )
            if len(nbrs) == 2 and gap > math.pi - STRAIGHT_TOLERANCE_RAD:
                raise SimError(
                    f"node {label!r}: pipes to {u!r} and {v!r} are collinear; "
                    "that is straight pipe, not a node"
                )
        xy = {n.label: (n.x_m, n.y_m) for n in self.nodes}
        for i, p in enumerate(self.pipes):
            for q in self.pipes[i + 1 :]:
                if {p.a, p.b} & {q.a, q.b}:
                    continue  # meeting at a shared node is checked by the angle rule
                if segments_touch(xy[p.a], xy[p.b], xy[q.a], xy[q.b]):
                    raise SimError(f"pipes {p} and {q} cross or touch")
        for n in self.nodes:
            for p in self.pipes:
                if n.label in (p.a, p.b):
                    continue
                gap_m = point_segment_distance_m(xy[n.label], xy[p.a], xy[p.b])
                if gap_m < d - _EPS:
                    raise SimError(
                        f"node {n.label!r} is {gap_m:.3f} m from pipe {p} "
                        f"(at least one diameter, {d:.3f} m)"
                    )

    @property
    def labels(self) -> tuple[str, ...]:
        """Node labels in the given node order."""
        return tuple(n.label for n in self.nodes)

    def node(self, label: str) -> Node:
        """The node labelled ``label``."""
        try:
            return self._by_label[label]
        except KeyError:
            raise SimError(f"no node {label!r} in the network") from None

    def degree(self, label: str) -> int:
        """Number of pipes at node ``label``."""
        return len(self.pipe_headings(label))

    def kind(self, label: str) -> NodeKind:
        """The kind of node ``label``, from its number of pipes."""
        deg = self.degree(label)
        if deg == 1:
            return NodeKind.ENTRY if label == self.entry else NodeKind.DEAD_END
        return {2: NodeKind.CORNER, 3: NodeKind.TEE, 4: NodeKind.CROSS}[deg]

    def pipe_headings(self, label: str) -> dict[str, float]:
        """Neighbour label -> heading (rad, in (-pi, pi], 0 = +x) of the pipe to it."""
        self.node(label)
        return dict(self._headings[label])

    def neighbours(self, label: str) -> tuple[str, ...]:
        """Neighbours of ``label`` counter-clockwise by heading, smallest heading first."""
        headings = self.pipe_headings(label)
        return tuple(sorted(headings, key=lambda nbr: headings[nbr]))

    def length_m(self, a: str, b: str) -> float:
        """Length of the pipe between ``a`` and ``b``."""
        if b not in self.pipe_headings(a):
            raise SimError(f"no pipe between {a!r} and {b!r}")
        na, nb = self._by_label[a], self._by_label[b]
        return math.hypot(nb.x_m - na.x_m, nb.y_m - na.y_m)

    def to_networkx(self) -> nx.Graph:
        """The network as a graph: nodes carry ``pos`` (x_m, y_m), edges ``length_m``."""
        g = nx.Graph()
        for n in self.nodes:
            g.add_node(n.label, pos=(n.x_m, n.y_m))
        for p in self.pipes:
            g.add_edge(p.a, p.b, length_m=self.length_m(p.a, p.b))
        return g

    def bounds_m(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the node positions."""
        xs = [n.x_m for n in self.nodes]
        ys = [n.y_m for n in self.nodes]
        return (min(xs), min(ys), max(xs), max(ys))


def _paper() -> Network:
    spots = {"S": (0.0, 0.0), "A": (0.0, 1.5), "B": (1.0, 1.5), "C": (0.0, 3.0)}
    spots |= {"D": (0.75, 3.0), "E": (-1.2, 3.0), "F": (0.0, 4.0)}
    return Network(
        tuple(Node(k, x, y) for k, (x, y) in spots.items()),
        tuple(Pipe(s[0], s[1]) for s in ("SA", "AB", "AC", "CD", "CE", "CF")),
        entry="S",
    )


def _grid(rows: int, cols: int, spacing_m: float) -> Network:
    nodes = [Node("S", 0.0, -spacing_m)]
    pipes = [Pipe("S", "r0c0")]
    for r in range(rows):
        for c in range(cols):
            nodes.append(Node(f"r{r}c{c}", c * spacing_m, r * spacing_m))
            if c + 1 < cols:
                pipes.append(Pipe(f"r{r}c{c}", f"r{r}c{c + 1}"))
            if r + 1 < rows:
                pipes.append(Pipe(f"r{r}c{c}", f"r{r + 1}c{c}"))
    return Network(tuple(nodes), tuple(pipes), entry="S")


_MAX_ATTEMPTS = 2000
#: Generated layouts keep wider margins than validation asks, so the walls clear.
_GEN_CLEARANCE_DIAMETERS = 2.0
#: Generated corners turn the pipe by at least 20 degrees. A gentler bend is a deflected
#: pipe, not a junction: the robot's gyro cannot tell it from the follower's own weave
#: (measured: every generated corner turning under 15 degrees went unnoticed).
_GEN_STRAIGHT_RAD = math.radians(160.0)


def _scatter(
    n: int, rng: np.random.Generator, min_gap_m: float, side_m: float
) -> np.ndarray | None:
    """``n`` points in a square, pairwise at least ``min_gap_m`` apart (dart throwing)."""
    pts: list[np.ndarray] = []
    for _ in range(60 * n):
        cand = rng.uniform(0.0, side_m, size=2)
        if all(float(np.hypot(*(cand - p))) >= min_gap_m for p in pts):
            pts.append(cand)
            if len(pts) == n:
                return np.round(np.array(pts), 3)
    return None


class _Builder:
    """Pipes added one at a time, each only if the layout stays buildable."""

    def __init__(self, pts: np.ndarray, diameter_m: float) -> None:
        self.xy = [(float(x), float(y)) for x, y in pts]
        self.diameter_m = diameter_m
        self.heads: list[dict[int, float]] = [{} for _ in self.xy]
        self.edges: list[tuple[int, int]] = []

    def heading(self, u: int, v: int) -> float:
        (x0, y0), (x1, y1) = self.xy[u], self.xy[v]
        return _heading_rad(x0, y0, x1, y1)

    def can_add(self, u: int, v: int) -> bool:
        if v in self.heads[u] or len(self.heads[u]) >= 4 or len(self.heads[v]) >= 4:
            return False
        if math.dist(self.xy[u], self.xy[v]) < MIN_PIPE_DIAMETERS * self.diameter_m:
            return False
        for a, b in ((u, v), (v, u)):
            h = self.heading(a, b)
            for other in self.heads[a].values():
                if abs(wrap_rad(h - other)) < MIN_JUNCTION_ANGLE_RAD:
                    return False
        for a, b in self.edges:
            if {a, b} & {u, v}:
                continue
            if segments_touch(self.xy[u], self.xy[v], self.xy[a], self.xy[b]):
                return False
        clearance_m = _GEN_CLEARANCE_DIAMETERS * self.diameter_m
        return all(
            point_segment_distance_m(p, self.xy[u], self.xy[v]) >= clearance_m
            for w, p in enumerate(self.xy)
            if w not in (u, v)
        )

    def add(self, u: int, v: int) -> None:
        self.heads[u][v] = self.heading(u, v)
        self.heads[v][u] = self.heading(v, u)
        self.edges.append((u, v))


def _candidate_edges(pts: np.ndarray) -> list[tuple[int, int]]:
    if len(pts) == 2:
        return [(0, 1)]
    try:
        tri = Delaunay(pts)
    except QhullError:
        return []
    found = set()
    for simplex in tri.simplices:
        for i in range(3):
            a, b = int(simplex[i]), int(simplex[(i + 1) % 3])
            found.add((min(a, b), max(a, b)))
    return sorted(found)


def _try_random(
    n: int, rng: np.random.Generator, spacing_m: float, loops: bool, diameter_m: float
) -> Network | None:
    """One draw of a random layout; ``None`` when it fails a requirement."""
    min_gap_m = max(0.8 * spacing_m, (MIN_PIPE_DIAMETERS + 1.0) * diameter_m)
    pts = _scatter(n, rng, min_gap_m, 1.4 * spacing_m * math.sqrt(n))
    if pts is None:
        return None
    candidates = _candidate_edges(pts)
    if not candidates:
        return None
    order = [candidates[int(i)] for i in rng.permutation(len(candidates))]
    builder = _Builder(pts, diameter_m)
    root = list(range(n))

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = root[i]
        return i

    spare = []
    for u, v in order:
        ru, rv = find(u), find(v)
        if ru != rv and builder.can_add(u, v):
            builder.add(u, v)
            root[ru] = rv
        else:
            spare.append((u, v))
    if len(builder.edges) != n - 1:
        return None
    leaves = [i for i in range(n) if len(builder.heads[i]) == 1]
    entry = leaves[int(rng.integers(len(leaves)))]
    if loops:
        target = int(rng.integers(1, max(1, n // 4) + 1))
        added = 0
        for u, v in spare:
            if added == target:
                break
            if entry not in (u, v) and builder.can_add(u, v):
                builder.add(u, v)
                added += 1
        if n >= 5 and added == 0:
            return None
    for heads in builder.heads:
        if len(heads) == 2:
            h1, h2 = heads.values()
            if abs(wrap_rad(h1 - h2)) > _GEN_STRAIGHT_RAD:
                return None
    # Entry first, then the rest in drawn order, labelled by their place.
    order_nodes = [entry] + [i for i in range(n) if i != entry]
    label = {idx: ("S" if k == 0 else f"n{k}") for k, idx in enumerate(order_nodes)}
    nodes = tuple(Node(label[i], builder.xy[i][0], builder.xy[i][1]) for i in order_nodes)
    pipes = tuple(Pipe(label[u], label[v]) for u, v in builder.edges)
    try:
        return Network(nodes, pipes, entry="S", diameter_m=diameter_m)
    except SimError:
        return None


def _random(spec: str, n: int, seed: int, spacing_m: float, loops: bool) -> Network:
    rng = np.random.default_rng(seed)
    for _ in range(_MAX_ATTEMPTS):
        net = _try_random(n, rng, spacing_m, loops, diameter_m=0.2)
        if net is not None:
            return net
    raise SimError(f"network spec {spec!r}: no valid layout in {_MAX_ATTEMPTS} draws")


_SPEC = re.compile(r"^(?:(paper)|grid:(\d+)x(\d+)|(random|tree):(\d+))$")


def build_network(spec: str, seed: int = 0, spacing_m: float = 1.0) -> Network:
    """The network of a preset ``spec``: ``paper``, ``grid:RxC``, ``random:N``, ``tree:N``.

    ``paper`` is the fixed layout of the paper's experiment (``spacing_m`` is ignored).
    ``grid:RxC`` is an R x C lattice ``spacing_m`` apart, nodes ``r{row}c{col}``, with
    the entry ``S`` one spacing below ``r0c0``. ``random:N`` (with loops) and
    ``tree:N`` (without) are N-node layouts drawn from ``seed``, pipes about
    ``spacing_m`` long, entry ``S`` and other nodes ``n1``, ``n2``, ...; the same spec
    and seed give the same network.
    """
    m = _SPEC.match(spec.strip()) if isinstance(spec, str) else None
    if m is None:
        raise SimError(
            f"unknown network spec {spec!r} (expected paper, grid:RxC, random:N or tree:N)"
        )
    if not (math.isfinite(spacing_m) and spacing_m > 0):
        raise SimError(f"network spec {spec!r}: spacing must be > 0 m, got {spacing_m}")
    if m.group(1):
        return _paper()
    if m.group(2):
        rows, cols = int(m.group(2)), int(m.group(3))
        if rows < 2 or cols < 2:
            raise SimError(f"network spec {spec!r}: a grid needs at least 2 rows and 2 columns")
        return _grid(rows, cols, spacing_m)
    kind, n = m.group(4), int(m.group(5))
    least = 3 if kind == "random" else 2
    if n < least:
        raise SimError(f"network spec {spec!r}: {kind} needs at least {least} nodes")
    return _random(spec, n, seed, spacing_m, loops=kind == "random")
