"""The robot as the explorer drives it: motion commands and the estimates they keep.

:class:`Motion` owns what the explorer knows of itself, from its own sensors only:
the heading (gyro, less the bias measured whenever the robot stands still), the
position (odometry along that heading), the latest ranges, the stall time, and the
run's result so far (readings, events, distance). Its primitives drive
(:meth:`Motion.drive`, :meth:`Motion.straight`, :meth:`Motion.turn_to`), log
(:meth:`Motion.event`) and watch (:meth:`Motion.stalled`, :meth:`Motion.watchdog`);
the behaviours of :mod:`sim.follow`, :mod:`sim.junction_actions` and
:mod:`sim.unstuck` are made of them.
"""

from __future__ import annotations

import math

import numpy as np

from pipemap.sim.explorer_config import ExplorationResult, ExplorerConfig
from pipemap.sim.policy import RunStatus
from pipemap.sim.recovery import RecoveryConfig
from pipemap.sim.robot import NS_PER_S, EncoderReading, ImuReading, RangeReading, Robot
from pipemap.sim.stream import ControlStep, Note, RecordSink, TruePose

__all__ = ["Motion"]


class Motion:
    """Drives ``robot`` with ``config``'s speeds; ``sink`` (if any) gets every control
    step, reading and event; the watchdog stops at ``time_limit_ns``."""

    def __init__(
        self,
        robot: Robot,
        config: ExplorerConfig,
        recovery: RecoveryConfig,
        sink: RecordSink | None,
        time_limit_ns: int,
    ) -> None:
        self.robot = robot
        self.config = config
        self.recovery = recovery
        self.sink = sink
        self.time_limit_ns = time_limit_ns
        self.yaw_est = robot.pose.yaw_rad  # the robot's own heading estimate (gyro)
        # Gyro bias, measured whenever the robot stands still (a zero-velocity update).
        self._still_rate_sum = 0.0
        self._still_samples = 0
        self.xy_est = np.array([robot.pose.x_m, robot.pose.y_m], dtype=np.float64)  # odometry
        self._ticks = (0, 0)
        self.ranges = robot.ranges()
        self.result = ExplorationResult(RunStatus.FINISHED)
        self._last_progress_ns = 0
        self.state = "calibrating"  # what the robot believes it is doing, for the log
        # Commanded motion with the encoders standing still, so far (a stall).
        self.stall_ns = 0
        self.halt: RunStatus | None = None  # a watchdog fired during a recovery
        #: Active-vision probe sweeps taken so far (they number after the visits').
        self.probe_sweeps = 0

    def put_down(self) -> None:
        """The robot has been carried by hand and put down: its gyro measured the
        carry's turn (the heading estimate keeps integrating it), but no wheel turned,
        so its position estimate starts again at its own origin. The odometer stays."""
        self.xy_est = np.zeros(2, dtype=np.float64)
        self.stall_ns = 0
        self._last_progress_ns = self.robot.t_ns  # the watchdog's progress starts here

    def _emit_step(self, v: float, w: float) -> None:
        if self.sink is None:
            return
        t = self.robot.t_ns
        self.sink(TruePose(t, self.robot.pose))
        x, y = (float(c) for c in self.xy_est)
        self.sink(ControlStep(t, self.state, v, w, self.yaw_est, x, y))

    def drive(self, v: float, w: float, duration_ns: int) -> None:
        """Command ``v`` (m/s) and ``w`` (rad/s) for ``duration_ns`` and keep the
        estimates (heading by gyro less its bias, position by odometry), the readings
        and the stall time up to date."""
        self._emit_step(v, w)
        readings = self.robot.drive(v, w, duration_ns)
        spec = self.robot.spec
        metres_per_tick = math.pi * spec.wheel_diameter_m / spec.encoder_ticks_per_rev
        still = v == 0.0 and w == 0.0
        ticks_before = self._ticks
        first_imu = True
        for r in readings:
            if isinstance(r, ImuReading):
                # Standing still the heading holds and the rate is all bias; the first
                # sample may still hold the end of the motion before, so it is integrated.
                if still and not first_imu:
                    self._still_rate_sum += r.yaw_rate_rps
                    self._still_samples += 1
                else:
                    rate = r.yaw_rate_rps - self._gyro_bias()
                    self.yaw_est += rate * spec.period_ns(spec.imu_rate_hz) / NS_PER_S
                first_imu = False
            elif isinstance(r, EncoderReading):
                dl = (r.left_ticks - self._ticks[0]) * metres_per_tick
                dr = (r.right_ticks - self._ticks[1]) * metres_per_tick
                self._ticks = (r.left_ticks, r.right_ticks)
                step = (dl + dr) / 2.0
                self.xy_est += step * np.array([math.cos(self.yaw_est), math.sin(self.yaw_est)])
                self.result.distance_m += abs(step)
                if abs(step) > 1e-4:
                    self._last_progress_ns = r.t_ns
            elif isinstance(r, RangeReading):
                self.ranges = r.ranges_m
            if self.sink is not None:
                self.sink(r)
        self.result.readings.extend(readings)
        if not still and self._ticks == ticks_before:
            self.stall_ns += duration_ns
        else:
            self.stall_ns = 0

    def stalled(self) -> bool:
        """Commanded motion, and the wheels have not turned for the recovery's stall time."""
        return self.stall_ns >= self.recovery.stall_ns

    def _gyro_bias(self) -> float:
        """Mean yaw rate over every sample taken standing still (0 before any)."""
        return self._still_rate_sum / self._still_samples if self._still_samples else 0.0

    def event(self, text: str, warning: bool = False) -> None:
        """Note ``text`` in the run's events (and the sink)."""
        self.result.events.append((self.robot.t_ns, text))
        if self.sink is not None:
            self.sink(Note(self.robot.t_ns, text, warning))

    def watchdog(self) -> RunStatus | None:
        """Why the run must end now (wall contact, no progress, the time limit), if so."""
        if self.robot.in_contact():
            return RunStatus.LEFT_PIPE
        if self.robot.t_ns - self._last_progress_ns > self.config.stuck_after_ns:
            return RunStatus.STUCK
        if self.robot.t_ns > self.time_limit_ns:
            return RunStatus.TIME_LIMIT
        return None

    def straight(
        self, distance_m: float, heading: float, stop_on_stall: bool = False
    ) -> RunStatus | None:
        """Drive ``distance_m`` by odometry holding ``heading``; backwards if negative.
        With ``stop_on_stall`` a stall ends the drive early (see :meth:`stalled`);
        without, the watchdog ends a drive that makes no progress."""
        c = self.config
        travelled = 0.0
        start = self.xy_est.copy()
        speed = math.copysign(c.speed_mps, distance_m)
        distance_m = abs(distance_m)
        while travelled < distance_m:
            error = math.remainder(heading - self.yaw_est, 2.0 * math.pi)
            step_ns = min(
                c.control_period_ns, int((distance_m - travelled) / c.speed_mps * NS_PER_S) + 1
            )
            self.drive(speed, 4.0 * error, step_ns)
            travelled = float(np.linalg.norm(self.xy_est - start))
            status = self.watchdog()
            if status is not None:
                return status
            if stop_on_stall and self.stalled():
                return None
        return None

    def turn_to(self, heading: float) -> None:
        """Turn in place to ``heading`` (by the gyro's estimate)."""
        c = self.config
        self.state = "turning"
        for _ in range(400):
            error = math.remainder(heading - self.yaw_est, 2.0 * math.pi)
            if abs(error) < 0.01:
                return
            duration = max(
                1, int(min(abs(error) / c.turn_rate_rps, c.control_period_ns / NS_PER_S) * NS_PER_S)
            )
            self.drive(0.0, math.copysign(c.turn_rate_rps, error), duration)
