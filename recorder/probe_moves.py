"""The autonomous robot's answer to the localizer's probe requests.

:class:`RobotProbes` is the online localizer's
:class:`~pipemap.localizer.ProbeSource` in an autonomous run: each
:class:`~pipemap.localizer.ProbeRequest` becomes a move of the robot
(:class:`~pipemap.sim.probe_moves.ProbeMover`), whose probe sweep is logged as a probe
sweep of the visit, exactly as the placed ``active`` condition logs its own; a replay
answers the same requests from those sweeps. A move the robot's rangers refuse is
answered ``None`` (and a warning note in the log says why).
"""

from __future__ import annotations

from pipemap.localizer import ImageSet, ProbeRequest
from pipemap.recorder.online import gray_set
from pipemap.sim.controller import Explorer
from pipemap.sim.probe_moves import ProbeMover

__all__ = ["RobotProbes"]


class RobotProbes:
    """Probe requests made by the autonomous robot (see the module)."""

    def __init__(self, fov_rad: float) -> None:
        self.fov_rad = fov_rad
        self.mover: ProbeMover | None = None

    def attach(self, explorer: Explorer) -> None:
        """Make the moves with ``explorer``'s robot (``autonomous_run``'s hook)."""
        self.mover = ProbeMover(explorer)

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        """The probe sweep after ``request``'s move, or ``None`` if it was not made."""
        if self.mover is None:
            return None
        sweep = self.mover.probe(
            request.kind.value, request.yaw_rad, request.forward_m, request.left_m
        )
        if sweep is None:
            return None
        return gray_set(sweep.images, self.fov_rad, sweep.camera_angle_rad, sweep.imu_tilt_rad)
