"""Map-driven exploration: choose the next pipe from the robot's own port-level map.

Trémaux's rule for mazes, on the map the localizer builds as the robot goes
(Dudek et al. 1991: a robot that recognises places and tells the pipes of a place
apart can map any graph). At each junction, after the localizer has decided where
the robot is:

1. leave by an *untraversed* port of this junction (one the robot has neither come
   in nor left by), the right-most one relative to the way it came in (so on a tree
   the walk is the paper's right-hand tour);
2. otherwise plan the shortest route through the map to the nearest junction that
   has one, and take its first pipe (the route is planned again at every junction,
   from wherever the localizer says the robot is);
3. when no known port is untraversed the network is explored: drive the shortest
   route back to the start (a real robot leaves the pipes where it came in) and
   stop there.

A port the robot gave up as blocked (:meth:`TopoMap.block`) is neither untraversed
nor routable: the exploration is ``finished`` when every port that is not blocked
has been traversed, and no route goes through a blocked pipe. Back at the junction
after giving a pipe up, :meth:`MapExplorer.blocked` chooses again at once.

Consistency. The map can be wrong (a false merge or a false new node). The
explorer watches for what that looks like, and counts it:

* a route's pipe that led elsewhere than the map said;
* a port conflict: the robot came through a pipe end the map joins elsewhere;
* odometry: a junction declared new where the robot's dead reckoning puts a known
  junction with as many pipes, or a junction declared known far from where the
  robot first saw it. The tolerance grows with the distance driven, as the
  right-hand rule's search for the start does, and for a known junction also with
  the distance driven since its first visit (a long loop's drift) and with the
  path's moment since then (the heading's drift, :mod:`localizer.odometry`). A
  junction declared new is checked against the capped tolerance only: two places
  are taken for one only where the dead reckoning is sure.

  Once the loops the robot closed pin the heading's drift down (the localizer's
  :meth:`~localizer.odometry.DeadReckoning.fitted`, handed over as
  :attr:`MapExplorer.odometry`), both checks compare positions with the fitted drift
  taken out: a known junction is checked as the localizer checked it, before the
  loop it closes was fitted (:meth:`~localizer.odometry.DeadReckoning.closing_check`).
  Until then every position and tolerance is the robot's dead reckoning as given.

After ``max_inconsistencies`` junctions that show any of these the explorer stops with the status
``map inconsistent`` rather than wander: a map it cannot trust cannot say what is
left to explore, and every false new node would add ports to explore forever. It
only reads the localizer's decisions (it never overrides them), so a replay of the
log, which makes the same decisions from ``/robot``, makes the same choices.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from pipemap.localizer.decision import Decision
from pipemap.localizer.odometry import DeadReckoning, PathMark, PathMoment, scaled
from pipemap.localizer.routes import RouteStep, describe_step, nearest_route, plan_route
from pipemap.localizer.topomap import TopoMap

__all__ = [
    "ExploreConfig",
    "ExploreEnd",
    "ExploreStep",
    "MapExplorer",
    "Planner",
    "RouteFollower",
    "telling_exit",
]

#: Each live map with the port of each exit of the last visit in it
#: (``Localizer.hypothesis_exits``).
RivalMaps = Sequence[tuple[TopoMap, tuple[int, ...] | None]]


class Planner(Protocol):
    """Chooses the port to leave a junction by, from the localizer's map and decision
    (:class:`MapExplorer`, :class:`RouteFollower`)."""

    def step(
        self, topomap: TopoMap, decision: Decision, x_m: float, y_m: float, odometer_m: float
    ) -> ExploreStep:
        """The choice at the junction of ``decision``."""
        ...

    def blocked(
        self, topomap: TopoMap, decision: Decision, x_m: float, y_m: float, odometer_m: float
    ) -> ExploreStep:
        """The choice at the same junction again, now that the port last chosen is
        blocked (``topomap`` has it marked)."""
        ...


class ExploreEnd(enum.Enum):
    """Why a map-driven exploration stopped."""

    #: Every known port traversed, and back at the start.
    FINISHED = "finished"
    #: The map and what the robot saw disagreed too often.
    INCONSISTENT = "map inconsistent"


@dataclass(frozen=True)
class ExploreConfig:
    """Settings of :class:`MapExplorer`."""

    #: After exploring, drive back to the junction the run started at.
    return_home: bool = True
    #: Stop after this many junctions that showed signs that the map is wrong.
    max_inconsistencies: int = 3
    #: Odometry check: junctions closer than this plus ``drift_per_m`` per metre
    #: driven, up to ``odometry_limit_m``, are taken for the same place. Measured at
    #: 400 px (``benchmarks/bench_explore.py``): a revisit's dead reckoning was at most
    #: 0.39 m from the first visit's (after some 60 m), and two junctions with as many
    #: pipes were at least 0.79 m apart by it (the simulator's junctions are at least
    #: 0.8 m apart). 0.6 m sits between the two.
    odometry_radius_m: float = 0.3
    drift_per_m: float = 0.005
    odometry_limit_m: float = 0.6
    #: A known junction is not far from where it was while it lies within this much
    #: of the distance driven since its first visit (the localizer's
    #: ``odometry_loop_drift_per_m``): a long loop drifts past the limit above.
    loop_drift_per_m: float = 0.004
    #: ... and while it lies within ``odometry_radius_m`` plus this times the path's
    #: moment since its first visit (the localizer's ``odometry_heading_drift_per_m``):
    #: the heading's drift over long pipes.
    heading_drift_per_m: float = 0.0006

    def __post_init__(self) -> None:
        if self.max_inconsistencies < 1:
            raise ValueError("max_inconsistencies must be >= 1")
        limits = (self.odometry_radius_m, self.drift_per_m, self.odometry_limit_m)
        if min(*limits, self.loop_drift_per_m, self.heading_drift_per_m) < 0.0:
            raise ValueError("odometry tolerances must be >= 0")

    def drifting(self, factor: float) -> ExploreConfig:
        """These settings for a robot whose odometry drifts ``factor`` times as much
        (``record --odometry-drift``): the drift per metre, the limit and the loop's
        and the heading's allowances ``factor`` times as wide, as
        :func:`localizer.odometry.drift_allowed` widens the localizer's."""
        if factor == 1.0:
            return self
        fields = ("drift_per_m", "odometry_limit_m", "loop_drift_per_m", "heading_drift_per_m")
        return dataclasses.replace(self, **scaled(self, factor, fields))


