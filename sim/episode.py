"""Episodes in the placement conditions of the paper: junction sweeps along a tour.

The robot visits the nodes in the order of the right-most-branch rule
(:func:`sim.plan.right_hand_tour`) and sweeps its camera at each:

* ``perfect``: placed exactly at the node centre;
* ``noise``: placed about 3 cm off centre in a random direction;
* ``active``: as ``noise``, and the caller may ask for probe sweeps after small
  moves (:meth:`Visit.probe`), as the localizer's active vision does;
* ``entrance``: placed at the node entrance and driven the radius to the centre
  with odometry error (a slipping, noisy drive).

The camera turns clockwise (seen from above) by ``2*pi/N`` between images, the
convention in which the paper's rotation estimate ``I*2pi/N + P*fov/W`` equals the
heading change. In the paper a sweep starts straight ahead. pipemap's robot, by
default, starts it at the multiple of ``2*pi/N`` nearest its heading estimate
(``align_sweeps``): two visits of a node then see along the same directions
whatever pipe they arrived by, where junctions 90 degrees apart would leave
6-image sweeps half a step out of line. The start angle relative to the heading is
part of the sweep (``camera_angle_rad``), so rotations stay between headings. A
visit's sweep starts nearest the heading the robot estimates (the recorder's placed
robot: its gyro's, :meth:`Visit.take_sweep`) or, for ``pipemap sim``'s image sets,
its true heading (:attr:`Visit.sweep`).
The fully autonomous condition, driven by the sensor-based controller, is not
part of this module.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from pipemap.defaults import IMAGES_PER_SWEEP
from pipemap.errors import SimError
from pipemap.sim.network import Network
from pipemap.sim.plan import right_hand_tour
from pipemap.sim.world import CameraSpec, World

#: The seed stream of the robot's tilt (with the run's seed).
TILT_STREAM = 20

__all__ = [
    "Condition",
    "Episode",
    "Pose",
    "SimConfig",
    "Sweep",
    "SweepTruth",
    "Visit",
    "sweep_start_angle",
]


class Condition(enum.Enum):
    """How the robot is placed at each junction (the paper's experiment conditions)."""

    PERFECT = "perfect"
    NOISE = "noise"
    ACTIVE = "active"
    ENTRANCE = "entrance"
    AUTONOMOUS = "autonomous"


@dataclass(frozen=True)
class Pose:
    """Camera pose in the world: position (m) and roll, pitch, yaw (rad)."""

    x_m: float
    y_m: float
    z_m: float
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0


@dataclass(frozen=True)
class SimConfig:
    """Settings of an episode."""

    condition: Condition = Condition.PERFECT
    seed: int = 0
    camera: CameraSpec = field(default_factory=CameraSpec)
    images_per_sweep: int = IMAGES_PER_SWEEP
    camera_height_m: float = 0.05
    noise_offset_m: float = 0.03
    entrance_slip: float = 0.05
    align_sweeps: bool = True
    #: The robot off level: at each visit its roll and pitch are drawn uniformly
    #: within +-this (floor deposits, a sagging pipe); 0 stands it level.
    tilt_rad: float = 0.0
    #: Standard deviation of the IMU's roll and pitch (from gravity, at rest).
    imu_tilt_noise_rad: float = 0.002

    def __post_init__(self) -> None:
        if self.images_per_sweep < 1:
            raise SimError(f"images per sweep must be >= 1, got {self.images_per_sweep}")
        check_tilt(self.tilt_rad, self.imu_tilt_noise_rad)
        if self.noise_offset_m < 0 or self.entrance_slip < 0:
            raise SimError("noise offset and slip must be >= 0")


def check_tilt(tilt_rad: float, imu_tilt_noise_rad: float) -> None:
    """The robot off level, placed or exploring: a tilt in [0, 0.3] rad, IMU noise >= 0."""
    if not 0.0 <= tilt_rad <= 0.3:
        raise SimError(f"tilt must be in [0, 0.3] rad, got {tilt_rad}")
    if not imu_tilt_noise_rad >= 0.0:
        raise SimError(f"IMU tilt noise must be >= 0 rad, got {imu_tilt_noise_rad}")


@dataclass(frozen=True, eq=False)
class Sweep:
    """One camera sweep, as the robot has it: N RGB images (N, H, W, 3) in sweep
    order and the commanded camera angle of the first image relative to the robot's
    heading. Its ground truth travels beside it (:class:`SweepTruth`)."""

    images: np.ndarray
    probe: tuple[float, float, float] | None = None  # (yaw, forward, left) of a probe
    camera_angle_rad: float = 0.0
    #: Roll and pitch as the robot's IMU reports them (robot data, noisy).
    imu_tilt_rad: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class SweepTruth:
    """Ground truth of a sweep, for scoring only: the node it was taken at (``?``
    when none is near) and the camera's true pose at its first image."""

    node: str
    camera_pose: Pose


def sweep_start_angle(heading_estimate_rad: float, images: int, align: bool) -> float:
    """Camera angle of a sweep's first image, relative to the robot's heading.

    Aligned, it turns the first image to the multiple of ``2*pi/images`` nearest the
    heading estimate; otherwise the sweep starts straight ahead, as in the paper.
    """
    if not align:
        return 0.0
    return -math.remainder(heading_estimate_rad, 2.0 * math.pi / images)


class Visit:
    """The robot at one node: its sweep, and probe sweeps on request."""

    def __init__(self, episode: Episode, index: int, node: str, pose: Pose) -> None:
        self._episode = episode
        self.index = index
        self.node = node
        self.pose = pose
        self._sweep: tuple[Sweep, SweepTruth] | None = None

    @property
    def sweep(self) -> Sweep:
        """The sweep at the placement, started at the multiple of ``2*pi/N`` nearest
        the robot's true heading (a robot told its heading; ``pipemap sim``'s image
        sets). The same sweep every time it is asked for."""
        return self._told()[0]

    @property
    def sweep_truth(self) -> SweepTruth:
        """The truth of :attr:`sweep`."""
        return self._told()[1]

    def _told(self) -> tuple[Sweep, SweepTruth]:
        if self._sweep is None:
            self._sweep = self.take_sweep(self.pose.yaw_rad)
        return self._sweep

    def take_sweep(self, heading_estimate_rad: float) -> tuple[Sweep, SweepTruth]:
        """The sweep at the placement, started at the multiple of ``2*pi/N`` nearest
        ``heading_estimate_rad``, the robot's own estimate of its heading."""
        return self._episode._sweep(self.node, self.pose, heading_estimate_rad)

    def moved(self, yaw_rad: float, forward_m: float, left_m: float) -> Pose:
        """The pose after turning by ``yaw_rad`` and moving in the robot's own frame."""
        p = self.pose
        x = p.x_m + forward_m * math.cos(p.yaw_rad) - left_m * math.sin(p.yaw_rad)
        y = p.y_m + forward_m * math.sin(p.yaw_rad) + left_m * math.cos(p.yaw_rad)
        return Pose(x, y, p.z_m, p.roll_rad, p.pitch_rad, p.yaw_rad + yaw_rad)

    def probe(
        self,
        yaw_rad: float,
        forward_m: float,
        left_m: float,
        heading_estimate_rad: float | None = None,
    ) -> tuple[Sweep, SweepTruth]:
        """The sweep after turning by ``yaw_rad`` and moving in the robot's own frame,
        started nearest ``heading_estimate_rad`` (default: the true heading there)."""
        if self._episode.config.condition is not Condition.ACTIVE:
            raise SimError("probe moves are only made in the active condition")
        moved = self.moved(yaw_rad, forward_m, left_m)
        estimate = moved.yaw_rad if heading_estimate_rad is None else heading_estimate_rad
        sweep, truth = self._episode._sweep(self.node, moved, estimate)
        probe = (yaw_rad, forward_m, left_m)
        return dataclasses.replace(sweep, probe=probe), truth


class Episode:
    """A tour of a network in a placement condition. Iterate to get the visits."""

    def __init__(self, world: World, config: SimConfig, start: str | None = None) -> None:
        if config.condition is Condition.AUTONOMOUS:
            raise SimError("the autonomous condition needs the robot controller, not an Episode")
        self.world = world
        self.network: Network = world.network
        self.config = config
        self.tour = right_hand_tour(self.network, start)
        self._rng = np.random.default_rng(config.seed)
        # Tilts draw from their own stream: a level run's placements stay as they were.
        self._tilt_rng = np.random.default_rng([config.seed, TILT_STREAM])

    def _sweep(
        self, node: str, pose: Pose, heading_estimate_rad: float
    ) -> tuple[Sweep, SweepTruth]:
        n = self.config.images_per_sweep
        angle = sweep_start_angle(heading_estimate_rad, n, self.config.align_sweeps)
        first = pose.yaw_rad + angle
        # A hair off any ring of mesh vertices: TinyRenderer slows down 100x on one.
        eye = (pose.x_m + 1.3e-4, pose.y_m + 0.7e-4, pose.z_m)
        camera_spec = self.config.camera
        if pose.roll_rad == 0.0 and pose.pitch_rad == 0.0:
            views = [
                self.world.render(eye, first - j * 2.0 * math.pi / n, camera_spec) for j in range(n)
            ]
        else:
            views = [
                self.world.render_tilted(
                    eye,
                    pose.yaw_rad,
                    angle - j * 2.0 * math.pi / n,
                    pose.roll_rad,
                    pose.pitch_rad,
                    camera_spec,
                )
                for j in range(n)
            ]
        camera = Pose(pose.x_m, pose.y_m, pose.z_m, pose.roll_rad, pose.pitch_rad, first)
        noise = self.config.imu_tilt_noise_rad if self.config.tilt_rad > 0.0 else 0.0
        imu = (
            pose.roll_rad + float(self._tilt_rng.normal(0.0, noise)) if noise else pose.roll_rad,
            pose.pitch_rad + float(self._tilt_rng.normal(0.0, noise)) if noise else pose.pitch_rad,
        )
        sweep = Sweep(np.stack(views), camera_angle_rad=angle, imu_tilt_rad=imu)
        return sweep, SweepTruth(node, camera)

    def _arrival_heading(self, node: str, arrived_from: str | None) -> float:
        headings = self.network.pipe_headings(node)
        if not headings:
            return 0.0
        # At the start, as if just arrived along the pipe from the first neighbour (the
        # tour's and the autonomous robot's convention): the right-most exit the robot
        # finds there is then the tour's first pipe.
        came = arrived_from if arrived_from is not None else self.network.neighbours(node)[0]
        return math.remainder(headings[came] + math.pi, 2.0 * math.pi)

    def _placed(self, node: str, heading: float) -> Pose:
        n = self.network.node(node)
        x, y = n.x_m, n.y_m
        condition = self.config.condition
        if condition in (Condition.NOISE, Condition.ACTIVE):
            angle = self._rng.uniform(0.0, 2.0 * math.pi)
            offset = self.config.noise_offset_m * self._rng.uniform(0.8, 1.2)
            x, y = x + offset * math.cos(angle), y + offset * math.sin(angle)
        elif condition is Condition.ENTRANCE:
            # Start where the node's sphere meets the incoming pipe, drive the radius
            # forward by odometry: the true distance differs by slip and the heading
            # by a small drift.
            radius = self.network.diameter_m / 2.0
            travelled = radius * (1.0 + self._rng.normal(0.0, self.config.entrance_slip))
            drift = self._rng.normal(0.0, 0.03)
            x -= radius * math.cos(heading)
            y -= radius * math.sin(heading)
            x += travelled * math.cos(heading + drift)
            y += travelled * math.sin(heading + drift)
        roll = pitch = 0.0
        if self.config.tilt_rad > 0.0:
            roll, pitch = (
                float(v) for v in self._tilt_rng.uniform(-1.0, 1.0, 2) * self.config.tilt_rad
            )
        return Pose(x, y, self.config.camera_height_m, roll, pitch, heading)

    def visits(self) -> Iterator[Visit]:
        """The visits in tour order; each takes its sweep when asked."""
        for index, visit in enumerate(self.tour.visits):
            heading = self._arrival_heading(visit.node, visit.arrived_from)
            yield Visit(self, index, visit.node, self._placed(visit.node, heading))
