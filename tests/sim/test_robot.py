"""The robot's motion and sensors in the paper's network (PyBullet rays, no rendering)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.errors import SimError
from pipemap.sim import World, build_network
from pipemap.sim.robot import EncoderReading, ImuReading, PlanarPose, RangeReading, Robot, RobotSpec

R = 0.1
# A horizontal ray at the rangers' height (5 cm above the floor of a 20 cm pipe) meets
# the wall at this lateral distance from the axis.
WALL_HALF_WIDTH_M = math.sqrt(R**2 - (R - 0.05) ** 2)


@pytest.fixture(scope="module")
def world():  # type: ignore[no-untyped-def]
    with World(build_network("paper"), seed=0, texture_px=32) as w:
        yield w


def _quiet() -> RobotSpec:
    return RobotSpec(
        slip_std=0.0,
        tof_noise_m=0.0,
        gyro_noise_rps=0.0,
        gyro_bias_std_rps=0.0,
        accel_noise_mps2=0.0,
    )


def test_rangers_in_a_straight_pipe_see_the_walls_at_40_degrees(world) -> None:  # type: ignore[no-untyped-def]
    robot = Robot(world, PlanarPose(0.0, 0.5, math.pi / 2), np.random.default_rng(0), _quiet())
    front, left, right = robot.ranges()
    assert front == pytest.approx(1.2)  # the pipe runs on out of range
    expected = WALL_HALF_WIDTH_M / math.sin(math.radians(40))
    assert left == pytest.approx(expected, abs=2e-3)
    assert right == pytest.approx(expected, abs=2e-3)


def test_front_right_ranger_sees_into_the_branch_at_a(world) -> None:  # type: ignore[no-untyped-def]
    # Heading north before A, the branch to B opens on the right (east): the ray at
    # 40 degrees to the right enters it and runs to the branch's far (north) wall.
    robot = Robot(world, PlanarPose(0.0, 1.30, math.pi / 2), np.random.default_rng(0), _quiet())
    _, left, right = robot.ranges()
    into_branch = (1.5 + WALL_HALF_WIDTH_M - 1.36) / math.cos(math.radians(40))
    assert right == pytest.approx(into_branch, abs=3e-3)
    assert right > 2 * left


def test_dead_end_ahead_is_seen_by_the_front_ranger(world) -> None:  # type: ignore[no-untyped-def]
    robot = Robot(world, PlanarPose(0.5, 1.5, 0.0), np.random.default_rng(0), _quiet())
    front, _, _ = robot.ranges()
    cap = 1.0 + WALL_HALF_WIDTH_M  # B's cap at the rangers' height
    assert front == pytest.approx(cap - 0.5 - 0.06, abs=3e-3)


def test_driving_straight_without_slip_is_exact_and_encoders_count_it(world) -> None:  # type: ignore[no-untyped-def]
    robot = Robot(world, PlanarPose(0.0, 0.3, math.pi / 2), np.random.default_rng(0), _quiet())
    readings = robot.drive(0.1, 0.0, 5 * 10**9)
    assert robot.pose.y_m == pytest.approx(0.8)
    assert robot.pose.x_m == pytest.approx(0.0, abs=1e-12)
    enc = [r for r in readings if isinstance(r, EncoderReading)]
    ticks_per_m = 360 / (math.pi * 0.028)
    assert enc[-1].left_ticks == pytest.approx(0.5 * ticks_per_m, abs=1)
    assert enc[-1].right_ticks == enc[-1].left_ticks


def test_each_sensor_reads_at_its_own_rate_in_time_order(world) -> None:  # type: ignore[no-untyped-def]
    robot = Robot(world, PlanarPose(0.0, 0.3, math.pi / 2), np.random.default_rng(0))
    readings = robot.drive(0.05, 0.0, 10**9)
    assert sum(isinstance(r, ImuReading) for r in readings) == 100
    assert sum(isinstance(r, EncoderReading) for r in readings) == 50
    assert sum(isinstance(r, RangeReading) for r in readings) == 20
    times = [r.t_ns for r in readings]
    assert times == sorted(times) and times[-1] == 10**9


def test_turning_in_place_integrates_to_the_turn(world) -> None:  # type: ignore[no-untyped-def]
    robot = Robot(world, PlanarPose(0.0, 1.5, math.pi / 2), np.random.default_rng(0), _quiet())
    readings = robot.drive(0.0, -math.pi / 4, 2 * 10**9)  # a right turn of 90 degrees
    assert robot.pose.yaw_rad == pytest.approx(0.0, abs=1e-9)
    gyro = [r.yaw_rate_rps for r in readings if isinstance(r, ImuReading)]
    assert sum(gyro) * 0.01 == pytest.approx(-math.pi / 2, abs=1e-9)


def test_slip_makes_odometry_drift_but_is_reproducible(world) -> None:  # type: ignore[no-untyped-def]
    ends = []
    for _ in range(2):
        robot = Robot(world, PlanarPose(0.0, 0.3, math.pi / 2), np.random.default_rng(42))
        readings = robot.drive(0.1, 0.0, 5 * 10**9)
        ends.append((robot.pose, readings[-1]))
    assert ends[0] == ends[1]
    assert ends[0][0].y_m != pytest.approx(0.8, abs=1e-6)  # the ground travel differs


def test_contact_with_the_wall_is_detected(world) -> None:  # type: ignore[no-untyped-def]
    centred = Robot(world, PlanarPose(0.0, 0.5, math.pi / 2), np.random.default_rng(0))
    off = Robot(world, PlanarPose(0.07, 0.5, math.pi / 2), np.random.default_rng(0))
    assert not centred.in_contact()
    assert off.in_contact()


def test_bad_settings_are_refused(world) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(SimError):
        RobotSpec(tof_rate_hz=0)
    robot = Robot(world, PlanarPose(0.0, 0.3, 0.0), np.random.default_rng(0))
    with pytest.raises(SimError):
        robot.drive(0.1, 0.0, 0)


def test_a_drifting_robot_slips_and_its_gyro_drifts_as_many_times_as_much(world) -> None:  # type: ignore[no-untyped-def]
    spec = RobotSpec()
    assert spec.drifting(1.0) is spec
    poor = spec.drifting(4.0)
    assert (poor.slip_std, poor.gyro_noise_rps, poor.gyro_bias_std_rps) == pytest.approx(
        (4 * spec.slip_std, 4 * spec.gyro_noise_rps, 4 * spec.gyro_bias_std_rps)
    )
    assert poor.tof_noise_m == spec.tof_noise_m  # the rangers are the same
    with pytest.raises(SimError):
        spec.drifting(0.5)

    def slip_m(robot_spec: RobotSpec, seed: int) -> float:
        """How far the ground travel is from what the encoders counted."""
        start = PlanarPose(0.0, 0.3, math.pi / 2)
        robot = Robot(world, start, np.random.default_rng(seed), robot_spec)
        readings = robot.drive(0.1, 0.0, 5 * 10**9)
        ticks = [r for r in readings if isinstance(r, EncoderReading)][-1]
        counted = (ticks.left_ticks + ticks.right_ticks) / 2 / spec.encoder_ticks_per_rev
        counted *= math.pi * spec.wheel_diameter_m
        return abs((robot.pose.y_m - 0.3) - counted)

    default = sum(slip_m(spec, seed) for seed in range(4))
    assert sum(slip_m(poor, seed) for seed in range(4)) > 2.0 * default


def test_gyro_reports_short_turns_between_its_samples(world) -> None:  # type: ignore[no-untyped-def]
    # Many turns shorter than the 10 ms IMU period: the gyro's mean rate over each
    # period still integrates to the whole turn, as an integrating MEMS gyro does.
    robot = Robot(world, PlanarPose(0.0, 1.5, 0.0), np.random.default_rng(0), _quiet())
    readings = []
    for _ in range(100):
        readings += robot.drive(0.0, 1.0, 3_000_000)  # 3 ms at 1 rad/s
        readings += robot.drive(0.0, 0.0, 4_000_000)
    readings += robot.drive(0.0, 0.0, 10_000_000)  # let the last period end
    gyro = [r.yaw_rate_rps for r in readings if isinstance(r, ImuReading)]
    assert sum(gyro) * 0.01 == pytest.approx(0.3, abs=1e-9)
    assert robot.pose.yaw_rad == pytest.approx(0.3, abs=1e-9)
