"""The autonomous explorer: right-most-branch exploration from the robot's own sensors.

It never reads ground truth: only the three rangers, the gyro and the encoders.

* **Follow** a pipe at constant speed, steering to balance the front-left and
  front-right ranges (which measures both offset and heading error). A node is
  detected ahead when a side ray finds an opening or the front ray a wall; the
  ranges give the distance to its centre.
* **Approach**: drive that distance by odometry, holding the heading by gyro.
* **Sweep** the camera (N images, clockwise), then **scan**: turn in place once
  round while the front ranger looks for openings. Openings, not a lookup table
  of junction types, give the exits, so junctions at any angle work.
* **Choose** the right-most exit relative to the arrival heading (turn around at a
  dead end), **turn** to it by gyro and **leave** until the node is behind.
* **Stop** when back at the start (by odometry) as many times as it has pipes: on
  a tree the right-hand rule has then covered everything. A watchdog ends a run
  whose robot touches a wall or stops making progress, with that reason.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from sim.episode import Pose, Sweep
from sim.robot import NS_PER_S, EncoderReading, ImuReading, PlanarPose, RangeReading, Reading, Robot
from sim.world import CameraSpec, World

__all__ = ["ExplorationResult", "Explorer", "ExplorerConfig", "RunStatus", "autonomous_run"]

#: Side range in a straight pipe with the robot centred (rays at 40 deg, 5 cm high).
_SIDE_NOMINAL_M = math.sqrt(0.1**2 - 0.05**2) / math.sin(math.radians(40.0))


class RunStatus(enum.Enum):
    """How an exploration ended."""

    FINISHED = "finished"
    STUCK = "stuck"
    LEFT_PIPE = "left the pipe"
    TIME_LIMIT = "time limit"


@dataclass(frozen=True)
class ExplorerConfig:
    """Speeds, thresholds and limits of the explorer."""

    speed_mps: float = 0.08
    turn_rate_rps: float = 1.2
    control_period_ns: int = 50_000_000
    steer_gain: float = 12.0
    opening_factor: float = 1.7
    wall_ahead_m: float = 0.12
    scan_open_m: float = 0.25
    sweep_step_ns: int = 500_000_000
    images_per_sweep: int = 6
    camera_height_m: float = 0.05
    start_radius_m: float = 0.5
    #: Odometry drifts with distance: the start is looked for this much further per
    #: metre driven, and only at a node with as many pipes as the start has.
    drift_per_m: float = 0.04
    #: Share of the estimated distance to a node centre driven before the scan that
    #: re-centres: short of it, so that a misjudged junction does not end at a wall.
    approach_fraction: float = 0.8
    stuck_after_ns: int = 30 * NS_PER_S
    time_limit_ns: int = 3600 * NS_PER_S


@dataclass
class ExplorationResult:
    """What a run produced: sweeps in visit order, every sensor reading, and why it ended."""

    status: RunStatus
    sweeps: list[Sweep] = field(default_factory=list)
    readings: list[Reading] = field(default_factory=list)
    events: list[tuple[int, str]] = field(default_factory=list)
    distance_m: float = 0.0
    duration_ns: int = 0


class Explorer:
    """Drives a :class:`Robot` through its world by the right-most-branch rule."""

    def __init__(
        self,
        robot: Robot,
        camera: CameraSpec,
        config: ExplorerConfig | None = None,
        true_node_of: Callable[[PlanarPose], str] | None = None,
    ) -> None:
        self.robot = robot
        self.camera = camera
        self.config = config if config is not None else ExplorerConfig()
        # Ground truth only labels the sweeps for scoring; no decision reads it.
        self._true_node_of = true_node_of
        self._yaw_est = robot.pose.yaw_rad  # the robot's own heading estimate (gyro)
        self._xy_est = np.array([robot.pose.x_m, robot.pose.y_m], dtype=np.float64)  # odometry
        self._ticks = (0, 0)
        self._ranges = robot.ranges()
        self._result = ExplorationResult(RunStatus.FINISHED)
        self._last_progress_ns = 0

    # -- low level: drive and keep the estimates ------------------------------------

    def _drive(self, v: float, w: float, duration_ns: int) -> None:
        readings = self.robot.drive(v, w, duration_ns)
        spec = self.robot.spec
        metres_per_tick = math.pi * spec.wheel_diameter_m / spec.encoder_ticks_per_rev
        for r in readings:
            if isinstance(r, ImuReading):
                self._yaw_est += r.yaw_rate_rps * spec.period_ns(spec.imu_rate_hz) / NS_PER_S
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
        self._result.readings.extend(readings)

    def _event(self, text: str) -> None:
        self._result.events.append((self.robot.t_ns, text))

    def _watchdog(self) -> RunStatus | None:
        if self.robot.in_contact():
            return RunStatus.LEFT_PIPE
        if self.robot.t_ns - self._last_progress_ns > self.config.stuck_after_ns:
            return RunStatus.STUCK
        if self.robot.t_ns > self.config.time_limit_ns:
            return RunStatus.TIME_LIMIT
        return None

    # -- behaviours -----------------------------------------------------------------

    def _node_distance_m(self) -> float | None:
        """Distance from the robot's centre to a node centre ahead, if one is in sight."""
        front, left, right = self._ranges
        spec = self.robot.spec
        half_width = _SIDE_NOMINAL_M * math.sin(math.radians(40.0))
        candidates = []
        if front < self.config.wall_ahead_m + spec.tof_forward_m:
            candidates.append(front + spec.tof_forward_m - half_width)
        if max(left, right) > self.config.opening_factor * _SIDE_NOMINAL_M:
            # The side ray meets the wall line this far ahead of the robot; the opening
            # starts a half-width before the node centre.
            ahead = spec.tof_forward_m + half_width / math.tan(math.radians(40.0))
            candidates.append(ahead + half_width)
        return min(candidates) if candidates else None

    def _follow(self) -> float | RunStatus:
        """Follow the pipe until a node is detected ahead; returns its distance."""
        c = self.config
        while True:
            distance = self._node_distance_m()
            if distance is not None:
                return distance
            _, left, right = self._ranges
            steer = c.steer_gain * (min(left, 0.3) - min(right, 0.3))
            self._drive(c.speed_mps, float(np.clip(steer, -1.0, 1.0)), c.control_period_ns)
            status = self._watchdog()
            if status is not None:
                return status

    def _straight(self, distance_m: float, heading: float) -> RunStatus | None:
        c = self.config
        travelled = 0.0
        start = self._xy_est.copy()
        while travelled < distance_m:
            error = math.remainder(heading - self._yaw_est, 2.0 * math.pi)
            step_ns = min(
                c.control_period_ns, int((distance_m - travelled) / c.speed_mps * NS_PER_S) + 1
            )
            self._drive(c.speed_mps, 4.0 * error, step_ns)
            travelled = float(np.linalg.norm(self._xy_est - start))
            status = self._watchdog()
            if status is not None:
                return status
        return None

    def _turn_to(self, heading: float) -> None:
        c = self.config
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
        pose = self.robot.pose
        images = []
        for j in range(c.images_per_sweep):
            yaw = pose.yaw_rad - j * 2.0 * math.pi / c.images_per_sweep
            eye = (pose.x_m + 1.3e-4, pose.y_m + 0.7e-4, c.camera_height_m)
            images.append(self.robot.world.render(eye, yaw, self.camera))
            self._drive(0.0, 0.0, c.sweep_step_ns)  # the camera motor turns; the robot waits
        truth = self._true_node_of(pose) if self._true_node_of is not None else ""
        start = Pose(pose.x_m, pose.y_m, c.camera_height_m, 0.0, 0.0, pose.yaw_rad)
        self._result.sweeps.append(Sweep(np.stack(images), start, str(truth)))
        self._event(f"sweep {len(self._result.sweeps)}")

    def _scan_samples(self) -> list[tuple[float, float]]:
        """Turn once round in place: (estimated heading, front range) pairs."""
        c = self.config
        samples: list[tuple[float, float]] = []
        start = self._yaw_est
        while self._yaw_est - start < 2.0 * math.pi:
            self._drive(0.0, c.turn_rate_rps, c.control_period_ns)
            samples.append((self._yaw_est, self._ranges[0]))
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
        facing = self._yaw_est
        forward = self.robot.spec.tof_forward_m
        points = np.array(
            [
                self._xy_est + (forward + r) * np.array([math.cos(y), math.sin(y)])
                for y, r in self._scan_samples()
                if r < c.scan_open_m
            ]
        )
        if len(points) < 8:
            return None
        offsets = np.arange(-0.08, 0.0801, 0.002)
        gx, gy = np.meshgrid(offsets, offsets)
        centres = self._xy_est + np.stack([gx.ravel(), gy.ravel()], 1)
        clearance = np.min(np.linalg.norm(centres[:, None, :] - points[None, :, :], axis=2), axis=1)
        widest = clearance >= clearance.max() - 0.003
        nearest = np.argmin(np.linalg.norm(centres[widest] - expected, axis=1))
        target = centres[widest][int(nearest)]
        move = target - self._xy_est
        distance = float(np.linalg.norm(move))
        if distance > 0.01:
            heading = math.atan2(move[1], move[0])
            self._turn_to(heading)
            status = self._straight(distance, heading)
            if status is not None:
                return status
        self._turn_to(facing)
        return None

    def _scan(self) -> list[float]:
        """Turn once round in place; the headings (estimated) of the openings seen."""
        c = self.config
        samples = self._scan_samples()
        yaws = np.array([y for y, _ in samples])
        is_open = np.array([r > c.scan_open_m for _, r in samples])
        if is_open.all() or not is_open.any():
            return []
        # Group circularly: start from a closed sample so no opening is split in two.
        k = int(np.argmin(is_open))
        yaws = np.concatenate([yaws[k:], yaws[:k] + 2.0 * math.pi])
        is_open = np.concatenate([is_open[k:], is_open[:k]])
        openings: list[float] = []
        run: list[float] = []
        for yaw, open_ in zip(yaws, is_open, strict=True):
            if open_:
                run.append(float(yaw))
            elif run:
                openings.append(float(np.mean(run)))
                run = []
        if run:
            openings.append(float(np.mean(run)))
        return [math.remainder(o, 2.0 * math.pi) for o in openings]

    def run(self) -> ExplorationResult:
        """Explore until back at the start after covering the network, or the watchdog."""
        c = self.config
        start_xy = self._xy_est.copy()
        returns_needed: int | None = None
        returns = 0
        arrival = self._yaw_est
        expected = self._xy_est.copy()
        first = True
        while True:
            if not first:
                status = self._recentre(expected)
                if status is not None:
                    self._result.status = status
                    self._event(f"watchdog: {status.value}")
                    break
            self._sweep()
            exits = self._scan()
            if first:
                returns_needed = max(1, len(exits))
                first = False
            elif (
                len(exits) == returns_needed
                and float(np.linalg.norm(self._xy_est - start_xy))
                < c.start_radius_m + c.drift_per_m * self._result.distance_m
            ):
                returns += 1
                if returns_needed is not None and returns >= returns_needed:
                    self._event("back at the start")
                    break
            back = arrival + math.pi
            choices = [e for e in exits if abs(math.remainder(e - back, 2.0 * math.pi)) > 0.5]
            if not choices:
                heading = back
            else:
                heading = min(choices, key=lambda e: math.remainder(e - arrival, 2.0 * math.pi))
            self._turn_to(heading)
            status = self._straight(0.2, heading)
            if status is None:
                found = self._follow()
                if isinstance(found, RunStatus):
                    status = found
                else:
                    toward = np.array([math.cos(self._yaw_est), math.sin(self._yaw_est)])
                    expected = self._xy_est + found * toward
                    status = self._straight(c.approach_fraction * found, self._yaw_est)
            if status is not None:
                self._result.status = status
                self._event(f"watchdog: {status.value}")
                break
            arrival = self._yaw_est
        self._result.duration_ns = self.robot.t_ns
        return self._result


def autonomous_run(
    world: World,
    camera: CameraSpec,
    seed: int,
    start: str | None = None,
    config: ExplorerConfig | None = None,
) -> ExplorationResult:
    """Place the robot at the start node (default the entry) and explore.

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

    return Explorer(robot, camera, config, true_node_of=true_node).run()
