"""The robot's tilt in the log: what its IMU read during each sweep (``/robot``) and
what it truly was (``/truth``), and the replay's sweeps carrying the reading."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from pipemap import __version__
from pipemap.recorder import RecordSettings, Topic, read_log, record_run, schemas
from pipemap.replay import FileSource, LoggedSweep, sweeps_of
from pipemap.sim import Condition
from pipemap.sim.network import build_network


def _record(
    path: Path, tilt_deg: float, condition: Condition = Condition.PERFECT, network: str = "paper"
) -> None:
    settings = RecordSettings(
        network=network,
        condition=condition,
        resolution_px=32,
        tilt_rad=math.radians(tilt_deg),
    )
    record_run(path, settings, build_network(network), __version__)


def _logged(path: Path) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """(IMU roll, pitch) of every sweep's START command, and the true (roll, pitch)."""
    imu, true = [], []
    for m in read_log(path).messages:
        if m.topic == Topic.SWEEP:
            command = schemas.SweepCommand.FromString(m.data)
            if command.phase == schemas.SweepCommand.START:
                imu.append((command.imu_roll_rad, command.imu_pitch_rad))
        elif m.topic == Topic.TRUE_SWEEP:
            t = schemas.TrueSweep.FromString(m.data)
            true.append((t.roll_rad, t.pitch_rad))
    return imu, true


def _sweeps(path: Path) -> list[LoggedSweep]:
    source = FileSource(path)
    return sweeps_of(source.robot_messages(), path.name).sweeps


@pytest.fixture(scope="module")
def tilted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("tilt") / "tilted.mcap"
    _record(path, 3.0)
    return path


def test_a_tilted_robot_logs_its_imu_reading_and_its_true_tilt(tilted: Path) -> None:
    assert _checked_tilt(tilted) == 13  # every visit of the paper's tour


def test_the_autonomous_robot_off_level_too(tmp_path: Path) -> None:
    """The explorer draws a tilt at each junction as the placements do: the camera
    sweeps from the tilted body, the IMU reads it, the truth holds it."""
    # tree:3: an autonomous run's every junction and revisit, in a cheap world.
    path = tmp_path / "autonomous.mcap"
    _record(path, 3.0, Condition.AUTONOMOUS, "tree:3")
    assert _checked_tilt(path) == 5  # its 5 visits
    level = tmp_path / "level.mcap"
    _record(level, 0.0, Condition.AUTONOMOUS, "tree:3")
    first = [s.images.images for s in _sweeps(path)][0]
    assert not (first == [s.images.images for s in _sweeps(level)][0]).all()


def _checked_tilt(path: Path) -> int:
    """Check the tilt of every sweep of the log; how many sweeps there were."""
    imu, true = _logged(path)
    assert len(imu) == len(true)
    limit = math.radians(3.0)
    assert all(abs(r) <= limit and abs(p) <= limit for r, p in true)
    assert sum(abs(r) > 0.005 or abs(p) > 0.005 for r, p in true) >= len(true) - 2  # seeded
    # The IMU reads the truth with a little noise (SimConfig.imu_tilt_noise_rad, 0.002).
    for (r, p), (tr, tp) in zip(imu, true, strict=True):
        assert abs(r - tr) < 0.01 and abs(p - tp) < 0.01
        assert (r, p) != (tr, tp)
    return len(imu)


def test_the_replay_reads_the_imu_from_robot_topics(tilted: Path) -> None:
    imu, _ = _logged(tilted)
    replayed = [s.imu_tilt_rad for s in _sweeps(tilted)]
    assert replayed == imu


def test_a_level_robot_logs_zero_tilt(tmp_path: Path) -> None:
    path = tmp_path / "level.mcap"
    _record(path, 0.0, network="tree:3")  # a small world: each of its sweeps is level
    imu, true = _logged(path)
    assert imu and all(v == (0.0, 0.0) for v in imu + true)
    assert all(s.imu_tilt_rad == (0.0, 0.0) for s in _sweeps(path))


def test_the_command_line_tilts_the_robot(tmp_path: Path) -> None:
    """``pipemap record --tilt-deg 3`` records the tilted robot, seeded within 3 degrees."""
    from tests.logs import record

    path = tmp_path / "cli.mcap"
    done = record(path, "--network", "tree:3", "--tilt-deg", "3")
    assert done.returncode == 0, done.stderr
    assert _checked_tilt(path) == 5  # tree:3's 5 visits
