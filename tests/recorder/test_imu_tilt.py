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


def _record(path: Path, tilt_deg: float) -> None:
    settings = RecordSettings(
        network="paper",
        condition=Condition.PERFECT,
        resolution_px=32,
        tilt_rad=math.radians(tilt_deg),
    )
    record_run(path, settings, build_network("paper"), __version__)


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
    imu, true = _logged(tilted)
    assert len(imu) == len(true) == 13
    limit = math.radians(3.0)
    assert all(abs(r) <= limit and abs(p) <= limit for r, p in true)
    assert sum(abs(r) > 0.005 or abs(p) > 0.005 for r, p in true) >= 10  # off level, seeded
    # The IMU reads the truth with a little noise (SimConfig.imu_tilt_noise_rad, 0.002).
    for (r, p), (tr, tp) in zip(imu, true, strict=True):
        assert abs(r - tr) < 0.01 and abs(p - tp) < 0.01
        assert (r, p) != (tr, tp)


def test_the_replay_reads_the_imu_from_robot_topics(tilted: Path) -> None:
    imu, _ = _logged(tilted)
    replayed = [s.imu_tilt_rad for s in _sweeps(tilted)]
    assert replayed == imu


def test_a_level_robot_logs_zero_tilt(tmp_path: Path) -> None:
    path = tmp_path / "level.mcap"
    _record(path, 0.0)
    imu, true = _logged(path)
    assert imu and all(v == (0.0, 0.0) for v in imu + true)
    assert all(s.imu_tilt_rad == (0.0, 0.0) for s in _sweeps(path))
