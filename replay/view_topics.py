"""A log's streams as rerun data on the ``sim_time`` timeline.

One function per stream: the network and the true pose (``/truth``), the range
rays, IMU, wheels and controller (``/robot``), the camera's direction and images.
High-rate streams go out as columns (``send_columns``), one call per entity, so
that viewing costs little next to the replay; rare events go out one by one.
rerun is imported by the functions that need it, never at import time.
"""

from __future__ import annotations

import json
import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from google.protobuf.message import DecodeError

from pipemap.errors import LogFormatError
from pipemap.recorder import LogMessage, Topic
from pipemap.recorder.schemas import (
    CompressedImage,
    ControllerState,
    FrameTransform,
    Imu,
    Log,
    NodeEvent,
    Ranges,
    SceneUpdate,
    SweepCommand,
    WheelEncoders,
)
from pipemap.replay.wire import Columns, FieldSpec, decode_columns, spec_of

if TYPE_CHECKING:
    import rerun as rr

__all__ = [
    "DECIMATED_TOPICS",
    "DEFAULT_MAX_RATE_HZ",
    "TIMELINE",
    "TRAIL_ENTITY",
    "TRAIL_PIECE_POINTS",
    "Carried",
    "RobotGeometry",
    "Trail",
    "decimated",
    "log_robot",
    "log_truth",
    "set_time",
    "time_column",
]

#: The one timeline of a view: log time, which is simulated time.
TIMELINE = "sim_time"
#: A new trajectory point when the robot has moved this far (the path is drawn as it grows).
_TRAJECTORY_STEP_M = 0.05
#: The trajectory's entities (see :class:`Trail`), and the points of each piece: 10 m.
TRAIL_ENTITY = "world/trajectory"
TRAIL_PIECE_POINTS = 200
_RAY_COLORS = np.array([[255, 80, 80], [80, 200, 80], [80, 140, 255]], dtype=np.uint8)
_CAMERA_RAY_M = 0.15
_LOG_TIME = operator.attrgetter("log_time_ns")
#: The high-rate streams a view thins out (the log keeps every message): the range
#: sensors (20 Hz), the IMU (100 Hz) and the wheel encoders (50 Hz), each of which a
#: 20-hour run logs millions of times.
DECIMATED_TOPICS = (Topic.RANGES, Topic.IMU, Topic.WHEELS)
#: The most messages of each decimated stream a view shows per second of log time.
DEFAULT_MAX_RATE_HZ = 10.0
_DATA = operator.attrgetter("data")


@dataclass(frozen=True)
class RobotGeometry:
    """Where the sensors sit on the robot; the defaults are the simulator's."""

    tof_angles_rad: tuple[float, ...] = (0.0, math.radians(40.0), math.radians(-40.0))
    tof_forward_m: float = 0.06
    tof_height_m: float = 0.05
    camera_height_m: float = 0.05
    length_m: float = 0.12
    width_m: float = 0.07

    @classmethod
    def from_run(cls, run: dict[str, str]) -> RobotGeometry:
        """The geometry recorded in the run metadata's simulator settings, where present."""
        try:
            settings = json.loads(run.get("simulator", "{}"))
        except json.JSONDecodeError:
            settings = {}
        robot = settings.get("robot", {}) if isinstance(settings, dict) else {}
        explorer = settings.get("explorer", {}) if isinstance(settings, dict) else {}
        base = cls()
        return cls(
            tof_angles_rad=tuple(robot.get("tof_angles_rad", base.tof_angles_rad)),
            tof_forward_m=float(robot.get("tof_forward_m", base.tof_forward_m)),
            tof_height_m=float(robot.get("tof_height_m", base.tof_height_m)),
            camera_height_m=float(explorer.get("camera_height_m", base.camera_height_m)),
            length_m=float(robot.get("length_m", base.length_m)),
            width_m=float(robot.get("width_m", base.width_m)),
        )


def time_column(times_ns: Sequence[int] | np.ndarray) -> rr.TimeColumn:
    """A ``sim_time`` column of integer nanoseconds."""
    import rerun as rr

    ns = np.asarray(times_ns, dtype=np.int64).astype("timedelta64[ns]")
    return rr.TimeColumn(TIMELINE, duration=ns)


