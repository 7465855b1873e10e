"""The streamed world (``World(stream=True)``, the default) builds each piece when an
image or a range ray first needs it, and draws and measures exactly what the world
built whole (``stream=False``) does."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.sim import CameraSpec, World, build_network
from pipemap.sim.lookalike import choose_looks

SMALL = CameraSpec(resolution_px=48)


def _views(network, labels):  # type: ignore[no-untyped-def]
    """Eyes at the given nodes and 0.3 m into each of their pipes, six headings each."""
    views = []
    for label in labels:
        node = network.node(label)
        for k, heading in enumerate(network.pipe_headings(label).values()):
            d = 0.3 * (k % 2)
            eye = (node.x_m + d * math.cos(heading) + 1e-4, node.y_m + d * math.sin(heading) + 1e-4)
            for j in range(6):
                views.append(((eye[0], eye[1], 0.06), heading + j * math.pi / 3))
    return views


def _rays(eye, yaw):  # type: ignore[no-untyped-def]
    origins = np.array([eye] * 3)
    dirs = np.array([[math.cos(yaw + a), math.sin(yaw + a), 0.0] for a in (0.0, 0.6, -0.6)])
    return origins, dirs


@pytest.fixture(scope="module")
def worlds():  # type: ignore[no-untyped-def]
    network = build_network("random:30", seed=4)
    looks = choose_looks(network, 0.3, seed=2)
    with (
        World(network, seed=5, texture_px=32, looks=looks, stream=False) as whole,
        World(network, seed=5, texture_px=32, looks=looks) as streamed,
    ):
        yield whole, streamed


def test_a_streamed_world_builds_nothing_until_asked() -> None:
    network = build_network("random:30", seed=4)
    with World(network, seed=5, texture_px=32) as world:
        assert world.pieces_built == (0, len(network.pipes) + len(network.nodes))
        assert world.triangle_count == 0
    with World(network, seed=5, texture_px=32, stream=False) as whole:
        assert whole.pieces_built == (len(network.pipes) + len(network.nodes),) * 2


def test_streamed_images_are_the_whole_worlds_to_the_bit(worlds) -> None:  # type: ignore[no-untyped-def]
    whole, streamed = worlds
    network = whole.network
    labels = [n.label for n in network.nodes[:6]]
    views = _views(network, labels)
    # The streamed world meets the pieces in another order than the whole one built them.
    for eye, yaw in reversed(views):
        pitch = 0.2 if int(yaw * 10) % 3 == 0 else 0.0
        a = streamed.render(eye, yaw, SMALL, pitch_rad=pitch)
        b = whole.render(eye, yaw, SMALL, pitch_rad=pitch)
        assert np.array_equal(a, b), (eye, yaw, pitch)
    built, pieces = streamed.pieces_built
    assert 0 < built < pieces  # what the cameras saw, not the whole network


def test_streamed_range_rays_hit_walls_not_built_for_any_image(worlds) -> None:  # type: ignore[no-untyped-def]
    whole, _ = worlds
    network = whole.network
    with World(network, seed=5, texture_px=32) as fresh:  # no image drawn: only rays
        hits = 0
        for eye, yaw in _views(network, [n.label for n in network.nodes[10:20]]):
            origins, dirs = _rays(eye, yaw)
            got = fresh.ray_distances_m(origins, dirs, 1.2)
            assert np.array_equal(got, whole.ray_distances_m(origins, dirs, 1.2)), (eye, yaw)
            hits += int((got < 1.2).sum())
        assert hits > 100
        built, pieces = fresh.pieces_built
        assert built < pieces


def test_a_streamed_world_drawing_everything_builds_everything(worlds) -> None:  # type: ignore[no-untyped-def]
    network = worlds[0].network
    with World(network, seed=5, texture_px=32, cull=False) as world:
        world.render((network.nodes[0].x_m + 1e-4, network.nodes[0].y_m + 1e-4, 0.06), 0.0, SMALL)
        assert world.pieces_built[0] == world.pieces_built[1]
