"""A pipemap log written as a ROS 2 bag (``pipemap export --ros2``).

The bag is a rosbag2 folder (metadata.yaml, one MCAP storage file, CDR messages of
ROS 2's standard types), written with the ``rosbags`` library, so that ``ros2 bag
info``, rosbags, Foxglove and RViz read it. Its topics are the ones ``pipemap
import`` reads by default (:mod:`recorder.ros2_contract`), so an export imports
back to a log that replays to the same map. Each message's header stamp and bag
time are its log time.
"""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from google.protobuf import json_format
from google.protobuf.message import DecodeError

from pipemap.errors import InputError, WriteError
from pipemap.recorder import schemas
from pipemap.recorder.reader import iter_log
from pipemap.recorder.ros2_bag import typestore
from pipemap.recorder.ros2_contract import (
    FRAME_BASE,
    FRAME_CAMERA,
    FRAME_MAP,
    FRAME_ODOM,
    FRAME_TRUTH,
    BagSpec,
    MsgType,
)
from pipemap.recorder.topics import Topic

__all__ = ["ExportResult", "export_ros2"]

_NS = 1_000_000_000
#: Foxglove Log levels to rcl_interfaces/msg/Log levels.
_LEVELS = {1: 10, 2: 20, 3: 30, 4: 40, 5: 50}
#: rosbag2 metadata version 8 (ROS 2 Iron and later read it).
BAG_VERSION: Literal[8] = 8


@dataclass
class ExportResult:
    """What an export wrote: messages per bag topic."""

    path: Path
    counts: dict[str, int] = field(default_factory=dict)
    #: Log messages that did not decode and were left out.
    undecodable: int = 0


def _json(message: Any) -> str:
    """A protobuf message as JSON, the same text for the same message."""
    return json.dumps(
        json_format.MessageToDict(message, preserving_proto_field_name=True), sort_keys=True
    )


class _Bag:
    """The rosbags writer, one connection per topic made on first use, and the
    message types of ROS 2 Humble."""

    def __init__(self, writer: Any, store: Any) -> None:
        self.writer, self.store = writer, store
        self.connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        t = store.types
        self.Header, self.Time = t["std_msgs/msg/Header"], t["builtin_interfaces/msg/Time"]
        self.Vector3, self.Quaternion = (
            t["geometry_msgs/msg/Vector3"],
            t["geometry_msgs/msg/Quaternion"],
        )

    def header(self, t_ns: int, frame: str) -> Any:
        return self.Header(stamp=self.stamp(t_ns), frame_id=frame)

    def stamp(self, t_ns: int) -> Any:
        return self.Time(sec=t_ns // _NS, nanosec=t_ns % _NS)

    def yaw(self, yaw_rad: float) -> Any:
        return self.Quaternion(x=0.0, y=0.0, z=math.sin(yaw_rad / 2), w=math.cos(yaw_rad / 2))

    def write(self, topic: str, msgtype: str, t_ns: int, **values: Any) -> None:
        message = self.store.types[msgtype](**values)
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(
                topic, msgtype, typestore=self.store
            )
            self.counts[topic] = 0
        self.writer.write(self.connections[topic], t_ns, self.store.serialize_cdr(message, msgtype))
        self.counts[topic] += 1

    def string(self, topic: str, t_ns: int, text: str) -> None:
        self.write(topic, MsgType.STRING, t_ns, data=text)

    def joints(self, t_ns: int, names: list[str], positions: list[float]) -> None:
        self.write(
            BagSpec.joint_states_topic,
            MsgType.JOINT_STATE,
            t_ns,
            header=self.header(t_ns, ""),
            name=names,
            position=np.array(positions, dtype=np.float64),
            velocity=np.zeros(0),
            effort=np.zeros(0),
        )

    def transform(self, t_ns: int, parent: str, child: str, x: float, y: float, yaw: float) -> None:
        t = self.store.types
        stamped = t["geometry_msgs/msg/TransformStamped"](
            header=self.header(t_ns, parent),
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=self.Vector3(x=x, y=y, z=0.0), rotation=self.yaw(yaw)
            ),
        )
        self.write(BagSpec.tf_topic, MsgType.TF, t_ns, transforms=[stamped])


def export_ros2(log: str | Path, output: str | Path, overwrite: bool = False) -> ExportResult:
    """Write the pipemap log ``log`` as the rosbag2 bag folder ``output`` (replaced,
    when it is a bag, only with ``overwrite``)."""
    store = typestore()
    from rosbags.rosbag2 import StoragePlugin, Writer

    target = Path(output)
    stream = iter_log(log)
    if target.exists():
        if not overwrite:
            raise InputError(f"{target}: exists; refusing to overwrite")
        shutil.rmtree(target) if target.is_dir() else target.unlink()
    result = ExportResult(target)
    try:
        with stream, Writer(target, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP) as w:
            bag = _Bag(w, store)
            first = True
            for m in stream:
                if first:
                    run = stream.contents.metadata.get("pipemap.run", {})
                    bag.string(BagSpec.run_topic, m.log_time_ns, json.dumps(run, sort_keys=True))
                    first = False
                try:
                    _export(bag, m.topic, m.log_time_ns, m.data)
                except DecodeError:
                    result.undecodable += 1
            result.counts = dict(bag.counts)
    except OSError as exc:
        raise WriteError(f"{target}: cannot write ({exc.strerror or exc})") from None
    return result


