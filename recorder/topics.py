"""The log format in one place: topics, their message types, the metadata records.

Topics under ``/robot`` hold what a real robot would have: its sensors, its
controller, its camera. ``/truth`` holds what only the simulator knows (true pose,
the true node of each sweep, the network) and ``/online`` the decisions of the
localizer that ran during the recording. Replay reads ``/robot`` alone.
"""

from __future__ import annotations

from typing import Any

from pipemap.recorder import schemas

__all__ = [
    "FORMAT_VERSION",
    "LIBRARY",
    "METADATA_RESULT",
    "METADATA_RUN",
    "PROFILE",
    "ROBOT_PREFIX",
    "TOPICS",
    "Topic",
]

#: Bumped whenever a topic, a message or a metadata key changes meaning. 2: the
#: exit scan of each visit (``/robot/node`` EXITS), the ports of each online
#: decision, and the ``explore`` policy in the run metadata.
FORMAT_VERSION = "2"
#: Every format this pipemap reads: format 1 logs replay as before, without ports.
READABLE_VERSIONS = ("1", "2")
#: The MCAP header's profile and library: how ``pipemap info`` tells its own logs.
PROFILE = ""
LIBRARY = "pipemap"
#: Written first: what was run (network, seed, condition, settings, versions).
METADATA_RUN = "pipemap.run"
#: Written last, when the run ends: how it ended and what it produced.
METADATA_RESULT = "pipemap.result"

ROBOT_PREFIX = "/robot/"


class Topic:
    """Topic names."""

    RANGES = "/robot/tof"
    IMU = "/robot/imu"
    WHEELS = "/robot/wheels"
    CONTROLLER = "/robot/controller"
    SWEEP = "/robot/camera/sweep"
    IMAGE = "/robot/camera/image"
    NODE = "/robot/node"
    EVENTS = "/robot/events"
    TRUE_POSE = "/truth/pose"
    TRUE_SWEEP = "/truth/sweep"
    NETWORK = "/truth/network"
    DECISION = "/online/decision"


#: Every topic with its message class, in the order channels are registered (so
#: that channel ids, and the file's bytes, never depend on what a run emits first).
TOPICS: tuple[tuple[str, Any], ...] = (
    (Topic.RANGES, schemas.Ranges),
    (Topic.IMU, schemas.Imu),
    (Topic.WHEELS, schemas.WheelEncoders),
    (Topic.CONTROLLER, schemas.ControllerState),
    (Topic.SWEEP, schemas.SweepCommand),
    (Topic.IMAGE, schemas.CompressedImage),
    (Topic.NODE, schemas.NodeEvent),
    (Topic.EVENTS, schemas.Log),
    (Topic.TRUE_POSE, schemas.FrameTransform),
    (Topic.TRUE_SWEEP, schemas.TrueSweep),
    (Topic.NETWORK, schemas.SceneUpdate),
    (Topic.DECISION, schemas.Decision),
)