@dataclass(frozen=True)
class ExploreStep:
    """The explorer's choice: leave by ``port`` of the current junction, or stop with
    ``stop``; neither (a junction whose pipes the map cannot tell apart) leaves it to
    the right-hand rule. ``goal`` is the junction the robot is heading for when it
    follows a route; ``notes`` say what happened (for the log)."""

    port: int | None = None
    stop: ExploreEnd | None = None
    goal: int | None = None
    notes: tuple[str, ...] = ()


@dataclass
class MapExplorer:
    """Trémaux-style exploration over the localizer's map; call :meth:`step` once per
    junction visit, after the localizer's decision."""

    config: ExploreConfig = field(default_factory=ExploreConfig)
    start: int | None = None
    inconsistencies: list[str] = field(default_factory=list)
    explored: bool = False
    _positions: dict[int, tuple[float, float]] = field(default_factory=dict)
    #: The odometer at each junction's first visit.
    _odometers: dict[int, float] = field(default_factory=dict)
    #: The path driven, and where on it each junction was first visited.
    _path: PathMoment = field(default_factory=PathMoment)
    _marks: dict[int, PathMark] = field(default_factory=dict)
    _expected: tuple[int, int | None] | None = None
    _goal: int | None = None
    #: The live maps (``Localizer.hypothesis_exits``): while more than one lives, an
    #: exit that one of them cannot take the outcome of goes first (:func:`telling_exit`).
    rivals: Callable[[], RivalMaps] | None = None
    #: The (node, port) of the leader's map already driven to tell maps apart.
    _told: set[tuple[int, int]] = field(default_factory=set)
    #: The localizer's dead reckoning (``Localizer.dead_reckoning``), at the visit
    #: being checked: once it has fitted the heading's drift, positions are compared
    #: with the drift taken out (``None``: always as given).
    odometry: DeadReckoning | None = None

    def _tolerance_m(self, odometer_m: float) -> float:
        c = self.config
        return min(c.odometry_radius_m + c.drift_per_m * odometer_m, c.odometry_limit_m)

    def _check(
        self, topomap: TopoMap, decision: Decision, here: tuple[float, float], odometer_m: float
    ) -> list[str]:
        """Signs that the map is wrong at this visit."""
        found: list[str] = []
        node = decision.node
        if self._expected is not None:
            node_x, port_x = self._expected
            arrived = decision.arrival_port
            if node != node_x or (port_x is not None and arrived is not None and arrived != port_x):
                found.append(
                    f"the map's pipe led to node {node_x} port {port_x}; the localizer says "
                    f"node {node} port {arrived}"
                )
        last = topomap.last_visit
        if last is not None and last.conflict is not None:
            found.append(last.conflict)
        tolerance = self._tolerance_m(odometer_m)
        self._path.add(here, odometer_m)
        ports = topomap.ports(node)
        fitted = self._fitted(here)
        if not decision.known:
            for k, (x, y) in sorted(self._positions.items()):
                same_kind = ports is not None and len(topomap.ports(k) or ()) == len(ports)
                off = self._offset_m(fitted, k, here, (x, y))
                if k != node and same_kind and off < tolerance:
                    found.append(
                        f"new junction {node} is {off:.2f} m from known junction {k} by odometry"
                    )
                    break
            self._first_visit(node, here, odometer_m)
        elif node in self._positions:
            # The localizer's check as it decided (the loop this visit closes not yet
            # in the fit), else the robot's dead reckoning as given.
            checked = None if fitted is None else fitted.closing_check(node)
            if checked is not None:
                off, allowed = checked[0], max(tolerance, checked[1])
            else:
                x, y = self._positions[node]
                off = math.hypot(here[0] - x, here[1] - y)
                allowed = max(tolerance, self._drift_since_m(node, odometer_m))
            if off > allowed:
                found.append(f"junction {node} is {off:.2f} m from where it was by odometry")
        else:
            self._first_visit(node, here, odometer_m)
        return found

    def _fitted(self, here: tuple[float, float]) -> DeadReckoning | None:
        """The localizer's dead reckoning, if it is at this visit (``here``) and has
        fitted the heading's drift to the loops closed; else ``None``."""
        odometry = self.odometry
        if odometry is None or odometry.here != here or not odometry.fitted():
            return None
        return odometry

    @staticmethod
    def _offset_m(
        fitted: DeadReckoning | None,
        node: int,
        here: tuple[float, float],
        there: tuple[float, float],
    ) -> float:
        """How far junction ``node``'s first visit (at ``there``) is from ``here``: with
        the fitted heading drift taken out when ``fitted`` is given."""
        off = None if fitted is None else fitted.offset_m(node)
        return math.hypot(here[0] - there[0], here[1] - there[1]) if off is None else off

    def _first_visit(self, node: int, here: tuple[float, float], odometer_m: float) -> None:
        self._positions[node] = here
        self._odometers[node] = odometer_m
        if self._path.mark is not None:
            self._marks[node] = self._path.mark

    def _drift_since_m(self, node: int, odometer_m: float) -> float:
        """How far known junction ``node`` may be from where it was by the drift since
        its first visit: over the distance driven, and by the heading's drift over the
        path's moment (:class:`localizer.odometry.PathMoment`)."""
        c = self.config
        drift = c.loop_drift_per_m * (odometer_m - self._odometers[node])
        mark = self._marks.get(node)
        if mark is not None:
            drift = max(drift, c.odometry_radius_m + c.heading_drift_per_m * self._path.since(mark))
        return drift

    def step(
        self, topomap: TopoMap, decision: Decision, x_m: float, y_m: float, odometer_m: float
    ) -> ExploreStep:
        """The port to leave the junction of ``decision`` by, or the end of the run.

        ``topomap`` is the localizer's map with this visit already in it; ``x_m``,
        ``y_m`` and ``odometer_m`` are the robot's dead reckoning here.
        """
        node = decision.node
        if self.start is None:
            self.start = node
        notes: list[str] = []
        found = self._check(topomap, decision, (x_m, y_m), odometer_m)
        self._expected = None
        if found:
            self.inconsistencies.append("; ".join(found))
            notes.append(f"map inconsistency {len(self.inconsistencies)}: {'; '.join(found)}")
        if len(self.inconsistencies) >= self.config.max_inconsistencies:
            notes.append(
                f"stopped: the map disagreed with the robot at {len(self.inconsistencies)} "
                "junctions; it is not trusted"
            )
            return ExploreStep(stop=ExploreEnd.INCONSISTENT, notes=tuple(notes))
        return self._choose(topomap, decision, notes)

    def blocked(
        self, topomap: TopoMap, decision: Decision, x_m: float, y_m: float, odometer_m: float
    ) -> ExploreStep:
        """The choice at the junction of ``decision`` again, its last port now blocked:
        as :meth:`step`, without checking the visit a second time."""
        node = decision.node
        blocked = " ".join(str(p) for p in topomap.blocked(node))
        notes = [f"junction {node}: port(s) {blocked} blocked"]
        self._goal = None  # plan again: the route may have gone that way
        self._expected = None
        return self._choose(topomap, decision, notes)

    def _choose(self, topomap: TopoMap, decision: Decision, notes: list[str]) -> ExploreStep:
        node = decision.node
        if topomap.ports(node) is None:
            notes.append(f"stopped: junction {node} has no known pipes")
            return ExploreStep(stop=ExploreEnd.INCONSISTENT, notes=tuple(notes))
        if decision.exit_ports is None:
            # Known, but its exits could not be put on its ports: the map cannot say
            # which pipe is which here. Leave by the right-hand rule (``port`` None).
            text = f"the exits do not fit junction {node}'s ports"
            self.inconsistencies.append(text)
            notes.append(f"map inconsistency {len(self.inconsistencies)}: {text}")
            return ExploreStep(notes=tuple(notes))
        telling = None if self.rivals is None else telling_exit(self.rivals())
        if telling is not None and (node, decision.exit_ports[telling]) not in self._told:
            port = decision.exit_ports[telling]
            self._told.add((node, port))
            self._goal, self._expected = None, None  # the maps disagree where it leads
            notes.append(f"port {port}: one of the maps alive cannot take where it leads")
            return ExploreStep(port=port, notes=tuple(notes))
        here = topomap.untraversed(node)
        if here and not self.explored:
            self._goal = None
            return ExploreStep(port=self._right_most(decision, here), notes=tuple(notes))
        targets = [] if self.explored else self._open_junctions(topomap)
        found_route = None
        if targets:
            found_route = nearest_route(topomap, node, targets)
            if found_route is None and any(topomap.blocked(n) for n in range(topomap.node_count)):
                # Left only behind blocked pipes: what can be reached is explored.
                notes.append("the junctions left to explore lie behind blocked pipes")
                targets, self.explored = [], True
        if targets:
            if found_route is None:
                notes.append("stopped: no route in the map to the junctions left to explore")
                return ExploreStep(stop=ExploreEnd.INCONSISTENT, notes=tuple(notes))
            goal, route = found_route
        else:
            if not self.explored:
                self.explored = True
                notes.append("explored: every known pipe traversed")
            goal = node if self.start is None else self.start  # set at the first step
            if goal == node or not self.config.return_home:
                if goal == node:
                    notes.append("back at the start")
                return ExploreStep(stop=ExploreEnd.FINISHED, notes=tuple(notes))
            home = plan_route(topomap, node, goal)
            if home is None:
                notes.append("stopped: no route in the map back to the start")
                return ExploreStep(stop=ExploreEnd.INCONSISTENT, notes=tuple(notes))
            route = home
        if goal != self._goal:
            way = "; ".join(describe_step(s) for s in route)
            notes.append(f"route to junction {goal}: {way}")
            self._goal = goal
        first, second = route[0], route[1]
        self._expected = (second.node, second.arrive_port)
        return ExploreStep(port=first.leave_port, goal=goal, notes=tuple(notes))

    @staticmethod
    def _open_junctions(topomap: TopoMap) -> list[int]:
        return [n for n in range(topomap.node_count) if topomap.untraversed(n)]

    @staticmethod
    def _right_most(decision: Decision, ports: list[int]) -> int:
        """The right-most of ``ports`` seen from the way the robot came in."""
        exits, exit_ports = decision.exits_rad, decision.exit_ports
        assert exits is not None and exit_ports is not None
        angle = {p: math.remainder(exits[exit_ports.index(p)], 2.0 * math.pi) for p in ports}
        return min(ports, key=lambda p: (angle[p], p))