def _export(bag: _Bag, topic: str, t_ns: int, data: bytes) -> None:
    """One log message as the bag's message(s)."""
    if topic == Topic.IMAGE:
        image = schemas.CompressedImage.FromString(data)
        bag.write(
            BagSpec.images_topic,
            MsgType.COMPRESSED_IMAGE,
            t_ns,
            header=bag.header(t_ns, FRAME_CAMERA),
            format=image.format,
            data=np.frombuffer(image.data, dtype=np.uint8),
        )
    elif topic == Topic.SWEEP:
        command = schemas.SweepCommand.FromString(data)
        if command.phase == schemas.SweepCommand.IMAGE:
            bag.joints(t_ns, [BagSpec.camera_joint], [command.camera_angle_rad])
        else:
            bag.string(BagSpec.sweep_topic, t_ns, _json(command))
    elif topic == Topic.WHEELS:
        wheels = schemas.WheelEncoders.FromString(data)
        turn = 2 * math.pi / max(wheels.ticks_per_rev, 1)
        bag.joints(
            t_ns,
            ["wheel_left", "wheel_right"],
            [wheels.left_ticks * turn, wheels.right_ticks * turn],
        )
    elif topic == Topic.IMU:
        _imu(bag, t_ns, schemas.Imu.FromString(data))
    elif topic == Topic.RANGES:
        _ranges(bag, t_ns, schemas.Ranges.FromString(data))
    elif topic == Topic.CONTROLLER:
        _odometry(bag, t_ns, schemas.ControllerState.FromString(data))
    elif topic == Topic.TRUE_POSE:
        pose = schemas.FrameTransform.FromString(data)
        q = pose.rotation
        yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
        bag.transform(t_ns, FRAME_MAP, FRAME_TRUTH, pose.translation.x, pose.translation.y, yaw)
    elif topic == Topic.NODE:
        bag.string(BagSpec.node_topic, t_ns, _json(schemas.NodeEvent.FromString(data)))
    elif topic == Topic.EVENTS:
        line = schemas.Log.FromString(data)
        bag.write(
            BagSpec.rosout_topic,
            MsgType.LOG,
            t_ns,
            stamp=bag.stamp(t_ns),
            level=_LEVELS.get(int(line.level), 0),
            name=line.name,
            msg=line.message,
            file="",
            function="",
            line=0,
        )


def _imu(bag: _Bag, t_ns: int, imu: Any) -> None:
    unknown = np.zeros(9)
    no_orientation = np.zeros(9)
    no_orientation[0] = -1.0  # REP 145: the IMU gives no orientation
    bag.write(
        BagSpec.imu_topic,
        MsgType.IMU,
        t_ns,
        header=bag.header(t_ns, FRAME_BASE),
        orientation=bag.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=no_orientation,
        angular_velocity=bag.Vector3(x=0.0, y=0.0, z=float(imu.yaw_rate_rps)),
        angular_velocity_covariance=unknown,
        linear_acceleration=bag.Vector3(
            x=float(imu.accel_forward_mps2), y=float(imu.accel_left_mps2), z=0.0
        ),
        linear_acceleration_covariance=unknown,
    )


def _ranges(bag: _Bag, t_ns: int, ranges: Any) -> None:
    for topic, frame, value in (
        (BagSpec.range_front_topic, "range_front", ranges.front_m),
        (BagSpec.range_left_topic, "range_left", ranges.front_left_m),
        (BagSpec.range_right_topic, "range_right", ranges.front_right_m),
    ):
        bag.write(
            topic,
            MsgType.RANGE,
            t_ns,
            header=bag.header(t_ns, frame),
            radiation_type=1,  # INFRARED: time-of-flight rangers
            field_of_view=0.0,
            min_range=0.0,
            max_range=float(ranges.max_range_m),
            range=float(value),
        )


def _odometry(bag: _Bag, t_ns: int, state: Any) -> None:
    t = bag.store.types
    x, y, yaw = state.x_estimate_m, state.y_estimate_m, state.heading_estimate_rad
    bag.write(
        BagSpec.odometry_topic,
        MsgType.ODOMETRY,
        t_ns,
        header=bag.header(t_ns, FRAME_ODOM),
        child_frame_id=FRAME_BASE,
        pose=t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=bag.yaw(yaw)
            ),
            covariance=np.zeros(36),
        ),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](
            twist=t["geometry_msgs/msg/Twist"](
                linear=bag.Vector3(x=state.linear_mps, y=0.0, z=0.0),
                angular=bag.Vector3(x=0.0, y=0.0, z=state.angular_rps),
            ),
            covariance=np.zeros(36),
        ),
    )
    bag.transform(t_ns, FRAME_ODOM, FRAME_BASE, x, y, yaw)
