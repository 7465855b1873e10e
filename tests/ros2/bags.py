"""ROS 2 bags for the tests, written with the rosbags library (not by pipemap), as a
robot's logger would write them: JPEG ``CompressedImage`` messages of a camera
whose yaw is the ``camera_yaw`` joint of ``/joint_states``."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

rosbags = pytest.importorskip("rosbags", reason="the ros extra (pipemap[ros]) is not installed")

from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

STORE = get_typestore(Stores.ROS2_HUMBLE)
NS = 1_000_000_000


def _header(t_ns: int, frame: str) -> Any:
    Header = STORE.types["std_msgs/msg/Header"]
    Time = STORE.types["builtin_interfaces/msg/Time"]
    return Header(stamp=Time(sec=t_ns // NS, nanosec=t_ns % NS), frame_id=frame)


class BagWriter:
    """A rosbags ``Writer`` with one connection per topic, made on first use."""

    def __init__(self, writer: Any) -> None:
        self.writer = writer
        self.connections: dict[str, Any] = {}

    def write(self, topic: str, msgtype: str, t_ns: int, message: Any) -> None:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=STORE)
        self.writer.write(self.connections[topic], t_ns, STORE.serialize_cdr(message, msgtype))

    def raw(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        if topic not in self.connections:
            self.connections[topic] = self.writer.add_connection(topic, msgtype, typestore=STORE)
        self.writer.write(self.connections[topic], t_ns, data)

    def image(
        self, t_ns: int, data: bytes, fmt: str = "jpeg", topic: str = "/camera/image/compressed"
    ) -> None:
        kind = "sensor_msgs/msg/CompressedImage"
        message = STORE.types[kind](
            header=_header(t_ns, "camera_link"),
            format=fmt,
            data=np.frombuffer(data, dtype=np.uint8),
        )
        self.write(topic, kind, t_ns, message)

    def joint(self, t_ns: int, names: Sequence[str], positions: Sequence[float]) -> None:
        kind = "sensor_msgs/msg/JointState"
        message = STORE.types[kind](
            header=_header(t_ns, ""),
            name=list(names),
            position=np.array(positions, dtype=np.float64),
            velocity=np.zeros(0),
            effort=np.zeros(0),
        )
        self.write("/joint_states", kind, t_ns, message)


def write_bag(path: Path, fill: Callable[[BagWriter], None], storage: str = "mcap") -> Path:
    """A rosbag2 bag at ``path`` (a new folder), its messages written by ``fill``."""
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=8, storage_plugin=plugin) as writer:
        fill(BagWriter(writer))
    return path


def sweep_bag(
    path: Path, folders: Sequence[Path], gap_s: float = 10.0, storage: str = "mcap"
) -> Path:
    """A bag of one sweep per image-set folder, in order: each folder's
    ``camera_image1..N`` JPEG files as ``CompressedImage`` messages 0.5 s apart, the
    camera turning clockwise by 2*pi/N (the ``camera_yaw`` joint published just
    before each image), the sweeps ``gap_s`` apart."""

    def fill(bag: BagWriter) -> None:
        t_ns = NS
        for folder in folders:
            files = sorted(folder.glob("camera_image*.jp*g"), key=lambda p: int(p.stem[12:]))
            n = len(files)
            for k, file in enumerate(files):
                bag.joint(
                    t_ns - NS // 10, ["wheel_left", "camera_yaw"], [0.0, -2 * math.pi * k / n]
                )
                bag.image(t_ns, file.read_bytes())
                t_ns += NS // 2
            t_ns += int(gap_s * NS)

    return write_bag(path, fill, storage)
