"""Getting past a stall in a pipe, or giving the pipe up: the explorer's side of it.

:func:`travel` follows a pipe (:func:`sim.follow.follow`) and, on a stall, hands
the robot to :func:`sim.recovery.recover` through :class:`Driving`, the adapter
that protocol asks for. When every try stalls the pipe is given up
(:func:`give_up`: log it, drive back to the junction :class:`Left`) and the policy
is asked again (:func:`choose_again`), without a new sweep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipemap.sim.follow import Bend, Stall, follow, follow_offset
from pipemap.sim.motion import Motion
from pipemap.sim.policy import ExitChoice, ExitPolicy, Junction, RunStatus
from pipemap.sim.recovery import recover
from pipemap.sim.stream import PipeBlocked

__all__ = ["Driving", "Left", "choose_again", "give_up", "travel"]


@dataclass(frozen=True)
class Left:
    """A junction the robot left, to come back to if the pipe is blocked."""

    junction: Junction
    exits: list[float]
    steer: list[float]
    arrival: float
    turn_rad: float


class Driving:
    """The explorer's :class:`~pipemap.sim.motion.Motion` as
    :func:`sim.recovery.recover` drives it."""

    def __init__(self, motion: Motion) -> None:
        self._motion = motion
        self._state = "recovering"

    def position(self) -> np.ndarray:
        """Dead reckoning."""
        return self._motion.xy_est.copy()

    def straight(self, distance_m: float, heading_rad: float) -> bool:
        """Drive; False on a stall or a watchdog."""
        m = self._motion
        if abs(distance_m) < 1e-3:
            return True
        m.stall_ns = 0
        m.state = self._state
        status = m.straight(distance_m, heading_rad, stop_on_stall=True)
        if status is not None:
            m.halt = status
            return False
        return not m.stalled()

    def heading(self) -> float:
        """The gyro's heading."""
        return self._motion.yaw_est

    def halted(self) -> bool:
        """A watchdog fired."""
        return self._motion.halt is not None

    def follow(self, left_m: float, distance_m: float) -> bool:
        """Follow off the axis; False on a stall or a watchdog."""
        m = self._motion
        m.stall_ns = 0
        m.state = self._state
        status = follow_offset(m, left_m, distance_m)
        if status is not None:
            m.halt = status
            return False
        return not m.stalled()

    def note(self, text: str, state: str) -> None:
        """An event; ``state`` names what follows in the controller's log."""
        self._motion.event(text)
        self._state = state

    def wait(self, duration_ns: int) -> None:
        """Stand still, the motors off (the gyro's bias is measured meanwhile)."""
        wait_still(self._motion, duration_ns, self._state)


def wait_still(m: Motion, duration_ns: int, state: str) -> None:
    """Stand still for ``duration_ns``, in control periods; ``state`` for the log."""
    m.state = state
    m.stall_ns = 0
    left = duration_ns
    while left > 0:
        step = min(m.config.control_period_ns, left)
        m.drive(0.0, 0.0, step)
        left -= step


def travel(m: Motion, origin: np.ndarray) -> float | Bend | RunStatus | None:
    """Follow the pipe entered at ``origin`` (as :func:`~pipemap.sim.follow.follow`), getting past
    what stalls the robot (:func:`sim.recovery.recover`). ``None``: every try
    stalled and the pipe is given up; the robot stands clear of the stall, facing
    along the pipe."""
    driver = Driving(m)
    while True:
        found = follow(m)
        if not isinstance(found, Stall):
            return found
        stall = m.xy_est.copy()
        move = stall - origin
        depth = float(np.linalg.norm(move))
        m.event(f"stall {depth:.2f} m into the pipe", warning=True)
        # Back off no nearer the junction than 12 cm: still in its pipe.
        if recover(driver, m.recovery, stall, room_m=depth - 0.12):
            continue
        return m.halt


def give_up(m: Motion, left: Left, origin: np.ndarray) -> RunStatus | None:
    """Log the pipe as blocked and drive back to where the robot left the junction
    (``origin``, by odometry: it is less than a pipe away); a watchdog's status
    if one fires, or ``STUCK`` if the way back stalls even after waiting for the
    motors."""
    visit = left.junction.visit_id
    if m.sink is not None:
        m.sink(PipeBlocked(m.robot.t_ns, visit, left.turn_rad))
    m.event(
        f"pipe blocked: gave up the exit at {left.turn_rad:+.3f} rad of visit {visit}",
        warning=True,
    )
    move = origin - m.xy_est
    back = math.atan2(move[1], move[0])  # held all the way: the way it came
    m.turn_to(back)
    distance = float(np.linalg.norm(move))
    for waited in range(m.recovery.motor_waits + 1):
        m.state = "returning to junction"
        m.stall_ns = 0
        status = m.straight(distance, back, stop_on_stall=True)
        if status is not None or not m.stalled():
            return status
        if waited < m.recovery.motor_waits:  # nothing can be in the way it came: the motors
            m.event("stall on the way back: motors off", warning=True)
            wait_still(m, m.recovery.motor_wait_ns, "waiting")
            distance = float(np.linalg.norm(origin - m.xy_est))
    return RunStatus.STUCK


def choose_again(m: Motion, policy: ExitPolicy, left: Left) -> ExitChoice:
    """Back at the junction ``left`` from a blocked pipe: face as at the visit and
    ask ``policy`` again."""
    m.turn_to(left.arrival)
    m.event(f"back at the junction of visit {left.junction.visit_id}")
    return policy.blocked(left.junction)
