"""Getting unstuck, on a robot of a few lines (no PyBullet): a pipe along +x, a
deposit 1 m in, a robot that stops where its footprint would enter it and whose
follower closes on its lateral target at 20 degrees."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from pipemap.errors import SimError
from pipemap.sim.obstacles import Obstacle, ObstacleKind, footprint_hits
from pipemap.sim.recovery import RecoveryConfig, recover


def _deposit(kind: ObstacleKind, right: float, left: float) -> Obstacle:
    return Obstacle("A", "B", kind, 1.0, right, left, (1.0, (left + right) / 2), 0.0)


PASSABLE_LEFT = _deposit(ObstacleKind.PASSABLE, 0.02, 0.1)
PASSABLE_RIGHT = _deposit(ObstacleKind.PASSABLE, -0.1, -0.02)
BLOCKING = _deposit(ObstacleKind.BLOCKING, -0.1, 0.1)


@dataclass
class Corridor:
    """A perfect robot: it drives exactly, and stops short of a deposit."""

    deposits: tuple[Obstacle, ...]
    xy: np.ndarray = field(default_factory=lambda: np.array([0.5, 0.0]))
    yaw: float = 0.0
    drives: int = 0
    notes: list[str] = field(default_factory=list)
    halt_after: int | None = None
    #: The motors are cut out for this long (seconds) from the first stall on: no
    #: drive moves the robot until :meth:`wait` has stood out the rest.
    cut_out_s: float = 0.0
    waited_s: float = 0.0

    def _motors_off(self) -> bool:
        return self.waited_s < self.cut_out_s and self.drives > 1

    def position(self) -> np.ndarray:
        return self.xy.copy()

    def straight(self, distance_m: float, heading_rad: float) -> bool:
        self.drives += 1
        self.yaw = heading_rad
        if self._motors_off():
            return False
        step = math.copysign(0.002, distance_m)
        direction = np.array([math.cos(heading_rad), math.sin(heading_rad)])
        for _ in range(int(abs(distance_m) / 0.002)):
            nxt = self.xy + step * direction
            if footprint_hits(nxt[0], nxt[1], heading_rad, 0.12, 0.07, self.deposits):
                return False
            if abs(nxt[1]) > 0.0516:
                raise AssertionError(f"touched the wall at {nxt}")
            self.xy = nxt
        return True

    def heading(self) -> float:
        return self.yaw

    def halted(self) -> bool:
        return self.halt_after is not None and self.drives >= self.halt_after

    def follow(self, left_m: float, distance_m: float) -> bool:
        self.drives += 1
        self.yaw = 0.0
        if self._motors_off():
            return False
        for _ in range(int(distance_m / 0.002)):
            dy = float(np.clip(left_m - self.xy[1], -0.002 * 0.36, 0.002 * 0.36))
            nxt = self.xy + np.array([0.002, dy])
            if footprint_hits(nxt[0], nxt[1], 0.0, 0.12, 0.07, self.deposits):
                return False
            self.xy = nxt
        return True

    def note(self, text: str, state: str) -> None:
        self.notes.append(text)

    def wait(self, duration_ns: int) -> None:
        self.waited_s += duration_ns / 1e9


def _stalled(corridor: Corridor) -> np.ndarray:
    """Drive along the axis until stopped: the stall point."""
    assert not corridor.straight(2.0, 0.0)
    return corridor.position()


@pytest.mark.parametrize(
    ("deposit", "passed_at"), [(PASSABLE_LEFT, "try 3"), (PASSABLE_RIGHT, "try 2")]
)
def test_a_passable_deposit_is_passed_on_its_free_side(deposit: Obstacle, passed_at: str) -> None:
    robot = Corridor((deposit,))
    stall = _stalled(robot)
    assert recover(robot, RecoveryConfig(), stall)
    assert f"stall: past it at {passed_at}" in robot.notes
    assert robot.position()[0] - stall[0] >= RecoveryConfig().pass_m - 0.01
    assert robot.position()[0] > 1.04 + 0.06  # its tail is past the deposit


def test_a_blocking_deposit_is_given_up_after_every_try_clear_of_it() -> None:
    robot = Corridor((BLOCKING,))
    stall = _stalled(robot)
    assert not recover(robot, RecoveryConfig(), stall)
    assert [n for n in robot.notes if "back off" in n] == [
        "stall: try 1 of 3: back off 0.25 m, drive on the axis",
        "stall: try 2 of 3: back off 0.25 m, drive left of the axis",
        "stall: try 3 of 3: back off 0.25 m, drive right of the axis",
    ]
    assert robot.position()[0] - stall[0] == pytest.approx(-0.25, abs=0.01)  # room to turn
    assert robot.drives == 1 + 3 * 2 + 1  # the stall, two moves a try, the last back-off


def test_fewer_tries_give_up_sooner() -> None:
    robot = Corridor((PASSABLE_LEFT,))  # passed only by the third try
    assert not recover(robot, RecoveryConfig(tries=2), _stalled(robot))
    assert sum("back off" in n for n in robot.notes) == 2


def test_a_watchdog_stops_the_tries() -> None:
    robot = Corridor((BLOCKING,))
    stall = _stalled(robot)
    robot.halt_after = robot.drives + 1
    assert not recover(robot, RecoveryConfig(), stall)
    assert sum("back off" in n for n in robot.notes) == 1


@pytest.mark.parametrize("tries", [0, 4])
def test_the_number_of_tries_is_bounded(tries: int) -> None:
    with pytest.raises(SimError, match="tries"):
        RecoveryConfig(tries=tries)


def test_a_stall_that_will_not_back_off_waits_for_the_motors_and_follows_on() -> None:
    # Nothing in the pipe: the motors cut out at the first stall for 3 s.
    robot = Corridor((), cut_out_s=3.0)
    robot.drives = 1  # the drive that stalled
    stall = robot.position()
    assert recover(robot, RecoveryConfig(), stall)
    waits = [n for n in robot.notes if "motors off" in n]
    assert waits == [
        "stall: the wheels turn backwards no more than forwards: motors off 2.0 s (1 of 3)",
        "stall: the wheels turn backwards no more than forwards: motors off 2.0 s (2 of 3)",
    ]
    assert robot.waited_s == 4.0
    # No retry's fixed run: the follower drives on (it knows where the pipe ends).
    assert robot.notes[-1] == "stall: the motors stalled, nothing ahead: driving on"
    assert not any("retrying" in n for n in robot.notes)
    assert robot.position()[0] == pytest.approx(stall[0] - 0.25, abs=0.01)


def test_without_waiting_a_motor_cut_out_costs_the_pipe() -> None:
    robot = Corridor((), cut_out_s=3.0)
    robot.drives = 1
    assert not recover(robot, RecoveryConfig(motor_waits=0), robot.position())
    assert robot.waited_s == 0.0 and not any("motors off" in n for n in robot.notes)


def test_a_deposit_is_not_waited_for() -> None:
    # Backing off from a deposit works: the motors are fine, nothing to wait for.
    robot = Corridor((BLOCKING,))
    assert not recover(robot, RecoveryConfig(), _stalled(robot))
    assert robot.waited_s == 0.0


def test_motor_waits_are_checked() -> None:
    with pytest.raises(SimError, match="motor waits"):
        RecoveryConfig(motor_waits=-1)
    with pytest.raises(SimError, match="motor waits"):
        RecoveryConfig(motor_wait_ns=0)
