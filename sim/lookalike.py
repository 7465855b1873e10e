"""Junctions that look alike: which junctions of a network share one fitting's look.

By default every pipe and chamber has its own seeded texture, so no two junctions look
the same (:mod:`sim.textures`). A network built from identical fittings breaks that.
Two nodes are of one type when they have as many pipes and the angles between their
pipes, in counter-clockwise order, agree within :data:`TYPE_TOLERANCE_RAD` after some
cyclic turn (a fitting is cast for a nominal angle; a layout's pipes meet it within
the fitting's play). ``alike`` (0..1) is the fraction of the nodes that can take the
look of another (those with another node of their type) that do. The seed chooses, in
each type, the node whose look the others take, and which nodes take it; ``alike = 1``
gives every node of a type the one look. A node that takes a look gets the look's
chamber texture turned with the node, and in each pipe the look's texture of the
matching port over the half of the pipe at the node (the same metres of texture from
the centre outwards, whatever the pipe's length). The far halves of its pipes keep
their own look unless the node at the other end shares one too.

``alike = 0`` chooses nothing, and the world is built exactly as without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pipemap.errors import SimError
from pipemap.sim.network_model import Network
from pipemap.sim.textures import MAX_SIZE_PX, MIN_SIZE_PX, node_texture, pipe_texture

__all__ = ["TYPE_TOLERANCE_RAD", "Look", "LookAlike", "LookTextures", "choose_looks"]

#: Two nodes are of one type when their angles between pipes agree within this.
TYPE_TOLERANCE_RAD = math.radians(15.0)
#: The seed stream of the choice of looks (with the world's seed).
_LOOK_STREAM = 42


@dataclass(frozen=True)
class Look:
    """The look a node wears: the node ``look`` whose fitting it has, turned by
    ``turn_rad`` (counter-clockwise, from the look's node to this one), and for each of
    its neighbours the look's port (0.. counter-clockwise from the look's smallest
    heading) whose texture its pipe wears at this node."""

    look: str
    turn_rad: float
    ports: dict[str, int]


@dataclass(frozen=True)
class LookAlike:
    """Which nodes share a look: ``looks`` holds every node that wears a shared look
    (the node whose look it is included, with ``look`` itself and no turn)."""

    fraction: float
    looks: dict[str, Look] = field(default_factory=dict)

    def groups(self) -> list[list[str]]:
        """The sets of nodes that look alike, each sorted, the look's node first."""
        by_look: dict[str, list[str]] = {}
        for label, look in self.looks.items():
            by_look.setdefault(look.look, []).append(label)
        return [
            [name, *sorted(m for m in members if m != name)]
            for name, members in sorted(by_look.items())
        ]


def _gaps(headings: list[float]) -> list[float]:
    """The angles between consecutive pipes, counter-clockwise from the smallest heading."""
    if len(headings) == 1:
        return [2.0 * math.pi]
    return [
        (headings[(i + 1) % len(headings)] - h) % (2.0 * math.pi) for i, h in enumerate(headings)
    ]


def _fit(
    source: list[float], target: list[float], tolerance_rad: float = TYPE_TOLERANCE_RAD
) -> int | None:
    """The cyclic shift s with target port (i + s) matching source port i best, or None
    when no shift matches every angle within ``tolerance_rad``."""
    if len(source) != len(target):
        return None
    gs, gt = _gaps(source), _gaps(target)
    n = len(gs)
    best: tuple[float, int] | None = None
    for s in range(n):
        worst = max(abs(gt[(i + s) % n] - gs[i]) for i in range(n))
        if worst <= tolerance_rad and (best is None or worst < best[0]):
            best = (worst, s)
    return None if best is None else best[1]


