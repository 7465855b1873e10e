"""The autonomous explorer: exploration from the robot's own sensors.

It never reads ground truth: only the three rangers, the gyro and the encoders. Which
pipe to take at a junction is its :class:`~pipemap.sim.policy.ExitPolicy`'s choice
(the paper's right-most-branch rule unless it is given another).

* **Calibrate**: stand still for 2 s first; whenever the robot stands still (here
  and during every sweep) the gyro's reading is taken as its bias, and the heading
  estimate integrates the rate less that bias.
* **Follow** a pipe at constant speed, steering to balance the front-left and
  front-right ranges (which measures both offset and heading error). A node is
  detected ahead when a side ray finds an opening or the front ray a wall; the
  ranges give the distance to its centre.
* **Approach**: drive that distance by odometry, holding the heading by gyro.
* **Sweep** the camera (N images, clockwise, from the multiple of ``2*pi/N`` nearest
  the heading estimate, see :func:`sim.episode.sweep_start_angle`), then **scan**:
  turn in place once round while the front ranger looks for openings. Openings, not a lookup table
  of junction types, give the exits, so junctions at any angle work.
* **Choose**: the exits (relative to the arrival heading) and the odometry go to the
  policy, which names the exit to take (or straight back), or stops the run. The
  right-hand policy takes the right-most exit (turns around at a dead end) and stops
  when back at the start (by odometry) as many times as it has pipes: on a tree the
  rule has then covered everything. **Turn** to the exit by gyro and **leave** until
  the node is behind.
* **Get unstuck** (:mod:`sim.recovery`): a stall in a pipe (commanded motion, the
  wheels not turning) starts a bounded recovery: back off, re-centre, retry to
  either side. When every try stalls the pipe is given up: the robot logs it
  (:class:`~pipemap.sim.stream.PipeBlocked`), drives back to the junction it came
  from, faces as it did there, and asks its policy again
  (:meth:`~pipemap.sim.policy.ExitPolicy.blocked`), without a new sweep.
* A watchdog ends a run whose robot touches a wall or stops making progress, with
  that reason: the last resort.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipemap.sim.episode import Pose, Sweep, sweep_start_angle
from pipemap.sim.explorer_config import (
    MIN_TIME_LIMIT_S,
    TIME_LIMIT_S_PER_PIPE_M,
    ExplorationResult,
    ExplorerConfig,
    default_time_limit_ns,
)
from pipemap.sim.policy import ExitChoice, ExitPolicy, Junction, RightHandPolicy, RunStatus
from pipemap.sim.recovery import RecoveryConfig, recover
from pipemap.sim.robot import (
    NS_PER_S,
    EncoderReading,
    ImuReading,
    PlanarPose,
    RangeReading,
    Robot,
)
from pipemap.sim.scan_geometry import (
    HALF_WIDTH_M,
    SIDE_NOMINAL_M,
    axes_crossing,
    opening_headings,
    wall_points,
    widest_centre,
)
from pipemap.sim.stream import (
    ControlStep,
    NodeArrival,
    NodeDeparture,
    NodeExits,
    Note,
    PipeBlocked,
    RecordSink,
    SweepEnd,
    SweepImage,
    SweepStart,
    TruePose,
)
from pipemap.sim.world import CameraSpec, World

__all__ = [
    "MIN_TIME_LIMIT_S",
    "TIME_LIMIT_S_PER_PIPE_M",
    "ExplorationResult",
    "Explorer",
    "ExplorerConfig",
    "RunStatus",
    "autonomous_run",
    "default_time_limit_ns",
]


@dataclass(frozen=True)
class _Bend:
    """A bend passed while following: its estimated centre and the heading before it."""

    centre: np.ndarray
    arrival_heading: float


class _Stall:
    """What :meth:`Explorer._follow` returns when the robot stalled."""


_STALL = _Stall()


@dataclass(frozen=True)
class _Left:
    """A junction the robot left, to come back to if the pipe is blocked."""

    junction: Junction
    exits: list[float]
    steer: list[float]
    arrival: float
    turn_rad: float


class Explorer:
    """Drives a :class:`Robot` through its world; ``policy`` chooses the exits (default:
    the right-most-branch rule with the config's start radius and drift)."""

    def __init__(
        self,
        robot: Robot,
        camera: CameraSpec,
        config: ExplorerConfig | None = None,
        true_node_of: Callable[[PlanarPose], str] | None = None,
        sink: RecordSink | None = None,
        policy: ExitPolicy | None = None,
        recovery: RecoveryConfig | None = None,
    ) -> None:
        self.robot = robot
        self.recovery = recovery if recovery is not None else RecoveryConfig()
        self.camera = camera
        self.config = config if config is not None else ExplorerConfig()
        if policy is None:
            policy = RightHandPolicy(self.config.start_radius_m, self.config.drift_per_m)
        self.policy = policy
        limit = self.config.time_limit_ns
        self.time_limit_ns = (
            limit if limit is not None else default_time_limit_ns(robot.world.network)
        )
        # Ground truth only labels the sweeps for scoring; no decision reads it.
        self._true_node_of = true_node_of
        self._yaw_est = robot.pose.yaw_rad  # the robot's own heading estimate (gyro)
        # Gyro bias, measured whenever the robot stands still (a zero-velocity update).
        self._still_rate_sum = 0.0
        self._still_samples = 0
        self._xy_est = np.array([robot.pose.x_m, robot.pose.y_m], dtype=np.float64)  # odometry
        self._ticks = (0, 0)
        self._ranges = robot.ranges()
        self._result = ExplorationResult(RunStatus.FINISHED)
        self._last_progress_ns = 0
        self._sink = sink
        self._state = "calibrating"  # what the robot believes it is doing, for the log
        # Commanded motion with the encoders standing still, so far (a stall).
        self._stall_ns = 0
        self._halt: RunStatus | None = None  # a watchdog fired during a recovery

    # -- low level: drive and keep the estimates ------------------------------------

    def _emit_step(self, v: float, w: float) -> None:
        if self._sink is None:
            return
        t = self.robot.t_ns
        self._sink(TruePose(t, self.robot.pose))
        x, y = (float(c) for c in self._xy_est)
        self._sink(ControlStep(t, self._state, v, w, self._yaw_est, x, y))

    def _drive(self, v: float, w: float, duration_ns: int) -> None:
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
                    self._yaw_est += rate * spec.period_ns(spec.imu_rate_hz) / NS_PER_S
                first_imu = False
            elif isinstance(r, EncoderReading):
                dl = (r.left_ticks - self._ticks[0]) * metres_per_tick
                dr = (r.right_ticks - self._ticks[1]) * metres_per_tick
                self._ticks = (r.left_ticks, r.right_ticks)
                step = (dl + dr) / 2.0
                self._xy_est += step * np.array([math.cos(self._yaw_est), math.sin(self._yaw_est)])
                self._result.distance_m += abs(step)
                if abs(step) > 1e-4:
                    self._last_progress_ns = r.t_ns
            elif isinstance(r, RangeReading):
                self._ranges = r.ranges_m
            if self._sink is not None:
                self._sink(r)
        self._result.readings.extend(readings)
        if not still and self._ticks == ticks_before:
            self._stall_ns += duration_ns
        else:
            self._stall_ns = 0

    def _stalled(self) -> bool:
        """Commanded motion, and the wheels have not turned for the recovery's stall time."""
        return self._stall_ns >= self.recovery.stall_ns

    def _gyro_bias(self) -> float:
        """Mean yaw rate over every sample taken standing still (0 before any)."""
        return self._still_rate_sum / self._still_samples if self._still_samples else 0.0

    def _event(self, text: str, warning: bool = False) -> None:
        self._result.events.append((self.robot.t_ns, text))
        if self._sink is not None:
            self._sink(Note(self.robot.t_ns, text, warning))

    def _watchdog(self) -> RunStatus | None:
        if self.robot.in_contact():
            return RunStatus.LEFT_PIPE
        if self.robot.t_ns - self._last_progress_ns > self.config.stuck_after_ns:
            return RunStatus.STUCK
        if self.robot.t_ns > self.time_limit_ns:
            return RunStatus.TIME_LIMIT
        return None

    # -- behaviours -----------------------------------------------------------------

    def _node_distance_m(self) -> float | None:
        """Distance from the robot's centre to a node centre ahead, if one is in sight."""
        front, left, right = self._ranges
        spec = self.robot.spec
        candidates = []
        if front < self.config.wall_ahead_m + spec.tof_forward_m:
            candidates.append(front + spec.tof_forward_m - HALF_WIDTH_M)
        if max(left, right) > self.config.opening_factor * SIDE_NOMINAL_M:
            # The side ray meets the wall line this far ahead of the robot; the opening
            # starts a half-width before the node centre.
            ahead = spec.tof_forward_m + HALF_WIDTH_M / math.tan(math.radians(40.0))
            candidates.append(ahead + HALF_WIDTH_M)
        return min(candidates) if candidates else None

    def _follow(self) -> float | _Bend | RunStatus | _Stall:
        """Follow the pipe until a node is detected ahead (returns its distance), a
        bend has been passed (returns where it was) or the robot stalls."""
        c = self.config
        self._state = "following"
        track: list[tuple[float, np.ndarray, float]] = []  # (distance, position, heading)
        while True:
            distance = self._node_distance_m()
            if distance is not None:
                return distance
            self._drive(c.speed_mps, self._steer(0.0), c.control_period_ns)
            status = self._watchdog()
            if status is not None:
                return status
            if self._stalled():
                return _STALL
            track.append((self._result.distance_m, self._xy_est.copy(), self._yaw_est))
            bend = self._bend_passed(track)
            if bend is not None:
                return bend

    def _steer(self, left_m: float) -> float:
        """The follower's turn rate: balance the front-left and front-right ranges,
        shifted to hold the robot ``left_m`` left of the axis (at that offset, facing
        along the pipe, the left range is shorter by ``2 left_m / sin 40deg``)."""
        c = self.config
        _, left, right = self._ranges
        balance = min(left, 0.3) - min(right, 0.3)
        if left_m:
            balance += 2.0 * left_m / math.sin(math.radians(40.0))
        return float(np.clip(c.steer_gain * balance, -1.0, 1.0))

    def _follow_offset(self, left_m: float, distance_m: float) -> RunStatus | None:
        """Follow the pipe ``left_m`` left of its axis for ``distance_m`` (a recovery
        try: nodes and bends are not looked for). Stops early on a stall."""
        c = self.config
        start = self._result.distance_m
        while self._result.distance_m - start < distance_m:
            self._drive(c.speed_mps, self._steer(left_m), c.control_period_ns)
            status = self._watchdog()
            if status is not None:
                return status
            if self._stalled():
                return None
        return None

    def _bend_passed(self, track: list[tuple[float, np.ndarray, float]]) -> _Bend | None:
        """A shallow corner passed while following, from the gyro alone.

        A corner that turns the pipe by little shows no opening to the side rays and no
        wall ahead, so the follower steers through it. Its trace is in the heading: it
        differs from the heading held ``bend_window_m`` back by more than
        ``bend_deg``, and has settled again over the last ``bend_settle_m``. The
        corner's centre is where the pipe's axes before and after cross.
        """
        c = self.config
        now_d, now_xy, now_yaw = track[-1]
        if now_d - track[0][0] < c.bend_window_m:
            return None
        before = next(t for t in reversed(track) if now_d - t[0] >= c.bend_window_m)
        recent = next(t for t in reversed(track) if now_d - t[0] >= c.bend_settle_m)
        turned = math.remainder(now_yaw - before[2], 2.0 * math.pi)
        settled = abs(math.remainder(now_yaw - recent[2], 2.0 * math.pi))
        if abs(turned) < math.radians(c.bend_deg) or settled > math.radians(c.bend_settle_deg):
            return None
        d1 = np.array([math.cos(before[2]), math.sin(before[2])])
        d2 = np.array([math.cos(now_yaw), math.sin(now_yaw)])
        t, _ = np.linalg.solve(np.stack([d1, -d2], axis=1), now_xy - before[1])
        centre = before[1] + t * d1
        behind = float(np.dot(now_xy - centre, d2))
        if not 0.0 < behind < c.bend_window_m:
            return None
        return _Bend(centre, before[2])

    def _straight(
        self, distance_m: float, heading: float, stop_on_stall: bool = False
    ) -> RunStatus | None:
        """Drive ``distance_m`` by odometry holding ``heading``; backwards if negative.
        With ``stop_on_stall`` a stall ends the drive early (see :meth:`_stalled`);
        without, the watchdog ends a drive that makes no progress."""
        c = self.config
        travelled = 0.0
        start = self._xy_est.copy()
        speed = math.copysign(c.speed_mps, distance_m)
        distance_m = abs(distance_m)
        while travelled < distance_m:
            error = math.remainder(heading - self._yaw_est, 2.0 * math.pi)
            step_ns = min(
                c.control_period_ns, int((distance_m - travelled) / c.speed_mps * NS_PER_S) + 1
            )
            self._drive(speed, 4.0 * error, step_ns)
            travelled = float(np.linalg.norm(self._xy_est - start))
            status = self._watchdog()
            if status is not None:
                return status
            if stop_on_stall and self._stalled():
                return None
        return None

    def _turn_to(self, heading: float) -> None:
        c = self.config
        self._state = "turning"
        for _ in range(400):
            error = math.remainder(heading - self._yaw_est, 2.0 * math.pi)
            if abs(error) < 0.01:
                return
            duration = max(
                1, int(min(abs(error) / c.turn_rate_rps, c.control_period_ns / NS_PER_S) * NS_PER_S)
            )
            self._drive(0.0, math.copysign(c.turn_rate_rps, error), duration)

    def _sweep(self) -> None:
        c = self.config
        self._state = "sweeping"
        pose = self.robot.pose
        n = c.images_per_sweep
        number = len(self._result.sweeps) + 1  # one sweep per visit: the same number
        angle = sweep_start_angle(self._yaw_est, n, c.align_sweeps)
        first = pose.yaw_rad + angle  # where the camera truly points: the robot's true yaw
        sink = self._sink
        if sink is not None:
            sink(NodeArrival(self.robot.t_ns, number))
            sink(SweepStart(self.robot.t_ns, number, number, n, angle, self.camera.fov_rad))
        images = []
        for j in range(n):
            step = j * 2.0 * math.pi / n
            eye = (pose.x_m + 1.3e-4, pose.y_m + 0.7e-4, c.camera_height_m)
            images.append(self.robot.world.render(eye, first - step, self.camera))
            if sink is not None:
                sink(SweepImage(self.robot.t_ns, number, number, j, angle - step, images[-1]))
            self._drive(0.0, 0.0, c.sweep_step_ns)  # the camera motor turns; the robot waits
        truth = self._true_node_of(pose) if self._true_node_of is not None else ""
        start = Pose(pose.x_m, pose.y_m, c.camera_height_m, 0.0, 0.0, first)
        sweep = Sweep(np.stack(images), start, str(truth), camera_angle_rad=angle)
        self._result.sweeps.append(sweep)
        self._event(f"sweep {number}")
        if sink is not None:
            sink(SweepEnd(self.robot.t_ns, number, number, sweep))

    def _scan_samples(self) -> list[tuple[float, float]]:
        """Turn once round in place: (estimated heading, front range) pairs."""
        c = self.config
        self._state = "scanning"
        samples: list[tuple[float, float]] = []
        start = self._yaw_est
        while self._yaw_est - start < 2.0 * math.pi:
            self._drive(0.0, c.turn_rate_rps, c.control_period_ns)
            samples.append((self._yaw_est, self._ranges[0]))
            if self._stalled():  # cannot turn: the watchdog ends the run later
                break
        self._turn_to(start)
        return samples

    def _recentre(self, expected: np.ndarray) -> RunStatus | None:
        """Move to the node centre found from a range scan, then face as before.

        The centre is where the largest circle fits among the wall points seen
        (a 2 mm grid within 8 cm): the junction's walls all keep the pipe radius
        from it, and openings hold no points to pull it off. Along a pipe's axis
        every point fits as wide a circle; among those ties the one nearest to
        where the approach expected the centre wins.
        """
        c = self.config
        self._state = "recentring"
        facing = self._yaw_est
        forward = self.robot.spec.tof_forward_m
        samples = self._scan_samples()
        points = wall_points(samples, self._xy_est, forward, c.scan_open_m)
        if len(points) < 8:
            return None
        target = widest_centre(points, self._xy_est, expected)
        openings = opening_headings(samples, c.scan_open_m)
        if len(openings) == 2:
            corner = axes_crossing(
                samples, forward, points, self._xy_est, target, openings, c.shallow_corner_deg
            )
            if corner is not None:
                target = corner
        move = target - self._xy_est
        distance = float(np.linalg.norm(move))
        if distance > 0.01:
            heading = math.atan2(move[1], move[0])
            self._turn_to(heading)
            status = self._straight(distance, heading)
            if status is not None:
                return status
        self._turn_to(facing)
        # Settle only where the wall ahead is square to the heading: no opening within
        # 80 degrees of it (a dead end, a right-angle corner or T), not at a Y or a
        # sharp corner, whose walls ahead stand at other distances.
        clear = math.radians(c.settle_clear_deg)
        if all(abs(math.remainder(o - facing, 2.0 * math.pi)) > clear for o in openings):
            return self._settle_on_wall_ahead()
        return None

    def _settle_on_wall_ahead(self) -> RunStatus | None:
        """With a wall straight ahead, stand where the front range puts the node centre.

        The scan cannot tell where along the arrival pipe the centre lies when that
        pipe ends in a wall: a dead end's cap, a right-angle corner's outer wall, the
        far wall of a T entered by its stem. That wall is the pipe's radius from the centre, so
        the front ranger then reads a known distance; standing there makes two visits
        of such a node sweep from the same place.
        """
        c = self.config
        spec = self.robot.spec
        self._state = "settling"
        start = len(self._result.readings)
        self._drive(0.0, 0.0, c.settle_ns)
        fronts = [
            r.ranges_m[0] for r in self._result.readings[start:] if isinstance(r, RangeReading)
        ]
        if not fronts:
            return None
        front = float(np.median(fronts))
        if front > c.scan_open_m:  # open ahead: the scan's centre stands
            return None
        error = front - (HALF_WIDTH_M - spec.tof_forward_m)
        if abs(error) < c.settle_tolerance_m:
            return None
        return self._straight(error, self._yaw_est)

    def _scan(self) -> tuple[list[float], list[float]]:
        """Turn once round in place; the headings (estimated) of the exits, twice, in
        the same order: as reported (each opening's deepest samples, the pipe's axis;
        see :func:`~pipemap.sim.scan_geometry.opening_headings`) and as steered by
        (each opening's middle, which keeps the robot clear of the mouth's walls)."""
        samples = self._scan_samples()
        c = self.config
        return (
            opening_headings(samples, c.scan_open_m, c.exit_depth_fraction),
            opening_headings(samples, c.scan_open_m),
        )

    def _travel(self, origin: np.ndarray) -> float | _Bend | RunStatus | None:
        """Follow the pipe entered at ``origin`` (as :meth:`_follow`), getting past
        what stalls the robot (:func:`sim.recovery.recover`). ``None``: every try
        stalled and the pipe is given up; the robot stands clear of the stall, facing
        along the pipe."""
        driver = _Driving(self)
        while True:
            found = self._follow()
            if not isinstance(found, _Stall):
                return found
            stall = self._xy_est.copy()
            move = stall - origin
            depth = float(np.linalg.norm(move))
            self._event(f"stall {depth:.2f} m into the pipe", warning=True)
            # Back off no nearer the junction than 12 cm: still in its pipe.
            if recover(driver, self.recovery, stall, room_m=depth - 0.12):
                continue
            return self._halt

    def _give_up(self, left: _Left, origin: np.ndarray) -> RunStatus | None:
        """Log the pipe as blocked and drive back to where the robot left the junction
        (``origin``, by odometry: it is less than a pipe away); a watchdog's status
        if one fires, or ``STUCK`` if the way back stalls too."""
        visit = left.junction.visit_id
        if self._sink is not None:
            self._sink(PipeBlocked(self.robot.t_ns, visit, left.turn_rad))
        self._event(
            f"pipe blocked: gave up the exit at {left.turn_rad:+.3f} rad of visit {visit}",
            warning=True,
        )
        move = origin - self._xy_est
        back = math.atan2(move[1], move[0])
        self._turn_to(back)
        self._state = "returning to junction"
        self._stall_ns = 0
        status = self._straight(float(np.linalg.norm(move)), back, stop_on_stall=True)
        return RunStatus.STUCK if status is None and self._stalled() else status

    def _choose_again(self, left: _Left) -> ExitChoice:
        """Back at the junction ``left`` from a blocked pipe: face as at the visit and
        ask the policy again."""
        self._turn_to(left.arrival)
        self._event(f"back at the junction of visit {left.junction.visit_id}")
        return self.policy.blocked(left.junction)

    def run(self) -> ExplorationResult:
        """Explore until the policy stops the run, or the watchdog does.

        At each junction the exits go to the sink (as :class:`NodeExits`) before the
        policy is asked, so that whatever listens (an online localizer) can decide
        where the robot is first.
        """
        c = self.config
        arrival = self._yaw_est
        expected = self._xy_est.copy()
        first = True
        returning: _Left | None = None  # from a blocked pipe, to this junction
        self._drive(0.0, 0.0, c.calibrate_ns)  # stand still: measure the gyro bias
        while True:
            if not first:
                status = self._recentre(expected)
                if status is not None:
                    self._result.status = status
                    self._event(f"watchdog: {status.value}", warning=True)
                    break
            first = False
            if returning is not None:
                junction, exits, steer = returning.junction, returning.exits, returning.steer
                arrival = returning.arrival
                choice = self._choose_again(returning)
                returning = None
            else:
                self._sweep()
                exits, steer = self._scan()
                relative = tuple(math.remainder(e - arrival, 2.0 * math.pi) for e in exits)
                x, y = (float(v) for v in self._xy_est)
                odometer = self._result.distance_m
                junction = Junction(len(self._result.sweeps), relative, x, y, odometer)
                if self._sink is not None:
                    self._sink(
                        NodeExits(self.robot.t_ns, junction.visit_id, relative, x, y, odometer)
                    )
                choice = self.policy.choose(junction)
            visit = junction.visit_id
            for note in choice.notes:
                self._event(note)
            if choice.stop is not None:
                self._result.status = choice.stop
                if choice.stop is not RunStatus.FINISHED:
                    self._event(f"stopped: {choice.stop.value}", warning=True)
                break
            back = arrival + math.pi
            reported = back if choice.exit_index is None else exits[choice.exit_index]
            heading = back if choice.exit_index is None else steer[choice.exit_index]
            turn = math.remainder(reported - arrival, 2.0 * math.pi)
            if self._sink is not None:
                self._sink(NodeDeparture(self.robot.t_ns, visit, len(exits), turn))
            origin = self._xy_est.copy()
            self._turn_to(heading)
            self._state = "leaving node"
            status = self._straight(0.2, heading)
            if status is None:
                found = self._travel(origin)
                if found is None:
                    returning = _Left(junction, exits, steer, arrival, turn)
                    status = self._give_up(returning, origin)
                    if status is None:
                        expected = origin
                        continue  # re-centre at the junction and choose again
                elif isinstance(found, RunStatus):
                    status = found
                elif isinstance(found, _Bend):
                    # Back to the bend's centre, facing the way the robot came in.
                    self._event("bend passed")
                    move = found.centre - self._xy_est
                    back = math.atan2(move[1], move[0])
                    self._turn_to(back)
                    self._state = "returning to bend"
                    status = self._straight(float(np.linalg.norm(move)), back)
                    self._turn_to(found.arrival_heading)
                    expected = found.centre
                    if status is None:
                        arrival = found.arrival_heading
                        continue
                else:
                    toward = np.array([math.cos(self._yaw_est), math.sin(self._yaw_est)])
                    expected = self._xy_est + found * toward
                    self._state = "approaching node"
                    status = self._straight(c.approach_fraction * found, self._yaw_est)
            if status is not None:
                self._result.status = status
                self._event(f"watchdog: {status.value}", warning=True)
                break
            arrival = self._yaw_est
        self._result.duration_ns = self.robot.t_ns
        if self._sink is not None:
            self._sink(TruePose(self.robot.t_ns, self.robot.pose))
        return self._result


class _Driving:
    """The explorer as :func:`sim.recovery.recover` drives it."""

    def __init__(self, explorer: Explorer) -> None:
        self._explorer = explorer
        self._state = "recovering"

    def position(self) -> np.ndarray:
        """Dead reckoning."""
        return self._explorer._xy_est.copy()

    def straight(self, distance_m: float, heading_rad: float) -> bool:
        """Drive; False on a stall or a watchdog."""
        e = self._explorer
        if abs(distance_m) < 1e-3:
            return True
        e._stall_ns = 0
        e._state = self._state
        status = e._straight(distance_m, heading_rad, stop_on_stall=True)
        if status is not None:
            e._halt = status
            return False
        return not e._stalled()

    def heading(self) -> float:
        """The gyro's heading."""
        return self._explorer._yaw_est

    def halted(self) -> bool:
        """A watchdog fired."""
        return self._explorer._halt is not None

    def follow(self, left_m: float, distance_m: float) -> bool:
        """Follow off the axis; False on a stall or a watchdog."""
        e = self._explorer
        e._stall_ns = 0
        e._state = self._state
        status = e._follow_offset(left_m, distance_m)
        if status is not None:
            e._halt = status
            return False
        return not e._stalled()

    def note(self, text: str, state: str) -> None:
        """An event; ``state`` names what follows in the controller's log."""
        self._explorer._event(text)
        self._state = state


def autonomous_run(
    world: World,
    camera: CameraSpec,
    seed: int,
    start: str | None = None,
    config: ExplorerConfig | None = None,
    sink: RecordSink | None = None,
    policy: ExitPolicy | None = None,
) -> ExplorationResult:
    """Place the robot at the start node (default the entry) and explore, choosing
    exits by ``policy`` (default the right-most-branch rule).

    It starts as if it had just arrived from its first neighbour (in counter-clockwise
    order from the smallest heading), facing away from it: the convention of
    :func:`sim.plan.right_hand_tour`, so that the two tours can be compared.

    Ground truth labels each sweep with the node within 15 cm of the camera, the
    radius the paper's own data uses for "the same junction" (for scoring only);
    the explorer itself never sees it.
    """
    network = world.network
    label = start if start is not None else network.entry
    node = network.node(label)
    heading = network.pipe_headings(label)[network.neighbours(label)[0]] + math.pi
    robot = Robot(world, PlanarPose(node.x_m, node.y_m, heading), np.random.default_rng(seed))

    def true_node(pose: PlanarPose) -> str:
        nearest = min(network.nodes, key=lambda n: math.hypot(n.x_m - pose.x_m, n.y_m - pose.y_m))
        off = math.hypot(nearest.x_m - pose.x_m, nearest.y_m - pose.y_m)
        return nearest.label if off < 0.15 else "?"

    explorer = Explorer(robot, camera, config, true_node_of=true_node, sink=sink, policy=policy)
    return explorer.run()
