"""What a recording is asked to do: :class:`RecordSettings`, and its log's metadata.

The settings name the network, the start, the seed, the condition and the camera;
:meth:`RecordSettings.metadata` turns them into the ``pipemap.run`` record every log
begins with (strings only, the same for the same settings).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Any

from pipemap.defaults import (
    IMAGE_FORMAT,
    IMAGES_PER_SWEEP,
    JPEG_QUALITY,
    LAMP_STRENGTHS,
    LIGHTING,
    RESOLUTION_PX,
    SEED,
)
from pipemap.errors import InputError, SimError
from pipemap.localizer import DEFAULT_THRESHOLD, ExploreConfig
from pipemap.recorder.messages import ImageEncoding
from pipemap.recorder.online import Explore
from pipemap.recorder.topics import FORMAT_VERSION
from pipemap.sim.controller import ExplorerConfig
from pipemap.sim.episode import Condition, SimConfig
from pipemap.sim.lookalike import TYPE_TOLERANCE_RAD, LookAlike, choose_looks
from pipemap.sim.motor_faults import MOTOR_FAULT_S, MotorFault, draw_motor_faults
from pipemap.sim.network import Network
from pipemap.sim.obstacles import Obstacle, place_obstacles
from pipemap.sim.recovery import RecoveryConfig
from pipemap.sim.robot import RobotSpec
from pipemap.sim.world import CameraSpec

__all__ = ["RecordSettings"]


@dataclass(frozen=True)
class RecordSettings:
    """What to run: the network, the start, the seed, the condition, the camera."""

    network: str
    start: str | None = None
    seed: int = SEED
    condition: Condition = Condition.AUTONOMOUS
    resolution_px: int = RESOLUTION_PX
    images_per_sweep: int = IMAGES_PER_SWEEP
    align_sweeps: bool = True
    threshold: float = DEFAULT_THRESHOLD
    #: How the autonomous robot chooses exits (placed tours follow the paper's rule).
    explore: Explore = Explore.MAP
    #: The robot's lamp relative to full; 0.0 lights every surface evenly.
    lamp_strength: float = LAMP_STRENGTHS[LIGHTING]
    #: The robot off level (placement conditions): see ``SimConfig.tilt_rad``.
    tilt_rad: float = 0.0
    #: Floor deposits in as many pipes, drawn from the seed (autonomous condition):
    #: see :mod:`sim.obstacles`. 0: none, and the log is as without the setting.
    obstacles: int = 0
    #: Motor cut-outs while driving, drawn from the seed (autonomous condition): see
    #: :mod:`sim.motor_faults`. 0: none, and the log is as without the setting.
    motor_faults: int = 0
    #: How the log stores the camera's images: ``png`` (lossless) or ``jpeg``.
    image_format: str = IMAGE_FORMAT
    #: The JPEG quality (1..100) with ``image_format="jpeg"``.
    jpeg_quality: int = JPEG_QUALITY
    #: The fraction of junctions that take the look of another of their type, drawn
    #: from the seed: see :mod:`sim.lookalike`. 0: every junction its own look, and
    #: the log is as without the setting.
    alike: float = 0.0
    #: The online localizer's odometry check (``LocalizerConfig.odometry_check``);
    #: off only to measure what it buys (``benchmarks/bench_explore.py``). Off, the
    #: run metadata says so; on, the log is as without the setting.
    odometry_check: bool = True
    #: The autonomous robot makes the probe moves active vision asks for. Off (to
    #: measure what they change), the run metadata says so; on, a run that asks for
    #: no probe logs as without the setting.
    probe_moves: bool = True
    #: The online localizer's live maps at most (``LocalizerConfig.hypotheses``); 1
    #: only to measure what they buy. Not 8, the run metadata says so; 8, the log is
    #: as without the setting.
    hypotheses: int = 8
    #: The world in a child process restarted when its resident memory passes this
    #: many MiB (:mod:`sim.world_process`); ``None``: the world in the recording
    #: process. Not in the log: the log is the same bytes either way.
    world_memory_mib: int | None = None
    #: The robot's odometry this many times as poor as the default robot's
    #: (:meth:`RobotSpec.drifting`), and the localizer's odometry allowance as many
    #: times as wide (:func:`localizer.odometry.drift_allowed`). 1: the robot as built,
    #: and the log is as without the setting.
    odometry_drift: float = 1.0

    def __post_init__(self) -> None:
        try:
            self.image_encoding()
        except ValueError as exc:
            raise InputError(str(exc)) from None
        if not (math.isfinite(self.alike) and 0.0 <= self.alike <= 1.0):
            raise InputError(f"--alike must be a fraction in 0..1, got {self.alike}")
        if not (math.isfinite(self.odometry_drift) and 1.0 <= self.odometry_drift <= 10.0):
            raise InputError(f"--odometry-drift must be in 1..10, got {self.odometry_drift}")
        what = (
            ("--obstacles", self.obstacles, "a deposit"),
            ("--motor-faults", self.motor_faults, "a motor cut-out"),
        )
        for flag, count, meets in what:
            if count < 0:
                raise InputError(f"{flag} must be >= 0, got {count}")
            if count and self.condition is not Condition.AUTONOMOUS:
                raise InputError(
                    f"{flag}: only the autonomous robot drives into {meets}; placed by "
                    f"hand ({self.condition.value}) it never meets one"
                )

    def deposits(self, network: Network) -> tuple[Obstacle, ...]:
        """The run's floor deposits (none by default)."""
        try:
            return place_obstacles(network, self.obstacles, self.seed)
        except SimError as error:
            raise InputError(f"--obstacles {self.obstacles}: {error}") from None

    def cut_outs(self, network: Network) -> tuple[MotorFault, ...]:
        """The run's motor cut-outs (none by default)."""
        return draw_motor_faults(network, self.motor_faults, self.seed)

    def image_encoding(self) -> ImageEncoding:
        """How the log stores the camera's images."""
        return ImageEncoding(self.image_format, self.jpeg_quality)

    def looks(self, network: Network) -> LookAlike:
        """Which junctions share a look (none by default)."""
        return choose_looks(network, self.alike, self.seed)

    def camera(self) -> CameraSpec:
        """The camera of the run."""
        return CameraSpec(resolution_px=self.resolution_px, lamp_strength=self.lamp_strength)

    def metadata(self, network: Network, version: str) -> dict[str, str]:
        """The ``pipemap.run`` metadata record: strings only, deterministic."""
        camera = self.camera()
        simulator: dict[str, Any] = {
            "robot": dataclasses.asdict(self.robot_spec()),
            "camera": dataclasses.asdict(camera),
        }
        if self.alike:
            simulator["alike"] = {
                "fraction": self.alike,
                "type_tolerance_rad": TYPE_TOLERANCE_RAD,
                "groups": self.looks(network).groups(),
            }
        if self.condition is Condition.AUTONOMOUS:
            simulator["explorer"] = dataclasses.asdict(self.explorer_config())
            # Only with deposits or cut-outs: a log without them stays as it always was.
            recovery = dataclasses.asdict(RecoveryConfig())
            if self.obstacles:
                simulator["obstacles"] = {"count": self.obstacles, "recovery": recovery}
            if self.motor_faults:
                simulator["motor_faults"] = {
                    "count": self.motor_faults,
                    "duration_s": list(MOTOR_FAULT_S),
                    "recovery": recovery,
                }
        else:
            simulator["placement"] = dataclasses.asdict(self.sim_config())
            simulator["placement"].pop("camera")
            simulator["placement"]["condition"] = self.condition.value
        extra = {} if self.odometry_check else {"odometry_check": "false"}
        if not self.probe_moves and self.condition is Condition.AUTONOMOUS:
            extra["probe_moves"] = "false"
        if self.hypotheses != 8:
            extra["hypotheses"] = str(self.hypotheses)
        if self.odometry_drift != 1.0:
            extra["odometry_drift"] = repr(self.odometry_drift)
        return {
            "format_version": FORMAT_VERSION,
            "pipemap_version": version,
            "network": self.network,
            "seed": str(self.seed),
            "condition": self.condition.value,
            "start": self.start if self.start is not None else network.entry,
            "resolution_px": str(self.resolution_px),
            "images_per_sweep": str(self.images_per_sweep),
            "fov_rad": repr(camera.fov_rad),
            "align_sweeps": "true" if self.align_sweeps else "false",
            "threshold": repr(self.threshold),
            "explore": self.explore.value
            if self.condition is Condition.AUTONOMOUS
            else Explore.RIGHT_HAND.value,
            "simulator": json.dumps(simulator, sort_keys=True, default=_json_value),
            # Only for JPEG: a PNG run's metadata stays as it always was.
            **self.image_encoding().metadata(),
            **extra,
        }

    def robot_spec(self) -> RobotSpec:
        """The robot's build: the default one, with ``odometry_drift`` its odometry's."""
        return RobotSpec().drifting(self.odometry_drift)

    def explorer_config(self) -> ExplorerConfig:
        """The autonomous robot's settings."""
        return ExplorerConfig(
            images_per_sweep=self.images_per_sweep,
            align_sweeps=self.align_sweeps,
            tilt_rad=self.tilt_rad,
        )

    def explore_config(self) -> ExploreConfig:
        """The map-driven explorer's settings: its odometry checks as wide as the
        robot's drift (``odometry_drift``), as the localizer's are."""
        return ExploreConfig().drifting(self.odometry_drift)

    def sim_config(self) -> SimConfig:
        """The placement conditions' settings."""
        return SimConfig(
            condition=self.condition,
            seed=self.seed,
            camera=self.camera(),
            images_per_sweep=self.images_per_sweep,
            align_sweeps=self.align_sweeps,
            tilt_rad=self.tilt_rad,
        )


def _json_value(value: object) -> object:
    if isinstance(value, tuple):
        return list(value)
    if hasattr(value, "value"):
        return value.value  # enums
    raise TypeError(f"not JSON: {value!r}")
