"""The pipe network's model: nodes in the plane joined by straight pipes.

A node is any place where the pipe does more than go straight on: the open entry,
a dead end, a corner, a T or Y junction (three pipes) or a cross junction (four).
:class:`Network` refuses, with a :class:`~pipemap.errors.SimError` naming the bad
node or pipe, any layout the simulator could not build as pipe: crossings, pipes
that are too short or too close, junction angles under 60 degrees. The preset and
random layouts are made by :func:`~pipemap.sim.network.build_network`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import networkx as nx
import numpy as np

from pipemap.errors import SimError
from pipemap.sim.planar import EPS, heading_rad, point_segment_distance_m, segments_touch

__all__ = [
    "MIN_JUNCTION_ANGLE_RAD",
    "MIN_PIPE_DIAMETERS",
    "STRAIGHT_TOLERANCE_RAD",
    "Network",
    "Node",
    "NodeKind",
    "Pipe",
]

#: Sharper than this, the junction fitting cannot be built around both pipes.
MIN_JUNCTION_ANGLE_RAD = math.radians(60.0)
#: A corner this close to straight is straight pipe, not a node.
STRAIGHT_TOLERANCE_RAD = math.radians(1.0)
#: Shortest pipe, in pipe diameters: the junction fittings at its ends need the room.
MIN_PIPE_DIAMETERS = 3.0


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


def _pipe_boxes(pipes: tuple[Pipe, ...], xy: Mapping[str, tuple[float, float]]) -> np.ndarray:
    """Each pipe's bounding box as a row ``(xmin, ymin, xmax, ymax)``."""
    ends = np.array([(*xy[p.a], *xy[p.b]) for p in pipes], dtype=np.float64).reshape(-1, 4)
    return np.column_stack(
        (
            np.minimum(ends[:, 0], ends[:, 2]),
            np.minimum(ends[:, 1], ends[:, 3]),
            np.maximum(ends[:, 0], ends[:, 2]),
            np.maximum(ends[:, 1], ends[:, 3]),
        )
    )


def _overlapping(box: np.ndarray, boxes: np.ndarray, margin_m: float, start: int) -> list[int]:
    """Indices from ``start`` on, in order, of the boxes within ``margin_m`` (plus the
    tolerance) of ``box``: the only pipes a geometric rule can fail against, so the
    rules stay linear in practice and name the same first fault as a full scan."""
    reach = margin_m + 2.0 * EPS
    rest = boxes[start:]
    near = (
        (rest[:, 0] <= box[2] + reach)
        & (rest[:, 2] >= box[0] - reach)
        & (rest[:, 1] <= box[3] + reach)
        & (rest[:, 3] >= box[1] - reach)
    )
    return [start + int(k) for k in np.flatnonzero(near)]


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
            headings[p.a][p.b] = heading_rad(a.x_m, a.y_m, b.x_m, b.y_m)
            headings[p.b][p.a] = heading_rad(b.x_m, b.y_m, a.x_m, a.y_m)
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
            if self.length_m(p.a, p.b) < MIN_PIPE_DIAMETERS * d - EPS:
                raise SimError(
                    f"pipe {p} is {self.length_m(p.a, p.b):.3f} m long, shorter than "
                    f"{MIN_PIPE_DIAMETERS:g} diameters ({MIN_PIPE_DIAMETERS * d:.3f} m)"
                )
        for label, nbrs in self._headings.items():
            if len(nbrs) < 2:
                continue
            gap, u, v = _smallest_gap(nbrs)
            if gap < MIN_JUNCTION_ANGLE_RAD - EPS:
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
        boxes = _pipe_boxes(self.pipes, xy)
        for i, p in enumerate(self.pipes):
            for j in _overlapping(boxes[i], boxes, 0.0, start=i + 1):
                q = self.pipes[j]
                if {p.a, p.b} & {q.a, q.b}:
                    continue  # meeting at a shared node is checked by the angle rule
                if segments_touch(xy[p.a], xy[p.b], xy[q.a], xy[q.b]):
                    raise SimError(f"pipes {p} and {q} cross or touch")
        for n in self.nodes:
            point = np.array([n.x_m, n.y_m, n.x_m, n.y_m])
            for j in _overlapping(point, boxes, d, start=0):
                p = self.pipes[j]
                if n.label in (p.a, p.b):
                    continue
                gap_m = point_segment_distance_m(xy[n.label], xy[p.a], xy[p.b])
                if gap_m < d - EPS:
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
