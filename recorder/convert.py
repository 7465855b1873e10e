"""Simulator records to log messages, written as they come.

:class:`RecordConverter` takes each record a run emits (see :mod:`sim.stream`) and
writes its messages: sensors and the controller under ``/robot``, the true pose and
the truth of each sweep under ``/truth``. The online decisions arrive already made
(:class:`ReadyMessage`). A whole sweep is flushed to disk when it ends.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from pipemap.recorder import messages, schemas
from pipemap.recorder.topics import Topic
from pipemap.sim.episode import Pose
from pipemap.sim.robot import EncoderReading, ImuReading, RangeReading, RobotSpec
from pipemap.sim.stream import (
    ControlStep,
    NodeArrival,
    NodeDeparture,
    NodeExits,
    Note,
    PipeBlocked,
    SimRecord,
    SweepImage,
    SweepStart,
    TruePose,
)

__all__ = ["LogRecord", "MessageSink", "ReadyMessage", "RecordConverter", "SweepDone"]


class MessageSink(Protocol):
    """Where a :class:`RecordConverter` writes: a :class:`~pipemap.recorder.writer.LogWriter`,
    or anything with its three methods (the live view keeps the messages in memory)."""

    def write(self, topic: str, log_time_ns: int, message: Any) -> None:
        """Serialize ``message`` and write it on ``topic``."""

    def write_serialized(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Write an already serialized message on ``topic``."""

    def flush(self) -> None:
        """Hand what is buffered on (to disk, for a file)."""


@dataclass(frozen=True)
class SweepDone:
    """A sweep's end, without its images (they were logged one by one)."""

    t_ns: int
    sweep_id: int
    visit_id: int
    image_count: int
    start_pose: Pose
    true_node: str


@dataclass(frozen=True)
class ReadyMessage:
    """A message made elsewhere (the network, an online decision), serialized, to
    write as it is (protobuf classes do not pickle across processes; bytes do)."""

    t_ns: int
    topic: str
    data: bytes

    @classmethod
    def of(cls, t_ns: int, topic: str, message: Any) -> ReadyMessage:
        """The serialized form of ``message``."""
        return cls(t_ns, topic, message.SerializeToString())


LogRecord = SimRecord | SweepDone | ReadyMessage


