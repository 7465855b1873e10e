"""Which parts of a pipe network a camera can possibly see: portal culling in plan.

TinyRenderer draws every body of a world for every image, so an image of a
100-node network costs six times one of the 7-node ``paper`` network although the
camera sees a few pipes. :func:`visible_parts` returns the bodies a camera at a
given eye can see any pixel of, a superset of the truth, so that hiding the rest
cannot change an image.

Why it is a superset. All pipes are horizontal cylinders of radius ``r``; the
inside of the network is the union of half-cylinders (one per pipe end, starting at
the node centre) and a sphere of radius ``r`` per node. Cut every pipe at a
*portal* ``R`` from each end, where ``R`` (per node) is past every point two of the
node's half-strips (plan views of its half-cylinders) share. The inside is then the
union of *junction pieces* (a node's sphere and its pipes' stubs up to the portals)
and *pipe pieces* (the straight cylinder between two portals), and two pieces meet
only at a portal: pipes that do not share a node are at least one diameter apart
(network validation), so their cylinders do not meet. A line of sight is a straight
segment inside, so it goes from piece to piece through portals, and in plan its
direction lies in the arc of directions under which the eye sees each portal it
crosses. Propagating that arc from the eye's piece through the portals, narrowing
it at each, reaches every junction piece a line of sight can reach. A reached
junction makes its chamber and every half-pipe of its pipes visible (drawn whole:
parts of them lie in the junction piece); everything else is hidden behind a wall.
The horizontal extent of the view frustum narrows the first arc.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass

from pipemap.sim.network import Network

__all__ = ["ALL", "PortalGraph", "frustum_arc", "visible_parts"]

#: Widening of every portal and strip, metres: covers the rounding of the meshes.
MARGIN_M = 1e-3
_TWO_PI = 2.0 * math.pi
#: An arc ``(centre_rad, half_width_rad)``; a half width of pi or more is the whole circle.
Arc = tuple[float, float]
_FULL: Arc = (0.0, math.pi)
#: Every direction: the view arc that rules nothing out by the camera's heading.
ALL: Arc = _FULL


def _intersect(a: Arc, b: Arc) -> Arc | None:
    """The smallest arc holding ``a`` and ``b``'s common directions, or None."""
    if a[1] >= math.pi:
        return b
    if b[1] >= math.pi:
        return a
    pieces = []
    for shift in (-_TWO_PI, 0.0, _TWO_PI):
        d = math.remainder(b[0] - a[0], _TWO_PI) + shift
        lo, hi = max(-a[1], d - b[1]), min(a[1], d + b[1])
        if lo <= hi:
            pieces.append((lo, hi))
    if not pieces:
        return None
    lo, hi = min(p[0] for p in pieces), max(p[1] for p in pieces)
    return (a[0] + (lo + hi) / 2.0, (hi - lo) / 2.0)


def _contains(outer: Arc, inner: Arc) -> bool:
    if outer[1] >= math.pi:
        return True
    d = abs(math.remainder(inner[0] - outer[0], _TWO_PI))
    return d + inner[1] <= outer[1]


@dataclass(frozen=True)
class _Portal:
    """A pipe's cross-section ``offset_m`` from node ``node``, in plan: a segment."""

    centre: tuple[float, float]
    normal: tuple[float, float]  # along the pipe
    half_width_m: float

    def arc_from(self, eye: tuple[float, float]) -> Arc:
        """Directions from ``eye`` under which a line crosses the segment."""
        cx, cy = self.centre
        nx, ny = self.normal
        if abs((cx - eye[0]) * nx + (cy - eye[1]) * ny) < MARGIN_M:
            return _FULL  # the eye is on the portal's line: any direction may cross it
        ends = [
            (cx - ny * s - eye[0], cy + nx * s - eye[1])
            for s in (-self.half_width_m, self.half_width_m)
        ]
        a0 = math.atan2(ends[0][1], ends[0][0])
        a1 = math.atan2(ends[1][1], ends[1][0])
        span = math.remainder(a1 - a0, _TWO_PI)
        return (a0 + span / 2.0, abs(span) / 2.0 + 1e-9)


def _junction_radius_m(headings: list[float], r: float) -> float:
    """Distance from a node centre past which no two of its half-strips overlap."""
    reach = r * math.sqrt(2.0)  # a strip's own corners at the node
    for i, hu in enumerate(headings):
        for hv in headings[i + 1 :]:
            u = (math.cos(hu), math.sin(hu))
            v = (math.cos(hv), math.sin(hv))
            cross = u[0] * v[1] - u[1] * v[0]
            if abs(cross) < 1e-12:
                continue  # opposite pipes: the strips meet only at the node
            for su in (-r, r):
                for sv in (-r, r):
                    # Edge of u's strip (lateral su) meets edge of v's strip (lateral sv).
                    pu = (-u[1] * su, u[0] * su)
                    pv = (-v[1] * sv, v[0] * sv)
                    t = ((pv[0] - pu[0]) * v[1] - (pv[1] - pu[1]) * v[0]) / cross
                    x, y = pu[0] + t * u[0], pu[1] + t * u[1]
                    along_v = x * v[0] + y * v[1]
                    if t >= -MARGIN_M and along_v >= -MARGIN_M:
                        reach = max(reach, math.hypot(x, y))
    return reach + MARGIN_M