def set_time(rec: rr.RecordingStream, time_ns: int) -> None:
    """Put the next ``log`` calls of ``rec`` at ``time_ns`` on ``sim_time``."""
    rec.set_time(TIMELINE, duration=np.timedelta64(int(time_ns), "ns"))


def _columns(
    messages: list[LogMessage], message_type: Any, *names: str
) -> tuple[np.ndarray, Columns]:
    """Log times (int ns) and the fields ``names`` of ``messages``, as columns in the
    order of time (file order is not trusted)."""
    times = np.fromiter(map(_LOG_TIME, messages), dtype=np.int64, count=len(messages))
    if np.any(times[1:] < times[:-1]):
        order = np.argsort(times, kind="stable")
        times, messages = times[order], [messages[i] for i in order]
    spec = spec_of(message_type.DESCRIPTOR, only=names)
    try:
        return times, decode_columns(list(map(_DATA, messages)), spec)
    except LogFormatError:
        # A payload that is not this message type (damaged, or another writer's bug):
        # show the others, as a replay skips what it cannot read.
        keep = [i for i, m in enumerate(messages) if _columns_of_one(m.data, spec)]
        kept = [messages[i] for i in keep]
        return times[keep], decode_columns(list(map(_DATA, kept)), spec)


def _columns_of_one(payload: bytes, spec: FieldSpec) -> bool:
    try:
        decode_columns([payload], spec)
    except LogFormatError:
        return False
    return True


def _decoded(message_type: Any, message: LogMessage) -> Any:
    """``message`` decoded as ``message_type``, or ``None`` where it does not decode."""
    try:
        return message_type.FromString(message.data)
    except DecodeError:
        return None


def _all_decoded(message_type: Any, messages: list[LogMessage]) -> list[tuple[LogMessage, Any]]:
    """The messages that decode as ``message_type``, with their decoded message."""
    pairs = [(m, _decoded(message_type, m)) for m in messages]
    return [(m, d) for m, d in pairs if d is not None]


@dataclass
class Carried:
    """What a view logged in pieces (a log a window at a time, a live run a sweep at
    a time) carries from one piece to the next, so that the pieces log what the
    whole would: the entities whose static style is logged (once), the controller's
    last state (its text is logged where it changes) and the trajectory."""

    styled: set[str] = field(default_factory=set)
    controller_state: str | None = None
    trail: Trail = field(default_factory=lambda: Trail())
    #: At most this many messages a second of each of :data:`DECIMATED_TOPICS` are
    #: shown (0: every one).
    max_rate_hz: float = DEFAULT_MAX_RATE_HZ
    #: Per decimated topic, the time slot (log time // period) of the last one shown.
    shown_slot: dict[str, int] = field(default_factory=dict)


def decimated(messages: list[LogMessage], topic: str, carried: Carried) -> list[LogMessage]:
    """The messages of ``topic`` a view shows: the first of each ``1 / max_rate_hz``
    slot of log time not shown yet (all of them when ``max_rate_hz`` is 0). Slots are
    fixed on log time, and the last one shown is carried, so a log viewed a window at
    a time or whole shows the same messages."""
    if not messages or carried.max_rate_hz <= 0.0:
        return messages
    period_ns = max(1, round(1e9 / carried.max_rate_hz))
    times = np.fromiter(map(_LOG_TIME, messages), dtype=np.int64, count=len(messages))
    slots = times // period_ns
    before = carried.shown_slot.get(topic, np.iinfo(np.int64).min)
    # A message is shown when its slot is later than every slot before it.
    highest = np.maximum.accumulate(np.concatenate(([before], slots[:-1])))
    shown = np.flatnonzero(slots > highest)
    carried.shown_slot[topic] = int(max(before, slots.max()))
    return [messages[i] for i in shown]


def _static(rec: rr.RecordingStream, entity: str, value: Any, carried: Carried) -> None:
    """Log ``value`` to ``entity`` as static, unless an earlier piece did."""
    if entity not in carried.styled:
        carried.styled.add(entity)
        rec.log(entity, value, static=True)


