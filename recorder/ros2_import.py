"""A ROS 2 bag made into a pipemap log (``pipemap import``).

The bag is read whole and checked before anything is written (the contract:
:mod:`recorder.ros2_contract`, docs/ros2.md): the camera topic and the camera's
joint must be there with their types, every image must decode and have the size of
the first, and each sweep's images must turn clockwise by 2*pi/N. Then the log is
written to a temporary file beside the output and moved into place, so a failure
leaves no half-written log. Each image is stored as lossless PNG of what the bag's
image decodes to, so the replay sees exactly the pixels the bag holds.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from google.protobuf import json_format

from pipemap.errors import InputError, WriteError
from pipemap.pngcheck import png_problem
from pipemap.recorder import schemas
from pipemap.recorder.messages import CAMERA_FRAME, encode_png, timestamp
from pipemap.recorder.ros2_bag import BagMessages, read_bag, typestore
from pipemap.recorder.ros2_contract import (
    FRAME_BASE,
    FRAME_ODOM,
    IMAGE_TYPES,
    RAW_ENCODINGS,
    BagSpec,
    MsgType,
)
from pipemap.recorder.ros2_exits import VisitWindow, derived_exits
from pipemap.recorder.ros2_sensors import (
    Latest,
    controller_states,
    events,
    imu_messages,
    node_events,
    range_messages,
)
from pipemap.recorder.topics import TOPICS, Topic
from pipemap.recorder.writer import LogWriter

__all__ = ["ImportResult", "import_bag"]

#: How far a sweep's image may be from the turn of 2*pi/N that the localizer assumes.
TURN_TOLERANCE_RAD = math.radians(10.0)
_NS = 1_000_000_000
_TOPIC_RANK = {topic: k for k, (topic, _) in enumerate(TOPICS)}


@dataclass
class ImportResult:
    """What an import wrote, and what the user should know about it."""

    path: Path
    sweeps: int = 0
    visits: int = 0
    #: Messages written per pipemap topic.
    counts: dict[str, int] = field(default_factory=dict)
    #: One line each: what was not used or is missing (no ranges, no ports, ...).
    notes: list[str] = field(default_factory=list)


def _seconds(t_ns: int) -> str:
    return f"{t_ns / _NS:.3f} s"


def _stamp_ns(message: Any, received_ns: int) -> int:
    """The header's stamp, or the time the bag received the message where it is 0."""
    stamp = message.header.stamp
    t = int(stamp.sec) * _NS + int(stamp.nanosec)
    return t if t > 0 else received_ns


def _check_topics(bag: BagMessages, spec: BagSpec, name: str) -> None:
    if not bag.types or not sum(bag.counts.values()):
        raise InputError(f"{name}: the bag holds no messages")
    required = {spec.images_topic: IMAGE_TYPES, spec.joint_states_topic: (MsgType.JOINT_STATE,)}
    for topic, kinds in required.items():
        if topic not in bag.types:
            raise InputError(
                f"{topic}: no such topic in {name} (it has: {', '.join(sorted(bag.types))})"
            )
        if bag.types[topic] not in kinds:
            raise InputError(f"{topic}: carries {bag.types[topic]}, not {' or '.join(kinds)}")
        if not bag.counts.get(topic):
            raise InputError(f"{topic}: no messages in {name}")
    for topic, kind in spec.optional_topics().items():
        if topic in bag.types and bag.types[topic] != kind:
            raise InputError(f"{topic}: carries {bag.types[topic]}, not {kind}")


class _Decoder:
    """CDR messages decoded with rosbags' type store, naming the message that fails."""

    def __init__(self, types: dict[str, str]) -> None:
        self._store = typestore()
        self._types = types

    def __call__(self, topic: str, time_ns: int, raw: bytes) -> Any:
        kind = self._types[topic]
        try:
            return self._store.deserialize_cdr(raw, kind)
        except Exception:  # rosbags raises several kinds for bytes that do not decode
            raise InputError(
                f"{topic}: message at {_seconds(time_ns)} does not decode as {kind}"
            ) from None