class PortalGraph:
    """A network cut into junction and pipe pieces at portals (see the module)."""

    def __init__(self, network: Network) -> None:
        self.network = network
        r = network.diameter_m / 2.0
        self.half_width_m = r + MARGIN_M
        self.xy = {n.label: (n.x_m, n.y_m) for n in network.nodes}
        self.radius_m = {
            n.label: _junction_radius_m(list(network.pipe_headings(n.label).values()), r)
            for n in network.nodes
        }
        self.neighbours: dict[str, list[str]] = defaultdict(list)
        for p in network.pipes:
            self.neighbours[p.a].append(p.b)
            self.neighbours[p.b].append(p.a)

    def portal(self, node: str, other: str) -> _Portal:
        """The portal of pipe ``node``-``other`` at ``node``'s end."""
        (ax, ay), (bx, by) = self.xy[node], self.xy[other]
        length = math.hypot(bx - ax, by - ay)
        ux, uy = (bx - ax) / length, (by - ay) / length
        d = self.radius_m[node]
        return _Portal((ax + ux * d, ay + uy * d), (ux, uy), self.half_width_m)

    def is_open(self, a: str, b: str) -> bool:
        """Whether pipe ``a``-``b`` is too short for two portals: its junctions touch."""
        return self.radius_m[a] + self.radius_m[b] >= math.dist(self.xy[a], self.xy[b])

    def pieces_of(self, eye: tuple[float, float]) -> tuple[set[str], set[tuple[str, str]]]:
        """The junction pieces (node labels) and pipe pieces (``(a, b)``) that may hold ``eye``."""
        junctions: set[str] = set()
        pipes: set[tuple[str, str]] = set()
        for label, (x, y) in self.xy.items():
            if math.hypot(eye[0] - x, eye[1] - y) <= self.radius_m[label] + self.half_width_m:
                junctions.add(label)
        for p in self.network.pipes:
            (ax, ay), (bx, by) = self.xy[p.a], self.xy[p.b]
            length = math.hypot(bx - ax, by - ay)
            ux, uy = (bx - ax) / length, (by - ay) / length
            s = (eye[0] - ax) * ux + (eye[1] - ay) * uy
            lateral = abs(-(eye[0] - ax) * uy + (eye[1] - ay) * ux)
            if lateral > self.half_width_m or not -MARGIN_M <= s <= length + MARGIN_M:
                continue
            if s <= self.radius_m[p.a] + MARGIN_M:
                junctions.add(p.a)
            if s >= length - self.radius_m[p.b] - MARGIN_M:
                junctions.add(p.b)
            if not self.is_open(p.a, p.b):
                pipes.add((p.a, p.b))
        return junctions, pipes


def frustum_arc(yaw_rad: float, pitch_rad: float, fov_rad: float) -> Arc:
    """Plan directions of the points a square camera of ``fov_rad``, turned by
    ``yaw_rad`` and pitched by ``pitch_rad`` but not rolled, can see."""
    t = math.tan(fov_rad / 2.0)
    denominator = math.cos(pitch_rad) - t * abs(math.sin(pitch_rad))
    if denominator <= 1e-6:
        return _FULL
    return (yaw_rad, min(math.pi, math.atan(t / denominator) + 1e-6))


def visible_parts(
    graph: PortalGraph, eye: tuple[float, float], view: Arc
) -> tuple[set[str], set[tuple[str, str]]] | None:
    """The parts a line of sight from ``eye`` in plan directions ``view`` may reach:
    the nodes whose junction pieces it may enter (draw their chambers and every
    half-pipe of their pipes) and the pipes holding the eye (draw both halves); or
    None if ``eye`` is in no piece (then nothing can be ruled out).
    """
    starts, pipes = graph.pieces_of(eye)
    if not starts and not pipes:
        return None
    queue: list[tuple[str, Arc, str | None]] = [(n, view, None) for n in starts]
    for a, b in pipes:
        for here, there in ((a, b), (b, a)):
            arc = _intersect(view, graph.portal(here, there).arc_from(eye))
            if arc is not None:
                queue.append((here, arc, there))
    seen: dict[tuple[str, str | None], list[Arc]] = defaultdict(list)
    reached: set[str] = set()
    while queue:
        node, arc, via = queue.pop()
        explored = seen[(node, via)]
        if any(_contains(done, arc) for done in explored):
            continue
        explored.append(arc)
        reached.add(node)
        for other in graph.neighbours[node]:
            if other == via:
                continue
            nxt: Arc | None = arc
            if not graph.is_open(node, other):
                nxt = _intersect(arc, graph.portal(node, other).arc_from(eye))
                if nxt is not None:
                    nxt = _intersect(nxt, graph.portal(other, node).arc_from(eye))
            if nxt is not None:
                queue.append((other, nxt, node))
    return reached, pipes
