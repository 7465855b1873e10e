"""What a log tells of each visit: its sweeps, put together from the camera's
commands and images, and its exit scan, departures and blocked pipes.

Both are read one message at a time (:class:`SweepAssembler`, :class:`NodeEvents`),
so that a replay can decide a visit as soon as the log has told all of it. What
cannot be read is lost alone: a sweep with an image missing, undecodable or not a
readable PNG is skipped with a warning, and the rest go on.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, overload

import cv2
import numpy as np
from google.protobuf.message import DecodeError

from pipemap.errors import PipemapError
from pipemap.localizer import IlluminationConfig, ImageSet, normalised
from pipemap.recorder import LogMessage, Topic
from pipemap.recorder.messages import IMAGE_FORMATS, blocked_visit, decode_image, refused_probe
from pipemap.recorder.schemas import CompressedImage, Log, NodeEvent, SweepCommand
from pipemap.replay.source import ordered

__all__ = [
    "LogTimeWentBack",
    "LoggedExits",
    "LoggedSweep",
    "NodeEvents",
    "SeenSets",
    "SweepAssembler",
    "SweepSets",
    "Sweeps",
    "in_order",
    "node_events_of",
    "sweeps_of",
]


@dataclass(frozen=True, eq=False)
class LoggedSweep:
    """A complete sweep of the log, as the localizer sees it.

    It keeps the grey frames as the camera gave them, 8 bits a pixel, and makes its
    :class:`ImageSet` (float32, four times the size) each time :attr:`images` is
    asked for. A replay holds every sweep of the log at once: a 400 px sweep takes
    0.96 MB so, 3.8 MB as float32, and a thousand-junction log has thousands."""

    sweep_id: int
    visit_id: int
    end_ns: int
    #: ``(N, height, width)`` uint8, read-only.
    frames: np.ndarray
    fov_rad: float
    camera_angle_rad: float
    #: ``(kind, yaw_rad, forward_m, left_m)`` of a probe sweep, else ``None``.
    probe: tuple[str, float, float, float] | None = None
    #: The robot's (roll, pitch) as its IMU read them during the sweep (0.0, 0.0 for a
    #: level robot and for logs from before the log held them).
    imu_tilt_rad: tuple[float, float] = (0.0, 0.0)

    @property
    def images(self) -> ImageSet:
        """The sweep as an image set (a new one each time: keep it only while needed)."""
        return ImageSet(
            self.frames,
            fov_rad=self.fov_rad,
            camera_angle_rad=self.camera_angle_rad,
            imu_tilt_rad=self.imu_tilt_rad,
        )

    @property
    def count(self) -> int:
        """How many images the sweep has."""
        return int(self.frames.shape[0])


class SweepSets(Mapping[int, ImageSet]):
    """Sweeps by id, each read as its :class:`ImageSet` only when looked up (see
    :class:`LoggedSweep`)."""

    def __init__(self, sweeps: Mapping[int, LoggedSweep]) -> None:
        self._sweeps = dict(sweeps)

    def __getitem__(self, sweep_id: int) -> ImageSet:
        return self._sweeps[sweep_id].images

    def __iter__(self) -> Iterator[int]:
        return iter(self._sweeps)

    def __len__(self) -> int:
        return len(self._sweeps)


class SeenSets(Sequence[ImageSet]):
    """The visit sets of sweeps ``ids`` as the localizer saw them (normalised under a
    lamp), each made when looked up: :func:`pipemap.localizer.pairwise_matches`
    prepares each set once and keeps only what it prepared, so the float32 sets of a
    whole log are never all held at once (a score's pairs with other matcher settings
    than the replay's)."""

    def __init__(
        self,
        sets: Mapping[int, ImageSet],
        ids: list[int],
        illumination: IlluminationConfig | None,
    ) -> None:
        self._sets, self._ids, self._illumination = sets, ids, illumination

    @overload
    def __getitem__(self, index: int) -> ImageSet: ...

    @overload
    def __getitem__(self, index: slice) -> Sequence[ImageSet]: ...

    def __getitem__(self, index: int | slice) -> ImageSet | Sequence[ImageSet]:
        if isinstance(index, slice):
            return [self[k] for k in range(len(self))[index]]
        image_set = self._sets[self._ids[index]]
        if self._illumination is None:
            return image_set
        return normalised(image_set, self._illumination)

    def __len__(self) -> int:
        return len(self._ids)


@dataclass(frozen=True)
class LoggedExits:
    """A visit's exit scan and where the robot left by, as the log holds them."""

    visit_id: int
    exits_rad: tuple[float, ...] | None = None
    x_m: float = 0.0
    y_m: float = 0.0
    odometer_m: float | None = None
    #: The pipe taken, relative to the arrival heading; ``None``: no departure.
    departure_rad: float | None = None
    #: The pipes the robot left by first and gave up as blocked (``pipemap.blocked``
    #: events), in order, before it left by ``departure_rad``.
    blocked_rad: tuple[float, ...] = ()

    @property
    def position_m(self) -> tuple[float, float] | None:
        """The dead reckoning logged with the exits (``None`` without them)."""
        return None if self.exits_rad is None else (self.x_m, self.y_m)


@dataclass
class Sweeps:
    """The complete sweeps of a log, and what became of the others."""

    sweeps: list[LoggedSweep] = field(default_factory=list)
    #: One line per sweep that was skipped, or message that could not be read.
    warnings: list[str] = field(default_factory=list)


def _seconds(t_ns: int) -> str:
    return f"{t_ns / 1e9:.3f} s"


class _Sweep:
    """A sweep being put together: its start command, its frames, what broke it."""

    def __init__(self, start: Any) -> None:
        self.start = start
        self.frames: list[np.ndarray] = []
        self.broken = ""

    def label(self) -> str:
        kind = f" ({self.start.probe_kind} probe)" if self.start.probe else ""
        return f"sweep {self.start.sweep_id}{kind} of visit {self.start.visit_id}"


class SweepAssembler:
    """Puts the sweeps of ordered ``/robot`` messages together one message at a time
    (:meth:`feed`), so a replay can decide a visit as soon as its sweeps are complete
    instead of holding the whole log. A sweep with an image that is missing, does
    not decode or is not a readable PNG or JPEG is skipped, and so is one cut off by the
    end of the log (:meth:`finish`); each gets a line in :attr:`warnings`."""

    def __init__(self, name: str = "log") -> None:
        self.name = name
        #: One line per sweep that was skipped, or message that could not be read.
        self.warnings: list[str] = []
        self._images_at: dict[int, tuple[str, bytes]] = {}
        # Log time of an image message -> why it is unusable.
        self._unreadable: dict[int, str] = {}
        self._current: _Sweep | None = None
        self._undecodable = 0  # camera commands that do not decode
        #: The visit whose sweep the last message started (``None``: it started none).
        self.started: int | None = None

    def _skip(self, sweep: _Sweep, why: str) -> None:
        self.warnings.append(f"{self.name}: {sweep.label()} skipped: {why}")

    def feed(self, m: LogMessage) -> LoggedSweep | None:
        """Take the next message; returns the sweep it completes, if any."""
        self.started = None
        if m.topic == Topic.IMAGE:
            try:
                image = CompressedImage.FromString(m.data)
            except DecodeError:
                self._unreadable[m.log_time_ns] = "does not decode as foxglove.CompressedImage"
                return None
            if image.format not in IMAGE_FORMATS:
                self._unreadable[m.log_time_ns] = (
                    f"is in format {image.format!r}, not {' or '.join(IMAGE_FORMATS)}"
                )
            else:
                self._images_at[m.log_time_ns] = (image.format, image.data)
            return None
        if m.topic != Topic.SWEEP:
            return None
        current = self._current
        try:
            command = SweepCommand.FromString(m.data)
        except DecodeError:
            self._undecodable += 1
            if current is not None and not current.broken:
                current.broken = f"a command at {_seconds(m.log_time_ns)} does not decode"
            return None
        if command.phase == SweepCommand.START:
            if current is not None:
                self._skip(current, "it never ended")
            self._current = _Sweep(command)
            self.started = int(command.visit_id)
        elif command.phase == SweepCommand.IMAGE and current is not None:
            if not current.broken:
                self._add_image(current, command, m.log_time_ns)
        elif command.phase == SweepCommand.END and current is not None:
            self._current = None
            return self._ended(current, command, m.log_time_ns)
        return None

    def _add_image(self, sweep: _Sweep, command: Any, log_time_ns: int) -> None:
        n = sweep.start.image_count
        which = f"image {command.image_index + 1} of {n} ({_seconds(log_time_ns)})"
        image = self._images_at.pop(log_time_ns, None)
        if image is None:
            why = self._unreadable.pop(log_time_ns, "is missing")
            sweep.broken = f"{which} {why}"
            return
        rgb = decode_image(image[1], image[0])
        if rgb is None:
            sweep.broken = f"{which} is not a readable {image[0].upper()}"
            return
        sweep.frames.append(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))

    def _ended(self, sweep: _Sweep, command: Any, log_time_ns: int) -> LoggedSweep | None:
        if sweep.broken:
            self._skip(sweep, sweep.broken)
            return None
        start = sweep.start
        if len(sweep.frames) != start.image_count:
            self._skip(sweep, f"{len(sweep.frames)} images of the {start.image_count} commanded")
            return None
        frames = np.stack(sweep.frames)
        frames.setflags(write=False)
        tilt = (start.imu_roll_rad, start.imu_pitch_rad)
        try:  # checked once here: a sweep that makes no image set is skipped
            ImageSet(
                frames,
                fov_rad=start.fov_rad,
                camera_angle_rad=start.camera_angle_rad,
                imu_tilt_rad=tilt,
            )
        except (PipemapError, ValueError) as exc:
            self._skip(sweep, str(exc))
            return None
        probe = None
        if start.probe:
            probe = (
                start.probe_kind,
                start.probe_yaw_rad,
                start.probe_forward_m,
                start.probe_left_m,
            )
        return LoggedSweep(
            command.sweep_id,
            start.visit_id,
            log_time_ns,
            frames,
            start.fov_rad,
            start.camera_angle_rad,
            probe,
            tilt,
        )

    def finish(self) -> None:
        """The log has ended: a sweep still open was cut off by it."""
        if self._current is not None:
            self.warnings.append(
                f"{self.name}: {self._current.label()} was cut off by the end of the log; skipped"
            )
            self._current = None
        if self._undecodable:
            self.warnings.append(
                f"{self.name}: {self._undecodable} camera command(s) do not decode as "
                "pipemap.SweepCommand; their sweeps are lost"
            )
            self._undecodable = 0


