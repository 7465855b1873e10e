"""Pipe networks by name: :func:`build_network` and the network's public names.

:func:`build_network` parses a spec (``paper``, ``grid:RxC``, ``random:N``,
``tree:N``) and makes the layout: the paper's fixed one and grids here, the seeded
random ones in :mod:`sim.random_layout`. The model itself (:class:`Network` and its
nodes, pipes and rules) is :mod:`sim.network_model`, the plane geometry
:mod:`sim.planar`; their names are re-exported here, where the rest of the
simulator and its callers import them.
"""

from __future__ import annotations

import math
import re

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
from pipemap.sim.random_layout import random_network
from pipemap.sim.town_layout import TOWN_ABOVE, town_network

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


#: The most nodes a preset network may have: a town's worth. Larger specs are refused
#: before anything is drawn or built.
MAX_NODES = 5000

_SPEC = re.compile(r"^(?:(paper)|grid:(\d+)x(\d+)|(random|tree):(\d+))$")


def build_network(spec: str, seed: int = 0, spacing_m: float = 1.0) -> Network:
    """The network of a preset ``spec``: ``paper``, ``grid:RxC``, ``random:N``, ``tree:N``.

    ``paper`` is the fixed layout of the paper's experiment (``spacing_m`` is ignored).
    ``grid:RxC`` is an R x C lattice ``spacing_m`` apart, nodes ``r{row}c{col}``, with
    the entry ``S`` one spacing below ``r0c0``. ``random:N`` (with loops) and
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