def _rgb(topic: str, t_ns: int, message: Any, kind: str) -> np.ndarray:
    """The RGB pixels of an image message, or an :class:`InputError` naming it."""
    where = f"{topic}: image at {_seconds(t_ns)}"
    if kind == MsgType.IMAGE:
        if message.encoding not in RAW_ENCODINGS:
            raise InputError(
                f"{where} has encoding {message.encoding!r}, not {', '.join(RAW_ENCODINGS)}"
            )
        channels = 1 if message.encoding == "mono8" else 3
        h, w, step = int(message.height), int(message.width), int(message.step)
        raw = np.asarray(message.data, dtype=np.uint8)
        if h * w == 0 or step < w * channels or raw.size < h * step:
            raise InputError(f"{where}: {raw.size} bytes for {w}x{h} {message.encoding}")
        pixels = raw[: h * step].reshape(h, step)[:, : w * channels].reshape(h, w, channels)
        if message.encoding == "mono8":
            return np.ascontiguousarray(np.repeat(pixels, 3, axis=2))
        if message.encoding == "bgr8":
            return np.ascontiguousarray(pixels[:, :, ::-1])
        return np.ascontiguousarray(pixels)
    data = bytes(message.data)
    form = message.format.lower()
    if "png" in form:
        problem = png_problem(data)
        if problem:
            raise InputError(f"{where} is {problem}")
    elif "jpeg" in form or "jpg" in form:
        # libjpeg decodes a truncated JPEG with only a warning: demand the end marker.
        if not data.rstrip(b"\0").endswith(b"\xff\xd9"):
            raise InputError(f"{where} is a truncated or corrupt JPEG image")
    else:
        raise InputError(f"{where} has format {message.format!r}, not jpeg or png")
    bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if bgr is None or bgr.size == 0:
        raise InputError(f"{where} does not decode as {message.format}")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


@dataclass
class _Image:
    t_ns: int
    png: bytes
    yaw_rad: float


@dataclass
class _Sweep:
    start: Any  # schemas.SweepCommand
    images: list[_Image] = field(default_factory=list)
    end_ns: int | None = None


def _joint_yaws(
    messages: Iterable[tuple[int, Any]], joint: str, topic: str
) -> list[tuple[int, float]]:
    """(stamp, position) of ``joint`` in every JointState that names it, by stamp."""
    found: list[tuple[int, float]] = []
    names: set[str] = set()
    for t_ns, message in messages:
        names.update(message.name)
        if joint in message.name:
            k = list(message.name).index(joint)
            if k >= len(message.position):
                raise InputError(f"{topic}: joint {joint} at {_seconds(t_ns)} has no position")
            found.append((t_ns, float(message.position[k])))
    if not found:
        raise InputError(
            f"{topic}: no joint named {joint!r} (joints: {', '.join(sorted(names)) or 'none'})"
        )
    found.sort(key=lambda p: p[0])
    return found


def _marker(text: str, t_ns: int, topic: str) -> Any:
    """A sweep marker: pipemap's SweepCommand as JSON, or any other text for a START."""
    command = schemas.SweepCommand(phase=schemas.SweepCommand.START)
    if text.strip().startswith("{"):
        try:
            json_format.Parse(text, command, ignore_unknown_fields=True)
        except json_format.ParseError as exc:
            raise InputError(
                f"{topic}: marker at {_seconds(t_ns)} is not a sweep ({exc})"
            ) from None
    command.time_ns = t_ns
    return command


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _check_turn(sweep: _Sweep, topic: str) -> None:
    n = len(sweep.images)
    if n < 2:
        raise InputError(
            f"{topic}: the sweep at {_seconds(sweep.images[0].t_ns)} has 1 image; "
            "a sweep needs 2 or more"
        )
    step = -2.0 * math.pi / n
    for a, b in zip(sweep.images, sweep.images[1:], strict=False):
        turn = _wrap(b.yaw_rad - a.yaw_rad)
        if abs(_wrap(turn - step)) > TURN_TOLERANCE_RAD:
            raise InputError(
                f"{topic}: the sweep at {_seconds(sweep.images[0].t_ns)} turns by "
                f"{math.degrees(turn):+.1f} deg at {_seconds(b.t_ns)}, not "
                f"{math.degrees(step):+.1f} (clockwise by 360/{n})"
            )