def sweeps_of(messages: list[LogMessage], name: str = "log") -> Sweeps:
    """Every complete sweep of ``messages`` (ordered ``/robot`` messages); see
    :class:`SweepAssembler` for what is skipped."""
    assembler = SweepAssembler(name)
    out = Sweeps()
    for m in messages:
        sweep = assembler.feed(m)
        if sweep is not None:
            out.sweeps.append(sweep)
    assembler.finish()
    out.warnings = assembler.warnings
    return out


class NodeEvents:
    """Each visit's exit scan and departures from ordered ``/robot`` messages, taken
    one at a time (:meth:`feed`). Node events that do not decode are skipped and
    counted (:meth:`finish` says how many).

    A visit may have several departures: each but the last was given up (a
    ``pipemap.blocked`` event of ``/robot/events`` follows it) and the robot came
    back; the last is the pipe it left by (or another given up, when the run ended
    before it left again)."""

    def __init__(self, name: str = "log") -> None:
        self.name = name
        self._scans: dict[int, NodeEvent] = {}
        self._departures: dict[int, list[float]] = {}
        self._given_up: dict[int, int] = {}
        self._refused: dict[int, list[str]] = {}
        self._undecodable = 0

    def feed(self, m: LogMessage) -> int | None:
        """Take the next message; returns the visit it names, if it is a node event
        or a blocked pipe (``None`` for any other message)."""
        if m.topic == Topic.EVENTS:
            refused = _refused_event(m.data)
            if refused is not None:
                self._refused.setdefault(refused[0], []).append(refused[1])
            blocked = _blocked_event(m.data)
            if blocked is not None:
                self._given_up[blocked] = self._given_up.get(blocked, 0) + 1
            return blocked
        if m.topic != Topic.NODE:
            return None
        try:
            event = NodeEvent.FromString(m.data)
        except DecodeError:
            self._undecodable += 1
            return None
        if event.kind == NodeEvent.EXITS:
            self._scans.setdefault(event.visit_id, event)
        elif event.kind == NodeEvent.DEPARTURE:
            self._departures.setdefault(event.visit_id, []).append(event.exit_rad)
        return int(event.visit_id)

    def refused(self, visit_id: int) -> list[str]:
        """The kinds of the probe moves the robot refused at the visit (its log's
        warnings say so), in the order it refused them."""
        return list(self._refused.get(visit_id, []))

    def visits(self) -> list[int]:
        """The visits with an exit scan or a departure so far, in order."""
        return sorted(set(self._scans) | set(self._departures))

    def of(self, visit_id: int) -> LoggedExits | None:
        """The visit's scan and departures so far (``None``: neither)."""
        scan = self._scans.get(visit_id)
        left = self._departures.get(visit_id, [])
        if scan is None and not left:
            return None
        blocked = min(self._given_up.get(visit_id, 0), len(left))
        return LoggedExits(
            visit_id,
            None if scan is None else tuple(scan.exits_rad),
            0.0 if scan is None else scan.x_estimate_m,
            0.0 if scan is None else scan.y_estimate_m,
            None if scan is None else scan.odometer_m,
            left[blocked] if blocked < len(left) else None,
            tuple(left[:blocked]),
        )

    def finish(self, warnings: list[str]) -> None:
        """The log has ended: a line in ``warnings`` if node events did not decode."""
        if self._undecodable:
            warnings.append(
                f"{self.name}: {self._undecodable} node event(s) do not decode as "
                "pipemap.NodeEvent; their visits' exits are lost"
            )
            self._undecodable = 0


