"""Pipe networks by name: :func:`build_network` and the network's public names.

:func:`build_network` parses a spec (``paper``, ``grid:RxC``, ``random:N``,
``tree:N``) and makes the layout: the paper's fixed one and grids here (above
:data:`~sim.town_layout.TOWN_ABOVE` nodes a seeded town street grid, checked by
:mod:`sim.town_layout`'s rules), the seeded random ones in :mod:`sim.random_layout`
and :mod:`sim.town_layout`. The model itself (:class:`Network` and its
nodes, pipes and rules) is :mod:`sim.network_model`, the plane geometry
:mod:`sim.planar`; their names are re-exported here, where the rest of the
simulator and its callers import them.
"""

from __future__ import annotations

import math
import re
from collections import deque

import numpy as np

from pipemap.errors import SimError
from pipemap.sim.network_model import (
    MIN_JUNCTION_ANGLE_RAD,
    MIN_PIPE_DIAMETERS,
    STRAIGHT_TOLERANCE_RAD,
    Network,
    Node,
    NodeKind,
    Pipe,
)
from pipemap.sim.planar import point_segment_distance_m, segments_touch, wrap_rad
from pipemap.sim.random_layout import first_draw, random_network
from pipemap.sim.town_layout import TOWN_ABOVE, _TownBuilder, town_network

__all__ = [
    "Node",
    "Pipe",
    "NodeKind",
    "Network",
    "build_network",
    "wrap_rad",
    "MIN_JUNCTION_ANGLE_RAD",
    "MAX_NODES",
    "MIN_PIPE_DIAMETERS",
    "STRAIGHT_TOLERANCE_RAD",
    "point_segment_distance_m",
    "segments_touch",
]


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


#: A town grid's district: this many street gaps along each axis share one spacing
#: (about 30 nodes, as :mod:`sim.town_layout`'s districts).
_GRID_DISTRICT = 5
#: Street spacings of a town grid's districts, log-uniform between these, in ``spacing_m``.
_GRID_DENSE, _GRID_SPARSE = 1.25, 12.0
#: Chance that a street bends (half of it shifted sideways), and the most it shifts,
#: as a share of the gaps beside it; every node is also jittered by up to
#: :data:`_GRID_JITTER` of its smaller gap in x and y.
_GRID_BEND_CHANCE, _GRID_BEND, _GRID_JITTER = 0.2, 0.2, 0.05
_GRID_ATTEMPTS = 20


