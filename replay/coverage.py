"""How much of the true network a run mapped, and whether its ports are right.

The truth comes from the log: the network (``/truth/network``: node positions and
pipes) and the true node and camera pose of every sweep (``/truth/sweep``).

* **Coverage**: the true nodes the robot swept, and the true pipes it drove (two
  consecutive visits at the two ends of a pipe), against the network's.
* **Blocked pipes**: a pipe with a blocking deposit (``obstacle/K`` entities of
  the network, kind ``blocking``) cannot be driven. Coverage then asks for the
  nodes reachable from the start without driving one, and the pipes among them
  that are not blocked: a node reachable only through a blocked pipe is
  unreachable, and is not missed. Each pipe the map marks blocked is a true
  positive when it is truly blocked, else a false "blocked"; a truly blocked pipe
  with an end the robot could reach and no mark is missed (:func:`blocked_of`).
* **Ports**: each map node's ports are turned into world headings with the true
  heading of the robot at the node's first visit, and each must lie within
  :data:`~pipemap.localizer.PORT_TOLERANCE_RAD` of its own true pipe; each map edge
  must join, at either end, the pipe that leads to the other end's true node.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from google.protobuf.message import DecodeError

from pipemap.localizer import PORT_TOLERANCE_RAD, TopoMap, wrap_angle_rad
from pipemap.recorder import Topic
from pipemap.recorder.schemas import SceneUpdate
from pipemap.replay.source import MessageSource

__all__ = [
    "BlockedPipes",
    "Coverage",
    "TrueNetwork",
    "blocked_of",
    "coverage_of",
    "ports_correct",
    "true_network",
]


@dataclass(frozen=True)
class TrueNetwork:
    """The network of the log's truth: node positions and pipes (sorted label pairs)."""

    positions: dict[str, tuple[float, float]]
    pipes: frozenset[tuple[str, str]]
    #: Pipes with a deposit, and its kind (``passable`` or ``blocking``).
    deposits: tuple[tuple[tuple[str, str], str], ...] = ()

    @property
    def blocked_pipes(self) -> frozenset[tuple[str, str]]:
        """The pipes no robot can drive through."""
        return frozenset(p for p, kind in self.deposits if kind == "blocking")

    def reachable(self, start: str) -> set[str]:
        """The nodes reachable from ``start`` without driving a blocked pipe."""
        open_pipes = self.pipes - self.blocked_pipes
        seen, todo = {start}, [start]
        while todo:
            here = todo.pop()
            for a, b in open_pipes:
                for u, v in ((a, b), (b, a)):
                    if u == here and v not in seen:
                        seen.add(v)
                        todo.append(v)
        return seen

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


def true_network(source: MessageSource, problems: list[str] | None = None) -> TrueNetwork | None:
    """The network of the log's ``/truth/network``, or ``None`` if it has none. What
    makes a network message unusable (it does not decode, it holds no node) is added
    to ``problems``, a line each, so that a score can say what it could not score."""
    for m in source.truth():
        if m.topic != Topic.NETWORK:
            continue
        try:
            scene = SceneUpdate.FromString(m.data)
        except DecodeError:
            if problems is not None:
                problems.append(f"{Topic.NETWORK} does not decode")
            continue
        positions: dict[str, tuple[float, float]] = {}
        pipes: set[tuple[str, str]] = set()
        deposits: list[tuple[tuple[str, str], str]] = []
        for entity in scene.entities:
            kind, _, name = entity.id.partition("/")
            if kind == "node" and entity.spheres:
                p = entity.spheres[0].pose.position
                positions[name] = (p.x, p.y)
            elif kind == "pipe":
                a, _, b = name.partition("-")
                pipes.add((min(a, b), max(a, b)))
            elif kind == "obstacle":
                meta = {kv.key: kv.value for kv in entity.metadata}
                a, _, b = meta.get("pipe", "").partition("-")
                deposits.append(((min(a, b), max(a, b)), meta.get("kind", "")))
        if positions:
            return TrueNetwork(positions, frozenset(pipes), tuple(deposits))
        if problems is not None:
            problems.append(f"{Topic.NETWORK} holds no node")
    return None


