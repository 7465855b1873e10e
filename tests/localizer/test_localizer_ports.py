"""Tests of :class:`localizer.Localizer` with the visit's exits: ports for new
junctions, revisits whose exits agree or not, and the map's traversals."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer.localizer import (
    PAPER,
    Localizer,
    LocalizerConfig,
)
from pipemap.localizer.twoview import TwoViewFit
from tests.localizer.junctions import (
    CORNER_EXITS,
    PI,
    STEP_RAD,
    TEE_EXITS,
    junction,
)


def test_exits_give_a_new_junction_its_ports() -> None:
    loc = Localizer()
    d = loc.localize(junction(0), exits_rad=(0.0 - 0.01, -PI / 2, PI))
    assert d.exits_rad == (-0.01, -PI / 2, PI)
    assert d.exit_ports == (1, 2, 0)  # ahead, right, behind: behind is port 0, then clockwise
    assert d.arrival_port is None  # the run's first visit came by no pipe
    assert loc.map.ports(0) == pytest.approx((PI, -0.01, -PI / 2))
    assert loc.depart(-PI / 2 + 0.05) == 2
    assert loc.map.visit_records[0].departure_port == 2


@pytest.mark.parametrize(
    ("off_rad", "port"), [(0.5, 2), (-0.5, 2), (0.55, None), (0.8, None), (1.2, 1)]
)
def test_a_departure_is_a_port_only_within_30_degrees_of_its_exit(
    off_rad: float, port: int | None
) -> None:
    """The robot leaves by the exit nearest its departure heading, if within 30
    degrees of it; further off from every exit, which pipe it took is not known."""
    loc = Localizer()
    loc.localize(junction(0), exits_rad=(0.0, -PI / 2, PI))
    assert loc.depart(-PI / 2 + off_rad) == port
    assert loc.map.visit_records[0].departure_port == port


def test_a_revisit_whose_exits_agree_is_known_and_its_exits_get_ports() -> None:
    loc = Localizer()
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    loc.depart(PI / 2)
    loc.localize(junction(1), exits_rad=CORNER_EXITS)
    loc.depart(PI / 2)
    # The same sweep (rotation 0), its exits measured a little off and in another order.
    d = loc.localize(junction(0), exits_rad=(-PI / 2 + 0.05, PI - 0.04, PI / 2))
    assert d.known and d.node == 0
    assert d.exit_ports == (2, 0, 1)
    assert d.arrival_port == 0
    assert d.port_residual_rad == pytest.approx(0.05, abs=1e-6)
    assert d.rejected == ()
    edges = loc.map.edges()
    assert [(e.u, e.u_port, e.v, e.v_port) for e in edges] == [(0, 1, 1, 0), (1, 1, 0, 0)]


@pytest.mark.parametrize("config", [LocalizerConfig(), PAPER, replace(PAPER, port_check=True)])
def test_a_match_whose_exits_disagree_is_passed_over(config: LocalizerConfig) -> None:
    loc = Localizer(config)
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    loc.localize(junction(1), exits_rad=CORNER_EXITS)
    d = loc.localize(junction(0), exits_rad=CORNER_EXITS)  # the images say T, the scan a corner
    if not config.port_check:
        assert d.known and d.node == 0 and d.exit_ports is None
        return
    assert not d.known and d.node == 2
    assert d.exit_ports == (0, 1)
    if config.verify:
        # The two-view check does not even fit a junction whose pipes cannot line up.
        assert d.rejected == ()
    else:
        # The threshold rule takes the most similar junction, and the ports say no.
        assert d.rejected == ((0, "2 exits where the junction has 3 ports"),)


def test_the_next_candidate_whose_exits_agree_is_taken() -> None:
    loc = Localizer(replace(PAPER, port_check=True))
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    # A look-alike corner (the same images, a little noise): a new junction by its exits.
    first = loc.localize(junction(0, noise=0.1), exits_rad=CORNER_EXITS)
    assert not first.known and first.rejected[0][0] == 0
    d = loc.localize(junction(0), exits_rad=CORNER_EXITS)
    assert d.known and d.node == 1
    assert [c for c, _ in d.rejected] == [0]
    assert d.similarity < 1.0 - 1e-6 < loc.compare(junction(0))[0].similarity


def test_turned_exits_agree_through_the_measured_rotation() -> None:
    loc = Localizer()
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    loc.localize(junction(1), exits_rad=CORNER_EXITS)
    # The sweep started one image later: the robot heads one step (60 degrees) further
    # left (the rotation to the first visit's heading is -60 degrees), so every pipe
    # is 60 degrees further right of it.
    turned = tuple(math.remainder(e - STEP_RAD, 2 * PI) for e in TEE_EXITS)
    d = loc.localize(junction(0, roll=1), exits_rad=turned)
    assert d.known and d.exit_ports == (0, 1, 2)


def test_port_tolerance_is_validated() -> None:
    with pytest.raises(LocalizerError, match="port tolerance"):
        LocalizerConfig(port_tolerance_rad=0.0)


def test_without_exits_nothing_changes() -> None:
    loc = Localizer()
    d = loc.localize(junction(0))
    assert d.exits_rad is None and d.exit_ports is None and d.arrival_port is None
    assert loc.depart(0.0) is None
    assert loc.map.ports(0) is None


def test_a_new_traversal_may_start_at_the_last_junction() -> None:
    loc = Localizer()
    loc.localize(junction(0))
    loc.localize(junction(1))
    loc.new_traversal()
    d = loc.localize(junction(1))  # left out right after junction 1, allowed now
    assert d.known and d.node == 1
    assert len(loc.map.edges()) == 1


def test_a_junction_whose_ports_line_up_at_no_turn_is_not_fitted() -> None:
    loc = Localizer()
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    loc.localize(junction(1), exits_rad=CORNER_EXITS)
    fitted: list[int] = []
    real = loc._fit

    def fit(node: int, *args: Any) -> TwoViewFit | None:
        fitted.append(node)
        return real(node, *args)

    loc._fit = fit  # type: ignore[method-assign]
    # The images say T, the scan three pipes 120 degrees apart: as many exits as
    # ports, but no turn lines them up, so the T takes no candidate's place.
    d = loc.localize(junction(0), exits_rad=(PI, PI / 3, -PI / 3))
    assert not d.known and d.node == 2
    assert 0 not in fitted and d.rejected == ()