def import_bag(
    bag: str | Path, output: str | Path, spec: BagSpec | None = None, version: str = ""
) -> ImportResult:
    """Read the ROS 2 bag ``bag`` by ``spec`` (default: :class:`BagSpec`'s defaults)
    and write its pipemap log to ``output`` (replaced if it exists: the caller checks);
    ``version``, pipemap's, names the writer in the log."""
    spec = spec or BagSpec()
    path = Path(bag)
    wanted = {spec.images_topic, spec.joint_states_topic, *spec.optional_topics()}
    contents = read_bag(path, wanted)
    _check_topics(contents, spec, str(path))
    decode = _Decoder(contents.types)
    by_topic: dict[str, list[tuple[int, Any]]] = defaultdict(list)
    for topic, received_ns, raw in contents.messages:
        message = decode(topic, received_ns, raw)
        has_header = hasattr(message, "header")
        by_topic[topic].append(
            (_stamp_ns(message, received_ns) if has_header else received_ns, message)
        )
    result = ImportResult(Path(output))
    if contents.cut_short:
        result.notes.append(f"{contents.cut_short}: kept the messages before it")
    writes: list[tuple[int, str, Any]] = []
    yaws = _joint_yaws(
        by_topic[spec.joint_states_topic], spec.camera_joint, spec.joint_states_topic
    )
    images = _images(
        by_topic[spec.images_topic], spec, contents.types[spec.images_topic], Latest(yaws)
    )
    sweeps = _sweeps(images, by_topic.get(spec.sweep_topic, []), spec, result)
    if contents.cut_short and len(sweeps) > 1 and len(sweeps[-1].images) != len(sweeps[-2].images):
        # The bag stops inside its last sweep: keep what is whole.
        lost = sweeps.pop()
        result.notes.append(
            f"{spec.images_topic}: the last sweep ({_seconds(lost.images[0].t_ns)}) was cut "
            f"short after {len(lost.images)} image(s); dropped"
        )
    _sweep_writes(sweeps, spec, writes, result)
    _sensor_writes(by_topic, spec, writes, result, sweeps)
    run = _run_metadata(by_topic.get(spec.run_topic, []), path, spec, version)
    _write(Path(output), run, writes, result)
    return result


def _images(
    messages: list[tuple[int, Any]], spec: BagSpec, kind: str, yaws: Latest
) -> list[_Image]:
    out: list[_Image] = []
    first: tuple[int, int] | None = None
    for t_ns, message in sorted(messages, key=lambda p: p[0]):
        rgb = _rgb(spec.images_topic, t_ns, message, kind)
        size = (rgb.shape[1], rgb.shape[0])
        if first is None:
            first = size
        elif size != first:
            raise InputError(
                f"{spec.images_topic}: image at {_seconds(t_ns)} is {size[0]}x{size[1]}, "
                f"the first is {first[0]}x{first[1]}"
            )
        out.append(_Image(t_ns, encode_png(rgb), yaws.at_or_first(t_ns)))
    return out


