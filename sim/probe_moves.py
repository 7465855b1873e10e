"""Active-vision probe moves of the autonomous robot (the paper's Algorithm 3).

When a junction's sweep matches no known junction well enough, the localizer asks for
probe sweeps after small moves relative to the pose of the visit's sweep: a turn in
place by the estimated relative angle, then 3 cm forward, back, left and right.
:class:`ProbeMover` makes them with the explorer's own motion and sensors, between
the exit scan and the choice of exit (the localizer decides then):

* **Turn** in place to the sweep's heading plus the move's turn (gyro).
* **Translate** by turning to face the move's direction, reading the front ranger
  standing still, and driving only if the wall ahead is farther than the move plus
  :attr:`ProbeMoveConfig.clearance_m` (and every front ray clear by that much); while
  it drives, a front reading that no longer leaves that clearance stops it. Then it
  turns back to the sweep's heading.
* **Sweep** the camera there, logged as a probe sweep of the visit
  (:func:`~pipemap.sim.junction_actions.take_sweep`), and **return** to where it swept
  (by its dead reckoning) and to the sweep's heading, so the next move starts from
  the same pose and the explorer goes on as if it had not moved.

A move refused before it starts, or stopped short, gives no sweep: the robot says so
in its log (a warning note) and the localizer goes on without that probe. Every
decision here reads the robot's estimates and rangers only, never the simulator's
truth; the probe sweep's true node labels it for scoring, as every sweep's does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipemap.sim.controller import Explorer
from pipemap.sim.episode import Sweep
from pipemap.sim.junction_actions import take_sweep
from pipemap.sim.motion import Motion
from pipemap.sim.robot import NS_PER_S

__all__ = ["REFUSED_NOTE", "ProbeMoveConfig", "ProbeMover"]

#: The warning a refused probe move leaves in the run's events (``/robot/events``);
#: a replay reads it back (:func:`pipemap.recorder.messages.refused_probe`) to tell
#: a move the robot refused from a probe sweep missing from the log.
REFUSED_NOTE = "probe {kind} of visit {visit} not made: {why}"


@dataclass(frozen=True)
class ProbeMoveConfig:
    """How carefully the robot makes a probe move."""

    #: What the front ranger must read beyond the move's length before and while it
    #: drives (the ranger sits at the body's front, so this is the body's margin).
    clearance_m: float = 0.03
    #: The front-left and front-right rays must read at least this much at the start.
    side_clearance_m: float = 0.03
    #: A translation shorter than this is none (the robot only turns).
    min_move_m: float = 1e-4
    #: Back at the sweep's place within this (dead reckoning), it does not drive.
    return_tolerance_m: float = 0.002


class ProbeMover:
    """Probe moves with ``explorer``'s robot, at the junction of its latest sweep."""

    def __init__(self, explorer: Explorer, config: ProbeMoveConfig | None = None) -> None:
        self.explorer = explorer
        self.config = config if config is not None else ProbeMoveConfig()
        self.made = 0
        self.refused = 0

    @property
    def motion(self) -> Motion:
        """The explorer's motion: its estimates, its sensors, the log."""
        return self.explorer.motion

    def probe(self, kind: str, yaw_rad: float, forward_m: float, left_m: float) -> Sweep | None:
        """Make the move ``(yaw_rad, forward_m, left_m)`` from the pose of the visit's
        sweep, sweep there as probe ``kind`` of the visit, return to that pose; the
        sweep, or ``None`` when the move was refused or stopped short."""
        m = self.motion
        x = self.explorer
        visit = len(m.result.sweeps)
        origin = m.xy_est.copy()
        heading = x.sweep_heading
        distance = math.hypot(forward_m, left_m)
        taken: Sweep | None = None
        if distance >= self.config.min_move_m:
            direction = heading + math.atan2(left_m, forward_m)
            why = self._translate(direction, distance)
            if why is not None:
                m.event(REFUSED_NOTE.format(kind=kind, visit=visit, why=why), warning=True)
                self.refused += 1
                self._return(origin, heading)
                return None
        m.turn_to(heading + yaw_rad)
        m.drive(0.0, 0.0, m.config.control_period_ns)  # settle before the camera turns
        probe = (kind, yaw_rad, forward_m, left_m)
        taken = take_sweep(m, x.camera, x.true_node_of, visit, probe, *x.junction_tilt)
        self.made += 1
        self._return(origin, heading)
        return taken

    def _translate(self, direction: float, distance: float) -> str | None:
        """Face ``direction`` and drive ``distance`` if the rangers allow; why not, if
        they do not (the robot may then have moved part of the way)."""
        m = self.motion
        c = m.config
        m.turn_to(direction)
        m.drive(0.0, 0.0, c.control_period_ns)  # a fresh range reading, standing still
        front, left, right = m.ranges
        need = distance + self.config.clearance_m
        if front < need:
            return f"the wall {front:.3f} m ahead leaves less than {need:.3f} m"
        side = min(left, right)
        if side < self.config.side_clearance_m:
            return f"a wall {side:.3f} m off a front ray"
        start = m.xy_est.copy()
        m.state = "probe move"
        travelled = 0.0
        while travelled < distance:
            remaining = distance - travelled
            if m.ranges[0] < remaining + self.config.clearance_m:
                return f"stopped after {travelled:.3f} m: the wall {m.ranges[0]:.3f} m ahead"
            step_ns = min(c.control_period_ns, int(remaining / c.speed_mps * NS_PER_S) + 1)
            error = math.remainder(direction - m.yaw_est, 2.0 * math.pi)
            m.drive(c.speed_mps, 4.0 * error, step_ns)
            travelled = float(np.linalg.norm(m.xy_est - start))
            if m.stalled():
                return f"stopped after {travelled:.3f} m: the wheels stalled"
        return None

    def _return(self, origin: np.ndarray, heading: float) -> None:
        """Back to ``origin`` (dead reckoning) and the sweep's ``heading``."""
        m = self.motion
        move = origin - m.xy_est
        distance = float(np.linalg.norm(move))
        if distance > self.config.return_tolerance_m:
            back = math.atan2(move[1], move[0])
            m.turn_to(back)
            m.state = "probe return"
            m.straight(distance, back, stop_on_stall=True)
        m.turn_to(heading)
