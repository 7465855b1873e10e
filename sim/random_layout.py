"""Seeded random pipe networks: ``random:N`` (with loops) and ``tree:N``.

Points are scattered in a square (dart throwing), candidate pipes are the edges of
their Delaunay triangulation, and pipes are added in a drawn order, each only if
the layout stays buildable with wider margins than :class:`~pipemap.sim.network_model.Network`
asks: first a spanning tree, then (``random``) a few loops. A draw that fails a
requirement is thrown away and drawn again; the same seed gives the same network.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Protocol

import numpy as np
from scipy.spatial import Delaunay, QhullError

from pipemap.errors import SimError
from pipemap.sim.network_model import (
    MIN_JUNCTION_ANGLE_RAD,
    MIN_PIPE_DIAMETERS,
    Network,
    Node,
    Pipe,
)
from pipemap.sim.planar import heading_rad, point_segment_distance_m, segments_touch, wrap_rad

__all__ = ["random_network"]

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
        return heading_rad(x0, y0, x1, y1)

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


def min_gap_m(spacing_m: float, diameter_m: float) -> float:
    """Closest two drawn nodes may be."""
    return max(0.8 * spacing_m, (MIN_PIPE_DIAMETERS + 1.0) * diameter_m)


def side_m(n: int, spacing_m: float) -> float:
    """Side of the square ``n`` nodes are drawn in."""
    return 1.4 * spacing_m * math.sqrt(n)


class _Growing(Protocol):
    def can_add(self, u: int, v: int) -> bool: ...
    def add(self, u: int, v: int) -> None: ...


def grow_tree(builder: _Growing, order: list[tuple[int, int]], n: int) -> list[tuple[int, int]]:
    """Add the pipes of ``order`` that join two parts and fit (Kruskal's order: a
    spanning tree when nothing blocks); returns the pipes not added, in order."""
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
    return spare


def labelled(
    xy: Sequence[tuple[float, float]],
    edges: Iterable[tuple[int, int]],
    entry: int,
    diameter_m: float,
) -> Network | None:
    """The network of points ``xy`` and pipes ``edges``: the entry first, then the rest
    in drawn order, labelled by their place; ``None`` if it breaks a rule."""
    order_nodes = [entry] + [i for i in range(len(xy)) if i != entry]
    label = {idx: ("S" if k == 0 else f"n{k}") for k, idx in enumerate(order_nodes)}
    nodes = tuple(Node(label[i], xy[i][0], xy[i][1]) for i in order_nodes)
    pipes = tuple(Pipe(label[u], label[v]) for u, v in edges)
    try:
        return Network(nodes, pipes, entry="S", diameter_m=diameter_m)
    except SimError:
        return None


def _try_random(
    n: int, rng: np.random.Generator, spacing_m: float, loops: bool, diameter_m: float
) -> Network | None:
    """One draw of a random layout; ``None`` when it fails a requirement."""
    pts = _scatter(n, rng, min_gap_m(spacing_m, diameter_m), side_m(n, spacing_m))
    if pts is None:
        return None
    candidates = _candidate_edges(pts)
    if not candidates:
        return None
    order = [candidates[int(i)] for i in rng.permutation(len(candidates))]
    builder = _Builder(pts, diameter_m)
    spare = grow_tree(builder, order, n)
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
    return labelled(builder.xy, builder.edges, entry, diameter_m)


def random_network(spec: str, n: int, seed: int, spacing_m: float, loops: bool) -> Network:
    """An ``n``-node layout drawn from ``seed``, pipes about ``spacing_m`` long, with
    a few loops if ``loops``; ``spec`` names it in the error when no draw succeeds."""
    return first_draw(spec, seed, _MAX_ATTEMPTS, _try_random, n, spacing_m, loops)


_Draw = Callable[[int, np.random.Generator, float, bool, float], "Network | None"]


def first_draw(
    spec: str, seed: int, attempts: int, draw: _Draw, n: int, spacing_m: float, loops: bool
) -> Network:
    """The first of ``attempts`` draws from ``seed`` that gives a network."""
    rng = np.random.default_rng(seed)
    for _ in range(attempts):
        net = draw(n, rng, spacing_m, loops, 0.2)
        if net is not None:
            return net
    raise SimError(f"network spec {spec!r}: no valid layout in {attempts} draws")
