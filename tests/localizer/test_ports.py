"""Ports: numbering a junction's pipes, and mapping a revisit's exits onto them."""

from __future__ import annotations

import math

import pytest

from pipemap.localizer.ports import (
    PORT_TOLERANCE_RAD,
    clockwise_ports,
    match_ports,
    nearest_exit,
    port_rotations,
)

PI = math.pi


def test_port_zero_is_behind_then_clockwise_left_ahead_right() -> None:
    # A cross, exits in scan order: ahead, right, behind, left.
    angles, port_of = clockwise_ports([0.0, -PI / 2, PI, PI / 2])
    assert port_of == (2, 3, 0, 1)
    assert angles == pytest.approx((PI, PI / 2, 0.0, -PI / 2))


@pytest.mark.parametrize("behind", [PI - 0.2, PI, -PI + 0.2])
def test_the_pipe_behind_is_port_zero_whichever_side_of_pi_it_was_measured(behind: float) -> None:
    _, port_of = clockwise_ports([0.1, behind, -1.5])
    assert port_of[1] == 0
    assert port_of == (1, 0, 2)


def test_a_dead_end_has_one_port() -> None:
    assert clockwise_ports([3.1]) == ((3.1,), (0,))
    assert clockwise_ports([]) == ((), ())


def test_exits_turned_by_the_rotation_map_onto_the_ports() -> None:
    # First visit of a T: came in from its stem (behind), pipes left and right.
    ports, _ = clockwise_ports([PI, PI / 2, -PI / 2])
    # Revisit from the left pipe: the robot now heads 90 degrees to the right of its
    # first heading, so rotation (first heading - this heading) is +90 degrees.
    exits = [PI, -PI / 2 + 0.03, 0.0 - 0.02]  # behind (the left pipe), right, ahead
    match = match_ports(ports, exits, rotation_rad=PI / 2)
    assert match.agrees
    # Behind now is the first visit's left (port 1); the right is the stem (port 0);
    # ahead is the first visit's right (port 2).
    assert match.exit_ports == (1, 0, 2)
    assert match.residual_rad == pytest.approx(0.03)


def test_a_different_number_of_exits_disagrees() -> None:
    match = match_ports((PI, 0.0), (PI, 1.0, -1.0), 0.0)
    assert not match.agrees
    assert match.reason == "3 exits where the junction has 2 ports"
    assert match.residual_rad is None


def test_exits_that_do_not_line_up_disagree() -> None:
    # A corner turning by 90 degrees against one turning by 135.
    ports, _ = clockwise_ports([PI, PI / 2])
    match = match_ports(ports, [PI, PI / 4 - 0.1], 0.0)
    assert not match.agrees
    assert match.residual_rad == pytest.approx(PI / 4 + 0.1)
    assert "off the junction's ports" in match.reason


def test_the_tolerance_is_inclusive_and_configurable() -> None:
    ports, _ = clockwise_ports([PI, 0.0])
    assert match_ports(ports, [PI, PORT_TOLERANCE_RAD], 0.0).agrees
    assert not match_ports(ports, [PI, PORT_TOLERANCE_RAD + 0.01], 0.0).agrees
    assert match_ports(ports, [PI, 0.45], 0.0, tolerance_rad=0.5).agrees
    assert 0.3 < PORT_TOLERANCE_RAD < math.radians(30.0)


def test_no_ports_and_no_exits_agree() -> None:
    assert match_ports((), (), 1.0).exit_ports == ()


@pytest.mark.parametrize("rotation", [-3.0, -1.0, 0.0, 0.5, 2.9])
def test_any_rotation_of_a_y_is_recovered(rotation: float) -> None:
    first = [PI, 2.0, -2.2]
    ports, port_of = clockwise_ports(first)
    turned = [math.remainder(a + rotation, 2 * PI) for a in first]
    match = match_ports(ports, turned, rotation)
    assert match.exit_ports == port_of


def test_nearest_exit_within_the_tolerance() -> None:
    exits = (PI - 0.01, 1.5, -1.6)
    assert nearest_exit(exits, -PI) == 0
    assert nearest_exit(exits, 1.6) == 1
    assert nearest_exit(exits, 0.0) is None
    assert nearest_exit((), 0.0) is None


@pytest.mark.parametrize(
    ("exits", "turns"),
    [
        ((PI, PI / 2, 0.0, -PI / 2), 4),  # a cross looks the same four ways
        ((PI, 0.0), 2),  # a straight pipe two ways
        ((PI, PI / 2, -PI / 2), 1),  # a T one way
        ((PI,), 1),  # a dead end one way
    ],
)
def test_the_rotations_the_ports_allow(exits: tuple[float, ...], turns: int) -> None:
    """Each rotation the exits allow lines them up with the ports (as the port check
    asks); half a tolerance beside it they still do, and past the tolerance not."""
    ports, _ = clockwise_ports(exits)
    scanned = tuple(math.remainder(e + 0.7 + 0.05 * k, 2 * PI) for k, e in enumerate(exits))
    allowed = port_rotations(ports, scanned)
    assert len(allowed) == turns
    for rotation in allowed:
        assert match_ports(ports, scanned, rotation).agrees
        assert match_ports(ports, scanned, rotation + PORT_TOLERANCE_RAD / 2).agrees
        assert not match_ports(ports, scanned, rotation + 2.5 * PORT_TOLERANCE_RAD).agrees
    # Every rotation that agrees is near one of them.
    for step in range(360):
        rotation = math.radians(step)
        if match_ports(ports, scanned, rotation).agrees:
            assert min(abs(math.remainder(rotation - r, 2 * PI)) for r in allowed) <= 0.5


def test_no_rotation_lines_up_other_counts_or_shapes() -> None:
    tee, _ = clockwise_ports((PI, PI / 2, -PI / 2))
    assert port_rotations(tee, (PI, 0.0)) == ()  # a corner's two exits
    assert port_rotations(tee, (PI, 2.4, -2.4)) == ()  # a Y, not a T
    assert port_rotations((), ()) == ()
