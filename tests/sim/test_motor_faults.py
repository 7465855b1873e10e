"""Motor cut-outs (``sim.motor_faults``): where and how long they happen, what they do
to the wheels, and the explorer telling one from a deposit (it waits, and keeps the
pipe)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.errors import SimError
from pipemap.sim import CameraSpec, World, build_network
from pipemap.sim.controller import RunStatus, autonomous_run
from pipemap.sim.motor_faults import MOTOR_FAULT_S, MotorFault, draw_motor_faults
from pipemap.sim.recovery import RecoveryConfig
from pipemap.sim.robot import EncoderReading, PlanarPose, Robot, RobotSpec


def test_cut_outs_are_drawn_from_the_seed_within_the_first_pass() -> None:
    network = build_network("grid:2x3", seed=1)
    total = sum(network.length_m(p.a, p.b) for p in network.pipes)
    faults = draw_motor_faults(network, 5, seed=1)
    assert faults == draw_motor_faults(network, 5, seed=1)
    assert faults != draw_motor_faults(network, 5, seed=2)
    assert [f.at_m for f in faults] == sorted(f.at_m for f in faults)
    assert all(0.3 <= f.at_m <= total for f in faults)
    lo, hi = MOTOR_FAULT_S
    assert all(lo * 1e9 <= f.duration_ns <= hi * 1e9 for f in faults)
    assert draw_motor_faults(network, 0, seed=1) == ()
    with pytest.raises(SimError, match="count must be >= 0"):
        draw_motor_faults(network, -1, seed=1)


@pytest.fixture(scope="module")
def paper_world():  # type: ignore[no-untyped-def]
    with World(build_network("paper"), seed=0, texture_px=32) as world:
        yield world


def _ticks(readings: list[object]) -> list[int]:
    return [r.left_ticks for r in readings if isinstance(r, EncoderReading)]


def test_a_cut_out_stops_the_wheels_for_its_duration_then_they_turn(paper_world) -> None:  # type: ignore[no-untyped-def]
    quiet = RobotSpec(slip_std=0.0, gyro_bias_std_rps=0.0)
    fault = MotorFault(at_m=0.05, duration_ns=1_000_000_000)
    pose = PlanarPose(0.0, 0.3, math.pi / 2)
    robot = Robot(paper_world, pose, np.random.default_rng(0), quiet, motor_faults=(fault,))
    # Standing still past nothing: no cut-out starts while nothing is commanded.
    robot.drive(0.0, 0.0, 500_000_000)
    y0 = robot.pose.y_m
    ticks = _ticks(robot.drive(0.1, 0.0, 3_000_000_000))
    # 0.05 m at 0.1 m/s: 0.5 s of driving, then 1 s still, then driving again.
    moved = robot.pose.y_m - y0
    assert moved == pytest.approx(0.1 * 2.0, abs=0.01)
    still = [a == b for a, b in zip(ticks, ticks[1:], strict=False)]
    rate = len(ticks) / 3.0
    assert sum(still) == pytest.approx(rate * 1.0, abs=2)
    # Each cut-out happens once: driving on, the wheels turn.
    assert _ticks(robot.drive(0.1, 0.0, 1_000_000_000))[-1] > ticks[-1]


def _run(recovery: RecoveryConfig):  # type: ignore[no-untyped-def]
    network = build_network("grid:2x3", seed=1)
    faults = draw_motor_faults(network, 3, seed=1)
    with World(network, seed=1) as world:
        return autonomous_run(
            world, CameraSpec(resolution_px=32), 1, motor_faults=faults, recovery=recovery
        )


def test_the_explorer_waits_out_a_cut_out_and_keeps_the_pipe() -> None:
    result = _run(RecoveryConfig())
    texts = [text for _, text in result.events]
    assert result.status is RunStatus.FINISHED
    assert sum(t.startswith("stall ") and "into the pipe" in t for t in texts) >= 2
    assert any("motors off" in t for t in texts)
    assert not any(t.startswith("pipe blocked") for t in texts)


def test_without_waiting_a_cut_out_is_taken_for_a_blocked_pipe() -> None:
    result = _run(RecoveryConfig(motor_waits=0))
    texts = [text for _, text in result.events]
    assert any(t.startswith("pipe blocked") for t in texts)
    assert not any("motors off" in t for t in texts)
