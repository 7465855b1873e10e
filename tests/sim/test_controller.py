"""The autonomous explorer: sensors only, the right-most-branch rule, the watchdog."""

from __future__ import annotations

import pytest

from sim import CameraSpec, World, build_network, right_hand_tour
from sim.controller import ExplorerConfig, RunStatus, autonomous_run

TINY = CameraSpec(resolution_px=32)


@pytest.fixture(scope="module")
def paper_world():  # type: ignore[no-untyped-def]
    with World(build_network("paper"), seed=0, texture_px=32) as world:
        yield world


@pytest.mark.parametrize("start", list("SABCDEF"))
def test_paper_is_explored_from_every_start(paper_world, start: str) -> None:  # type: ignore[no-untyped-def]
    result = autonomous_run(paper_world, TINY, seed=1, start=start)
    assert result.status is RunStatus.FINISHED
    # Every sweep is taken within 15 cm of a node centre, in the right-hand tour's order:
    # every node and every pipe is visited, and the robot ends where it started.
    planned = [v.node for v in right_hand_tour(paper_world.network, start).visits]
    assert [s.true_node for s in result.sweeps] == planned
    assert result.distance_m == pytest.approx(13.9, abs=0.4)


def test_same_seed_same_sensor_streams(paper_world) -> None:  # type: ignore[no-untyped-def]
    config = ExplorerConfig(time_limit_ns=40 * 10**9)
    one = autonomous_run(paper_world, TINY, seed=5, config=config)
    two = autonomous_run(paper_world, TINY, seed=5, config=config)
    assert one.readings == two.readings
    assert len(one.readings) > 1000


def test_watchdog_ends_the_run_and_keeps_what_was_produced(paper_world) -> None:  # type: ignore[no-untyped-def]
    result = autonomous_run(
        paper_world, TINY, seed=1, config=ExplorerConfig(time_limit_ns=60 * 10**9)
    )
    assert result.status is RunStatus.TIME_LIMIT
    assert [s.true_node for s in result.sweeps][:2] == ["S", "A"]
    assert result.events[-1][1] == "watchdog: time limit"
