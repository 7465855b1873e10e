"""The explorer's settings, its default time limit, and what a run returns.

:class:`ExplorerConfig` holds every speed, threshold and limit of
:class:`~pipemap.sim.controller.Explorer`; :func:`default_time_limit_ns` is the
safety stop of a run whose config names none; :class:`ExplorationResult` is what a
run produced. Plain records: nothing here drives the robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pipemap.defaults import IMAGES_PER_SWEEP
from pipemap.sim.episode import Sweep, SweepTruth, check_tilt
from pipemap.sim.network import Network
from pipemap.sim.policy import RunStatus
from pipemap.sim.robot import NS_PER_S, Reading

__all__ = [
    "MIN_TIME_LIMIT_S",
    "TIME_LIMIT_S_PER_PIPE_M",
    "ExplorationResult",
    "ExplorerConfig",
    "default_time_limit_ns",
]


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
    #: An exit is reported at the mean of its opening's samples that see at least this
    #: share as far as the farthest (see
    #: :func:`~pipemap.sim.scan_geometry.opening_headings`); the robot steers by the
    #: mean of all of them.
    exit_depth_fraction: float = 0.8
    sweep_step_ns: int = 500_000_000
    images_per_sweep: int = IMAGES_PER_SWEEP
    #: Start each sweep at the multiple of 2*pi/N nearest the heading estimate.
    align_sweeps: bool = True
    #: Standing still this long at the start measures the gyro's bias.
    calibrate_ns: int = 2 * NS_PER_S
    camera_height_m: float = 0.05
    #: The robot off level: at each junction its roll and pitch are drawn within
    #: +-``tilt_rad`` (floor deposits, a pipe's curvature; seeded, from a stream of
    #: their own, so a level run is what it was), the camera sweeps from the tilted
    #: body, and the IMU reads the tilt with ``imu_tilt_noise_rad`` of noise (logged
    #: with the sweep). The drive and the range sensors stay planar. As
    #: ``SimConfig.tilt_rad`` of the placement conditions.
    tilt_rad: float = 0.0
    imu_tilt_noise_rad: float = 0.002
    #: The right-hand policy's stop (:class:`~pipemap.sim.policy.RightHandPolicy`).
    #: Nodes are at least 3 pipe diameters (0.6 m) apart, so the start is looked for
    #: within less than that.
    start_radius_m: float = 0.3
    #: Odometry drifts with distance: the start is looked for this much further per
    #: metre driven, and only at a node with as many pipes as the start has. With the
    #: gyro's bias measured, the drift measured on random trees is about 2 mm per metre.
    drift_per_m: float = 0.005
    #: Share of the estimated distance to a node centre driven before the scan that
    #: re-centres: short of it, so that a misjudged junction does not end at a wall.
    approach_fraction: float = 0.8
    #: Standing still this long to read the front range before settling on a wall.
    settle_ns: int = 500_000_000
    settle_tolerance_m: float = 0.003
    settle_clear_deg: float = 80.0
    #: A re-centring scan whose ranger passed through a wall (a reading nearer than
    #: ``touch_m`` beside one of nothing; see
    #: :func:`~pipemap.sim.scan_geometry.through_wall`) backs off ``touch_backoff_m``
    #: from that wall and scans again, at most ``touch_retries`` times.
    touch_m: float = 0.01
    touch_backoff_m: float = 0.03
    touch_retries: int = 2
    #: A corner whose pipes turn by less than this is centred where their axes cross
    #: (see :func:`~pipemap.sim.scan_geometry.axes_crossing`); a sharper one by its
    #: widest circle alone.
    shallow_corner_deg: float = 70.0
    #: A bend passed while following: the heading turned by more than ``bend_deg``
    #: over ``bend_window_m`` and held within ``bend_settle_deg`` over ``bend_settle_m``.
    bend_deg: float = 15.0
    bend_window_m: float = 0.3
    bend_settle_deg: float = 4.0
    bend_settle_m: float = 0.06
    stuck_after_ns: int = 30 * NS_PER_S
    #: Simulated time after which the run stops (``RunStatus.TIME_LIMIT``); None:
    #: :func:`default_time_limit_ns` of the world's network, which grows with it.
    time_limit_ns: int | None = None

    def __post_init__(self) -> None:
        check_tilt(self.tilt_rad, self.imu_tilt_noise_rad)


#: The shortest default time limit, and the simulated time allowed per metre of pipe
#: in the network: an exploration drives each pipe about twice and sweeps at every
#: node (``paper``: 14.3 m driven and 13 sweeps in 390 s for 7.0 m of pipe, 56 s per
#: metre), so 3.6 times that is room for the detours of a loopy network.
MIN_TIME_LIMIT_S = 3600
TIME_LIMIT_S_PER_PIPE_M = 200


def default_time_limit_ns(network: Network) -> int:
    """A run's default time limit: ``TIME_LIMIT_S_PER_PIPE_M`` per metre of pipe in
    ``network``, at least ``MIN_TIME_LIMIT_S`` (a safety stop of the simulation, not
    known to the explorer's policy)."""
    pipe_m = sum(network.length_m(p.a, p.b) for p in network.pipes)
    seconds = max(MIN_TIME_LIMIT_S, math.ceil(TIME_LIMIT_S_PER_PIPE_M * pipe_m))
    return int(seconds) * NS_PER_S


@dataclass
class ExplorationResult:
    """What a run produced: sweeps in visit order (and beside them, their truth, for
    scoring only), every sensor reading, and why it ended."""

    status: RunStatus
    sweeps: list[Sweep] = field(default_factory=list)
    sweep_truths: list[SweepTruth] = field(default_factory=list)
    readings: list[Reading] = field(default_factory=list)
    events: list[tuple[int, str]] = field(default_factory=list)
    distance_m: float = 0.0
    duration_ns: int = 0
