"""Map-driven exploration (:mod:`localizer.explore`) and routes (:mod:`localizer.routes`),
on the simulator's networks walked without images: a stand-in localizer that knows
where the robot is (or is told to be wrong) feeds the real map and explorer."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import pytest

from pipemap.localizer import (
    Decision,
    ExploreConfig,
    ExploreEnd,
    LocalizerConfig,
    MapExplorer,
    RouteStep,
    TopoMap,
    clockwise_ports,
    describe_step,
    match_ports,
    nearest_exit,
    nearest_route,
    plan_route,
    route_length_m,
)
from pipemap.localizer.odometry import DeadReckoning
from pipemap.sim.network import Network, build_network
from pipemap.sim.network_model import Node, Pipe


@dataclass
class Walk:
    """A robot on a network, its map built by a stand-in localizer.

    ``wrong`` makes the localizer err: ``"new"`` declares every visit new, ``"merge"``
    takes every junction for the first known junction with as many pipes.
    """

    network: Network
    start: str | None = None
    wrong: str | None = None
    config: ExploreConfig = field(default_factory=ExploreConfig)
    topomap: TopoMap = field(default_factory=TopoMap)
    path: list[str] = field(default_factory=list)
    odometer_m: float = 0.0
    #: Dead reckoning drifts east by this much per metre driven.
    drift_per_m: float = 0.0
    #: Dead reckoning's heading drifts by this much (rad) per metre driven: it
    #: integrates each pipe with a heading error that grows as the robot drives.
    heading_drift_per_m: float = 0.0
    #: Pipes (sorted label pairs) the robot cannot get through: it gives them up.
    blocked_pipes: frozenset[tuple[str, str]] = frozenset()
    gave_up: list[tuple[str, str]] = field(default_factory=list)
    #: Hand the explorer a localizer's dead reckoning, fed each visit's position and
    #: decision as :meth:`Localizer.localize` feeds it (the heading's drift fitted to
    #: the loops closed).
    fit: bool = False
    localizer: LocalizerConfig = field(default_factory=LocalizerConfig)

    def __post_init__(self) -> None:
        self.explorer = MapExplorer(self.config)
        self.odometry = DeadReckoning(self.localizer) if self.fit else None
        self.explorer.odometry = self.odometry
        self.first_heading: dict[int, float] = {}
        self.label_of: dict[int, str] = {}
        self.node_of: dict[str, int] = {}
        self.dead_reckoning: tuple[float, float] | None = None

    def _drive(self, a: str, b: str) -> None:
        """Dead reckoning along the pipe from ``a`` to ``b`` (heading drift only)."""
        net = self.network
        assert self.dead_reckoning is not None
        x, y = self.dead_reckoning
        length = net.length_m(a, b)
        heading = net.pipe_headings(a)[b]
        steps = 50
        for k in range(steps):
            error = self.heading_drift_per_m * (self.odometer_m + (k + 0.5) * length / steps)
            x += length / steps * math.cos(heading + error)
            y += length / steps * math.sin(heading + error)
        self.dead_reckoning = (x, y)

    def _decide(self, label: str, heading: float, exits: list[float]) -> Decision:
        m = self.topomap
        node = None if self.wrong == "new" else self.node_of.get(label)
        if self.wrong == "merge":
            node = next(
                (n for n in range(m.node_count) if len(m.ports(n) or ()) == len(exits)), node
            )
        arrival = None
        if node is None:
            node = m.node_count
            ports, exit_ports = clockwise_ports(exits)
            self.first_heading[node] = heading
            self.node_of.setdefault(label, node)
            known = False
        else:
            ports = None
            rotation = self.first_heading[node] - heading
            exit_ports = match_ports(m.ports(node) or (), exits, rotation, 3.0).exit_ports
            known = True
        if self.path:
            behind = nearest_exit(exits, math.pi)
            arrival = None if behind is None or exit_ports is None else exit_ports[behind]
        m.visit(node, ports, arrival, self.odometer_m)
        return Decision(
            node,
            known,
            None,
            0.0,
            None,
            None,
            exits_rad=tuple(exits),
            exit_ports=exit_ports,
            arrival_port=arrival,
        )

    def run(self, max_visits: int = 500) -> ExploreEnd | None:
        net = self.network
        label = self.start if self.start is not None else net.entry
        heading = net.pipe_headings(label)[net.neighbours(label)[0]] + math.pi
        for _ in range(max_visits):
            headings = net.pipe_headings(label)
            neighbours = net.neighbours(label)
            exits = [math.remainder(headings[n] - heading, 2 * math.pi) for n in neighbours]
            decision = self._decide(label, heading, exits)
            self.path.append(label)
            node = net.node(label)
            x, y = node.x_m + self.drift_per_m * self.odometer_m, node.y_m
            if self.heading_drift_per_m:
                if self.dead_reckoning is None:
                    self.dead_reckoning = (node.x_m, node.y_m)
                x, y = self.dead_reckoning
            if self.odometry is not None:
                self.odometry.at((x, y), self.odometer_m)
                if decision.known:
                    self.odometry.closed(decision.node)
                else:
                    self.odometry.remember(decision.node)
            step = self.explorer.step(self.topomap, decision, x, y, self.odometer_m)
            if step.stop is not None:
                return step.stop
            assert step.port is not None and decision.exit_ports is not None
            leave = neighbours[decision.exit_ports.index(step.port)]
            self.topomap.depart(step.port)
            while tuple(sorted((label, leave))) in self.blocked_pipes:
                assert len(self.gave_up) < 50, "the explorer keeps choosing blocked pipes"
                self.gave_up.append((label, leave))
                self.topomap.block()
                step = self.explorer.blocked(self.topomap, decision, x, y, self.odometer_m)
                if step.stop is not None:
                    return step.stop
                assert step.port is not None
                leave = neighbours[decision.exit_ports.index(step.port)]
                self.topomap.depart(step.port)
            if self.heading_drift_per_m:
                self._drive(label, leave)
            self.odometer_m += net.length_m(label, leave)
            heading = headings[leave]
            label = leave
        return None

    def label_of_node(self, node: int) -> str:
        """The true label of map node ``node``."""
        return next(label for label, n in self.node_of.items() if n == node)

    def traversals(self) -> list[tuple[str, str]]:
        return [tuple(sorted(p)) for p in zip(self.path, self.path[1:], strict=False)]  # type: ignore[misc]


def _pipes(network: Network) -> set[tuple[str, str]]:
    return {tuple(sorted((p.a, p.b))) for p in network.pipes}  # type: ignore[misc]


@pytest.mark.parametrize(
    "spec, seed, start",
    [
        ("paper", 0, None),
        ("paper", 0, "C"),
        ("grid:3x3", 0, None),
        ("grid:5x5", 0, None),
        ("random:20", 3, None),
        ("random:40", 1, None),
        ("tree:15", 2, None),
    ],
)
def test_every_pipe_is_driven_and_the_robot_ends_at_its_start(
    spec: str, seed: int, start: str | None
) -> None:
    network = build_network(spec, seed=seed)
    walk = Walk(network, start)
    assert walk.run() is ExploreEnd.FINISHED
    driven = walk.traversals()
    assert set(driven) == _pipes(network)
    assert walk.path[-1] == walk.path[0]
    # Trémaux: each pipe at most twice while exploring; the way home crosses each
    # pipe at most once more.
    counts = {p: driven.count(p) for p in set(driven)}
    assert max(counts.values()) <= 3
    assert len(driven) <= 2 * len(network.pipes) + len(network.nodes)
    assert walk.topomap.node_count == len(network.nodes)
    assert len(walk.topomap.edges()) == len(network.pipes)
    assert walk.explorer.inconsistencies == []


def test_on_a_tree_the_walk_is_the_right_hand_tour() -> None:
    from pipemap.sim.plan import right_hand_tour

    network = build_network("paper")
    walk = Walk(network)
    walk.run()
    assert walk.path == list(right_hand_tour(network).nodes)


def test_without_going_home_it_stops_where_the_last_pipe_ends() -> None:
    network = build_network("paper")
    walk = Walk(network, config=ExploreConfig(return_home=False))
    assert walk.run() is ExploreEnd.FINISHED
    assert walk.path[-1] == "E"  # the last dead end of the right-hand tour
    assert walk.path == list("SABACDCFCE")


@pytest.mark.parametrize("wrong", ["new", "merge"])
def test_a_wrong_localizer_ends_the_run_as_inconsistent(wrong: str) -> None:
    network = build_network("grid:4x4")
    walk = Walk(network, wrong=wrong)
    assert walk.run() is ExploreEnd.INCONSISTENT
    assert len(walk.explorer.inconsistencies) == 3
    assert len(walk.path) < 40
    # Among them the map's own conflicts: a pipe end already joined elsewhere.
    assert any("already leads to" in found for found in walk.explorer.inconsistencies)


def test_one_inconsistency_is_tolerated() -> None:
    network = build_network("grid:3x3")
    walk = Walk(network, config=ExploreConfig(max_inconsistencies=1))
    assert walk.run() is ExploreEnd.FINISHED
    with pytest.raises(ValueError):
        ExploreConfig(max_inconsistencies=0)


# --- routes -----------------------------------------------------------------------


def _explored(spec: str = "grid:3x3") -> tuple[Walk, TopoMap]:
    walk = Walk(build_network(spec))
    walk.run()
    return walk, walk.topomap


def test_a_route_follows_ports_to_the_goal() -> None:
    walk, m = _explored()
    goal = walk.node_of["r2c2"]
    route = plan_route(m, 0, goal)
    assert route is not None
    assert route[0].node == 0 and route[0].arrive_port is None
    assert route[-1] == RouteStep(goal, route[-1].arrive_port, None)
    # Each step leaves by the port whose edge arrives at the next step's port.
    for here, there in zip(route, route[1:], strict=False):
        assert here.leave_port is not None
        edge = m.edge_at(here.node, here.leave_port)
        assert edge is not None and edge.label == here.edge
        assert edge.other(here.node, here.leave_port) == (there.node, there.arrive_port)
    # S, r0c0 .. r2c2: 1 + 4 pipes of 1 m (as driven).
    assert len(route) == 6
    assert route_length_m(m, route) == pytest.approx(5.0)


def test_route_to_itself_and_unknown_nodes() -> None:
    _, m = _explored()
    assert plan_route(m, 3, 3) == [RouteStep(3, None, None)]
    with pytest.raises(ValueError, match="not in the map"):
        plan_route(m, 0, 99)


def test_no_route_in_a_map_without_port_edges() -> None:
    m = TopoMap()
    m.visit(0)
    m.visit(1)
    assert plan_route(m, 0, 1) is None
    assert nearest_route(m, 0, [1]) is None


def test_a_pipe_of_unknown_length_counts_one_metre() -> None:
    """From r0c0 to r0c1 of a grid: the pipe between them, its length unknown, or the
    way round by three pipes whose lengths are known. The unknown one counts 1 m: it
    wins against 3 x 1 m, and loses against 3 x 0.2 m."""
    walk, topomap = _explored("grid:3x3")
    a, b, c, d = (walk.node_of[n] for n in ("r0c0", "r0c1", "r1c0", "r1c1"))
    around = {frozenset(p) for p in ((a, c), (c, d), (d, b))}

    def planned(around_m: float) -> list[int]:
        doc = topomap.to_dict()
        for edge in doc["edges"]:
            pair = frozenset((edge["u"], edge["v"]))
            if pair == {a, b}:
                edge["length_m"] = None
            elif pair in around:
                edge["length_m"] = around_m
        m = TopoMap.from_dict(doc)
        route = plan_route(m, a, b)
        assert route is not None
        return [step.node for step in route]

    assert planned(1.0) == [a, b]
    assert planned(0.2) == [a, c, d, b]


def test_the_nearest_goal_wins_ties_to_the_lowest_node() -> None:
    walk, m = _explored("paper")
    a, b, d = walk.node_of["A"], walk.node_of["B"], walk.node_of["D"]
    found = nearest_route(m, a, [b, d])
    assert found is not None and found[0] == b


def test_steps_read_as_instructions() -> None:
    assert describe_step(RouteStep(3, 0, 2, 7)) == "at node 3, arriving by port 0, leave by port 2"
    assert describe_step(RouteStep(0, None, 1, 1)) == "at node 0, leave by port 1"
    assert describe_step(RouteStep(5, 2, None)) == "arrive at node 5 by port 2"
    assert describe_step(RouteStep(5, None, None)) == "already at node 5"


def test_a_known_junction_may_drift_by_the_loop_allowance() -> None:
    # Dead reckoning 2 cm off per metre, every tolerance 0.1 m: a revisit lies farther
    # from the first visit than that, but within 3 % of the distance driven since.
    tight = ExploreConfig(odometry_radius_m=0.1, drift_per_m=0.0, odometry_limit_m=0.1)
    walks = {
        allowance: Walk(
            build_network("grid:3x3"),
            drift_per_m=0.02,
            config=replace(tight, loop_drift_per_m=allowance),
        )
        for allowance in (0.03, 0.0)
    }
    ends = {allowance: walk.run() for allowance, walk in walks.items()}
    assert ends == {0.03: ExploreEnd.FINISHED, 0.0: ExploreEnd.INCONSISTENT}
    assert "from where it was by odometry" in walks[0.0].explorer.inconsistencies[0]


#: The heading drift of ``random:200`` seed 4711's dead reckoning on pipes of 1-20 m.
MEASURED_RAD_PER_M = 3.8e-4


def _long_pipes(
    heading_drift_per_m: float,
    config: ExploreConfig,
    fit: bool = False,
    localizer: LocalizerConfig | None = None,
) -> Walk:
    """A walk of ``grid:3x3`` with 20 m pipes (loops of 80 m) whose dead reckoning's
    heading drifts by ``heading_drift_per_m`` (``fit``, ``localizer``: see
    :attr:`Walk.fit`)."""
    network = build_network("grid:3x3", spacing_m=20.0)
    walk = Walk(network, heading_drift_per_m=heading_drift_per_m, config=config, fit=fit)
    if localizer is not None:
        walk = replace(walk, localizer=localizer)
    return walk


def test_a_known_junction_may_drift_by_the_heading_allowance() -> None:
    walks = {
        heading: _long_pipes(MEASURED_RAD_PER_M, ExploreConfig(heading_drift_per_m=heading))
        for heading in (ExploreConfig().heading_drift_per_m, 0.0)
    }
    ends = {heading: walk.run() for heading, walk in walks.items()}
    assert ends == {0.0006: ExploreEnd.FINISHED, 0.0: ExploreEnd.INCONSISTENT}
    assert "from where it was by odometry" in walks[0.0].explorer.inconsistencies[0]
    assert set(_pipes(walks[0.0006].network)) <= set(walks[0.0006].traversals())


def test_the_heading_allowance_widens_with_the_robot_s_drift() -> None:
    # --odometry-drift 4: the robot's gyro is 4 times as poor, and so is its heading.
    poor = 4.0 * MEASURED_RAD_PER_M
    assert _long_pipes(poor, ExploreConfig()).run() is ExploreEnd.INCONSISTENT
    assert _long_pipes(poor, ExploreConfig().drifting(4.0)).run() is ExploreEnd.FINISHED
    wide = ExploreConfig().drifting(4.0)
    plain = ExploreConfig()
    assert (wide.drift_per_m, wide.odometry_limit_m, wide.loop_drift_per_m) == pytest.approx(
        (4 * plain.drift_per_m, 4 * plain.odometry_limit_m, 4 * plain.loop_drift_per_m)
    )
    assert wide.heading_drift_per_m == pytest.approx(4 * plain.heading_drift_per_m)
    assert wide.odometry_radius_m == plain.odometry_radius_m
    assert ExploreConfig().drifting(1.0) == plain


def test_with_the_heading_fitted_a_revisit_is_checked_as_the_localizer_checked_it() -> None:
    # 1e-3 rad/m, past the 6e-4 the explorer allows for: by raw dead reckoning the
    # robot finds its first junctions metres from where they were. A localizer that
    # allows for 1.5e-3 recognises them; once it has fitted the drift to the loops
    # closed, the explorer checks each revisit as the localizer did, and the same walk
    # is consistent throughout and covers every pipe.
    wide = LocalizerConfig(odometry_heading_drift_per_m=1.5e-3)
    raw = _long_pipes(1e-3, ExploreConfig())
    fitted = _long_pipes(1e-3, ExploreConfig(), fit=True, localizer=wide)
    assert raw.run() is ExploreEnd.INCONSISTENT
    assert "from where it was by odometry" in raw.explorer.inconsistencies[0]
    assert fitted.run() is ExploreEnd.FINISHED
    assert fitted.explorer.inconsistencies == []
    assert fitted.odometry is not None and fitted.odometry.fitted()
    assert _pipes(fitted.network) <= set(fitted.traversals())


def test_until_the_heading_is_fitted_the_explorer_checks_by_its_own_allowances() -> None:
    # A localizer that allows for 1.5e-3 rad/m and trusts its fit only late (what
    # the fit leaves uncertain is at least 1.4e-3): at the first revisits its fit is
    # not used, and the explorer's own allowance (6e-4) finds the robot's 1e-3 too
    # much, at two junctions; then the fit is trusted and the rest is consistent.
    late = LocalizerConfig(
        odometry_heading_drift_per_m=1.5e-3, odometry_heading_residual_per_m=1.4e-3
    )
    walk = _long_pipes(1e-3, ExploreConfig(), fit=True, localizer=late)
    assert walk.run() is ExploreEnd.FINISHED
    assert walk.odometry is not None and walk.odometry.fitted()
    assert len(walk.explorer.inconsistencies) == 2
    assert all("from where it was by odometry" in i for i in walk.explorer.inconsistencies)
    # Fitted, the localizer's check decides, whatever the explorer's own allowance.
    own = ExploreConfig(heading_drift_per_m=0.0)
    fitted = _long_pipes(MEASURED_RAD_PER_M, own, fit=True)
    assert fitted.run() is ExploreEnd.FINISHED
    assert fitted.explorer.inconsistencies == []


def _loop_then_comb(teeth: int = 5, gap_m: float = 4.0) -> Network:
    """A 25 m square loop the robot closes first (so the heading's drift can be
    fitted), then a comb: a row of junctions 10 m apart going west, each with a 6 m
    dead end north, and a row back east ``6 + gap_m`` m further north, each with a
    6 m dead end south. A tooth of the row back ends ``gap_m`` from one of the row
    out."""
    nodes = [Node("S", 0.0, -8.0), Node("A", 0.0, 0.0), Node("E", 25.0, 0.0)]
    nodes += [Node("F", 25.0, 25.0), Node("R", 0.0, 25.0)]
    pipes = [Pipe("S", "A"), Pipe("A", "E"), Pipe("E", "F"), Pipe("F", "R"), Pipe("R", "A")]
    back_y = 12.0 + gap_m
    nodes += [Node("u", -10.0 * (teeth + 1), 0.0), Node("v", -10.0 * (teeth + 1), back_y)]
    pipes += [Pipe(f"o{teeth}", "u"), Pipe("u", "v")]
    for i in range(1, teeth + 1):
        nodes += [Node(f"o{i}", -10.0 * i, 0.0), Node(f"ot{i}", -10.0 * i, 6.0)]
        pipes += [Pipe("A" if i == 1 else f"o{i - 1}", f"o{i}"), Pipe(f"o{i}", f"ot{i}")]
        nodes += [Node(f"b{i}", -10.0 * i, back_y), Node(f"bt{i}", -10.0 * i, 6.0 + gap_m)]
        pipes += [Pipe("v" if i == teeth else f"b{i + 1}", f"b{i}"), Pipe(f"b{i}", f"bt{i}")]
    return Network(tuple(nodes), tuple(pipes), entry="S")


def test_with_the_heading_fitted_a_new_junction_is_not_put_on_a_known_one() -> None:
    # Dead reckoning whose heading drifts by -7e-4 rad/m puts a dead end of the row
    # back (4 m from the row out's) on top of a dead end of the row out: a correct new
    # junction taken, by raw dead reckoning, for a known junction's place. With the
    # drift fitted to the loop closed first, it lies metres away.
    network = _loop_then_comb()
    raw = Walk(network, heading_drift_per_m=-7e-4)
    fitted = Walk(network, heading_drift_per_m=-7e-4, fit=True)
    raw.run()
    assert "from known junction" in raw.explorer.inconsistencies[0]
    assert fitted.run() is ExploreEnd.FINISHED
    assert fitted.explorer.inconsistencies == []
    assert _pipes(network) <= set(fitted.traversals())


@pytest.mark.parametrize("limit", [1, 2])
def test_the_run_stops_at_the_configured_number_of_inconsistencies(limit: int) -> None:
    walk = Walk(
        build_network("grid:4x4"), wrong="new", config=ExploreConfig(max_inconsistencies=limit)
    )
    assert walk.run() is ExploreEnd.INCONSISTENT
    assert len(walk.explorer.inconsistencies) == limit


def test_the_odometry_tolerance_is_the_configured_one() -> None:
    # Dead reckoning 5 cm off per metre: within the defaults' 0.3 m plus 5 mm per
    # metre on paper (13 m), not within a 0.1 m radius that does not grow.
    drifting = Walk(build_network("paper"), drift_per_m=0.05)
    assert drifting.run() is ExploreEnd.FINISHED
    tight = Walk(
        build_network("paper"),
        drift_per_m=0.05,
        config=ExploreConfig(odometry_radius_m=0.1, drift_per_m=0.0),
    )
    assert tight.run() is ExploreEnd.INCONSISTENT
    assert "from where it was by odometry" in tight.explorer.inconsistencies[0]
    # The same radius growing by as much per metre as the robot drifts: within it,
    # unless the growth is capped below the drift.
    grown = ExploreConfig(odometry_radius_m=0.1, drift_per_m=0.05, odometry_limit_m=10.0)
    assert Walk(build_network("paper"), drift_per_m=0.05, config=grown).run() is (
        ExploreEnd.FINISHED
    )
    capped = Walk(
        build_network("paper"), drift_per_m=0.05, config=replace(grown, odometry_limit_m=0.15)
    )
    assert capped.run() is ExploreEnd.INCONSISTENT
    assert "from where it was by odometry" in capped.explorer.inconsistencies[0]
    # A radius wider than the network: every new junction lies "at" a known one.
    wide = Walk(
        build_network("paper"),
        config=ExploreConfig(odometry_radius_m=10.0, odometry_limit_m=10.0),
    )
    assert wide.run() is ExploreEnd.INCONSISTENT
    assert "from known junction" in wide.explorer.inconsistencies[0]
    for bad in (
        {"odometry_radius_m": -0.1},
        {"drift_per_m": -1.0},
        {"odometry_limit_m": -1.0},
        {"loop_drift_per_m": -1.0},
        {"heading_drift_per_m": -1.0},
    ):
        with pytest.raises(ValueError):
            ExploreConfig(**bad)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "spec, blocked",
    [
        ("grid:3x3", {("r0c0", "r0c1"), ("r1c1", "r2c1")}),
        ("paper", {("A", "B")}),  # a dead end's only pipe: B is unreachable
        ("paper", {("C", "D"), ("C", "F")}),
    ],
)
def test_a_blocked_pipe_is_never_driven_and_the_rest_is_explored(
    spec: str, blocked: set[tuple[str, str]]
) -> None:
    network = build_network(spec)
    blocked_pipes = frozenset(tuple(sorted(p)) for p in blocked)
    walk = Walk(network, blocked_pipes=blocked_pipes)  # type: ignore[arg-type]
    assert walk.run() is ExploreEnd.FINISHED
    assert walk.path[-1] == walk.path[0]
    driven = set(walk.traversals())
    assert not driven & blocked_pipes
    # Every pipe reachable without a blocked one is driven.
    reach, todo = {walk.path[0]}, [walk.path[0]]
    while todo:
        here = todo.pop()
        for there in network.neighbours(here):
            if tuple(sorted((here, there))) not in blocked_pipes and there not in reach:
                reach.add(there)
                todo.append(there)
    assert set(walk.path) == reach
    assert driven == {p for p in _pipes(network) - blocked_pipes if p[0] in reach}
    # Each blocked pipe with a reachable end is marked at that end, and given up once.
    marked = {
        (walk.label_of_node(n), p)
        for n in range(walk.topomap.node_count)
        for p in walk.topomap.blocked(n)
    }
    assert len(marked) == len(walk.gave_up)
    assert {tuple(sorted(g)) for g in walk.gave_up} == {
        p for p in blocked_pipes if p[0] in reach or p[1] in reach
    }
    assert walk.explorer.inconsistencies == []


def test_a_route_goes_round_a_blocked_pipe_and_none_uses_one() -> None:
    walk, topomap = _explored("grid:3x3")
    direct = plan_route(topomap, 1, 2)
    assert direct is not None
    first = direct[0]
    # The route's first pipe blocked at its start, as a map document says it.
    doc = topomap.to_dict()
    doc["nodes"][first.node]["ports"][first.leave_port]["blocked"] = True
    topomap = TopoMap.from_dict(doc)
    around = plan_route(topomap, 1, 2)
    assert around is not None and around[-1].node == 2
    assert all(
        not topomap.is_blocked(s.node, s.leave_port)
        and not topomap.is_blocked(s.node, s.arrive_port)
        for s in around
    )
    assert route_length_m(topomap, around) > route_length_m(topomap, direct)
    assert first.leave_port not in topomap.untraversed(first.node)
