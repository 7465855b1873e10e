"""Portal culling: which bodies a camera may see, and that hiding the rest changes no pixel."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.sim import CameraSpec, World, build_network
from pipemap.sim.network import Network, Node, Pipe
from pipemap.sim.visibility import (
    PortalGraph,
    _intersect,
    _junction_radius_m,
    frustum_arc,
    visible_parts,
)

SMALL = CameraSpec(resolution_px=64)
ALL_AROUND = (0.0, math.pi)


def _row(n: int) -> Network:
    """``n`` nodes on a line with a side branch at each inner node (no straight-through nodes)."""
    nodes = [Node("S", -1.0, 0.0)] + [Node(f"a{i}", float(i), 0.0) for i in range(n)]
    nodes += [Node(f"b{i}", float(i), 1.0) for i in range(n - 1)]
    pipes = [Pipe("S", "a0")] + [Pipe(f"a{i}", f"a{i + 1}") for i in range(n - 1)]
    pipes += [Pipe(f"a{i}", f"b{i}") for i in range(n - 1)]
    return Network(tuple(nodes), tuple(pipes), entry="S")


def test_a_straight_row_is_seen_to_its_end_and_the_side_pipes_are_not() -> None:
    graph = PortalGraph(_row(6))
    parts = visible_parts(graph, (0.5, 0.0), ALL_AROUND)
    assert parts is not None
    nodes, pipes = parts
    assert pipes == {("a0", "a1")}
    # Along the row in both directions, the entry included; never into the side pipes'
    # far junctions, which turn 90 degrees away.
    assert nodes == {"S", "a0", "a1", "a2", "a3", "a4", "a5"}


def test_the_view_arc_limits_the_reach() -> None:
    graph = PortalGraph(_row(6))
    parts = visible_parts(graph, (2.5, 0.0), (0.0, math.radians(40.0)))  # looking +x
    assert parts is not None
    # Not a2 behind the eye (its pipe a2-a3 is drawn whole all the same), nor the side
    # pipes' far ends.
    assert parts == ({"a3", "a4", "a5"}, {("a2", "a3")})


def test_from_a_junction_the_side_pipe_is_seen_into_but_not_beyond_a_bend() -> None:
    nodes = (Node("S", 0.0, -1.0), Node("A", 0.0, 0.0), Node("B", 1.0, 0.0), Node("C", 1.0, 1.0))
    net = Network(nodes, (Pipe("S", "A"), Pipe("A", "B"), Pipe("B", "C")), entry="S")
    parts = visible_parts(PortalGraph(net), (0.0, -0.5), ALL_AROUND)  # in pipe S-A
    assert parts is not None
    assert parts[0] == {"S", "A"}  # B is around A's corner


def test_an_eye_outside_every_pipe_rules_nothing_out() -> None:
    assert visible_parts(PortalGraph(_row(3)), (0.5, 0.7), ALL_AROUND) is None


def test_the_frustum_arc_is_the_field_of_view_level_and_widens_with_pitch() -> None:
    fov = math.radians(80.0)
    assert frustum_arc(1.0, 0.0, fov) == pytest.approx((1.0, fov / 2.0), abs=1e-5)
    assert frustum_arc(1.0, 0.3, fov)[1] > fov / 2.0
    assert frustum_arc(1.0, 1.2, fov)[1] == math.pi  # steep: every direction


def _in_arc(angle: float, arc: tuple[float, float]) -> bool:
    return arc[1] >= math.pi or abs(math.remainder(angle - arc[0], 2 * math.pi)) <= arc[1]


def test_an_intersection_keeps_every_direction_both_arcs_hold() -> None:
    rng = np.random.default_rng(0)
    for _ in range(2000):
        a = (rng.uniform(-7, 7), rng.uniform(0, 3.3))
        b = (rng.uniform(-7, 7), rng.uniform(0, 1.6))
        both = _intersect(a, b)
        for angle in rng.uniform(-math.pi, math.pi, 20):
            if _in_arc(angle, a) and _in_arc(angle, b):
                assert both is not None and _in_arc(angle, both), (a, b, angle)


def test_past_the_junction_radius_no_two_pipes_of_a_node_overlap() -> None:
    # Points of one pipe's plan strip past the radius lie in no other pipe's strip, for
    # random junctions down to the network's smallest angle between pipes.
    rng = np.random.default_rng(1)
    r = 0.1
    for _ in range(300):
        headings = list(rng.uniform(0, 2 * math.pi, rng.integers(2, 5)))
        gaps = np.diff(sorted(headings + [min(headings) + 2 * math.pi]))
        if gaps.min() < math.radians(30):
            continue
        reach = _junction_radius_m(headings, r)
        for i, hu in enumerate(headings):
            u = np.array([math.cos(hu), math.sin(hu)])
            n = np.array([-u[1], u[0]])
            s = rng.uniform(reach, reach + 0.5, 200)
            points = s[:, None] * u + rng.uniform(-r, r, 200)[:, None] * n
            for j, hv in enumerate(headings):
                if j == i:
                    continue
                v = np.array([math.cos(hv), math.sin(hv)])
                along, across = points @ v, np.abs(points @ np.array([-v[1], v[0]]))
                inside = (along >= 0) & (across <= r)
                assert not inside.any(), (headings, reach)


@pytest.fixture(scope="module")
def grid_world():  # type: ignore[no-untyped-def]
    with World(build_network("grid:3x3"), seed=1, texture_px=128) as world:
        yield world


def _views(network: Network) -> list[tuple[tuple[float, float, float], float, float]]:
    """Eyes at every node and along its pipes, looking every way, some tilted."""
    views = []
    for i, node in enumerate(network.nodes):
        for k, heading in enumerate(network.pipe_headings(node.label).values()):
            d = (0.0, 0.25, 0.45)[k % 3]
            eye = (
                node.x_m + d * math.cos(heading) + 1e-4,
                node.y_m + d * math.sin(heading) + 1e-4,
                0.06 + 0.01 * (i % 3),
            )
            for j in range(6):
                views.append((eye, heading + j * math.pi / 3, (0.0, 0.0, 0.25)[j % 3]))
    return views


def test_culling_hides_bodies_and_changes_no_pixel(grid_world) -> None:  # type: ignore[no-untyped-def]
    drawn = []
    for eye, yaw, pitch in _views(grid_world.network):
        grid_world.cull = True
        culled = grid_world.render(eye, yaw, SMALL, pitch_rad=pitch)
        drawn.append(grid_world.drawn_bodies)
        grid_world.cull = False
        whole = grid_world.render(eye, yaw, SMALL, pitch_rad=pitch)
        total = grid_world.drawn_bodies
        assert np.array_equal(culled, whole), (eye, yaw, pitch)
    grid_world.cull = True
    assert len(drawn) > 100
    assert max(drawn) < total  # every view hid something
    assert np.median(drawn) <= total / 3


def test_hidden_bodies_still_stop_range_rays(grid_world) -> None:  # type: ignore[no-untyped-def]
    grid_world.cull = True
    origin = np.array([[0.0, 0.0, 0.1]])
    east = np.array([[1.0, 0.0, 0.0]])
    before = grid_world.ray_distances_m(origin, east, 5.0)
    node = grid_world.network.node("r2c2")
    grid_world.render((node.x_m + 1e-4, node.y_m + 1e-4, 0.06), 0.0, SMALL)
    row0 = [
        b
        for pipe, bodies in grid_world._pipe_bodies.items()
        for b in bodies
        if "r1" not in "".join(pipe) and "r2" not in "".join(pipe)
    ]
    assert row0 and set(row0) <= grid_world._hidden  # row 0 is hidden, yet the rays hit it
    assert np.array_equal(grid_world.ray_distances_m(origin, east, 5.0), before)
    assert before[0] == pytest.approx(2.1, abs=2e-3)  # along row 0 to r0c2's wall