class RecordConverter:
    """Writes each record's messages to a :class:`MessageSink` (a log writer)."""

    def __init__(
        self,
        writer: MessageSink,
        spec: RobotSpec | None = None,
        encoding: messages.ImageEncoding | None = None,
    ) -> None:
        self.writer = writer
        self.spec = spec if spec is not None else RobotSpec()
        self.encoding = encoding or messages.ImageEncoding()

    def __call__(self, record: LogRecord) -> None:
        w, t = self.writer, record.t_ns
        if isinstance(record, RangeReading):
            front, left, right = record.ranges_m
            w.write(
                Topic.RANGES,
                t,
                schemas.Ranges(
                    time_ns=t,
                    front_m=front,
                    front_left_m=left,
                    front_right_m=right,
                    max_range_m=self.spec.tof_max_range_m,
                ),
            )
        elif isinstance(record, ImuReading):
            w.write(
                Topic.IMU,
                t,
                schemas.Imu(
                    time_ns=t,
                    yaw_rate_rps=record.yaw_rate_rps,
                    accel_forward_mps2=record.accel_forward_mps2,
                    accel_left_mps2=record.accel_left_mps2,
                ),
            )
        elif isinstance(record, EncoderReading):
            w.write(
                Topic.WHEELS,
                t,
                schemas.WheelEncoders(
                    time_ns=t,
                    left_ticks=record.left_ticks,
                    right_ticks=record.right_ticks,
                    ticks_per_rev=self.spec.encoder_ticks_per_rev,
                    wheel_diameter_m=self.spec.wheel_diameter_m,
                ),
            )
        elif isinstance(record, TruePose):
            p = record.pose
            w.write(Topic.TRUE_POSE, t, messages.pose_message(t, p.x_m, p.y_m, p.yaw_rad))
        elif isinstance(record, ControlStep):
            w.write(
                Topic.CONTROLLER,
                t,
                schemas.ControllerState(
                    time_ns=t,
                    state=record.state,
                    linear_mps=record.linear_mps,
                    angular_rps=record.angular_rps,
                    heading_estimate_rad=record.heading_estimate_rad,
                    x_estimate_m=record.x_estimate_m,
                    y_estimate_m=record.y_estimate_m,
                ),
            )
        elif isinstance(record, SweepStart):
            self._sweep_start(record)
        elif isinstance(record, SweepImage):
            w.write(Topic.IMAGE, t, messages.image_message(t, record.image, self.encoding))
            w.write(
                Topic.SWEEP,
                t,
                schemas.SweepCommand(
                    time_ns=t,
                    phase=schemas.SweepCommand.IMAGE,
                    sweep_id=record.sweep_id,
                    visit_id=record.visit_id,
                    image_index=record.index,
                    camera_angle_rad=record.camera_angle_rad,
                ),
            )
        elif isinstance(record, SweepDone):
            self._sweep_done(record)
        elif isinstance(record, ReadyMessage):
            w.write_serialized(record.topic, t, record.data)
        elif isinstance(record, NodeArrival):
            w.write(
                Topic.NODE,
                t,
                schemas.NodeEvent(
                    time_ns=t, kind=schemas.NodeEvent.ARRIVAL, visit_id=record.visit_id
                ),
            )
        elif isinstance(record, NodeExits):
            w.write(
                Topic.NODE,
                t,
                schemas.NodeEvent(
                    time_ns=t,
                    kind=schemas.NodeEvent.EXITS,
                    visit_id=record.visit_id,
                    exits_rad=list(record.exits_rad),
                    x_estimate_m=record.x_m,
                    y_estimate_m=record.y_m,
                    odometer_m=record.odometer_m,
                ),
            )
        elif isinstance(record, NodeDeparture):
            w.write(
                Topic.NODE,
                t,
                schemas.NodeEvent(
                    time_ns=t,
                    kind=schemas.NodeEvent.DEPARTURE,
                    visit_id=record.visit_id,
                    exits=record.exits,
                    exit_rad=record.exit_rad,
                ),
            )
        elif isinstance(record, PipeBlocked):
            w.write(Topic.EVENTS, t, messages.blocked_message(t, record.visit_id, record.exit_rad))
        elif isinstance(record, Note):
            w.write(Topic.EVENTS, t, messages.log_message(t, record.text, record.warning))
        else:
            raise TypeError(f"no log message for {type(record).__name__}")

    def _sweep_start(self, record: SweepStart) -> None:
        command = schemas.SweepCommand(
            time_ns=record.t_ns,
            phase=schemas.SweepCommand.START,
            sweep_id=record.sweep_id,
            visit_id=record.visit_id,
            image_count=record.image_count,
            camera_angle_rad=record.camera_angle_rad,
            fov_rad=record.fov_rad,
            # 0.0 is not written (proto3): a level robot's logs keep their bytes.
            imu_roll_rad=record.imu_tilt_rad[0],
            imu_pitch_rad=record.imu_tilt_rad[1],
        )
        if record.probe is not None:
            kind, yaw, forward, left = record.probe
            command.probe = True
            command.probe_kind = kind
            command.probe_yaw_rad = yaw
            command.probe_forward_m = forward
            command.probe_left_m = left
        self.writer.write(Topic.SWEEP, record.t_ns, command)

    def _sweep_done(self, record: SweepDone) -> None:
        t, p = record.t_ns, record.start_pose
        self.writer.write(
            Topic.SWEEP,
            t,
            schemas.SweepCommand(
                time_ns=t,
                phase=schemas.SweepCommand.END,
                sweep_id=record.sweep_id,
                visit_id=record.visit_id,
                image_count=record.image_count,
            ),
        )
        self.writer.write(
            Topic.TRUE_SWEEP,
            t,
            schemas.TrueSweep(
                time_ns=t,
                sweep_id=record.sweep_id,
                visit_id=record.visit_id,
                node=record.true_node,
                x_m=p.x_m,
                y_m=p.y_m,
                z_m=p.z_m,
                yaw_rad=p.yaw_rad,
                roll_rad=p.roll_rad,
                pitch_rad=p.pitch_rad,
            ),
        )
        # A whole sweep is on disk before the robot moves on: a hard kill loses less.
        self.writer.flush()
