"""The pipe robot: kinematic differential drive and its range-only sensors.

A 12 cm, six-wheel-leg robot (wheel diameter 28 mm) driving on the pipe floor. Full
contact physics made T and cross turns fail in every try of a probe, so motion is
kinematic: the commanded wheel speeds, each disturbed by slip, move the robot along
exact arcs (unless the move would put its footprint into a floor deposit of
:mod:`sim.obstacles`, or its motors have cut out, :mod:`sim.motor_faults`: then it
stays and its wheels stall), and PyBullet is used for what it does well here: range
rays and the collision check.

Sensors, each with noise and its own rate, all drawn from the run's generator:

* three time-of-flight rangers at the front (front, front-left, front-right), one
  ``rayTestBatch`` per reading;
* an IMU: yaw rate (with a constant bias), forward and lateral acceleration; the
  rate is the mean over the sample period (the gyro integrates between samples, as
  a MEMS gyro's filter does), so that short turns are not missed between samples;
* two wheel encoders counting wheel rotation, which is not ground travel when a
  wheel slips: dead reckoning drifts as on the real robot.

Time is an integer count of nanoseconds of simulated time.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from pipemap.errors import SimError
from pipemap.sim.motor_faults import MotorFault
from pipemap.sim.obstacles import footprint_hits
from pipemap.sim.world import World

__all__ = ["EncoderReading", "ImuReading", "PlanarPose", "RangeReading", "Robot", "RobotSpec"]

NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class RobotSpec:
    """The robot's build and its sensors' behaviour."""

    length_m: float = 0.12
    width_m: float = 0.07
    #: Contact: a wall nearer to the centre line than half the body's width.
    contact_clearance_m: float = 0.035
    wheel_diameter_m: float = 0.028
    track_m: float = 0.06
    encoder_ticks_per_rev: int = 360
    slip_std: float = 0.03
    tof_forward_m: float = 0.06
    tof_height_m: float = 0.05
    tof_angles_rad: tuple[float, float, float] = (0.0, math.radians(40.0), math.radians(-40.0))
    tof_max_range_m: float = 1.2
    tof_noise_m: float = 0.004
    tof_rate_hz: float = 20.0
    imu_rate_hz: float = 100.0
    gyro_noise_rps: float = 0.002
    gyro_bias_std_rps: float = 0.001
    accel_noise_mps2: float = 0.02
    encoder_rate_hz: float = 50.0

    def __post_init__(self) -> None:
        for name in ("tof_rate_hz", "imu_rate_hz", "encoder_rate_hz", "wheel_diameter_m"):
            if getattr(self, name) <= 0:
                raise SimError(f"{name} must be > 0, got {getattr(self, name)}")

    def period_ns(self, rate_hz: float) -> int:
        """Sampling period of a sensor in whole nanoseconds."""
        return round(NS_PER_S / rate_hz)

    def drifting(self, factor: float) -> RobotSpec:
        """This robot with odometry ``factor`` times as poor: its wheels slip and its
        gyro's noise and bias are ``factor`` times as large (a worn drive on a slimy
        pipe floor, a cheaper IMU). ``factor`` 1 is this robot itself."""
        if not (math.isfinite(factor) and factor >= 1.0):
            raise SimError(f"odometry drift factor must be >= 1, got {factor}")
        if factor == 1.0:
            return self
        return dataclasses.replace(
            self,
            slip_std=self.slip_std * factor,
            gyro_noise_rps=self.gyro_noise_rps * factor,
            gyro_bias_std_rps=self.gyro_bias_std_rps * factor,
        )


@dataclass(frozen=True)
class PlanarPose:
    """The robot on the pipe floor: position of its centre and heading."""

    x_m: float
    y_m: float
    yaw_rad: float


@dataclass(frozen=True)
class RangeReading:
    """Front, front-left and front-right ranges; ``max_range`` when nothing is in reach."""

    t_ns: int
    ranges_m: tuple[float, float, float]


@dataclass(frozen=True)
class ImuReading:
    """Yaw rate (counter-clockwise positive) and body-frame accelerations."""

    t_ns: int
    yaw_rate_rps: float
    accel_forward_mps2: float
    accel_left_mps2: float


@dataclass(frozen=True)
class EncoderReading:
    """Cumulative tick counts of the left and right wheels."""

    t_ns: int
    left_ticks: int
    right_ticks: int


Reading = RangeReading | ImuReading | EncoderReading


class Robot:
    """The robot in a world. :meth:`drive` advances time and returns the readings due."""

    def __init__(
        self,
        world: World,
        pose: PlanarPose,
        rng: np.random.Generator,
        spec: RobotSpec | None = None,
        motor_faults: tuple[MotorFault, ...] = (),
    ) -> None:
        self.world = world
        self.spec = spec if spec is not None else RobotSpec()
        self.pose = pose
        self.t_ns = 0
        self._rng = rng
        self._gyro_bias = float(rng.normal(0.0, self.spec.gyro_bias_std_rps))
        self._wheel_rad = [0.0, 0.0]  # cumulative wheel rotation, left and right
        self._speed_mps = 0.0
        self._turned_rad = 0.0  # true yaw change since the last IMU sample
        # Motor cut-outs still to come, in order, and the end of the one under way.
        self._faults = sorted(motor_faults, key=lambda f: f.at_m)
        self._cut_until_ns = -1
        self._driven_m = 0.0  # true distance driven, either way
        self._due = {
            "range": self.spec.period_ns(self.spec.tof_rate_hz),
            "imu": self.spec.period_ns(self.spec.imu_rate_hz),
            "encoder": self.spec.period_ns(self.spec.encoder_rate_hz),
        }

    def place(self, pose: PlanarPose, t_ns: int) -> None:
        """Carry the robot by hand to ``pose`` and put it down at time ``t_ns`` (a
        placement condition's experimenter): it stands still there, its wheels (and
        encoders) as they were, each sensor reading again on its own grid after
        ``t_ns``. The gyro ran while it was carried: its first sample after ``t_ns``
        holds the carry's turn (the shortest way round)."""
        if t_ns < self.t_ns:
            raise SimError(f"a placement at {t_ns} ns is before the robot's time {self.t_ns} ns")
        self._turned_rad += math.remainder(pose.yaw_rad - self.pose.yaw_rad, 2.0 * math.pi)
        self.pose = pose
        self.t_ns = t_ns
        self._speed_mps = 0.0
        self._accel = (0.0, 0.0)
        for key, rate in (
            ("range", self.spec.tof_rate_hz),
            ("imu", self.spec.imu_rate_hz),
            ("encoder", self.spec.encoder_rate_hz),
        ):
            period = self.spec.period_ns(rate)
            self._due[key] = (t_ns // period + 1) * period

    def ranges(self) -> tuple[float, float, float]:
        """One noisy reading of the three rangers at the current pose."""
        s, p = self.spec, self.pose
        origin = np.array(
            [
                p.x_m + s.tof_forward_m * math.cos(p.yaw_rad),
                p.y_m + s.tof_forward_m * math.sin(p.yaw_rad),
                s.tof_height_m,
            ]
        )
        dirs = np.array(
            [[math.cos(p.yaw_rad + a), math.sin(p.yaw_rad + a), 0.0] for a in s.tof_angles_rad]
        )
        true = self.world.ray_distances_m(np.tile(origin, (3, 1)), dirs, s.tof_max_range_m)
        noisy = true + self._rng.normal(0.0, s.tof_noise_m, 3)
        clipped = np.where(
            true >= s.tof_max_range_m, s.tof_max_range_m, np.clip(noisy, 0.0, s.tof_max_range_m)
        )
        return (float(clipped[0]), float(clipped[1]), float(clipped[2]))

    def clearance_m(self, rays: int = 16) -> float:
        """Smallest horizontal distance from the robot's centre line to a wall."""
        p = self.pose
        origin = np.array([p.x_m, p.y_m, self.spec.tof_height_m])
        angles = np.linspace(0.0, 2.0 * math.pi, rays, endpoint=False) + p.yaw_rad
        dirs = np.stack([np.cos(angles), np.sin(angles), np.zeros(rays)], 1)
        return float(self.world.ray_distances_m(np.tile(origin, (rays, 1)), dirs, 1.0).min())

    def in_contact(self) -> bool:
        """True when the robot touches a wall: clearance below ``contact_clearance_m``."""
        return self.clearance_m() < self.spec.contact_clearance_m

    def _cut_out(self, commanded: tuple[float, float]) -> bool:
        """Whether the motors are cut out now; a cut-out starts when the wheels are
        commanded past its distance."""
        if self.t_ns < self._cut_until_ns:
            return True
        if self._faults and commanded != (0.0, 0.0) and self._driven_m >= self._faults[0].at_m:
            self._cut_until_ns = self.t_ns + self._faults.pop(0).duration_ns
            return True
        return False

    def _move(self, v_mps: float, omega_rps: float, dt_s: float) -> float:
        """Advance the true pose by one step of slipping wheels; returns the true yaw rate."""
        s = self.spec
        half_track = s.track_m / 2.0
        commanded = (v_mps - omega_rps * half_track, v_mps + omega_rps * half_track)
        actual = [w * (1.0 + self._rng.normal(0.0, s.slip_std)) for w in commanded]
        v = (actual[0] + actual[1]) / 2.0
        w = (actual[1] - actual[0]) / s.track_m
        p = self.pose
        if abs(w) < 1e-9:
            x = p.x_m + v * dt_s * math.cos(p.yaw_rad)
            y = p.y_m + v * dt_s * math.sin(p.yaw_rad)
        else:
            yaw_end = p.yaw_rad + w * dt_s
            x = p.x_m + v / w * (math.sin(yaw_end) - math.sin(p.yaw_rad))
            y = p.y_m - v / w * (math.cos(yaw_end) - math.cos(p.yaw_rad))
        yaw = math.remainder(p.yaw_rad + w * dt_s, 2.0 * math.pi)
        obstacles = self.world.obstacles
        if self._cut_out(commanded) or (
            obstacles and footprint_hits(x, y, yaw, s.length_m, s.width_m, obstacles)
        ):
            # Against a deposit, or the motors cut out: the body stays and the geared
            # motors stall, so the wheels (and their encoders) stop too.
            self._accel = (-self._speed_mps / dt_s, 0.0)
            self._speed_mps = 0.0
            return 0.0
        for i in (0, 1):  # encoders see the wheel turn, not the ground it covers
            self._wheel_rad[i] += commanded[i] * dt_s / (s.wheel_diameter_m / 2.0)
        self.pose = PlanarPose(x, y, yaw)
        self._driven_m += abs(v) * dt_s
        self._accel = ((v - self._speed_mps) / dt_s, v * w)
        self._speed_mps = v
        return w

    def drive(self, v_mps: float, omega_rps: float, duration_ns: int) -> list[Reading]:
        """Drive with constant commands for ``duration_ns``; the readings due, in time order.

        The motion is integrated at the IMU's rate; each sensor reads on its own grid
        of multiples of its period.
        """
        if duration_ns <= 0:
            raise SimError(f"drive duration must be > 0 ns, got {duration_ns}")
        s = self.spec
        step = self.spec.period_ns(s.imu_rate_hz)
        end = self.t_ns + duration_ns
        readings: list[Reading] = []
        while self.t_ns < end:
            dt = min(step, end - self.t_ns)
            w = self._move(v_mps, omega_rps, dt / NS_PER_S)
            self._turned_rad += w * dt / NS_PER_S
            self.t_ns += dt
            if self.t_ns >= self._due["imu"]:
                mean_rate = self._turned_rad / (step / NS_PER_S)
                self._turned_rad = 0.0
                readings.append(
                    ImuReading(
                        self.t_ns,
                        mean_rate
                        + self._gyro_bias
                        + float(self._rng.normal(0.0, s.gyro_noise_rps)),
                        self._accel[0] + float(self._rng.normal(0.0, s.accel_noise_mps2)),
                        self._accel[1] + float(self._rng.normal(0.0, s.accel_noise_mps2)),
                    )
                )
                self._due["imu"] += s.period_ns(s.imu_rate_hz)
            if self.t_ns >= self._due["encoder"]:
                ticks = [
                    math.floor(r / (2.0 * math.pi) * s.encoder_ticks_per_rev)
                    for r in self._wheel_rad
                ]
                readings.append(EncoderReading(self.t_ns, ticks[0], ticks[1]))
                self._due["encoder"] += s.period_ns(s.encoder_rate_hz)
            if self.t_ns >= self._due["range"]:
                readings.append(RangeReading(self.t_ns, self.ranges()))
                self._due["range"] += s.period_ns(s.tof_rate_hz)
        return readings