def telling_exit(maps: RivalMaps) -> int | None:
    """The first exit of the last visit whose outcome one of the live ``maps`` cannot
    take, or ``None``: a map says where the exit's pipe leads (a junction's pipe end)
    and another has that pipe end joined to some other pipe. Arriving there would be
    a port conflict in the other map (:mod:`localizer.hypotheses` drops it); arriving
    elsewhere, one in the first. A far end that differs only in which look-alike it
    is tells nothing, and is not chosen. One map, or exits not on every map's ports:
    ``None``."""
    if len(maps) < 2 or any(exits is None for _, exits in maps):
        return None
    counts = {len(exits) for _, exits in maps if exits is not None}
    if len(counts) != 1:
        return None
    for index in range(counts.pop()):
        ends = []
        for topomap, exits in maps:
            assert exits is not None
            ends.append((topomap, topomap.visits[-1], exits[index]))
        if any(m.is_blocked(node, port) for m, node, port in ends):
            continue
        for m, node, port in ends:
            edge = m.edge_at(node, port)
            if edge is None:
                continue
            far = edge.other(node, port)
            if far[1] is None:
                continue
            for other, o_node, o_port in ends:
                there = other.edge_at(far[0], far[1])
                if there is not None and there.other(*far) != (o_node, o_port):
                    return index
    return None


