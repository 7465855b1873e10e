"""The PyBullet world and the placement episodes, end to end (small renders)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pipemap.errors import SimError
from pipemap.sim import CameraSpec, Condition, Episode, SimConfig, World, build_network

SMALL = CameraSpec(resolution_px=96)
EVEN = CameraSpec(resolution_px=96, lamp_strength=0.0)


@pytest.fixture(scope="module")
def paper_world():  # type: ignore[no-untyped-def]
    with World(build_network("paper"), seed=3, texture_px=128) as world:
        yield world


def test_renders_are_deterministic_and_depend_on_the_seed(paper_world) -> None:  # type: ignore[no-untyped-def]
    eye = (0.0001, 1.5001, 0.05)
    one = paper_world.render(eye, 1.0, SMALL)
    two = paper_world.render(eye, 1.0, SMALL)
    assert one.shape == (96, 96, 3) and one.dtype == np.uint8
    assert np.array_equal(one, two)
    with World(build_network("paper"), seed=4, texture_px=128) as other:
        assert not np.array_equal(one, other.render(eye, 1.0, SMALL))


def test_a_built_world_keeps_no_files_and_still_draws_its_textures(paper_world) -> None:  # type: ignore[no-untyped-def]
    # A batch's worker killed mid-run would otherwise leave its texture files in /tmp:
    # each piece's file goes as soon as PyBullet has read it.
    image = paper_world.render((0.0001, 1.5001, 0.05), 1.0, EVEN)
    assert float(image.std()) > 5.0  # textured walls, not a flat colour
    assert paper_world.pieces_built[0] > 0
    folder = Path(paper_world._tmp.name)
    assert not folder.exists() or list(folder.iterdir()) == []


def test_every_view_from_a_junction_sees_walls(paper_world) -> None:  # type: ignore[no-untyped-def]
    # The network is closed everywhere (capped entry and dead ends): no black holes.
    for node in "SABCDEF":
        n = paper_world.network.node(node)
        for j in range(6):
            image = paper_world.render((n.x_m + 1e-4, n.y_m + 1e-4, 0.05), j * math.pi / 3, EVEN)
            assert np.mean(image.max(axis=2) == 0) < 0.01, (node, j)


def test_the_lamp_is_on_by_default_and_the_far_pipe_stays_dark(paper_world) -> None:  # type: ignore[no-untyped-def]
    assert CameraSpec().lamp_strength == 1.0
    eye = (0.0001, 1.5001, 0.05)  # in the main pipe, looking along it (east, to B)
    lamp = paper_world.render(eye, 0.0, SMALL).astype(float).mean(axis=2)
    even = paper_world.render(eye, 0.0, EVEN).astype(float).mean(axis=2)
    centre = (slice(40, 56), slice(40, 56))  # down the pipe, a metre away
    assert lamp[centre].mean() < 0.2 * even[centre].mean()
    # The wall beside the camera is lit about as brightly as even light shows it.
    assert lamp[:, :8].mean() > 0.5 * even[:, :8].mean()


def test_range_rays_hit_the_walls_where_geometry_says(paper_world) -> None:  # type: ignore[no-untyped-def]
    r = 0.1
    origin = np.array([[0.0, 1.5, r]] * 4)
    dirs = np.array([[1.0, 0, 0], [0, 1.0, 0], [-1.0, 0, 0], [0, 0, 1.0]])
    d = paper_world.ray_distances_m(origin, dirs, 5.0)
    assert d[0] == pytest.approx(1.0 + r, abs=2e-3)  # east: B's cap
    assert d[1] == pytest.approx(4.0 + r - 1.5, abs=2e-3)  # north: through C to F's cap
    assert d[2] == pytest.approx(r, abs=2e-3)  # west: the main pipe's wall
    assert d[3] == pytest.approx(r, abs=2e-3)  # up: the crown


def test_camera_settings_are_checked() -> None:
    with pytest.raises(SimError):
        CameraSpec(resolution_px=8)
    with pytest.raises(SimError):
        CameraSpec(lamp_strength=1.5)


def test_perfect_tour_visits_in_right_hand_order_at_the_centres(paper_world) -> None:  # type: ignore[no-untyped-def]
    episode = Episode(paper_world, SimConfig(Condition.PERFECT, camera=SMALL))
    visits = list(episode.visits())
    assert [v.node for v in visits] == list("SABACDCFCECAS")
    for v in visits:
        n = paper_world.network.node(v.node)
        assert (v.pose.x_m, v.pose.y_m) == (n.x_m, n.y_m)
        assert v.sweep.images.shape == (6, 96, 96, 3)
    # Arriving at A from S the robot heads north; from B, west.
    assert visits[1].pose.yaw_rad == pytest.approx(math.pi / 2)
    assert visits[3].pose.yaw_rad == pytest.approx(math.pi)


def test_noise_places_about_3_cm_off_centre(paper_world) -> None:  # type: ignore[no-untyped-def]
    episode = Episode(paper_world, SimConfig(Condition.NOISE, seed=5, camera=SMALL))
    for v in episode.visits():
        n = paper_world.network.node(v.node)
        assert 0.024 <= math.hypot(v.pose.x_m - n.x_m, v.pose.y_m - n.y_m) <= 0.036


def test_entrance_drives_the_radius_with_odometry_error(paper_world) -> None:  # type: ignore[no-untyped-def]
    episode = Episode(paper_world, SimConfig(Condition.ENTRANCE, seed=6, camera=SMALL))
    offsets = []
    for v in episode.visits():
        n = paper_world.network.node(v.node)
        offsets.append(math.hypot(v.pose.x_m - n.x_m, v.pose.y_m - n.y_m))
    assert 0.0 < max(offsets) < 0.05


def test_the_entrance_slip_is_the_along_pipe_error(paper_world) -> None:  # type: ignore[no-untyped-def]
    """Driving the radius in from the pipe's mouth, the robot ends short or long by
    the wheel slip (``entrance_slip``, 5% of the radius) and aside by the heading's
    drift (0.03 rad): across the tour, the along-pipe errors spread as the slip."""
    config = SimConfig(Condition.ENTRANCE, seed=6, camera=SMALL)
    radius = paper_world.network.diameter_m / 2.0
    along, aside = [], []
    for v in Episode(paper_world, config).visits():
        n = paper_world.network.node(v.node)
        dx, dy = v.pose.x_m - n.x_m, v.pose.y_m - n.y_m
        heading = v.pose.yaw_rad
        along.append(dx * math.cos(heading) + dy * math.sin(heading))
        aside.append(-dx * math.sin(heading) + dy * math.cos(heading))
    spread = float(np.std(along)) / radius
    assert 0.5 * config.entrance_slip < spread < 1.6 * config.entrance_slip
    assert float(np.std(aside)) / radius < 0.06


def test_probes_only_in_the_active_condition(paper_world) -> None:  # type: ignore[no-untyped-def]
    perfect = next(iter(Episode(paper_world, SimConfig(Condition.PERFECT, camera=SMALL)).visits()))
    with pytest.raises(SimError):
        perfect.probe(0.1, 0.0, 0.0)
    active = Episode(paper_world, SimConfig(Condition.ACTIVE, seed=1, camera=SMALL))
    visit = list(active.visits())[1]
    moved, truth = visit.probe(0.5, 0.03, 0.0)
    assert moved.probe == (0.5, 0.03, 0.0) and truth.node == visit.node
    # The camera starts at its angle to the turned robot's heading.
    turned = visit.pose.yaw_rad + 0.5
    assert truth.camera_pose.yaw_rad == pytest.approx(turned + moved.camera_angle_rad)
    step = 2.0 * math.pi / 6
    assert abs(moved.camera_angle_rad) <= step / 2 + 1e-12
    assert math.remainder(truth.camera_pose.yaw_rad, step) == pytest.approx(0.0, abs=1e-9)
    assert math.hypot(
        truth.camera_pose.x_m - visit.pose.x_m, truth.camera_pose.y_m - visit.pose.y_m
    ) == pytest.approx(0.03)


def test_autonomous_is_not_an_episode(paper_world) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(SimError):
        Episode(paper_world, SimConfig(Condition.AUTONOMOUS))


def test_same_seed_same_sweeps() -> None:
    net = build_network("paper")
    sweeps = []
    for _ in range(2):
        with World(net, seed=9, texture_px=64) as world:
            episode = Episode(world, SimConfig(Condition.NOISE, seed=9, camera=SMALL))
            sweeps.append(np.stack([v.sweep.images for v in list(episode.visits())[:3]]))
    assert np.array_equal(sweeps[0], sweeps[1])
