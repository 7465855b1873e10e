"""The world says how far its build has come (``World(on_build=...)``)."""

from __future__ import annotations

from pipemap.sim.network import build_network
from pipemap.sim.world import World


def test_world_reports_every_piece_built_then_the_total() -> None:
    network = build_network("paper")
    calls: list[tuple[int, int]] = []
    with World(
        network, seed=0, texture_px=32, stream=False, on_build=lambda b, t: calls.append((b, t))
    ):
        pass
    pieces = len(network.pipes) + len(network.nodes)
    assert calls == [(k, pieces) for k in range(pieces + 1)]


def test_a_streamed_world_builds_nothing_up_front_so_reports_nothing() -> None:
    calls: list[tuple[int, int]] = []
    with World(
        build_network("paper"), seed=0, texture_px=32, on_build=lambda b, t: calls.append((b, t))
    ):
        pass
    assert calls == []
