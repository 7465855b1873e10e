"""Floor deposits: seeded placement and the footprint test (no PyBullet)."""

from __future__ import annotations

import math

import pytest

from pipemap.errors import SimError
from pipemap.sim.network import build_network
from pipemap.sim.obstacles import (
    MIN_PIPE_M,
    PASSABLE_EDGE_M,
    Obstacle,
    ObstacleKind,
    footprint_hits,
    place_obstacles,
)

ROBOT = (0.12, 0.07)  # length, width


def test_placement_is_seeded_and_deterministic() -> None:
    net = build_network("grid:3x3")
    first = place_obstacles(net, 5, seed=7)
    assert first == place_obstacles(net, 5, seed=7)
    assert first != place_obstacles(net, 5, seed=8)
    assert len({o.pipe for o in first}) == 5  # one per pipe


def test_no_obstacles_draw_nothing() -> None:
    assert place_obstacles(build_network("paper"), 0, seed=1) == ()


def test_deposits_lie_in_the_middle_of_long_pipes_only() -> None:
    net = build_network("random:12", seed=3)
    for seed in range(5):
        for o in place_obstacles(net, 3, seed=seed):
            length = net.length_m(o.a, o.b)
            assert length >= MIN_PIPE_M
            assert 0.42 * length <= o.along_m <= 0.58 * length
            assert o.along_m - o.length_m / 2 > 0.3 and length - o.along_m - o.length_m / 2 > 0.3


def test_both_kinds_are_drawn_and_passable_ones_leave_one_side_free() -> None:
    net = build_network("grid:4x4")
    found = place_obstacles(net, 20, seed=0)
    kinds = {o.kind for o in found}
    assert kinds == {ObstacleKind.PASSABLE, ObstacleKind.BLOCKING}
    for o in found:
        if o.kind is ObstacleKind.BLOCKING:
            assert (o.right_m, o.left_m) == (-0.1, 0.1)
        else:
            assert min(abs(o.right_m), abs(o.left_m)) == PASSABLE_EDGE_M


@pytest.mark.parametrize("count", [-1, 100])
def test_a_bad_count_is_refused(count: int) -> None:
    net = build_network("grid:3x3")
    with pytest.raises(SimError, match="obstacle"):
        place_obstacles(net, count, seed=0)


def _deposit(kind: ObstacleKind, right: float, left: float) -> Obstacle:
    """A deposit 1 m along a pipe from (0, 0) heading east (+x): left is +y."""
    middle = (left + right) / 2
    return Obstacle("A", "B", kind, 1.0, right, left, (1.0, middle), 0.0)


def test_a_centred_robot_hits_either_kind_and_one_off_axis_passes_a_passable_one() -> None:
    passable = (_deposit(ObstacleKind.PASSABLE, PASSABLE_EDGE_M, 0.1),)
    blocking = (_deposit(ObstacleKind.BLOCKING, -0.1, 0.1),)
    ahead = 1.0 - 0.04 - 0.06 + 0.005  # the robot's nose 5 mm into the deposit
    assert footprint_hits(ahead, 0.0, 0.0, *ROBOT, passable)
    assert footprint_hits(ahead, 0.0, 0.0, *ROBOT, blocking)
    # 3 cm right of the axis (the recovery's side-step): past the passable one.
    for x in (ahead, 1.0, 1.05):
        assert not footprint_hits(x, -0.03, 0.0, *ROBOT, passable)
        assert footprint_hits(x, -0.03, 0.0, *ROBOT, blocking)
    # Short of it: nothing.
    assert not footprint_hits(ahead - 0.01, 0.0, 0.0, *ROBOT, blocking)


def test_a_turned_robot_hits_with_its_corner() -> None:
    blocking = (_deposit(ObstacleKind.BLOCKING, -0.1, 0.1),)
    # Facing 45 degrees, the corner reaches 0.0672 m ahead of the centre.
    reach = math.hypot(0.06, 0.035) * math.cos(math.atan2(0.035, 0.06) - math.pi / 4)
    assert footprint_hits(0.96 - reach + 0.002, 0.0, math.pi / 4, *ROBOT, blocking)
    assert not footprint_hits(0.96 - reach - 0.002, 0.0, math.pi / 4, *ROBOT, blocking)
