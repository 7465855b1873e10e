"""From what the simulator and the localizer produce to log messages.

One function per message type; each takes plain values and returns a protobuf
message, so the conversions are tested without a simulator. Images are stored as
lossless PNG by default, so that a replay sees exactly what the robot saw; a run
recorded with ``--image-format jpeg`` stores JPEG, as a real robot's camera often
gives it (docs/recorder.md measures what that does to the decisions).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.Pose_pb2 import Pose as FoxglovePose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive
from foxglove_schemas_protobuf.TextPrimitive_pb2 import TextPrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp

from pipemap.defaults import IMAGE_FORMAT, JPEG_QUALITY
from pipemap.pngcheck import png_problem
from pipemap.recorder import schemas

if TYPE_CHECKING:
    from pipemap.localizer import Decision as LocalizerDecision
    from pipemap.sim.network import Network
    from pipemap.sim.obstacles import Obstacle

__all__ = [
    "WORLD_FRAME",
    "decision_message",
    "ImageEncoding",
    "decode_image",
    "decode_png",
    "encode_png",
    "image_message",
    "labelled_sphere",
    "blocked_message",
    "blocked_visit",
    "log_message",
    "network_message",
    "png_problem",
    "pose_message",
    "timestamp",
]

WORLD_FRAME = "world"
ROBOT_FRAME = "robot"
CAMERA_FRAME = "camera"
_NS_PER_S = 1_000_000_000


def timestamp(t_ns: int) -> Timestamp:
    """A protobuf timestamp of simulated time (seconds since the run began)."""
    return Timestamp(seconds=t_ns // _NS_PER_S, nanos=t_ns % _NS_PER_S)


def _yaw_quaternion(yaw_rad: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw_rad / 2.0), w=math.cos(yaw_rad / 2.0))


def encode_png(rgb: np.ndarray) -> bytes:
    """Lossless PNG bytes of an RGB (H x W x 3, uint8) image."""
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"expected an H x W x 3 uint8 image, got {rgb.shape} {rgb.dtype}")
    ok, png = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
        raise ValueError("PNG encoding failed")
    return png.tobytes()


def decode_png(data: bytes) -> np.ndarray | None:
    """The RGB image of PNG bytes, or ``None`` when they are not a readable image
    (:func:`png_problem` says why)."""
    if png_problem(data):
        return None
    bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        return None
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


@dataclass(frozen=True)
class ImageEncoding:
    """How the camera's images are stored: ``png`` (lossless) or ``jpeg`` at
    ``jpeg_quality`` (1..100, OpenCV's scale)."""

    image_format: str = IMAGE_FORMAT
    jpeg_quality: int = JPEG_QUALITY

    def __post_init__(self) -> None:
        if self.image_format not in IMAGE_FORMATS:
            raise ValueError(f"image format {self.image_format!r}, not one of {IMAGE_FORMATS}")
        if not 1 <= self.jpeg_quality <= 100:
            raise ValueError(f"JPEG quality {self.jpeg_quality}, not in 1..100")

    @classmethod
    def of_run(cls, run: Mapping[str, str]) -> ImageEncoding:
        """The encoding a run's ``pipemap.run`` metadata names (PNG where it names none)."""
        if run.get("image_format", "png") != "jpeg":
            return cls()
        return cls("jpeg", int(run.get("jpeg_quality", "90")))

    def metadata(self) -> dict[str, str]:
        """The keys of ``pipemap.run`` that say so (none for PNG: such a log stays as
        it always was)."""
        if self.image_format == "png":
            return {}
        return {"image_format": self.image_format, "jpeg_quality": str(self.jpeg_quality)}

    def encode(self, rgb: np.ndarray) -> bytes:
        """The image's bytes in this encoding."""
        if self.image_format == "png":
            return encode_png(rgb)
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        ok, data = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
            raise ValueError("JPEG encoding failed")
        return bytes(data.tobytes())


#: The image formats a log may hold.
IMAGE_FORMATS = ("png", "jpeg")


def decode_image(data: bytes, image_format: str) -> np.ndarray | None:
    """The RGB image of PNG or JPEG bytes, or ``None`` when they are not a whole,
    readable image of that format (a JPEG without its end marker is cut short:
    libjpeg would decode it with only a warning)."""
    if image_format == "png":
        return decode_png(data)
    if image_format != "jpeg" or not data.rstrip(b"\0").endswith(b"\xff\xd9"):
        return None
    bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if bgr is None:
        return None
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def image_message(
    t_ns: int, rgb: np.ndarray, encoding: ImageEncoding | None = None
) -> schemas.CompressedImage:
    """A camera image as Foxglove's ``CompressedImage`` (PNG by default)."""
    encoding = encoding or ImageEncoding()
    return schemas.CompressedImage(
        timestamp=timestamp(t_ns),
        frame_id=CAMERA_FRAME,
        data=encoding.encode(rgb),
        format=encoding.image_format,
    )


def pose_message(t_ns: int, x_m: float, y_m: float, yaw_rad: float) -> schemas.FrameTransform:
    """The robot's true pose on the pipe floor as Foxglove's ``FrameTransform``."""
    return schemas.FrameTransform(
        timestamp=timestamp(t_ns),
        parent_frame_id=WORLD_FRAME,
        child_frame_id=ROBOT_FRAME,
        translation=Vector3(x=x_m, y=y_m, z=0.0),
        rotation=_yaw_quaternion(yaw_rad),
    )


def log_message(t_ns: int, text: str, warning: bool = False) -> schemas.Log:
    """A notable event as Foxglove's ``Log``."""
    level = schemas.Log.Level.WARNING if warning else schemas.Log.Level.INFO
    return schemas.Log(timestamp=timestamp(t_ns), level=level, message=text, name="pipemap")


#: The ``name`` of the ``/robot/events`` log line that says a pipe was given up.
BLOCKED_NAME = "pipemap.blocked"
_BLOCKED_TEXT = re.compile(r"^pipe blocked: visit (\d+), exit (\S+) rad$")


#: The text of the warning a refused probe move leaves in ``/robot/events``
#: (:data:`pipemap.sim.probe_moves.REFUSED_NOTE`): its kind and visit.
_REFUSED_TEXT = re.compile(r"^probe (\w+) of visit (\d+) not made: ")


def refused_probe(log: schemas.Log) -> tuple[int, str] | None:
    """The visit id and probe kind of a refused probe move's warning, or ``None``
    for any other log line."""
    if log.level != schemas.Log.Level.WARNING:
        return None
    found = _REFUSED_TEXT.match(log.message)
    return None if found is None else (int(found.group(2)), found.group(1))


def blocked_message(t_ns: int, visit_id: int, exit_rad: float) -> schemas.Log:
    """The robot gave up the pipe it last left visit ``visit_id``'s junction by, at
    ``exit_rad`` from its arrival heading: a ``/robot/events`` warning named
    :data:`BLOCKED_NAME` (the log's schemas stay as they were)."""
    return schemas.Log(
        timestamp=timestamp(t_ns),
        level=schemas.Log.Level.WARNING,
        message=f"pipe blocked: visit {visit_id}, exit {exit_rad!r} rad",
        name=BLOCKED_NAME,
    )


def blocked_visit(log: schemas.Log) -> tuple[int, float] | None:
    """The visit id and exit of a :func:`blocked_message`, or ``None`` for any other
    log line (or a malformed one)."""
    if log.name != BLOCKED_NAME:
        return None
    found = _BLOCKED_TEXT.match(log.message)
    if found is None:
        return None
    try:
        return int(found.group(1)), float(found.group(2))
    except ValueError:
        return None


def labelled_sphere(
    t_ns: int,
    frame: str,
    entity_id: str,
    xy_m: tuple[float, float],
    size_m: float,
    color: Color,
    text: str,
) -> SceneEntity:
    """A Foxglove scene entity: a sphere on the floor at ``xy_m`` with a white label."""
    at = FoxglovePose(position=Vector3(x=xy_m[0], y=xy_m[1]), orientation=Quaternion(w=1.0))
    entity = SceneEntity(timestamp=timestamp(t_ns), frame_id=frame, id=entity_id)
    entity.spheres.append(
        SpherePrimitive(pose=at, size=Vector3(x=size_m, y=size_m, z=size_m), color=color)
    )
    entity.texts.append(
        TextPrimitive(
            pose=at,
            billboard=True,
            font_size=14.0,
            scale_invariant=True,
            color=Color(r=1.0, g=1.0, b=1.0, a=1.0),
            text=text,
        )
    )
    return entity


def network_message(
    network: Network, t_ns: int = 0, obstacles: tuple[Obstacle, ...] = ()
) -> schemas.SceneUpdate:
    """The network's pipes (centre lines, with their diameter) and labelled nodes as
    Foxglove's ``SceneUpdate``: one entity per pipe (``pipe/A-B``) and per node
    (``node/A``), in the world frame; and one per floor deposit (``obstacle/K``, a
    cube, with metadata ``pipe`` ``A-B`` and ``kind`` ``passable`` or ``blocking``),
    when there are any."""
    update = schemas.SceneUpdate()
    grey = Color(r=0.6, g=0.6, b=0.6, a=1.0)
    for pipe in network.pipes:
        a, b = network.node(pipe.a), network.node(pipe.b)
        entity = SceneEntity(
            timestamp=timestamp(t_ns), frame_id=WORLD_FRAME, id=f"pipe/{pipe.a}-{pipe.b}"
        )
        entity.lines.append(
            LinePrimitive(
                type=LinePrimitive.Type.LINE_STRIP,
                pose=FoxglovePose(position=Vector3(), orientation=Quaternion(w=1.0)),
                thickness=network.diameter_m,
                points=[Point3(x=a.x_m, y=a.y_m, z=0.0), Point3(x=b.x_m, y=b.y_m, z=0.0)],
                color=grey,
            )
        )
        update.entities.append(entity)
    for node in network.nodes:
        size = network.diameter_m * 1.2
        entity = labelled_sphere(
            t_ns,
            WORLD_FRAME,
            f"node/{node.label}",
            (node.x_m, node.y_m),
            size,
            Color(r=0.9, g=0.5, a=0.8),
            node.label,
        )
        entity.metadata.add(key="kind", value=network.kind(node.label).value)
        update.entities.append(entity)
    for k, o in enumerate(obstacles):
        entity = SceneEntity(timestamp=timestamp(t_ns), frame_id=WORLD_FRAME, id=f"obstacle/{k}")
        at = FoxglovePose(
            position=Vector3(x=o.centre_xy_m[0], y=o.centre_xy_m[1], z=o.height_m / 2.0),
            orientation=_yaw_quaternion(o.heading_rad),
        )
        entity.cubes.append(
            CubePrimitive(
                pose=at,
                size=Vector3(x=o.length_m, y=o.width_m, z=o.height_m),
                color=Color(r=0.6, g=0.4, b=0.2, a=1.0),
            )
        )
        entity.metadata.add(key="pipe", value=f"{o.a}-{o.b}")
        entity.metadata.add(key="kind", value=o.kind.value)
        update.entities.append(entity)
    return update


def decision_message(
    t_ns: int, visit_id: int, decision: LocalizerDecision, threshold: float
) -> schemas.Decision:
    """The online localizer's decision for one visit."""
    message = schemas.Decision(
        time_ns=t_ns,
        visit_id=visit_id,
        node=decision.node,
        known=decision.known,
        similarity=decision.similarity,
        threshold=threshold,
    )
    if decision.candidate is not None:
        message.candidate = decision.candidate
    if decision.margin is not None:
        message.margin = decision.margin
    match = decision.match
    if match is not None:
        message.image_shift = match.image_shift
        message.pixel_shift = match.pixel_shift
        message.rotation_rad = match.rotation_rad
        message.rotation_pinhole_rad = match.rotation_pinhole_rad
    for probe in decision.probes:
        result = message.probes.add(kind=probe.request.kind.value, improved=probe.improved)
        if probe.similarity is not None:
            result.similarity = probe.similarity
    if decision.exit_ports is not None:
        message.exit_ports.extend(decision.exit_ports)
    if decision.arrival_port is not None:
        message.arrival_port = decision.arrival_port
    message.rejected.extend(c for c, _ in decision.rejected)
    # Competing maps: set only where there were several, so that a run whose maps
    # never branch logs the very bytes it did before these fields existed.
    if decision.hypotheses != 1:
        message.hypotheses = decision.hypotheses
    message.deferred.extend(decision.deferred)
    for visit, node in decision.settled:
        message.settled.add(visit=visit, node=node)
    return message