def _series(
    rec: rr.RecordingStream,
    carried: Carried,
    entity: str,
    times: np.ndarray,
    columns: Columns,
    *names: str,
) -> None:
    """The fields ``names`` as the series of one time-series entity, named after them."""
    import rerun as rr

    values = np.stack([columns[name].astype(np.float64) for name in names], axis=1)
    data = rr.Scalars.columns(scalars=values.reshape(-1)).partition([len(names)] * len(times))
    rec.send_columns(entity, indexes=[time_column(times)], columns=data)
    _static(rec, entity, rr.SeriesLines(names=list(names)), carried)


def log_truth(
    rec: rr.RecordingStream, truth: dict[str, list[LogMessage]], trail: Trail | None = None
) -> None:
    """The network (static) and the robot's true pose, with its trajectory so far
    (carried on from ``trail``, if given)."""
    import rerun as rr

    for _, scene in _all_decoded(SceneUpdate, truth.get(Topic.NETWORK, []))[:1]:
        strips: list[list[tuple[float, float, float]]] = []
        positions: list[tuple[float, float, float]] = []
        labels: list[str] = []
        for entity in scene.entities:
            for line in entity.lines:
                strips.append([(p.x, p.y, p.z) for p in line.points])
            for sphere in entity.spheres:
                p = sphere.pose.position
                positions.append((p.x, p.y, p.z))
                labels.append(entity.texts[0].text if entity.texts else entity.id)
        rec.log(
            "world/network/pipes",
            rr.LineStrips3D(strips, radii=0.004, colors=(150, 150, 150)),
            static=True,
        )
        rec.log(
            "world/network/nodes",
            rr.Points3D(positions, labels=labels, radii=0.03, colors=(230, 130, 0)),
            static=True,
        )
    poses = truth.get(Topic.TRUE_POSE, [])
    if not poses:
        return
    times, c = _columns(poses, FrameTransform, "translation", "rotation")
    xyz = np.stack([c[f"translation.{k}"] for k in "xyz"], axis=1)
    xyzw = np.stack([c[f"rotation.{k}"] for k in "xyzw"], axis=1)
    rec.send_columns(
        "world/robot",
        indexes=[time_column(times)],
        columns=rr.Transform3D.columns(translation=xyz, quaternion=xyzw),
    )
    (trail if trail is not None else Trail()).log(rec, times, xyz)


class Trail:
    """The robot's trajectory so far, a point every few centimetres of travel.

    Drawn in pieces of :data:`TRAIL_PIECE_POINTS` points, each its own entity
    (``world/trajectory/0000``, ``0001``, ...): the piece being drawn is logged again
    with each new point, a full one stays as it was last logged, and a piece not yet
    begun has nothing at that time. So at any time the view shows the path so far,
    and the data logged grows with the path's length: one strip of the whole path at
    every point grew with its square (20 million points for the 100-junction run's
    323 m, most of a 2.3 GB view), pieces keep it to the piece's length times the
    points. Each piece begins at the last point of the one before, so the path is
    unbroken.

    It carries on across calls, so a run logged in pieces (the live view) draws the
    same path as the whole run logged at once.
    """

    def __init__(self) -> None:
        #: Every point kept so far.
        self.kept: list[np.ndarray] = []
        self._travelled_m = 0.0
        self._last: np.ndarray | None = None

    def log(self, rec: rr.RecordingStream, times: np.ndarray, xyz: np.ndarray) -> None:
        """Extend the trail by the poses ``xyz`` at ``times`` and log it as it grows."""
        import rerun as rr

        if len(times) == 0:
            return
        before = self._travelled_m
        path = xyz if self._last is None else np.concatenate([self._last[None], xyz])
        steps_m = np.linalg.norm(np.diff(path, axis=0), axis=1)
        travelled = before + np.cumsum(steps_m)
        if self._last is None:
            travelled = np.concatenate([[0.0], travelled])
        previous = -1.0 if self._last is None else np.floor(before / _TRAJECTORY_STEP_M)
        steps = np.floor(travelled / _TRAJECTORY_STEP_M)
        kept = np.nonzero(np.diff(steps, prepend=previous) > 0)[0]
        self._travelled_m, self._last = float(travelled[-1]), xyz[-1]
        by_piece: dict[int, tuple[list[np.ndarray], list[int]]] = {}
        for i in kept:
            self.kept.append(xyz[i])
            n = len(self.kept)
            if n < 2:
                continue
            # Point n - 1 ends piece (n - 2) // P, which starts at point piece * P.
            piece = (n - 2) // TRAIL_PIECE_POINTS
            strips, at = by_piece.setdefault(piece, ([], []))
            strips.append(np.array(self.kept[piece * TRAIL_PIECE_POINTS : n]))
            at.append(int(times[i]))
        for piece, (strips, at) in by_piece.items():
            entity = f"{TRAIL_ENTITY}/{piece:04d}"
            if len(strips[0]) == 2:  # the piece's first strip: its style with it
                style = rr.LineStrips3D.from_fields(colors=(60, 160, 255), radii=0.003)
                rec.log(entity, style, static=True)
            rec.send_columns(
                entity,
                indexes=[time_column(np.array(at))],
                columns=rr.LineStrips3D.columns(strips=strips),
            )


