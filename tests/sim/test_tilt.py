"""A robot off level in the placement conditions: seeded tilts, tilted renders, the IMU."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.cli import main
from pipemap.errors import SimError
from pipemap.sim import CameraSpec, Condition, Episode, SimConfig, World, build_network
from pipemap.sim.explorer_config import ExplorerConfig
from pipemap.sim.world import body_rotation

SMALL = CameraSpec(resolution_px=48)


@pytest.fixture(scope="module")
def paper_world():  # type: ignore[no-untyped-def]
    with World(build_network("paper"), seed=3, texture_px=128) as world:
        yield world


def test_body_rotation_is_a_rotation_and_pitch_lowers_the_nose() -> None:
    r = body_rotation(0.7, 0.05, -0.03)
    assert np.allclose(r @ r.T, np.eye(3)) and np.linalg.det(r) == pytest.approx(1.0)
    nose = body_rotation(0.0, 0.0, 0.1) @ np.array([1.0, 0.0, 0.0])
    assert nose[2] == pytest.approx(-math.sin(0.1))
    left = body_rotation(0.0, 0.1, 0.0) @ np.array([0.0, 1.0, 0.0])
    assert left[2] == pytest.approx(math.sin(0.1))  # roll right-hand about forward
    assert np.allclose(body_rotation(0.4, 0.0, 0.0)[:, 0], [math.cos(0.4), math.sin(0.4), 0.0])


def test_a_tilted_render_is_the_level_one_at_zero_tilt(paper_world) -> None:  # type: ignore[no-untyped-def]
    eye = (0.0001, 1.5001, 0.05)
    level = paper_world.render(eye, 0.3 - 1.0, SMALL).astype(float)
    same = paper_world.render_tilted(eye, 0.3, -1.0, 0.0, 0.0, SMALL).astype(float)
    rolled = paper_world.render_tilted(eye, 0.3, -1.0, 0.08, 0.0, SMALL).astype(float)
    assert np.abs(level - same).mean() < 0.5
    assert np.abs(level - rolled).mean() > 5.0


def _visits(world: World, config: SimConfig) -> list:  # type: ignore[type-arg]
    return list(Episode(world, config).visits())


def test_tilts_are_seeded_bounded_and_reported_by_the_imu(paper_world) -> None:  # type: ignore[no-untyped-def]
    tilt = math.radians(3.0)
    config = SimConfig(Condition.NOISE, seed=5, camera=SMALL, tilt_rad=tilt)
    one, two = _visits(paper_world, config), _visits(paper_world, config)
    level = _visits(paper_world, SimConfig(Condition.NOISE, seed=5, camera=SMALL))
    tilts = np.array([(v.pose.roll_rad, v.pose.pitch_rad) for v in one])
    assert np.array_equal(tilts, [(v.pose.roll_rad, v.pose.pitch_rad) for v in two])
    assert np.abs(tilts).max() <= tilt and np.abs(tilts).max() > tilt / 2
    assert len(set(tilts[:, 0])) == len(one)  # it wanders from visit to visit
    # The tilt draws from its own stream: the placements are the level run's.
    assert [(v.pose.x_m, v.pose.y_m) for v in one] == [(v.pose.x_m, v.pose.y_m) for v in level]
    for v in one:
        imu = np.array(v.sweep.imu_tilt_rad)
        assert np.abs(imu - (v.pose.roll_rad, v.pose.pitch_rad)).max() < 4 * 0.002
        assert v.sweep_truth.camera_pose.roll_rad == v.pose.roll_rad
    assert all(v.sweep.imu_tilt_rad == (0.0, 0.0) for v in level)
    assert not np.array_equal(one[1].sweep.images, level[1].sweep.images)


@pytest.mark.parametrize("config", [SimConfig, ExplorerConfig])
def test_tilt_settings_are_checked(config: type) -> None:
    with pytest.raises(SimError):
        config(tilt_rad=0.5)
    with pytest.raises(SimError):
        config(imu_tilt_noise_rad=-1.0)
    assert config(tilt_rad=0.3).tilt_rad == 0.3


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["sim", "--tilt-deg", "20"], "--tilt-deg"),
        (["record", "--tilt-deg", "-1"], "--tilt-deg"),
        (["record", "--tilt-deg", "nan"], "--tilt-deg"),
    ],
)
def test_the_command_line_refuses_a_tilt_it_cannot_simulate(
    argv: list[str],
    message: str,
    tmp_path,
    capfd,  # type: ignore[no-untyped-def]
) -> None:
    out = (
        ["--save-sweeps", str(tmp_path / "s")]
        if argv[0] == "sim"
        else ["-o", str(tmp_path / "r.mcap")]
    )
    try:
        status = main([argv[0], "--network", "paper", *argv[1:], *out])
    except SystemExit as exc:
        status = int(exc.code or 0)
    err = capfd.readouterr().err
    assert status == 2 and message in err and len(err.strip().splitlines()) <= 2
    assert not (tmp_path / "s").exists() and not (tmp_path / "r.mcap").exists()