def _sweeps(
    images: list[_Image], markers: list[tuple[int, Any]], spec: BagSpec, result: ImportResult
) -> list[_Sweep]:
    """The images grouped into sweeps: by the markers where the bag has them, else by
    gaps longer than ``sweep_gap_s``."""
    sweeps: list[_Sweep] = []
    if not markers:
        gap_ns = int(spec.sweep_gap_s * _NS)
        for image in images:
            if not sweeps or image.t_ns - sweeps[-1].images[-1].t_ns > gap_ns:
                start = schemas.SweepCommand(phase=schemas.SweepCommand.START, time_ns=image.t_ns)
                sweeps.append(_Sweep(start))
            sweeps[-1].images.append(image)
        return sweeps
    commands = sorted(
        ((t, _marker(m.data, t, spec.sweep_topic)) for t, m in markers), key=lambda p: p[0]
    )
    starts = [(t, c) for t, c in commands if c.phase != schemas.SweepCommand.END]
    ends = [t for t, c in commands if c.phase == schemas.SweepCommand.END]
    used = 0
    for k, (t_ns, command) in enumerate(starts):
        following = starts[k + 1][0] if k + 1 < len(starts) else None
        end = next((e for e in ends if e >= t_ns and (following is None or e < following)), None)
        sweep = _Sweep(command, end_ns=end)
        sweep.images = [
            image
            for image in images
            if image.t_ns >= t_ns
            and (end is None or image.t_ns <= end)
            and (following is None or image.t_ns < following)
        ]
        used += len(sweep.images)
        if sweep.images:
            sweeps.append(sweep)
    outside = len(images) - used
    if outside:
        result.notes.append(f"{spec.images_topic}: {outside} image(s) outside every sweep marker")
    return sweeps


def _sweep_writes(
    sweeps: list[_Sweep], spec: BagSpec, writes: list[tuple[int, str, Any]], result: ImportResult
) -> None:
    if not sweeps:
        raise InputError(f"{spec.images_topic}: no sweep (no images to group)")
    visit = 0
    for sweep_id, sweep in enumerate(sweeps, start=1):
        _check_turn(sweep, spec.images_topic)
        start = sweep.start
        if not start.probe and not start.visit_id:
            visit += 1
            start.visit_id = visit
        visit = max(visit, start.visit_id)
        start.sweep_id = start.sweep_id or sweep_id
        start.image_count = len(sweep.images)
        start.camera_angle_rad = sweep.images[0].yaw_rad
        start.fov_rad = start.fov_rad or spec.fov_rad
        start_ns = min(start.time_ns, sweep.images[0].t_ns)
        start.time_ns = start_ns
        writes.append((start_ns, Topic.SWEEP, start))
        for k, image in enumerate(sweep.images):
            writes.append(
                (
                    image.t_ns,
                    Topic.IMAGE,
                    schemas.CompressedImage(
                        timestamp=timestamp(image.t_ns),
                        frame_id=CAMERA_FRAME,
                        data=image.png,
                        format="png",
                    ),
                )
            )
            writes.append(
                (
                    image.t_ns,
                    Topic.SWEEP,
                    schemas.SweepCommand(
                        time_ns=image.t_ns,
                        phase=schemas.SweepCommand.IMAGE,
                        sweep_id=start.sweep_id,
                        visit_id=start.visit_id,
                        image_index=k,
                        image_count=len(sweep.images),
                        camera_angle_rad=image.yaw_rad,
                        fov_rad=start.fov_rad,
                    ),
                )
            )
        end_ns = max(sweep.end_ns or 0, sweep.images[-1].t_ns)
        end = schemas.SweepCommand(
            time_ns=end_ns,
            phase=schemas.SweepCommand.END,
            sweep_id=start.sweep_id,
            visit_id=start.visit_id,
        )
        writes.append((end_ns, Topic.SWEEP, end))
    result.sweeps = len(sweeps)
    result.visits = visit