def _log_ranges(
    rec: rr.RecordingStream, messages: list[LogMessage], geometry: RobotGeometry, carried: Carried
) -> None:
    import rerun as rr

    if not messages:
        return
    names = ("front_m", "front_left_m", "front_right_m")
    times, c = _columns(messages, Ranges, *names)
    _series(rec, carried, "sensors/tof/range_m", times, c, *names)
    values = np.stack([c[name] for name in names], axis=1)
    angles = np.asarray(geometry.tof_angles_rad[:3], dtype=np.float64)
    directions = np.stack([np.cos(angles), np.sin(angles), np.zeros(3)], axis=1)
    vectors = (values[:, :, None] * directions[None, :, :]).reshape(-1, 3)
    origin = (geometry.tof_forward_m, 0.0, geometry.tof_height_m)
    rec.send_columns(
        "world/robot/tof",
        indexes=[time_column(times)],
        columns=rr.Arrows3D.columns(vectors=vectors).partition([3] * len(times)),
    )
    _static(
        rec,
        "world/robot/tof",
        rr.Arrows3D.from_fields(origins=[origin] * 3, colors=_RAY_COLORS, radii=0.002),
        carried,
    )


def _log_body(
    rec: rr.RecordingStream, messages: dict[str, list[LogMessage]], carried: Carried
) -> None:
    imu, wheels = messages.get(Topic.IMU), messages.get(Topic.WHEELS)
    if imu:
        accel = ("accel_forward_mps2", "accel_left_mps2")
        times, c = _columns(imu, Imu, "yaw_rate_rps", *accel)
        _series(rec, carried, "sensors/imu/yaw_rate_rps", times, c, "yaw_rate_rps")
        _series(rec, carried, "sensors/imu/accel_mps2", times, c, *accel)
    if wheels:
        ticks = ("left_ticks", "right_ticks")
        times, c = _columns(wheels, WheelEncoders, *ticks)
        _series(rec, carried, "sensors/wheels/ticks", times, c, *ticks)


def _log_controller(rec: rr.RecordingStream, messages: list[LogMessage], carried: Carried) -> None:
    import rerun as rr

    if not messages:
        return
    times, c = _columns(messages, ControllerState, "state", "linear_mps", "angular_rps")
    _series(rec, carried, "controller/linear_mps", times, c, "linear_mps")
    _series(rec, carried, "controller/angular_rps", times, c, "angular_rps")
    # The state as text each time it changes: a line per control step would drown the log.
    changes = c.changes("state")
    states = c.strings("state", changes)
    if states and states[0] == carried.controller_state:  # no change from the last piece
        changes, states = changes[1:], states[1:]
    carried.controller_state = c.strings("state", np.array([len(times) - 1]))[0]
    texts = [f"controller: {state}" for state in states]
    rec.send_columns(
        "log/controller",
        indexes=[time_column(times[changes])],
        columns=rr.TextLog.columns(text=texts, level=["DEBUG"] * len(texts)),
    )


