"""The right-hand-rule tour: the ground-truth order in which the robot explores.

Arriving at a node with travel heading ``h``, the robot takes, among every pipe but
the one it came in by, the one with the smallest turn ``wrap(exit_heading - h)`` in
(-pi, pi]: the right-most (heading 0 is +x, east; pi/2 is +y, north; a right turn
is negative). At a dead end the only pipe is the one it came by, so it turns back.

This rule is deterministic and reversible (the exit from a pipe is the next pipe
counter-clockwise from it around the node), so the walk traces the boundary of one
face of the planar network and comes back to where it began. On a tree there is one
face and the tour covers every pipe in both directions; with loops it covers the
face it started on and stops when its state repeats.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from pipemap.errors import SimError
from pipemap.sim.network import Network, wrap_rad

__all__ = ["Visit", "TourEnd", "Tour", "right_hand_tour", "right_most_exit", "tour_edges"]


@dataclass(frozen=True)
class Visit:
    """The robot at ``node``, come from ``arrived_from``, leaving towards ``leave_to``.

    ``arrived_from`` is ``None`` for the start; ``leave_to`` is ``None`` for the end.
    """

    node: str
    arrived_from: str | None
    leave_to: str | None


class TourEnd(Enum):
    """Why a tour stopped."""

    COMPLETE = "complete"  # back at the start, every pipe traversed both ways
    REPEATED_STATE = "repeated_state"  # a (node, arrived_from) seen before: a closed loop
    MAX_STEPS = "max_steps"


@dataclass(frozen=True)
class Tour:
    """The visits of a right-hand-rule walk and what it covered.

    ``covered_pipes`` holds each traversed pipe once, as its two labels sorted.
    """

    visits: tuple[Visit, ...]
    end: TourEnd
    covered_pipes: frozenset[tuple[str, str]]
    covered_nodes: frozenset[str]

    @property
    def complete(self) -> bool:
        """Every pipe traversed in both directions and back at the start."""
        return self.end is TourEnd.COMPLETE

    @property
    def nodes(self) -> tuple[str, ...]:
        """The visited nodes in order, the start first."""
        return tuple(v.node for v in self.visits)


def right_most_exit(network: Network, node: str, arrived_from: str) -> str:
    """The neighbour the right-hand rule leaves ``node`` for, come from ``arrived_from``."""
    headings = network.pipe_headings(node)
    if arrived_from not in headings:
        raise SimError(f"no pipe between {arrived_from!r} and {node!r}")
    travel_rad = wrap_rad(headings[arrived_from] + math.pi)
    exits = [nbr for nbr in network.neighbours(node) if nbr != arrived_from]
    if not exits:
        return arrived_from
    return min(exits, key=lambda nbr: wrap_rad(headings[nbr] - travel_rad))


def right_hand_tour(network: Network, start: str | None = None, max_steps: int = 10_000) -> Tour:
    """Walk ``network`` by the right-most-branch rule from ``start`` (default the entry).

    The robot leaves the start as if it had just arrived along the pipe from the
    start's first neighbour in :meth:`Network.neighbours` order (smallest heading);
    for the entry or a dead end that is the only pipe, so it leaves by it. That
    virtual arrival is the tour's first state, so the tour stops when the robot
    really arrives at the start along that pipe: complete if every pipe has been
    traversed in both directions by then, a repeated state otherwise. It also
    stops at any other repeated ``(node, arrived_from)`` state, and after
    ``max_steps`` pipe traversals.
    """
    start = network.entry if start is None else start
    network.node(start)
    if max_steps < 0:
        raise SimError(f"max_steps must be >= 0, got {max_steps}")
    directed_total = 2 * len(network.pipes)
    virtual_from = network.neighbours(start)[0]
    seen = {(start, virtual_from)}
    directed: set[tuple[str, str]] = set()
    visits: list[Visit] = []
    node, came = start, None
    end = TourEnd.MAX_STEPS
    for _step in range(max_steps):
        nxt = right_most_exit(network, node, virtual_from if came is None else came)
        visits.append(Visit(node, came, nxt))
        directed.add((node, nxt))
        node, came = nxt, node
        if node == start and len(directed) == directed_total:
            end = TourEnd.COMPLETE
            break
        if (node, came) in seen:
            end = TourEnd.REPEATED_STATE
            break
        seen.add((node, came))
    visits.append(Visit(node, came, None))
    return Tour(
        visits=tuple(visits),
        end=end,
        covered_pipes=frozenset((min(a, b), max(a, b)) for a, b in directed),
        covered_nodes=frozenset(v.node for v in visits),
    )


def tour_edges(tour: Tour) -> list[tuple[str, str]]:
    """The distinct pipes of ``tour``, each once, as first traversed, in that order."""
    out: list[tuple[str, str]] = []
    done: set[frozenset[str]] = set()
    for v in tour.visits:
        if v.leave_to is None:
            continue
        key = frozenset((v.node, v.leave_to))
        if key not in done:
            done.add(key)
            out.append((v.node, v.leave_to))
    return out