@dataclass
class RouteFollower:
    """Drives a planned route (:func:`~pipemap.localizer.routes.plan_route`) over a
    known map: at each junction it leaves by the route's port, and stops when the
    localizer says the robot is at the goal. Where the localizer puts the robot off
    the route, it plans again from there (at most ``max_replans`` times)."""

    route: list[RouteStep]
    max_replans: int = 3
    replans: int = 0
    _index: int = 0

    @property
    def goal(self) -> int:
        """The junction the route leads to."""
        return self.route[-1].node

    def step(
        self, topomap: TopoMap, decision: Decision, x_m: float, y_m: float, odometer_m: float
    ) -> ExploreStep:
        """The port to leave by, or the end of the route (same signature as
        :meth:`MapExplorer.step`; the odometry is not used)."""
        node = decision.node
        if node == self.goal:
            return ExploreStep(stop=ExploreEnd.FINISHED, notes=(f"arrived at junction {node}",))
        notes: list[str] = []
        expected = self.route[self._index].node if self._index < len(self.route) else None
        if node != expected:
            self.replans += 1
            notes.append(f"expected junction {expected}, the localizer says {node}: replanning")
            route = (
                plan_route(topomap, node, self.goal) if self.replans <= self.max_replans else None
            )
            if route is None:
                notes.append(f"stopped: no way to junction {self.goal}")
                return ExploreStep(stop=ExploreEnd.INCONSISTENT, notes=tuple(notes))
            self.route, self._index = route, 0
        here = self.route[self._index]
        self._index += 1
        return ExploreStep(port=here.leave_port, goal=self.goal, notes=tuple(notes))

    def blocked(
        self, topomap: TopoMap, decision: Decision, x_m: float, y_m: float, odometer_m: float
    ) -> ExploreStep:
        """The route's pipe here is blocked: plan again from here, around it."""
        self.replans += 1
        node = decision.node
        notes = [f"junction {node}: the route's pipe is blocked: replanning"]
        route = plan_route(topomap, node, self.goal) if self.replans <= self.max_replans else None
        if route is None:
            notes.append(f"stopped: no way to junction {self.goal}")
            return ExploreStep(stop=ExploreEnd.INCONSISTENT, notes=tuple(notes))
        self.route, self._index = route, 1
        return ExploreStep(port=route[0].leave_port, goal=self.goal, notes=tuple(notes))