@dataclass(frozen=True)
class Coverage:
    """True nodes swept and true pipes driven, of the network's."""

    nodes_visited: int
    nodes_total: int
    pipes_traversed: int
    pipes_total: int
    #: With blocked pipes in the truth: the nodes reachable from the start without
    #: driving one, the pipes among them that are not blocked, and how many of each
    #: the run covered. ``None`` without blocked pipes.
    reachable: tuple[int, int, int, int] | None = None

    @property
    def complete(self) -> bool:
        """Every node swept and every pipe driven; with blocked pipes, every
        reachable node and every pipe that is not blocked among them."""
        if self.reachable is not None:
            visited, reachable, driven, open_pipes = self.reachable
            return visited == reachable and driven == open_pipes
        return self.nodes_visited == self.nodes_total and self.pipes_traversed == self.pipes_total

    def document(self) -> dict[str, int]:
        """As in ``pipemap score --json``."""
        doc = {
            "nodes_visited": self.nodes_visited,
            "nodes_total": self.nodes_total,
            "pipes_traversed": self.pipes_traversed,
            "pipes_total": self.pipes_total,
        }
        if self.reachable is not None:
            visited, reachable, driven, open_pipes = self.reachable
            doc |= {
                "reachable_nodes_visited": visited,
                "reachable_nodes": reachable,
                "open_pipes_traversed": driven,
                "open_pipes": open_pipes,
            }
        return doc


def coverage_of(network: TrueNetwork, true_nodes: Sequence[str]) -> Coverage:
    """The coverage of a run whose visits were at ``true_nodes``, in order."""
    visited = set(true_nodes) & set(network.positions)
    driven = {
        (min(a, b), max(a, b))
        for a, b in zip(true_nodes, true_nodes[1:], strict=False)
        if (min(a, b), max(a, b)) in network.pipes
    }
    reachable = None
    blocked = network.blocked_pipes
    if blocked and true_nodes and true_nodes[0] in network.positions:
        nodes = network.reachable(true_nodes[0])
        open_pipes = {p for p in network.pipes - blocked if p[0] in nodes}
        reachable = (len(visited & nodes), len(nodes), len(driven & open_pipes), len(open_pipes))
    return Coverage(
        len(visited), len(network.positions), len(driven), len(network.pipes), reachable
    )


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
        if topomap.unused(node):  # an id competing maps gave a junction this one has not
            continue
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


@dataclass(frozen=True)
class BlockedPipes:
    """The pipes a map marks blocked against the truly blocked ones (sorted label
    pairs; a mark whose pipe cannot be told is ``("?", "?")``)."""

    marked: tuple[tuple[str, str], ...]
    truly_blocked: tuple[tuple[str, str], ...]
    #: Truly blocked pipes with an end the robot could reach.
    reachable: tuple[tuple[str, str], ...]

    @property
    def true_positives(self) -> list[tuple[str, str]]:
        """Marked and truly blocked."""
        return sorted(set(self.marked) & set(self.truly_blocked))

    @property
    def false_blocked(self) -> list[tuple[str, str]]:
        """Marked, but not truly blocked (a deposit it could have passed, or none)."""
        return sorted(set(self.marked) - set(self.truly_blocked))

    @property
    def missed(self) -> list[tuple[str, str]]:
        """Truly blocked, reachable, and not marked."""
        return sorted(set(self.reachable) - set(self.marked))

    @property
    def correct(self) -> bool:
        """Every reachable blocked pipe marked, and nothing else."""
        return not self.false_blocked and not self.missed

    def document(self) -> dict[str, object]:
        """As in ``pipemap score --json``."""

        def names(pipes: list[tuple[str, str]]) -> list[str]:
            return [f"{a}-{b}" for a, b in pipes]

        return {
            "marked": names(sorted(set(self.marked))),
            "truly_blocked": names(sorted(self.truly_blocked)),
            "true_positives": names(self.true_positives),
            "false_blocked": names(self.false_blocked),
            "missed": names(self.missed),
        }


def blocked_of(
    topomap: TopoMap,
    network: TrueNetwork,
    created: dict[int, tuple[str, float]],
    start: str | None,
    tolerance_rad: float = PORT_TOLERANCE_RAD,
) -> BlockedPipes:
    """The map's blocked ports as true pipes (by the port's angle and the true heading
    at the node's first visit, as :func:`ports_correct` reads ports), against the
    truth. ``start`` is the true node the run started at."""
    marked: list[tuple[str, str]] = []
    for node in range(topomap.node_count):
        ports = topomap.ports(node)
        for port in topomap.blocked(node):
            pipe = ("?", "?")
            if ports is not None and node in created and created[node][0] in network.positions:
                label, heading = created[node]
                pipes = network.headings(label)
                world = heading + ports[port]
                nearest = min(
                    pipes, key=lambda n: abs(wrap_angle_rad(pipes[n] - world)), default=None
                )
                if (
                    nearest is not None
                    and abs(wrap_angle_rad(pipes[nearest] - world)) <= tolerance_rad
                ):
                    pipe = (min(label, nearest), max(label, nearest))
            marked.append(pipe)
    blocked = sorted(network.blocked_pipes)
    reach = network.reachable(start) if start in network.positions else set()
    reachable = [p for p in blocked if p[0] in reach or p[1] in reach]
    return BlockedPipes(tuple(marked), tuple(blocked), tuple(reachable))
