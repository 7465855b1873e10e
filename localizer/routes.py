"""Routes through a port-level map: which pipe to take at each junction.

A route is the shortest way through the map's edges from one junction to another,
by the distance the robot drove along each pipe when it mapped it (one metre where
that is unknown). It is told junction by junction: the port the robot arrives by
and the port it leaves by, as the map numbers them (see :mod:`localizer.ports`).
Only edges with both ports known can be driven, so only they are used. Ties go
to the lowest node and edge labels, so the same map always gives the same route.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable
from dataclasses import dataclass

from pipemap.localizer.topomap import MapEdge, TopoMap

__all__ = ["RouteStep", "describe_step", "nearest_route", "plan_route", "route_length_m"]

#: Length assumed for a pipe the map has no odometry for.
_UNKNOWN_LENGTH_M = 1.0


@dataclass(frozen=True)
class RouteStep:
    """One junction of a route: arrived by ``arrive_port`` (``None`` at the start),
    left by ``leave_port`` (``None`` at the goal) along ``edge`` (the map's edge
    label; ``None`` at the goal)."""

    node: int
    arrive_port: int | None
    leave_port: int | None
    edge: int | None = None


def _weight(edge: MapEdge) -> float:
    return _UNKNOWN_LENGTH_M if edge.length_m is None else max(edge.length_m, 0.0)


def _adjacency(topomap: TopoMap) -> dict[int, list[tuple[int, int, int, MapEdge]]]:
    """For each node, its drivable edges as (port here, far node, far port, edge)."""
    out: dict[int, list[tuple[int, int, int, MapEdge]]] = {}
    for e in topomap.edges():
        if e.u_port is None or e.v_port is None:
            continue
        if topomap.is_blocked(e.u, e.u_port) or topomap.is_blocked(e.v, e.v_port):
            continue  # given up as blocked from one side: not drivable
        out.setdefault(e.u, []).append((e.u_port, e.v, e.v_port, e))
        out.setdefault(e.v, []).append((e.v_port, e.u, e.u_port, e))
    for entries in out.values():
        entries.sort(key=lambda x: (x[0], x[3].label))
    return out


def _dijkstra(
    topomap: TopoMap, start: int
) -> tuple[dict[int, float], dict[int, tuple[int, int, int, MapEdge]]]:
    """Distances from ``start`` and, for each reached node, how it was reached:
    (previous node, port left by there, port arrived by here, edge)."""
    adjacency = _adjacency(topomap)
    dist = {start: 0.0}
    came: dict[int, tuple[int, int, int, MapEdge]] = {}
    heap = [(0.0, start)]
    done: set[int] = set()
    while heap:
        d, node = heapq.heappop(heap)
        if node in done:
            continue
        done.add(node)
        for port, far, far_port, edge in adjacency.get(node, []):
            nd = d + _weight(edge)
            if far not in dist or nd < dist[far] - 1e-12:
                dist[far] = nd
                came[far] = (node, port, far_port, edge)
                heapq.heappush(heap, (nd, far))
    return dist, came


def _steps(
    start: int, goal: int, came: dict[int, tuple[int, int, int, MapEdge]]
) -> list[RouteStep]:
    hops: list[tuple[int, int, int, MapEdge]] = []
    node = goal
    while node != start:
        hop = came[node]
        hops.append(hop)
        node = hop[0]
    hops.reverse()
    steps: list[RouteStep] = []
    arrive: int | None = None
    for previous, leave, far_port, edge in hops:
        steps.append(RouteStep(previous, arrive, leave, edge.label))
        arrive = far_port
    steps.append(RouteStep(goal, arrive, None))
    return steps


def _check(topomap: TopoMap, node: int) -> None:
    if not 0 <= node < topomap.node_count or topomap.unused(node):
        raise ValueError(f"node {node} is not in the map (it has {topomap.node_count})")


def plan_route(topomap: TopoMap, start: int, goal: int) -> list[RouteStep] | None:
    """The shortest route from ``start`` to ``goal``, junction by junction (a single
    step when they are the same), or ``None`` when the map has no way there."""
    _check(topomap, start)
    _check(topomap, goal)
    dist, came = _dijkstra(topomap, start)
    if goal not in dist:
        return None
    return _steps(start, goal, came)


def nearest_route(
    topomap: TopoMap, start: int, goals: Iterable[int]
) -> tuple[int, list[RouteStep]] | None:
    """The nearest of ``goals`` from ``start`` by the map (ties: lowest node) and the
    route there; ``None`` when none is reachable."""
    _check(topomap, start)
    dist, came = _dijkstra(topomap, start)
    reachable = [g for g in set(goals) if g in dist]
    if not reachable:
        return None
    goal = min(reachable, key=lambda g: (dist[g], g))
    return goal, _steps(start, goal, came)


def route_length_m(topomap: TopoMap, route: list[RouteStep]) -> float:
    """The route's length by the map (one metre for each pipe of unknown length)."""
    by_label = {e.label: e for e in topomap.edges()}
    return math.fsum(_weight(by_label[s.edge]) for s in route if s.edge is not None)


def describe_step(step: RouteStep) -> str:
    """One line of a route, e.g. ``at node 3, arriving by port 0, leave by port 2``."""
    if step.leave_port is None:
        if step.arrive_port is None:
            return f"already at node {step.node}"
        return f"arrive at node {step.node} by port {step.arrive_port}"
    if step.arrive_port is None:
        return f"at node {step.node}, leave by port {step.leave_port}"
    return (
        f"at node {step.node}, arriving by port {step.arrive_port}, leave by port {step.leave_port}"
    )
