"""The pipe follower's sight of a node ahead (:func:`sim.follow.node_distance_m`):
a wall straight ahead within ``wall_ahead_m``, or a side range opening past
``opening_factor`` times its nominal length."""

from __future__ import annotations

import math

import pytest

from pipemap.sim.explorer_config import ExplorerConfig
from pipemap.sim.follow import node_distance_m
from pipemap.sim.scan_geometry import HALF_WIDTH_M, SIDE_NOMINAL_M

TOF_FORWARD_M = 0.06
SIDES = (SIDE_NOMINAL_M, SIDE_NOMINAL_M)


@pytest.mark.parametrize(
    ("front_m", "wall_ahead_m", "seen"),
    [
        (0.10, 0.12, True),
        (0.17, 0.12, True),
        (0.19, 0.12, False),
        (0.10, 0.05, True),
        (0.12, 0.05, False),
    ],
)
def test_a_wall_ahead_is_a_node_within_the_configured_reach(
    front_m: float, wall_ahead_m: float, seen: bool
) -> None:
    """The front range sees the node's far wall (a dead end, a T from its stem) when
    it reads under ``wall_ahead_m`` from the rangers: the node's centre is then a
    half-width short of that wall."""
    config = ExplorerConfig(wall_ahead_m=wall_ahead_m)
    got = node_distance_m((front_m, *SIDES), TOF_FORWARD_M, config)
    if seen:
        assert got == pytest.approx(front_m + TOF_FORWARD_M - HALF_WIDTH_M)
    else:
        assert got is None


@pytest.mark.parametrize(("factor", "seen"), [(1.5, False), (1.8, True)])
def test_a_side_opening_is_a_node_past_the_configured_factor(factor: float, seen: bool) -> None:
    """A side range longer than ``opening_factor`` (1.7) times its nominal length is
    a pipe opening off: the node's centre is where that side ray meets the wall line,
    a half-width further."""
    ranges = (1.0, factor * SIDE_NOMINAL_M, SIDE_NOMINAL_M)
    got = node_distance_m(ranges, TOF_FORWARD_M, ExplorerConfig())
    ahead = TOF_FORWARD_M + HALF_WIDTH_M / math.tan(math.radians(40.0)) + HALF_WIDTH_M
    assert got == (pytest.approx(ahead) if seen else None)
