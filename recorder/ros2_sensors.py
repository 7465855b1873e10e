"""ROS 2 sensor messages to pipemap's log messages, for ``pipemap import``.

Each function takes ``(stamp in ns, decoded ROS message)`` pairs of one kind and
returns ``(log time in ns, pipemap message)`` pairs. Units and frames are REP 103's
(metres, radians, x forward, y left, z up), which are pipemap's own.
"""

from __future__ import annotations

import bisect
import math
from typing import Any, cast

from google.protobuf import json_format

from pipemap.errors import InputError
from pipemap.recorder import schemas
from pipemap.recorder.messages import timestamp

__all__ = [
    "Latest",
    "controller_states",
    "events",
    "imu_messages",
    "node_events",
    "range_messages",
    "yaw_of",
]

Stamped = list[tuple[int, Any]]


def yaw_of(q: Any) -> float:
    """The yaw (about z) of a quaternion with fields x, y, z, w."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class Latest:
    """Readings looked up by time: the one at or before a time (``None`` before the
    first)."""

    def __init__(self, readings: Stamped) -> None:
        ordered = sorted(readings, key=lambda p: p[0])
        self._times = [t for t, _ in ordered]
        self._values = [v for _, v in ordered]

    def at(self, t_ns: int) -> Any | None:
        k = bisect.bisect_right(self._times, t_ns) - 1
        return self._values[k] if k >= 0 else None

    def at_or_first(self, t_ns: int) -> Any:
        """The reading at or before ``t_ns``, or the first one for an earlier time."""
        found = self.at(t_ns)
        return self._values[0] if found is None else found


def range_messages(front: Stamped, left: Stamped, right: Stamped) -> list[tuple[int, Any]]:
    """One ``Ranges`` per front reading, with the left and right readings at or before
    it (the front's maximum range where there is none yet)."""
    lefts, rights = Latest(left), Latest(right)
    out = []
    for t_ns, reading in sorted(front, key=lambda p: p[0]):
        most = float(reading.max_range)
        side = [lefts.at(t_ns), rights.at(t_ns)]
        out.append(
            (
                t_ns,
                schemas.Ranges(
                    time_ns=t_ns,
                    front_m=float(reading.range),
                    front_left_m=most if side[0] is None else float(side[0].range),
                    front_right_m=most if side[1] is None else float(side[1].range),
                    max_range_m=most,
                ),
            )
        )
    return out


def imu_messages(readings: Stamped) -> list[tuple[int, Any]]:
    """pipemap's ``Imu``: the yaw rate and the forward and left accelerations."""
    return [
        (
            t_ns,
            schemas.Imu(
                time_ns=t_ns,
                yaw_rate_rps=float(m.angular_velocity.z),
                accel_forward_mps2=float(m.linear_acceleration.x),
                accel_left_mps2=float(m.linear_acceleration.y),
            ),
        )
        for t_ns, m in sorted(readings, key=lambda p: p[0])
    ]


def controller_states(
    odometry: Stamped, tf: Stamped, odom_frame: str, base_frame: str
) -> list[tuple[int, Any]]:
    """The dead-reckoned pose as pipemap's ``ControllerState`` (state ``odometry``):
    from ``nav_msgs/msg/Odometry`` where the bag has it, else from the
    ``odom_frame`` -> ``base_frame`` transforms of ``/tf``."""
    out = []
    for t_ns, m in sorted(odometry, key=lambda p: p[0]):
        pose = m.pose.pose
        out.append(
            (
                t_ns,
                schemas.ControllerState(
                    time_ns=t_ns,
                    state="odometry",
                    linear_mps=float(m.twist.twist.linear.x),
                    angular_rps=float(m.twist.twist.angular.z),
                    heading_estimate_rad=yaw_of(pose.orientation),
                    x_estimate_m=float(pose.position.x),
                    y_estimate_m=float(pose.position.y),
                ),
            )
        )
    if out:
        return out
    for received_ns, m in sorted(tf, key=lambda p: p[0]):
        for tr in m.transforms:
            if tr.header.frame_id != odom_frame or tr.child_frame_id != base_frame:
                continue
            stamp = tr.header.stamp
            t_ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec) or received_ns
            out.append(
                (
                    t_ns,
                    schemas.ControllerState(
                        time_ns=t_ns,
                        state="odometry",
                        heading_estimate_rad=yaw_of(tr.transform.rotation),
                        x_estimate_m=float(tr.transform.translation.x),
                        y_estimate_m=float(tr.transform.translation.y),
                    ),
                )
            )
    return out


def node_events(messages: Stamped, topic: str) -> list[tuple[int, Any]]:
    """pipemap's ``NodeEvent`` messages, each the JSON text of a ``std_msgs/msg/String``."""
    out = []
    for t_ns, m in messages:
        event = schemas.NodeEvent()
        try:
            json_format.Parse(m.data, event, ignore_unknown_fields=True)
        except json_format.ParseError as exc:
            raise InputError(
                f"{topic}: message at {t_ns / 1e9:.3f} s is not a node event ({exc})"
            ) from None
        event.time_ns = event.time_ns or t_ns
        out.append((t_ns, event))
    return out


#: rcl_interfaces/msg/Log levels to Foxglove's Log levels.
_LEVELS = {10: 1, 20: 2, 30: 3, 40: 4, 50: 5}


def events(messages: Stamped) -> list[tuple[int, Any]]:
    """``/rosout`` lines as Foxglove ``Log`` messages (``pipemap.blocked`` among them)."""
    out = []
    for received_ns, m in messages:
        t_ns = int(m.stamp.sec) * 1_000_000_000 + int(m.stamp.nanosec) or received_ns
        out.append(
            (
                t_ns,
                schemas.Log(
                    timestamp=timestamp(t_ns),
                    level=cast(Any, _LEVELS.get(int(m.level), 0)),
                    message=m.msg,
                    name=m.name,
                ),
            )
        )
    return out
