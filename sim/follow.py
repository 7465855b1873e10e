"""Following a pipe: the robot's way between nodes, from its rangers and gyro.

The follower drives at constant speed, steering to balance the front-left and
front-right ranges (:func:`steer`), until a node is in sight ahead
(:func:`node_distance_m`: a side opening or a wall), a shallow bend has been passed
(:func:`bend_passed`, from the heading alone) or the robot stalls (:data:`STALL`).
A recovery try follows off the axis (:func:`follow_offset`). The behaviours act on
a :class:`~pipemap.sim.motion.Motion`; reading the sensors (:func:`node_distance_m`,
:func:`bend_passed`) is pure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipemap.sim.explorer_config import ExplorerConfig
from pipemap.sim.motion import Motion
from pipemap.sim.policy import RunStatus
from pipemap.sim.scan_geometry import HALF_WIDTH_M, SIDE_NOMINAL_M

__all__ = [
    "STALL",
    "Bend",
    "Stall",
    "bend_passed",
    "follow",
    "follow_offset",
    "node_distance_m",
    "steer",
]


@dataclass(frozen=True)
class Bend:
    """A bend passed while following: its estimated centre and the heading before it."""

    centre: np.ndarray
    arrival_heading: float


class Stall:
    """What :func:`follow` returns when the robot stalled."""


STALL = Stall()


def follow(m: Motion) -> float | Bend | RunStatus | Stall:
    """Follow the pipe until a node is detected ahead (returns its distance), a
    bend has been passed (returns where it was) or the robot stalls."""
    c = m.config
    m.state = "following"
    track: list[tuple[float, np.ndarray, float]] = []  # (distance, position, heading)
    while True:
        distance = node_distance_m(m.ranges, m.robot.spec.tof_forward_m, m.config)
        if distance is not None:
            return distance
        m.drive(c.speed_mps, steer(m, 0.0), c.control_period_ns)
        status = m.watchdog()
        if status is not None:
            return status
        if m.stalled():
            return STALL
        track.append((m.result.distance_m, m.xy_est.copy(), m.yaw_est))
        bend = bend_passed(track, m.config)
        if bend is not None:
            return bend


def node_distance_m(
    ranges: tuple[float, float, float], tof_forward_m: float, config: ExplorerConfig
) -> float | None:
    """Distance from the robot's centre to a node centre ahead, if one is in sight in
    the ``ranges`` (front, front-left, front-right) of rangers ``tof_forward_m`` ahead
    of the centre."""
    front, left, right = ranges
    candidates = []
    if front < config.wall_ahead_m + tof_forward_m:
        candidates.append(front + tof_forward_m - HALF_WIDTH_M)
    if max(left, right) > config.opening_factor * SIDE_NOMINAL_M:
        # The side ray meets the wall line this far ahead of the robot; the opening
        # starts a half-width before the node centre.
        ahead = tof_forward_m + HALF_WIDTH_M / math.tan(math.radians(40.0))
        candidates.append(ahead + HALF_WIDTH_M)
    return min(candidates) if candidates else None


def steer(m: Motion, left_m: float) -> float:
    """The follower's turn rate: balance the front-left and front-right ranges,
    shifted to hold the robot ``left_m`` left of the axis (at that offset, facing
    along the pipe, the left range is shorter by ``2 left_m / sin 40deg``)."""
    c = m.config
    _, left, right = m.ranges
    balance = min(left, 0.3) - min(right, 0.3)
    if left_m:
        balance += 2.0 * left_m / math.sin(math.radians(40.0))
    return float(np.clip(c.steer_gain * balance, -1.0, 1.0))


def follow_offset(m: Motion, left_m: float, distance_m: float) -> RunStatus | None:
    """Follow the pipe ``left_m`` left of its axis for ``distance_m`` (a recovery
    try: nodes and bends are not looked for). Stops early on a stall."""
    c = m.config
    start = m.result.distance_m
    while m.result.distance_m - start < distance_m:
        m.drive(c.speed_mps, steer(m, left_m), c.control_period_ns)
        status = m.watchdog()
        if status is not None:
            return status
        if m.stalled():
            return None
    return None


def bend_passed(
    track: list[tuple[float, np.ndarray, float]], config: ExplorerConfig
) -> Bend | None:
    """A shallow corner passed while following, from the gyro alone: ``track`` holds
    (distance driven, position, heading) of each control step since the pipe began.

    A corner that turns the pipe by little shows no opening to the side rays and no
    wall ahead, so the follower steers through it. Its trace is in the heading: it
    differs from the heading held ``bend_window_m`` back by more than
    ``bend_deg``, and has settled again over the last ``bend_settle_m``. The
    corner's centre is where the pipe's axes before and after cross.
    """
    c = config
    now_d, now_xy, now_yaw = track[-1]
    if now_d - track[0][0] < c.bend_window_m:
        return None
    before = next(t for t in reversed(track) if now_d - t[0] >= c.bend_window_m)
    recent = next(t for t in reversed(track) if now_d - t[0] >= c.bend_settle_m)
    turned = math.remainder(now_yaw - before[2], 2.0 * math.pi)
    settled = abs(math.remainder(now_yaw - recent[2], 2.0 * math.pi))
    if abs(turned) < math.radians(c.bend_deg) or settled > math.radians(c.bend_settle_deg):
        return None
    d1 = np.array([math.cos(before[2]), math.sin(before[2])])
    d2 = np.array([math.cos(now_yaw), math.sin(now_yaw)])
    t, _ = np.linalg.solve(np.stack([d1, -d2], axis=1), now_xy - before[1])
    centre = before[1] + t * d1
    behind = float(np.dot(now_xy - centre, d2))
    if not 0.0 < behind < c.bend_window_m:
        return None
    return Bend(centre, before[2])
