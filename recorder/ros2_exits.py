"""A junction's exits worked out from raw ``sensor_msgs/msg/Range`` readings.

For ``pipemap import`` of a bag without pipemap's own exit scans (``node_topic``).
Each visit's readings of the three rangers, from its sweep's first image to
``exit_scan_s`` after its last, are placed around the junction: a reading's heading
is the robot's yaw at its stamp less the yaw at the sweep's first image (the
arrival heading), plus the ranger's mount (front 0, left ``+range_side_deg``, right
``-range_side_deg``; counter-clockwise positive, REP 103). The robot's yaw comes
from its odometry (``nav_msgs/msg/Odometry`` or ``/tf``), else from the IMU's yaw
rate integrated, else it is taken as constant: a robot that stands still while its
camera turns on its joint sees three directions, one that turns in place after
(or while) it sweeps sees them all.

The circle is cut into 36 sectors of 10 degrees; a sector whose readings mostly see
farther than ``exit_open_m`` (or nothing in range: ``+inf``, REP 117) is open, one
whose readings mostly see a wall nearer is closed, one without readings is unknown.
Each run of adjacent open sectors is one exit, at the circular mean of its open
readings' headings. The pipe the robot came by, straight back, is an exit too when
no reading looked within 45 degrees of it. ``NaN`` readings (REP 117: no valid
reading) are left out.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Any

from pipemap.recorder import schemas

__all__ = ["SECTORS", "VisitWindow", "derived_exits", "exits_from_readings"]

#: Sectors the circle round a junction is cut into.
SECTORS = 36
#: A reading within this of straight back means the scan saw the arrival pipe.
_BACK_RAD = math.radians(45.0)
_NS = 1_000_000_000


@dataclass(frozen=True)
class VisitWindow:
    """A visit's sweep: its id and its first and last image's stamps."""

    visit_id: int
    first_ns: int
    last_ns: int


def exits_from_readings(readings: list[tuple[float, float]], open_m: float) -> list[float]:
    """The exits seen by ``(heading_rad, range_m)`` readings around a junction, as
    headings in (-pi, pi] relative to the arrival heading, in increasing order."""
    width = 2.0 * math.pi / SECTORS
    votes = [[0, 0] for _ in range(SECTORS)]  # [open, closed] per sector
    opens: list[list[float]] = [[] for _ in range(SECTORS)]
    looked_back = False
    for heading, range_m in readings:
        if math.isnan(range_m):
            continue
        wrapped = heading % (2.0 * math.pi)
        k = int(wrapped // width) % SECTORS
        is_open = range_m > open_m
        votes[k][0 if is_open else 1] += 1
        if is_open:
            opens[k].append(wrapped)
        looked_back |= abs(math.remainder(heading - math.pi, 2.0 * math.pi)) < _BACK_RAD
    state = [None if o + c == 0 else o > c for o, c in votes]
    exits: list[float] = []
    runs: list[list[int]] = []
    if any(s is True for s in state) and not all(s is True for s in state):
        # Start after a sector that is not open, so that no run is split in two.
        begin = next(k for k in range(SECTORS) if state[k] is not True) + 1
        for step in range(SECTORS):
            k = (begin + step) % SECTORS
            if state[k] is True:
                if runs and runs[-1][-1] == (k - 1) % SECTORS:
                    runs[-1].append(k)
                else:
                    runs.append([k])
    for run in runs:
        headings = [h for k in run for h in opens[k]]
        mean = math.atan2(sum(math.sin(h) for h in headings), sum(math.cos(h) for h in headings))
        exits.append(math.remainder(mean, 2.0 * math.pi))
    if not looked_back:
        exits.append(math.pi)
    return sorted(exits)


class _Yaw:
    """The robot's yaw by time: from poses ``(t, yaw, x, y)`` where there are any,
    else the IMU's yaw rate ``(t, rate)`` integrated, else 0."""

    def __init__(
        self, poses: list[tuple[int, float, float, float]], rates: list[tuple[int, float]]
    ) -> None:
        self._times: list[int] = []
        self._yaws: list[float] = []
        if poses:
            for t, yaw, _, _ in sorted(poses):
                self._times.append(t)
                self._yaws.append(yaw)
        elif rates:
            total, last_t, last_rate = 0.0, None, 0.0
            for t, rate in sorted(rates):
                if last_t is not None:
                    total += 0.5 * (rate + last_rate) * (t - last_t) / _NS
                self._times.append(t)
                self._yaws.append(total)
                last_t, last_rate = t, rate

    def at(self, t_ns: int) -> float:
        if not self._times:
            return 0.0
        k = max(bisect.bisect_right(self._times, t_ns) - 1, 0)
        return self._yaws[k]


def _ranges(messages: list[tuple[int, Any]]) -> list[tuple[int, float]]:
    return sorted((t, float(m.range)) for t, m in messages)


def derived_exits(
    visits: list[VisitWindow],
    rangers: list[tuple[list[tuple[int, Any]], float]],
    poses: list[tuple[int, float, float, float]],
    rates: list[tuple[int, float]],
    open_m: float,
    scan_s: float,
) -> list[tuple[int, Any]]:
    """One pipemap ``NodeEvent`` (EXITS) per visit, at its last image's stamp.

    ``rangers``: each ranger's ``(stamp, sensor_msgs/msg/Range)`` readings and its
    mount angle; ``poses``: the dead reckoning ``(stamp, yaw, x, y)`` (may be empty);
    ``rates``: the IMU's ``(stamp, yaw rate)`` (may be empty). The event's position
    and odometer are the dead reckoning's at the sweep's first image (0 without it).
    """
    yaw = _Yaw(poses, rates)
    readings = [(_ranges(messages), mount) for messages, mount in rangers]
    track = sorted(poses)
    odometer = [0.0]
    for a, b in zip(track, track[1:], strict=False):
        odometer.append(odometer[-1] + math.hypot(b[2] - a[2], b[3] - a[3]))
    out = []
    for visit in visits:
        arrival = yaw.at(visit.first_ns)
        end_ns = visit.last_ns + int(scan_s * _NS)
        around = [
            (yaw.at(t) - arrival + mount, r)
            for ranger, mount in readings
            for t, r in ranger
            if visit.first_ns <= t <= end_ns
        ]
        event = schemas.NodeEvent(
            time_ns=visit.last_ns,
            kind=schemas.NodeEvent.EXITS,
            visit_id=visit.visit_id,
            exits_rad=exits_from_readings(around, open_m),
        )
        if track:
            k = max(bisect.bisect_right([p[0] for p in track], visit.first_ns) - 1, 0)
            event.x_estimate_m, event.y_estimate_m = track[k][2], track[k][3]
            event.odometer_m = odometer[k]
        out.append((visit.last_ns, event))
    return out