def _log_camera(
    rec: rr.RecordingStream,
    messages: dict[str, list[LogMessage]],
    geometry: RobotGeometry,
    carried: Carried,
) -> None:
    import rerun as rr

    images = _all_decoded(CompressedImage, messages.get(Topic.IMAGE, []))
    if images:
        decoded = [image for _, image in images]
        rec.send_columns(
            "camera/image",
            indexes=[time_column([m.log_time_ns for m, _ in images])],
            columns=rr.EncodedImage.columns(
                blob=[i.data for i in decoded], media_type=[f"image/{i.format}" for i in decoded]
            ),
        )
    sweep_commands = _all_decoded(SweepCommand, messages.get(Topic.SWEEP, []))
    if not sweep_commands:
        return
    sweeps = [m for m, _ in sweep_commands]
    # The camera's direction from a sweep's start to its end; nothing in between sweeps.
    commands = [command for _, command in sweep_commands]
    shown = [c for c in commands if c.phase != SweepCommand.END]
    vectors = [(math.cos(c.camera_angle_rad), math.sin(c.camera_angle_rad), 0.0) for c in shown]
    labels = [f"sweep {c.sweep_id}" + (f" ({c.probe_kind})" if c.probe else "") for c in shown]
    rec.send_columns(
        "world/robot/camera",
        indexes=[time_column([m.log_time_ns for m in sweeps])],
        columns=rr.Arrows3D.columns(
            vectors=_CAMERA_RAY_M * np.array(vectors).reshape(-1, 3), labels=labels
        ).partition([int(c.phase != SweepCommand.END) for c in commands]),
    )
    origin = (0.0, 0.0, geometry.camera_height_m)
    style = rr.Arrows3D.from_fields(origins=[origin], colors=(255, 220, 0), radii=0.004)
    _static(rec, "world/robot/camera", style, carried)


def _log_events(rec: rr.RecordingStream, messages: dict[str, list[LogMessage]]) -> None:
    import rerun as rr

    rows: list[tuple[int, str, str]] = []
    for m, event in _all_decoded(Log, messages.get(Topic.EVENTS, [])):
        level = "WARN" if event.level >= Log.Level.WARNING else "INFO"
        rows.append((m.log_time_ns, event.message, level))
    for m, node in _all_decoded(NodeEvent, messages.get(Topic.NODE, [])):
        if node.kind == NodeEvent.ARRIVAL:
            text = f"visit {node.visit_id}: arrived at a node"
        else:
            turn = math.degrees(node.exit_rad)
            text = f"visit {node.visit_id}: left by the exit at {turn:+.0f} deg"
        rows.append((m.log_time_ns, text, "INFO"))
    if rows:
        rows.sort(key=lambda row: row[0])
        times, texts, levels = zip(*rows, strict=True)
        rec.send_columns(
            "log/events",
            indexes=[time_column(times)],
            columns=rr.TextLog.columns(text=texts, level=levels),
        )


def log_robot(
    rec: rr.RecordingStream,
    messages: dict[str, list[LogMessage]],
    geometry: RobotGeometry,
    carried: Carried | None = None,
) -> None:
    """Every ``/robot`` stream: range rays and values, IMU, wheels, controller, camera
    (of one piece of a view logged in pieces, given what the pieces before left in
    ``carried``)."""
    import rerun as rr

    carried = carried if carried is not None else Carried()
    messages = {
        topic: decimated(found, topic, carried) if topic in DECIMATED_TOPICS else found
        for topic, found in messages.items()
    }
    half = (geometry.length_m / 2, geometry.width_m / 2, geometry.tof_height_m / 2)
    body = rr.Boxes3D(half_sizes=[half], centers=[(0.0, 0.0, half[2])], colors=(200, 200, 200))
    _static(rec, "world/robot/body", body, carried)
    # The images first: rerun encodes and writes them in its own threads while the
    # other streams are decoded here.
    _log_camera(rec, messages, geometry, carried)
    _log_ranges(rec, messages.get(Topic.RANGES, []), geometry, carried)
    _log_body(rec, messages, carried)
    _log_controller(rec, messages.get(Topic.CONTROLLER, []), carried)
    _log_events(rec, messages)