def _streets(
    count: int, rng: np.random.Generator, spacing_m: float, diameter_m: float
) -> np.ndarray:
    """Positions of ``count`` parallel streets, each district of gaps its own spacing,
    none under :data:`_GRID_DENSE` x (3 + 2) diameters, so that a bent and jittered
    street keeps its pipes three diameters long and clear of the next street."""
    bands = -(-(count - 1) // _GRID_DISTRICT)
    lo, hi = math.log(_GRID_DENSE), math.log(_GRID_SPARSE)
    floor_m = _GRID_DENSE * (MIN_PIPE_DIAMETERS + 2.0) * diameter_m
    spacing = np.maximum(spacing_m * np.exp(rng.uniform(lo, hi, size=bands)), floor_m)
    gaps = np.round(spacing[np.arange(count - 1) // _GRID_DISTRICT], 3)
    return np.concatenate([[0.0], np.cumsum(gaps)])


def _bends(
    count: int, across: int, gaps: np.ndarray, other: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Sideways shift of each of ``count`` streets at each of its ``across`` nodes: a
    bent street shifts from a drawn node on, by up to :data:`_GRID_BEND` of the gaps
    beside it and of the gap where it bends (so the bend turns by at most 11 degrees)."""
    shift = np.zeros((count, across))
    for k in range(count):
        at, share = int(rng.integers(1, across)), float(rng.uniform(-1.0, 1.0))
        if rng.uniform() >= _GRID_BEND_CHANCE:
            continue
        beside = min(gaps[max(k - 1, 0)], gaps[min(k, len(gaps) - 1)], other[at - 1])
        shift[k, at:] = share * _GRID_BEND * beside
    return shift


def _linked(heads: list[dict[int, float]], u: int, v: int) -> bool:
    """Whether node ``v`` is reached from ``u`` along the pipes of ``heads``."""
    seen, frontier = {u}, deque([u])
    while frontier:
        here = frontier.popleft()
        for w in heads[here]:
            if w == v:
                return True
            if w not in seen:
                seen.add(w)
                frontier.append(w)
    return False


def _town_grid_draw(
    rows: int, cols: int, rng: np.random.Generator, spacing_m: float, diameter_m: float
) -> Network | None:
    """One draw of a town street grid; ``None`` when a pipe breaks a rule.

    Streets are placed by :func:`_streets`, bent by :func:`_bends` and jittered; every
    lattice pipe must then pass :mod:`sim.town_layout`'s checks (length, junction
    angle, crossings, clearance to other nodes). Pipes are then left out in a drawn
    order, each only if the network stays connected and neither end is left as a
    two-pipe node going nearly straight on, until a drawn n/8 to n/4 loops (pipes
    beyond a spanning tree) are left, as in ``random:N``'s towns.
    """
    xs, ys = _streets(cols, rng, spacing_m, diameter_m), _streets(rows, rng, spacing_m, diameter_m)
    gx, gy = np.diff(xs), np.diff(ys)
    dy, dx = _bends(rows, cols, gy, gx, rng), _bends(cols, rows, gx, gy, rng).T
    near_x = np.minimum(np.r_[gx, gx[-1]], np.r_[gx[0], gx])
    near_y = np.minimum(np.r_[gy, gy[-1]], np.r_[gy[0], gy])
    jitter = rng.uniform(-_GRID_JITTER, _GRID_JITTER, size=(rows, cols, 2))
    x = xs[None, :] + dx + jitter[:, :, 0] * np.minimum(near_x[None, :], near_y[:, None])
    y = ys[:, None] + dy + jitter[:, :, 1] * np.minimum(near_x[None, :], near_y[:, None])
    pts = np.round(np.stack([x.ravel(), y.ravel()], axis=1), 3)
    pts = np.vstack([[pts[0, 0], round(pts[0, 1] - spacing_m, 3)], pts])
    edges = [(0, 1)] + [
        (1 + r * cols + c, 1 + rr * cols + cc)
        for r in range(rows)
        for c in range(cols)
        for rr, cc in ((r, c + 1), (r + 1, c))
        if rr < rows and cc < cols
    ]
    builder = _TownBuilder(pts, diameter_m, 2.0 * _GRID_DENSE * spacing_m, 20.0 * spacing_m)
    for u, v in edges:
        if not builder.can_add(u, v):
            return None
        builder.add(u, v)
    n = len(pts)
    target = len(pts) - 1 + int(rng.integers(n // 8, n // 4 + 1))
    kept = set(edges)
    for k in rng.permutation(np.arange(1, len(edges))):
        if len(kept) <= target:
            break
        u, v = edges[int(k)]
        key = builder._drop(u, v)
        if builder.straight(u) or builder.straight(v) or not _linked(builder.heads, u, v):
            builder.add(u, v)
        else:
            kept.discard((u, v))
        del builder.edges[key]
    names = ["S"] + [f"r{r}c{c}" for r in range(rows) for c in range(cols)]
    nodes = tuple(Node(names[i], float(px), float(py)) for i, (px, py) in enumerate(pts))
    pipes = tuple(Pipe(names[u], names[v]) for u, v in edges if (u, v) in kept)
    try:
        return Network(nodes, pipes, entry="S", diameter_m=diameter_m)
    except SimError:
        return None


def _town_grid(spec: str, rows: int, cols: int, seed: int, spacing_m: float) -> Network:
    def draw(
        n: int, rng: np.random.Generator, spacing_m: float, loops: bool, diameter_m: float
    ) -> Network | None:
        return _town_grid_draw(rows, cols, rng, spacing_m, diameter_m)

    return first_draw(spec, seed, _GRID_ATTEMPTS, draw, rows * cols + 1, spacing_m, True)


#: The most nodes a preset network may have: a town's worth. Larger specs are refused
#: before anything is drawn or built.
MAX_NODES = 5000

_SPEC = re.compile(r"^(?:(paper)|grid:(\d+)x(\d+)|(random|tree):(\d+))$")


def build_network(spec: str, seed: int = 0, spacing_m: float = 1.0) -> Network:
    """The network of a preset ``spec``: ``paper``, ``grid:RxC``, ``random:N``, ``tree:N``.

    ``paper`` is the fixed layout of the paper's experiment (``spacing_m`` is ignored).
    ``grid:RxC`` has nodes ``r{row}c{col}`` and the entry ``S`` ``spacing_m`` below
    ``r0c0``. Up to 100 grid nodes (R*C) it is a lattice ``spacing_m`` apart (``seed``
    is ignored); above, a town street grid drawn from ``seed``: districts of 5 x 5
    street gaps with spacings of 1.25-12 ``spacing_m`` (log-uniform), a fifth of the
    streets bent sideways part way, every node jittered, and pipes left out (dead
    ends, corners and T junctions; n/8 to n/4 loops remain) while it stays connected
    and no two-pipe node goes straight on. ``random:N`` (with loops) and
    ``tree:N`` (without) are N-node layouts drawn from ``seed``, pipes about
    ``spacing_m`` long, entry ``S`` and other nodes ``n1``, ``n2``, ...; the same spec
    and seed give the same network. Above 100 nodes they are drawn as town networks
    (:mod:`sim.town_layout`); a spec of more than :data:`MAX_NODES` nodes is refused.
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
        _check_size(spec, rows * cols + 1)
        if rows * cols > TOWN_ABOVE:
            return _town_grid(spec, rows, cols, seed, spacing_m)
        return _grid(rows, cols, spacing_m)
    kind, n = m.group(4), int(m.group(5))
    least = 3 if kind == "random" else 2
    if n < least:
        raise SimError(f"network spec {spec!r}: {kind} needs at least {least} nodes")
    _check_size(spec, n)
    if n > TOWN_ABOVE:
        return town_network(spec, n, seed, spacing_m, loops=kind == "random")
    return random_network(spec, n, seed, spacing_m, loops=kind == "random")


def _check_size(spec: str, n: int) -> None:
    if n > MAX_NODES:
        raise SimError(
            f"network spec {spec!r}: {n} nodes, more than the {MAX_NODES} a world is built for"
        )
