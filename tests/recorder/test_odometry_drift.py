"""``--odometry-drift F``: a robot whose odometry is F times as poor, recorded in the
log's settings, and replayed with the allowance it was recorded with."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from pipemap.localizer import LocalizerConfig
from pipemap.recorder import RecordSettings
from pipemap.recorder.metadata import odometry_drift
from pipemap.replay.replayer import _as_recorded
from pipemap.sim.network import build_network
from pipemap.sim.robot import RobotSpec
from tests.cli.common import assert_one_error, run


def _as_json(spec: RobotSpec) -> object:
    return json.loads(json.dumps(dataclasses.asdict(spec)))


def test_the_default_robot_logs_as_without_the_setting() -> None:
    network = build_network("paper")
    meta = RecordSettings("paper").metadata(network, "test")
    assert "odometry_drift" not in meta
    assert json.loads(meta["simulator"])["robot"] == _as_json(RobotSpec())
    assert RecordSettings("paper", odometry_drift=1.0).metadata(network, "test") == meta


def test_a_drifting_robot_is_in_the_run_settings() -> None:
    meta = RecordSettings("paper", odometry_drift=4.0).metadata(build_network("paper"), "t")
    assert meta["odometry_drift"] == "4.0" and odometry_drift(meta) == 4.0
    robot = json.loads(meta["simulator"])["robot"]
    assert robot == _as_json(RobotSpec().drifting(4.0))
    assert robot["slip_std"] == pytest.approx(4 * RobotSpec().slip_std)


def test_the_replay_allows_the_drift_the_run_was_recorded_with() -> None:
    plain = LocalizerConfig()
    config, _ = _as_recorded(plain, {"odometry_drift": "4.0"}, False)
    assert config.odometry_drift_per_m == pytest.approx(4 * plain.odometry_drift_per_m)
    assert config.odometry_limit_m == pytest.approx(4 * plain.odometry_limit_m)
    assert config.odometry_loop_drift_per_m == pytest.approx(4 * plain.odometry_loop_drift_per_m)
    # Where in a chamber the robot stops is no odometry: the radius stays.
    assert config.odometry_radius_m == plain.odometry_radius_m
    for run_meta in ({}, {"odometry_drift": "lots"}, {"odometry_drift": "0.5"}):
        assert _as_recorded(plain, run_meta, False)[0] == plain


@pytest.mark.parametrize("command", ["record", "sim"])
@pytest.mark.parametrize("value", ["0.5", "11", "nan", "poor"])
def test_a_bad_odometry_drift_gets_one_line_and_exit_2(
    command: str, value: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    out_flag = ["-o", str(tmp_path / "run.mcap")] if command == "record" else []
    out_flag = out_flag or ["--save-sweeps", str(tmp_path / "sweeps")]
    argv = [command, "--network", "paper", "--odometry-drift", value, *out_flag]
    status, out, err = run(argv, capfd)
    assert_one_error(status, out, err, "--odometry-drift")
    # The flag's own check, not argparse's refusal of a flag it does not know.
    reason = "not a number" if value == "poor" else "not in [1, 10]"
    assert f"argument --odometry-drift: {reason}" in err and value in err
    assert list(tmp_path.iterdir()) == []


class _Stop(Exception):
    """Ends a run before the robot moves."""


def test_the_map_explorer_allows_the_drift_the_run_is_recorded_with(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from pipemap.localizer import ExploreConfig
    from pipemap.recorder import session
    from pipemap.recorder.online import MapPolicy
    from pipemap.sim.episode import Condition

    policies = []

    def stop(world, camera, seed, policy=None, **_):  # type: ignore[no-untyped-def]
        policies.append(policy)
        raise _Stop

    monkeypatch.setattr(session, "autonomous_run", stop)
    network = build_network("paper")
    for factor in (1.0, 4.0):
        settings = RecordSettings(
            "paper", condition=Condition.AUTONOMOUS, resolution_px=32, odometry_drift=factor
        )
        assert settings.explore_config() == ExploreConfig().drifting(factor)
        with pytest.raises(_Stop):
            session.record_run(None, settings, network, "test")
    assert all(isinstance(p, MapPolicy) for p in policies)
    configs = [p.explorer.config for p in policies]  # type: ignore[union-attr]
    assert configs == [ExploreConfig(), ExploreConfig().drifting(4.0)]
    assert configs[1].heading_drift_per_m == pytest.approx(4 * configs[0].heading_drift_per_m)
    # It checks positions by the online localizer's dead reckoning (its heading fit).
    for p in policies:
        assert p.explorer.odometry is p.online.localizer.dead_reckoning  # type: ignore[union-attr]
