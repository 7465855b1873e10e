"""Getting unstuck: what the explorer does when it stalls in a pipe.

A stall is commanded motion with the wheels not turning (their encoders stand
still) for :attr:`RecoveryConfig.stall_ns`: the robot has run into something it
cannot climb (a floor deposit, :mod:`sim.obstacles`, lies below its rangers, so it
is not seen coming). The robot then tries, at most :attr:`RecoveryConfig.tries`
times, each try from :attr:`RecoveryConfig.back_off_m` behind where it first
stalled:

1. back off, re-centre on the pipe's axis (by odometry) and drive on;
2. back off, side-step to the left of the axis, and drive past;
3. back off, side-step to the right, and drive past;

and drives back onto the axis once past. When every try stalls it gives the pipe
up: the controller returns to the junction it came from and tells its exit policy
the pipe is blocked (:meth:`~pipemap.sim.policy.ExitPolicy.blocked`). Every step is
a note in the robot's events. The watchdog stays the last resort: a robot that
makes no progress for ``stuck_after_ns`` still ends the run as ``stuck``.

The pipe's axis is the line through where the robot first stalled along the mean
heading the follower held just before (it balances the side ranges, so it swings
about the axis); offsets from it are by odometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pipemap.errors import SimError
from pipemap.sim.robot import NS_PER_S

__all__ = ["Driver", "RecoveryConfig", "axis_offsets", "recover"]


@dataclass(frozen=True)
class RecoveryConfig:
    """How the explorer recognises a stall and tries to get past."""

    #: Commanded motion with the encoders standing still this long is a stall.
    stall_ns: int = 300_000_000
    #: Tries before the pipe is given up: re-centre, then each side (at most 3 kinds).
    tries: int = 3
    #: Each try starts this far behind the first stall, along the axis.
    back_off_m: float = 0.2
    #: A side-step puts the robot's centre this far off the axis: a passable deposit
    #: is passed 1.5 to 5.1 cm off the axis (``sim.obstacles``; wall contact at 5.2 cm).
    sidestep_m: float = 0.03
    #: Heading off the axis while side-stepping.
    sidestep_deg: float = 35.0
    #: A try ends (past the deposit) this far beyond the first stall, along the axis.
    pass_m: float = 0.22

    def __post_init__(self) -> None:
        if not 1 <= self.tries <= 3:
            raise SimError(f"recovery tries must be 1..3, got {self.tries}")
        if self.stall_ns <= 0:
            raise SimError(f"stall time must be > 0 ns, got {self.stall_ns}")

    @property
    def stall_s(self) -> float:
        """:attr:`stall_ns` in seconds."""
        return self.stall_ns / NS_PER_S


class Driver(Protocol):
    """What :func:`recover` needs of the explorer."""

    def position(self) -> np.ndarray:
        """The robot's dead-reckoned position (x, y)."""
        ...

    def straight(self, distance_m: float, heading_rad: float) -> bool:
        """Drive ``distance_m`` (backwards if negative) holding ``heading_rad``; False
        when it stalled (or a watchdog fired) on the way."""
        ...

    def heading(self) -> float:
        """The robot's heading estimate."""
        ...

    def halted(self) -> bool:
        """A watchdog has ended the run: stop trying."""
        ...

    def turn_to(self, heading_rad: float) -> None:
        """Turn in place to ``heading_rad``."""
        ...

    def note(self, text: str, state: str) -> None:
        """Log ``text`` as an event; ``state`` is what the robot does next."""
        ...


def axis_offsets(
    position: np.ndarray, stall_xy: np.ndarray, axis_rad: float
) -> tuple[float, float]:
    """``position`` along the axis from the stall point and to the left of the axis."""
    d = position - stall_xy
    along = math.cos(axis_rad) * d[0] + math.sin(axis_rad) * d[1]
    left = -math.sin(axis_rad) * d[0] + math.cos(axis_rad) * d[1]
    return float(along), float(left)


def _shift(
    driver: Driver, config: RecoveryConfig, stall: np.ndarray, axis: float, to_m: float
) -> bool:
    """Side-step to ``to_m`` left of the axis (by odometry), then face along it."""
    _, left = axis_offsets(driver.position(), stall, axis)
    delta = to_m - left
    if abs(delta) > 0.005:
        step = math.radians(config.sidestep_deg)
        heading = axis + math.copysign(step, delta)
        driver.turn_to(heading)
        if not driver.straight(abs(delta) / math.sin(step), heading):
            return False
    driver.turn_to(axis)
    return True


def recover(driver: Driver, config: RecoveryConfig, stall: np.ndarray, axis: float) -> bool:
    """Try to get past what stopped the robot at ``stall`` (heading ``axis``): True
    once past (back on the axis, facing along it), False when every try stalled (the
    robot then stands :attr:`~RecoveryConfig.back_off_m` behind the stall point)."""
    sides = (0.0, config.sidestep_m, -config.sidestep_m)[: config.tries]
    names = ("on the axis", "left of the axis", "right of the axis")
    for k, side in enumerate(sides, start=1):
        if driver.halted():
            return False
        along, _ = axis_offsets(driver.position(), stall, axis)
        driver.note(
            f"stall: try {k} of {len(sides)}: back off {along + config.back_off_m:.2f} m, "
            f"drive {names[k - 1]}",
            "backing off",
        )
        # Straight back as it stands first: turning in place against the deposit
        # would only stall again.
        if not driver.straight(-(along + config.back_off_m), driver.heading()):
            continue
        if not _shift(driver, config, stall, axis, side):
            continue
        along, _ = axis_offsets(driver.position(), stall, axis)
        driver.note(f"stall: try {k}: retrying", "retrying")
        if not driver.straight(config.pass_m - along, axis):
            continue
        if not _shift(driver, config, stall, axis, 0.0):
            continue
        driver.note(f"stall: past it at try {k}", "following")
        return True
    if driver.halted():
        return False
    # Back off once more, clear of the deposit, to turn round.
    along, _ = axis_offsets(driver.position(), stall, axis)
    driver.straight(-(along + config.back_off_m), axis)
    return False