def choose_looks(network: Network, alike: float, seed: int) -> LookAlike:
    """The shared looks of ``network`` for the fraction ``alike`` (0..1), drawn from
    ``seed``. Raises :class:`~pipemap.errors.SimError` for a fraction outside 0..1."""
    if not (isinstance(alike, (int, float)) and math.isfinite(alike) and 0.0 <= alike <= 1.0):
        raise SimError(f"alike must be a fraction in 0..1, got {alike!r}")
    if alike == 0.0:
        return LookAlike(0.0)
    headings = {n.label: sorted(network.pipe_headings(n.label).values()) for n in network.nodes}
    # Types in the network's node order: each node joins the first type it fits.
    types: list[list[str]] = []
    for node in network.nodes:
        for members in types:
            if _fit(headings[members[0]], headings[node.label]) is not None:
                members.append(node.label)
                break
        else:
            types.append([node.label])
    rng = np.random.default_rng([seed, _LOOK_STREAM])
    origin: dict[str, str] = {}
    candidates: list[str] = []
    for members in types:
        if len(members) < 2:
            continue
        name = members[int(rng.integers(len(members)))]
        for m in members:
            if m != name:
                origin[m] = name
                candidates.append(m)
    count = int(math.floor(alike * len(candidates) + 0.5))
    chosen = [candidates[int(i)] for i in rng.permutation(len(candidates))[:count]]
    looks: dict[str, Look] = {}
    for label in chosen:
        name = origin[label]
        looks.setdefault(name, _own_look(network, name))
        looks[label] = _look_of(network, name, label, headings)
    return LookAlike(float(alike), looks)


def _own_look(network: Network, label: str) -> Look:
    order = network.neighbours(label)
    return Look(label, 0.0, {nbr: i for i, nbr in enumerate(order)})


def _look_of(network: Network, name: str, label: str, headings: dict[str, list[float]]) -> Look:
    # Both fit their type's first node within the tolerance, so each other within twice
    # it: take the best turn of the two.
    shift = _fit(headings[name], headings[label], math.inf)
    assert shift is not None
    order = network.neighbours(label)
    n = len(order)
    diffs = [headings[label][(i + shift) % n] - headings[name][i] for i in range(n)]
    turn = math.atan2(sum(math.sin(d) for d in diffs), sum(math.cos(d) for d in diffs))
    return Look(name, turn, {order[(i + shift) % n]: i for i in range(n)})


class LookTextures:
    """The textures of the shared looks, each drawn once from ``seed`` and kept.

    A look's port texture spans ``half_length_m`` (the network's longest half-pipe)
    from the node's centre outwards, so each half-pipe that wears it shows the same
    metres of it near the node, whatever its own length.
    """

    def __init__(self, network: Network, looks: LookAlike, seed: int, texture_px: int) -> None:
        self.network = network
        self.looks = looks
        self.seed = seed
        self.texture_px = texture_px
        self.half_length_m = max(network.length_m(p.a, p.b) for p in network.pipes) / 2.0
        self._index = {n.label: i for i, n in enumerate(network.nodes)}
        self._cache: dict[tuple[str, int], np.ndarray] = {}

    def _rng(self, look: str, part: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, _LOOK_STREAM, self._index[look], part])

    def half_pipe(self, label: str, neighbour: str) -> tuple[str, np.ndarray, tuple[float, float]]:
        """The texture name, image and ``u`` range (centre, far end) of the half of the
        pipe to ``neighbour`` at the node ``label``, which wears a shared look."""
        look = self.looks.looks[label]
        port = look.ports[neighbour]
        key = (look.look, port + 1)
        if key not in self._cache:
            width = min(
                MAX_SIZE_PX, max(MIN_SIZE_PX, round(2 * self.texture_px * self.half_length_m))
            )
            self._cache[key] = pipe_texture(
                self._rng(*key),
                width_px=width,
                height_px=self.texture_px,
                length_m=self.half_length_m,
                circumference_m=math.pi * self.network.diameter_m,
            )
        half = self.network.length_m(label, neighbour) / 2.0
        return f"look-{look.look}-{port}", self._cache[key], (0.0, half / self.half_length_m)

    def chamber(self, label: str, origin_rad: float) -> np.ndarray:
        """The chamber texture of the node ``label``, which wears a shared look, for a
        chamber mesh whose texture ``u = 0`` is at longitude ``origin_rad``: the look's
        texture turned so that the look's features face the same ports."""
        look = self.looks.looks[label]
        key = (look.look, 0)
        if key not in self._cache:
            # Drawn for a 0.2 m sphere, as every chamber (sim.world says why).
            self._cache[key] = node_texture(
                self._rng(*key), self.texture_px, self.texture_px, radius_m=0.2
            )
        # The look's texture has u = 0 at longitude 0 of the look's node; this node's
        # longitude lon shows the look's lon - turn, at u = (lon - origin) / 2 pi.
        shift = (look.turn_rad - origin_rad) / (2.0 * math.pi)
        cols = self._cache[key].shape[1]
        return np.roll(self._cache[key], round(shift * cols) % cols, axis=1)