def node_events_of(
    messages: list[LogMessage], warnings: list[str] | None = None, name: str = "log"
) -> dict[int, LoggedExits]:
    """Each visit's exit scan and departure from ordered ``/robot`` messages (see
    :class:`NodeEvents`); a line in ``warnings`` for node events that do not decode."""
    events = NodeEvents(name)
    for m in messages:
        events.feed(m)
    events.finish(warnings if warnings is not None else [])
    out = {}
    for visit_id in events.visits():
        exits = events.of(visit_id)
        assert exits is not None
        out[visit_id] = exits
    return out


def _refused_event(data: bytes) -> tuple[int, str] | None:
    """The visit id and probe kind of a refused probe move's warning, or ``None``."""
    try:
        return refused_probe(Log.FromString(data))
    except DecodeError:
        return None


def _blocked_event(data: bytes) -> int | None:
    """The visit id of a ``pipemap.blocked`` event, or ``None`` for any other line."""
    try:
        found = blocked_visit(Log.FromString(data))
    except DecodeError:
        return None
    return None if found is None else found[0]


class LogTimeWentBack(Exception):
    """A log read as it goes is not in the order of its log times (see :func:`in_order`)."""


def in_order(messages: Iterable[LogMessage]) -> Iterator[LogMessage]:
    """``messages``, read in a log time that never goes back (as pipemap writes a
    log), in the total order of replay (:func:`replay.source.ordered`): each is held
    until one of a later log time comes, and messages of one log time are put in
    order together. Raises :class:`LogTimeWentBack` when a log time goes back (the
    caller then reads the log whole and orders it)."""
    held: list[LogMessage] = []
    time_ns: int | None = None
    for m in messages:
        if time_ns is not None and m.log_time_ns < time_ns:
            raise LogTimeWentBack(f"log time goes back at {m.log_time_ns} ns")
        if m.log_time_ns != time_ns:
            yield from ordered(held)
            held, time_ns = [], m.log_time_ns
        held.append(m)
    yield from ordered(held)
