"""What a simulated run emits, record by record, as it happens.

A run calls its sink with each record in time order: sensor readings, control
steps, camera sweeps, node arrivals and departures, notes. The recorder turns
them into log messages as they come, so a run cut short keeps everything it
emitted. Records that only a simulator can know are marked ``truth`` in their
docstrings: the true pose and the true node of a sweep.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipemap.sim.episode import Sweep, SweepTruth
from pipemap.sim.robot import EncoderReading, ImuReading, PlanarPose, RangeReading

__all__ = [
    "ControlStep",
    "NodeArrival",
    "NodeDeparture",
    "NodeExits",
    "Note",
    "PipeBlocked",
    "RecordSink",
    "SimRecord",
    "SweepEnd",
    "SweepImage",
    "SweepStart",
    "TruePose",
]


@dataclass(frozen=True)
class TruePose:
    """Truth: the robot's pose on the pipe floor at ``t_ns``."""

    t_ns: int
    pose: PlanarPose


@dataclass(frozen=True)
class ControlStep:
    """A command of the controller, with the state it acts on and its own estimates."""

    t_ns: int
    state: str
    linear_mps: float
    angular_rps: float
    heading_estimate_rad: float
    x_estimate_m: float
    y_estimate_m: float


@dataclass(frozen=True)
class SweepStart:
    """A camera sweep begins: ``image_count`` images from ``camera_angle_rad``.

    ``probe`` is ``(kind, yaw_rad, forward_m, left_m)`` for an active-vision probe
    sweep, made after that move from the visit's sweep pose. ``imu_tilt_rad`` is the
    robot's (roll, pitch) as its IMU reads them (see :class:`sim.episode.Sweep`).
    """

    t_ns: int
    sweep_id: int
    visit_id: int
    image_count: int
    camera_angle_rad: float
    fov_rad: float
    probe: tuple[str, float, float, float] | None = None
    imu_tilt_rad: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True, eq=False)
class SweepImage:
    """One image of a sweep (RGB, H x W x 3), the camera at ``camera_angle_rad``
    relative to the robot's heading."""

    t_ns: int
    sweep_id: int
    visit_id: int
    index: int
    camera_angle_rad: float
    image: np.ndarray


@dataclass(frozen=True, eq=False)
class SweepEnd:
    """A sweep is complete; ``sweep`` holds its images (robot data), ``truth`` where
    it truly was (truth: for the log's ``/truth`` and scoring only)."""

    t_ns: int
    sweep_id: int
    visit_id: int
    sweep: Sweep
    truth: SweepTruth


@dataclass(frozen=True)
class NodeArrival:
    """The robot stands at a node centre, about to sweep."""

    t_ns: int
    visit_id: int


@dataclass(frozen=True)
class NodeExits:
    """The pipes the robot found at a node, after its sweep: headings relative to the
    heading it arrived with (0 straight on, positive to the left, in (-pi, pi]), and
    its dead reckoning there (position in the start's frame, distance driven)."""

    t_ns: int
    visit_id: int
    exits_rad: tuple[float, ...]
    x_m: float
    y_m: float
    odometer_m: float


@dataclass(frozen=True)
class NodeDeparture:
    """The robot leaves a node by the pipe at ``exit_rad`` from its arrival heading
    (0 straight on, positive to the left), having found ``exits`` pipes there."""

    t_ns: int
    visit_id: int
    exits: int
    exit_rad: float


@dataclass(frozen=True)
class PipeBlocked:
    """The robot gave up the pipe it last left visit ``visit_id``'s junction by (at
    ``exit_rad`` from its arrival heading there): every try to get past what stalled
    it failed. It drives back to that junction and leaves it again by another pipe
    (a new :class:`NodeDeparture` of the same visit), without a new sweep."""

    t_ns: int
    visit_id: int
    exit_rad: float


@dataclass(frozen=True)
class Note:
    """A notable event, as text (a watchdog, back at the start, a bend passed)."""

    t_ns: int
    text: str
    warning: bool = False


SimRecord = (
    RangeReading
    | ImuReading
    | EncoderReading
    | TruePose
    | ControlStep
    | SweepStart
    | SweepImage
    | SweepEnd
    | NodeArrival
    | NodeExits
    | NodeDeparture
    | PipeBlocked
    | Note
)

#: Receives every record of a run, in time order.
RecordSink = Callable[[SimRecord], None]
