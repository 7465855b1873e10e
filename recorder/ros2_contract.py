"""What ``pipemap import`` reads from a ROS 2 bag, and what ``pipemap export --ros2``
writes: topic names, message types, and the settings a SPEC file overrides.

The defaults follow ROS 2's conventions (REP 103 units and frames, REP 105 frame
names): the camera on ``/camera/image/compressed``, its yaw relative to the robot as
the ``camera_yaw`` joint of ``/joint_states``, ranges as ``sensor_msgs/msg/Range``.
Three topics are pipemap's own, as ``std_msgs/msg/String`` JSON: ``/pipemap/sweep``
(each sweep's start and end: pipemap's ``SweepCommand``), ``/pipemap/node`` (each
visit's ``NodeEvent``) and ``/pipemap/run`` (the run's settings); the export writes
them so that a bag replays to the map of the log it came from, and the import uses
them where a bag has them. docs/ros2.md is the manual of this contract.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from pipemap.errors import InputError

__all__ = [
    "BagSpec",
    "FRAME_BASE",
    "FRAME_CAMERA",
    "FRAME_MAP",
    "FRAME_ODOM",
    "FRAME_TRUTH",
    "IMAGE_TYPES",
    "MsgType",
    "load_spec",
]

#: REP 105 frame names; the true pose is a frame of its own beside the robot's.
FRAME_MAP = "map"
FRAME_ODOM = "odom"
FRAME_BASE = "base_link"
FRAME_TRUTH = "base_link_truth"
FRAME_CAMERA = "camera_link"


class MsgType:
    """ROS 2 message type names."""

    COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
    IMAGE = "sensor_msgs/msg/Image"
    JOINT_STATE = "sensor_msgs/msg/JointState"
    IMU = "sensor_msgs/msg/Imu"
    RANGE = "sensor_msgs/msg/Range"
    ODOMETRY = "nav_msgs/msg/Odometry"
    TF = "tf2_msgs/msg/TFMessage"
    STRING = "std_msgs/msg/String"
    LOG = "rcl_interfaces/msg/Log"


#: The image message types the camera topic may carry.
IMAGE_TYPES = (MsgType.COMPRESSED_IMAGE, MsgType.IMAGE)
#: Raw image encodings read (``sensor_msgs/msg/Image``).
RAW_ENCODINGS = ("mono8", "rgb8", "bgr8")


@dataclass(frozen=True)
class BagSpec:
    """Which topics of a bag are read, and how. Every field has a default; a SPEC
    file (TOML, the same key names) overrides any of them. An optional topic that a
    bag does not have is not used; one that it has with another type is refused."""

    #: The camera: ``sensor_msgs/msg/CompressedImage`` (jpeg, png) or ``Image``.
    images_topic: str = "/camera/image/compressed"
    #: ``sensor_msgs/msg/JointState`` with the camera's yaw relative to the robot.
    joint_states_topic: str = "/joint_states"
    camera_joint: str = "camera_yaw"
    #: The camera's horizontal field of view.
    fov_deg: float = 80.0
    #: A gap between two images longer than this starts a new sweep.
    sweep_gap_s: float = 3.0
    #: Sweep markers (used where present; "" for sweeps by gaps alone).
    sweep_topic: str = "/pipemap/sweep"
    # Optional, used where present.
    imu_topic: str = "/imu"
    range_front_topic: str = "/range/front"
    range_left_topic: str = "/range/left"
    range_right_topic: str = "/range/right"
    odometry_topic: str = "/odom"
    tf_topic: str = "/tf"
    node_topic: str = "/pipemap/node"
    run_topic: str = "/pipemap/run"
    rosout_topic: str = "/rosout"
    # Exits from the rangers, for a bag without exit scans on node_topic.
    #: A range reading beyond this sees an opening (a pipe), nearer a wall.
    exit_open_m: float = 0.25
    #: Readings from a sweep's first image to this long after its last are its scan.
    exit_scan_s: float = 2.0
    #: The left ranger looks this far left of the front one, the right one as far right.
    range_side_deg: float = 90.0

    def optional_topics(self) -> dict[str, str]:
        """Each optional topic and the type it must carry ("" topics left out)."""
        topics = {
            self.sweep_topic: MsgType.STRING,
            self.imu_topic: MsgType.IMU,
            self.range_front_topic: MsgType.RANGE,
            self.range_left_topic: MsgType.RANGE,
            self.range_right_topic: MsgType.RANGE,
            self.odometry_topic: MsgType.ODOMETRY,
            self.tf_topic: MsgType.TF,
            self.node_topic: MsgType.STRING,
            self.run_topic: MsgType.STRING,
            self.rosout_topic: MsgType.LOG,
        }
        return {topic: kind for topic, kind in topics.items() if topic}

    @property
    def fov_rad(self) -> float:
        """The field of view in radians."""
        return math.radians(self.fov_deg)


def load_spec(path: str | Path | None) -> BagSpec:
    """The defaults, overridden by the TOML file ``path`` (``None``: the defaults).
    An unknown key, a value of the wrong type or out of range is an
    :class:`InputError` naming it."""
    spec = BagSpec()
    if path is None:
        return spec
    where = Path(path)
    try:
        doc = tomllib.loads(where.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"--spec {where}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"--spec {where}: cannot read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"--spec {where}: not TOML ({exc})") from None
    known = {f.name: f for f in fields(BagSpec)}
    values: dict[str, Any] = {}
    for key, value in doc.items():
        if key not in known:
            raise InputError(f"--spec {where}: unknown key {key!r} (known: {', '.join(known)})")
        default = getattr(spec, key)
        if isinstance(default, float):
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InputError(f"--spec {where}: {key} must be a number, not {value!r}")
            value = float(value)
            if not math.isfinite(value) or value <= 0.0:
                raise InputError(f"--spec {where}: {key} must be above 0, not {value!r}")
        elif not isinstance(value, str):
            raise InputError(f"--spec {where}: {key} must be a string, not {value!r}")
        values[key] = value
    spec = replace(spec, **values)
    if spec.fov_deg >= 180.0:
        raise InputError(f"--spec {where}: fov_deg must be below 180, not {spec.fov_deg!r}")
    if not spec.images_topic or not spec.joint_states_topic or not spec.camera_joint:
        raise InputError(
            f"--spec {where}: images_topic, joint_states_topic and camera_joint are required"
        )
    return spec
