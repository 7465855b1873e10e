"""How much of the true network a run mapped, and whether its ports are right.

The truth comes from the log: the network (``/truth/network``: node positions and
pipes) and the true node and camera pose of every sweep (``/truth/sweep``).

* **Coverage**: the true nodes the robot swept, and the true pipes it drove (two
  consecutive visits at the two ends of a pipe), against the network's.
* **Ports**: each map node's ports are turned into world headings with the true
  heading of the robot at the node's first visit, and each must lie within
  :data:`~pipemap.localizer.PORT_TOLERANCE_RAD` of its own true pipe; each map edge
  must join, at either end, the pipe that leads to the other end's true node.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from pipemap.localizer import PORT_TOLERANCE_RAD, TopoMap, wrap_angle_rad
from pipemap.recorder import Topic
from pipemap.recorder.schemas import SceneUpdate
from pipemap.replay.source import MessageSource

__all__ = ["Coverage", "TrueNetwork", "coverage_of", "ports_correct", "true_network"]


@dataclass(frozen=True)
class TrueNetwork:
    """The network of the log's truth: node positions and pipes (sorted label pairs)."""

    positions: dict[str, tuple[float, float]]
    pipes: frozenset[tuple[str, str]]

    def headings(self, node: str) -> dict[str, float]:
        """Neighbour -> heading of the pipe to it from ``node``."""
        x, y = self.positions[node]
        out = {}
        for a, b in self.pipes:
            if node in (a, b):
                other = b if a == node else a
                ox, oy = self.positions[other]
                out[other] = math.atan2(oy - y, ox - x)
        return out

    def total_length_m(self) -> float:
        """The length of all its pipes."""
        return math.fsum(
            math.dist(self.positions[a], self.positions[b]) for a, b in sorted(self.pipes)
        )


def true_network(source: MessageSource) -> TrueNetwork | None:
    """The network of the log's ``/truth/network``, or ``None`` if it has none."""
    for m in source.truth():
        if m.topic != Topic.NETWORK:
            continue
        scene = SceneUpdate.FromString(m.data)
        positions: dict[str, tuple[float, float]] = {}
        pipes: set[tuple[str, str]] = set()
        for entity in scene.entities:
            kind, _, name = entity.id.partition("/")
            if kind == "node" and entity.spheres:
                p = entity.spheres[0].pose.position
                positions[name] = (p.x, p.y)
            elif kind == "pipe":
                a, _, b = name.partition("-")
                pipes.add((min(a, b), max(a, b)))
        if positions:
            return TrueNetwork(positions, frozenset(pipes))
    return None


@dataclass(frozen=True)
class Coverage:
    """True nodes swept and true pipes driven, of the network's."""

    nodes_visited: int
    nodes_total: int
    pipes_traversed: int
    pipes_total: int

    @property
    def complete(self) -> bool:
        """Every node swept and every pipe driven."""
        return self.nodes_visited == self.nodes_total and self.pipes_traversed == self.pipes_total

    def document(self) -> dict[str, int]:
        """As in ``pipemap score --json``."""
        return {
            "nodes_visited": self.nodes_visited,
            "nodes_total": self.nodes_total,
            "pipes_traversed": self.pipes_traversed,
            "pipes_total": self.pipes_total,
        }


def coverage_of(network: TrueNetwork, true_nodes: Sequence[str]) -> Coverage:
    """The coverage of a run whose visits were at ``true_nodes``, in order."""
    visited = set(true_nodes) & set(network.positions)
    driven = {
        (min(a, b), max(a, b))
        for a, b in zip(true_nodes, true_nodes[1:], strict=False)
        if (min(a, b), max(a, b)) in network.pipes
    }
    return Coverage(len(visited), len(network.positions), len(driven), len(network.pipes))


def ports_correct(
    topomap: TopoMap,
    network: TrueNetwork,
    created: dict[int, tuple[str, float]],
    tolerance_rad: float = PORT_TOLERANCE_RAD,
) -> bool | None:
    """Whether every map node's ports are its true node's pipes and every map edge
    joins the true pipe ends; ``None`` when the map has no ports.

    ``created`` gives each map node's true node and the robot's true heading at
    the node's first visit.
    """
    if not any(topomap.ports(n) is not None for n in range(topomap.node_count)):
        return None
    leads: dict[tuple[int, int], str] = {}  # (map node, port) -> true neighbour
    for node in range(topomap.node_count):
        ports = topomap.ports(node)
        if ports is None or node not in created:
            return False
        label, heading = created[node]
        if label not in network.positions:
            return False
        pipes = network.headings(label)
        if len(pipes) != len(ports):
            return False
        taken: set[str] = set()
        for port, angle in enumerate(ports):
            world = heading + angle
            nearest = min(pipes, key=lambda n: abs(wrap_angle_rad(pipes[n] - world)))
            if abs(wrap_angle_rad(pipes[nearest] - world)) > tolerance_rad or nearest in taken:
                return False
            taken.add(nearest)
            leads[(node, port)] = nearest
    for e in topomap.edges():
        if e.u_port is None or e.v_port is None:
            return False
        if leads[(e.u, e.u_port)] != created[e.v][0] or leads[(e.v, e.v_port)] != created[e.u][0]:
            return False
    return True
