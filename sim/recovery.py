"""Getting unstuck: what the explorer does when it stalls in a pipe.

A stall is commanded motion with the wheels not turning (their encoders stand
still) for :attr:`RecoveryConfig.stall_ns`: the robot has run into something it
cannot climb (a floor deposit, :mod:`sim.obstacles`, lies below its rangers, so it
is not seen coming). The robot then tries, at most :attr:`RecoveryConfig.tries`
times, each try from :attr:`RecoveryConfig.back_off_m` behind where it stalled:

1. back off, re-centre on the pipe's axis and drive on;
2. back off, and drive on :attr:`RecoveryConfig.sidestep_m` left of the axis;
3. back off, and drive on as far right of it;

where the pipe's walls say where the axis is: the robot follows the pipe as it
always does (balancing its front-left and front-right ranges, which look above
any deposit), with the balance shifted to hold the offset. Past the stall point by
:attr:`RecoveryConfig.pass_m` it is through, and the ordinary follower centres it
again. When every try stalls it gives the pipe up: the controller returns to the
junction it came from and tells its exit policy the pipe is blocked
(:meth:`~pipemap.sim.policy.ExitPolicy.blocked`). Every step is a note in the
robot's events. The watchdog stays the last resort: a robot that makes no progress
for ``stuck_after_ns`` still ends the run as ``stuck``.

The back-off is a straight drive backwards holding the heading by gyro, measured by
odometry along that heading from the stall point. When the wheels will not turn
backwards either, nothing stands in front of the robot: its drive has stalled (the
motors cut out, :mod:`sim.motor_faults`). It then switches the motors off for
:attr:`RecoveryConfig.motor_wait_ns` and backs off again, at most
:attr:`RecoveryConfig.motor_waits` times, before it counts the try as failed: a
deposit is not what stopped it, and giving the pipe up would lose a pipe it can drive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pipemap.errors import SimError
from pipemap.sim.robot import NS_PER_S

__all__ = ["Driver", "RecoveryConfig", "recover"]


@dataclass(frozen=True)
class RecoveryConfig:
    """How the explorer recognises a stall and tries to get past."""

    #: Commanded motion with the encoders standing still this long is a stall.
    stall_ns: int = 300_000_000
    #: Tries before the pipe is given up: re-centre, then each side (at most 3 kinds).
    tries: int = 3
    #: Each try starts this far behind the stall: room for the follower to settle
    #: on the try's offset before the deposit.
    back_off_m: float = 0.25
    #: The side tries hold the robot's centre this far off the axis: a passable
    #: deposit is passed 1.5 to 5.1 cm off it (``sim.obstacles``; wall contact 5.2 cm).
    sidestep_m: float = 0.03
    #: A try ends (past the deposit) this far beyond the stall.
    pass_m: float = 0.22
    #: The wheels turn neither way: the motors are off this long (a motor driver's
    #: over-current trip resets in a second or so; a hot motor takes longer) ...
    motor_wait_ns: int = 2_000_000_000
    #: ... at most this many times per back-off (0: the robot does not wait).
    motor_waits: int = 3

    def __post_init__(self) -> None:
        if not 1 <= self.tries <= 3:
            raise SimError(f"recovery tries must be 1..3, got {self.tries}")
        if self.stall_ns <= 0:
            raise SimError(f"stall time must be > 0 ns, got {self.stall_ns}")
        if self.motor_waits < 0 or self.motor_wait_ns <= 0:
            raise SimError(
                f"motor waits must be >= 0 and last > 0 ns, got {self.motor_waits} x "
                f"{self.motor_wait_ns} ns"
            )

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

    def follow(self, left_m: float, distance_m: float) -> bool:
        """Follow the pipe ``left_m`` left of its axis (by the side ranges) for
        ``distance_m``; False when it stalled (or a watchdog fired) on the way."""
        ...

    def note(self, text: str, state: str) -> None:
        """Log ``text`` as an event; ``state`` is what the robot does next."""
        ...

    def wait(self, duration_ns: int) -> None:
        """Stand still, the motors off, for ``duration_ns``."""
        ...


def _behind_m(driver: Driver, stall: np.ndarray) -> float:
    """How far ahead of ``stall`` the robot stands, along its heading."""
    h = driver.heading()
    d = driver.position() - stall
    return float(math.cos(h) * d[0] + math.sin(h) * d[1])


def _back_off(
    driver: Driver, config: RecoveryConfig, stall: np.ndarray, back_off: float
) -> tuple[bool, bool]:
    """Back off to ``back_off`` behind ``stall``; when the wheels turn backwards no more
    than forwards, wait for the motors (see the module's text). Whether it backed off,
    and whether it had to wait for the motors."""
    for waited in range(config.motor_waits + 1):
        if driver.straight(-(_behind_m(driver, stall) + back_off), driver.heading()):
            return True, waited > 0
        if driver.halted() or waited == config.motor_waits:
            return False, waited > 0
        driver.note(
            f"stall: the wheels turn backwards no more than forwards: motors off "
            f"{config.motor_wait_ns / NS_PER_S:.1f} s ({waited + 1} of {config.motor_waits})",
            "waiting",
        )
        driver.wait(config.motor_wait_ns)
        driver.note("stall: motors on again", "backing off")
    return False, True


def recover(
    driver: Driver, config: RecoveryConfig, stall: np.ndarray, room_m: float | None = None
) -> bool:
    """Try to get past what stopped the robot at ``stall``: True once past (the
    follower then centres it again) or once the motors, not the way ahead, are found
    to have stalled (it then stands behind the stall point and the follower drives
    on), False when every try stalled (the robot then stands behind the stall
    point). It backs off :attr:`~RecoveryConfig.back_off_m`, or ``room_m`` if that
    is less (it stays in the pipe, clear of the junction)."""
    back_off = config.back_off_m if room_m is None else max(0.05, min(config.back_off_m, room_m))
    sides = (0.0, config.sidestep_m, -config.sidestep_m)[: config.tries]
    names = ("on the axis", "left of the axis", "right of the axis")
    for k, side in enumerate(sides, start=1):
        if driver.halted():
            return False
        driver.note(
            f"stall: try {k} of {len(sides)}: back off "
            f"{_behind_m(driver, stall) + back_off:.2f} m, drive {names[k - 1]}",
            "backing off",
        )
        backed_off, waited = _back_off(driver, config, stall, back_off)
        if not backed_off:
            continue
        if waited:
            # The drive stalled, not the way ahead: drive on as ever (the follower
            # knows where the pipe ends; a retry's fixed run may not).
            driver.note("stall: the motors stalled, nothing ahead: driving on", "following")
            return True
        driver.note(f"stall: try {k}: retrying", "retrying")
        if not driver.follow(side, back_off + config.pass_m):
            continue
        driver.note(f"stall: past it at try {k}", "following")
        return True
    if driver.halted():
        return False
    # Back off once more, clear of the deposit, to turn round.
    driver.straight(-(_behind_m(driver, stall) + back_off), driver.heading())
    return False