def _sensor_writes(
    by_topic: dict[str, list[tuple[int, Any]]],
    spec: BagSpec,
    writes: list[tuple[int, str, Any]],
    result: ImportResult,
    sweeps: list[_Sweep],
) -> None:
    fronts = by_topic.get(spec.range_front_topic, [])
    if fronts:
        left = by_topic.get(spec.range_left_topic, [])
        right = by_topic.get(spec.range_right_topic, [])
        writes.extend((t, Topic.RANGES, m) for t, m in range_messages(fronts, left, right))
    else:
        result.notes.append(f"{spec.range_front_topic}: no range readings")
    writes.extend((t, Topic.IMU, m) for t, m in imu_messages(by_topic.get(spec.imu_topic, [])))
    odometry = by_topic.get(spec.odometry_topic, [])
    states = controller_states(odometry, by_topic.get(spec.tf_topic, []), FRAME_ODOM, FRAME_BASE)
    if not states:
        result.notes.append(
            f"{spec.odometry_topic}: no odometry "
            f"(nor {FRAME_ODOM}->{FRAME_BASE} on {spec.tf_topic})"
        )
    writes.extend((t, Topic.CONTROLLER, m) for t, m in states)
    nodes = node_events(by_topic.get(spec.node_topic, []), spec.node_topic)
    if not nodes and fronts:
        nodes = _exits_from_ranges(by_topic, spec, sweeps, states)
        result.notes.append(
            f"{spec.node_topic}: no exit scans: the exits are worked out from the range "
            "readings (docs/ros2.md)"
        )
    elif not nodes:
        result.notes.append(f"{spec.node_topic}: no exit scans: the map has no ports")
    writes.extend((t, Topic.NODE, m) for t, m in nodes)
    writes.extend((t, Topic.EVENTS, m) for t, m in events(by_topic.get(spec.rosout_topic, [])))


def _exits_from_ranges(
    by_topic: dict[str, list[tuple[int, Any]]],
    spec: BagSpec,
    sweeps: list[_Sweep],
    states: list[tuple[int, Any]],
) -> list[tuple[int, Any]]:
    """Each visit's exits from the rangers' readings around its first sweep."""
    visits: dict[int, VisitWindow] = {}
    for sweep in sweeps:
        if not sweep.start.probe and sweep.start.visit_id not in visits:
            first, last = sweep.images[0].t_ns, sweep.images[-1].t_ns
            visits[sweep.start.visit_id] = VisitWindow(sweep.start.visit_id, first, last)
    side = math.radians(spec.range_side_deg)
    rangers = [
        (by_topic.get(spec.range_front_topic, []), 0.0),
        (by_topic.get(spec.range_left_topic, []), side),
        (by_topic.get(spec.range_right_topic, []), -side),
    ]
    poses = [(t, s.heading_estimate_rad, s.x_estimate_m, s.y_estimate_m) for t, s in states]
    rates = [(t, float(m.angular_velocity.z)) for t, m in by_topic.get(spec.imu_topic, [])]
    return derived_exits(
        list(visits.values()), rangers, poses, rates, spec.exit_open_m, spec.exit_scan_s
    )


def _run_metadata(
    messages: list[tuple[int, Any]], bag: Path, spec: BagSpec, version: str
) -> dict[str, str]:
    """The run's settings: the bag's ``/pipemap/run`` (what an export wrote), else
    what the import knows; with the bag it came from."""
    run: dict[str, str] = {}
    for t_ns, message in messages[:1]:
        try:
            loaded = json.loads(message.data)
        except ValueError:
            raise InputError(f"{spec.run_topic}: message at {_seconds(t_ns)} is not JSON") from None
        if not isinstance(loaded, dict):
            raise InputError(f"{spec.run_topic}: message at {_seconds(t_ns)} is not a JSON object")
        run = {str(k): str(v) for k, v in loaded.items() if k != "format_version"}
    run.setdefault("fov_rad", repr(spec.fov_rad))
    run["pipemap_version"] = version
    run["source"] = f"ros2 bag {bag.name}"
    return run


def _write(
    target: Path, run: dict[str, str], writes: list[tuple[int, str, Any]], result: ImportResult
) -> None:
    """Write the log to a temporary file beside ``target``, then move it into place."""
    order = sorted(range(len(writes)), key=lambda k: (writes[k][0], _TOPIC_RANK[writes[k][1]], k))
    handle, temporary = tempfile.mkstemp(
        dir=target.parent, prefix=f".{target.name}.", suffix=".part"
    )
    try:
        with os.fdopen(handle, "wb") as output, LogWriter(output, run) as log:
            for k in order:
                t_ns, topic, message = writes[k]
                log.write(topic, max(t_ns, 0), message)
            result.counts = {topic: log.count(topic) for topic, _ in TOPICS if log.count(topic)}
        os.replace(temporary, target)
    except OSError as exc:
        raise WriteError(f"{target}: cannot write ({exc.strerror or exc})") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
