"""Replay: rebuild the map from a log's ``/robot`` messages, deterministically.

The sweeps are put together from the camera's commands and images; every visit's
sweep goes to the localizer in the order the robot took them. When the localizer
asks for an active-vision probe, the probe sweeps the log holds for that visit
answer it, matched by kind and move; a probe the log does not hold is answered
``None``, and the decision records it as missing. Each visit's exit scan
(``/robot/node`` EXITS) goes with its sweep, and its departure tells the map which
port the robot left by, as online. Logs of format 1 have no exit scans: their maps
have no ports. The same log and settings give the same map, byte for byte.

What cannot be read is lost alone: a sweep with an image missing, undecodable or
not a readable PNG is skipped with a warning, and the replay goes on. Where a visit
is lost (its sweep skipped, or in a damaged part of the log), the map's path is
broken there: the visits either side are not joined by an edge.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from google.protobuf.message import DecodeError

from pipemap.errors import PipemapError
from pipemap.localizer import (
    Decision,
    IlluminationConfig,
    ImageSet,
    Localizer,
    LocalizerConfig,
    ProbeRequest,
    TopoMap,
    map_document,
)
from pipemap.recorder import Integrity, LogMessage, Topic
from pipemap.recorder.messages import blocked_visit, decode_png
from pipemap.recorder.metadata import lamp_strength
from pipemap.recorder.schemas import CompressedImage, Log, NodeEvent, SweepCommand
from pipemap.replay.source import MessageSource

__all__ = [
    "REPLAY_TOPICS",
    "LoggedExits",
    "LoggedSweep",
    "ReplayResult",
    "SweepSets",
    "Sweeps",
    "VisitDecision",
    "answer_probes",
    "node_events_of",
    "replay",
    "sweeps_of",
    "visit_label",
]

#: The topics a replay reads (:func:`sweeps_of`, :func:`node_events_of`): a source
#: may hold these alone (:class:`replay.source.FileSource`'s ``topics``).
REPLAY_TOPICS = (Topic.SWEEP, Topic.IMAGE, Topic.NODE, Topic.EVENTS)

#: A probe in the log answers a request for the same kind and move, to this much.
_PROBE_MATCH = 1e-9


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


@dataclass(frozen=True)
class VisitDecision:
    """The replay's decision for one node visit."""

    visit_id: int
    sweep_id: int
    time_ns: int
    decision: Decision
    #: Wall time of the decision (not part of any deterministic output).
    latency_s: float
    #: Probes the localizer asked for that the log does not hold.
    probes_not_in_log: int
    #: The visit's exit scan and departure (robot data), if the log has them.
    exits: LoggedExits | None = None


@dataclass
class ReplayResult:
    """The decisions of a replay, its map, and what it had to say about the log."""

    visits: list[VisitDecision]
    topomap: TopoMap
    integrity: Integrity
    warnings: list[str] = field(default_factory=list)
    sweeps: int = 0
    #: The log's duration (:attr:`replay.source.MessageSource.duration_ns`).
    duration_ns: int = 0
    images: int = 0
    #: Camera angle of each sweep's first image relative to the robot (robot data).
    camera_angles: dict[int, float] = field(default_factory=dict)
    #: The image set of each visit's own sweep (probes aside), by sweep id; made on
    #: each lookup (:class:`SweepSets`).
    visit_sets: Mapping[int, ImageSet] = field(default_factory=dict)
    #: Positions in ``visits`` before which the path is broken (a visit was lost).
    breaks: tuple[int, ...] = ()
    #: The localizer after the replay: its map and its junctions' sweeps, ready to
    #: go on (to drive a route on the same map, say).
    localizer: Localizer | None = None
    #: The localizer's illumination settings (``lamp`` decided): how it saw the sets.
    illumination: IlluminationConfig | None = None

    def document(self) -> dict[str, Any]:
        """The map document, in the format of ``pipemap map --json``."""
        return map_document(
            self.topomap, [(visit_label(v.visit_id), v.decision) for v in self.visits]
        )


def visit_label(visit_id: int) -> str:
    """A visit's name in the map document: its number, as ``pipemap sim`` names folders."""
    return f"{visit_id:04d}"


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


def sweeps_of(messages: list[LogMessage], name: str = "log") -> Sweeps:
    """Every complete sweep of ``messages`` (ordered ``/robot`` messages). A sweep with
    an image that is missing, does not decode or is not a readable PNG is skipped, and
    so is one cut off by the end of the log; each gets a warning, and the rest go on."""
    images_at: dict[int, bytes] = {}
    unreadable: dict[int, str] = {}  # log time of an image message -> why it is unusable
    out = Sweeps()
    current: _Sweep | None = None
    undecodable = 0  # camera commands that do not decode

    def skip(sweep: _Sweep, why: str) -> None:
        out.warnings.append(f"{name}: {sweep.label()} skipped: {why}")

    for m in messages:
        if m.topic == Topic.IMAGE:
            try:
                image = CompressedImage.FromString(m.data)
            except DecodeError:
                unreadable[m.log_time_ns] = "does not decode as foxglove.CompressedImage"
                continue
            if image.format != "png":
                unreadable[m.log_time_ns] = f"is in format {image.format!r}, not png"
            else:
                images_at[m.log_time_ns] = image.data
        elif m.topic == Topic.SWEEP:
            try:
                command = SweepCommand.FromString(m.data)
            except DecodeError:
                undecodable += 1
                if current is not None and not current.broken:
                    current.broken = f"a command at {_seconds(m.log_time_ns)} does not decode"
                continue
            if command.phase == SweepCommand.START:
                if current is not None:
                    skip(current, "it never ended")
                current = _Sweep(command)
            elif command.phase == SweepCommand.IMAGE and current is not None:
                if current.broken:
                    continue
                n = current.start.image_count
                which = f"image {command.image_index + 1} of {n} ({_seconds(m.log_time_ns)})"
                png = images_at.pop(m.log_time_ns, None)
                if png is None:
                    why = unreadable.pop(m.log_time_ns, "is missing")
                    current.broken = f"{which} {why}"
                    continue
                rgb = decode_png(png)
                if rgb is None:
                    current.broken = f"{which} is not a readable PNG"
                    continue
                current.frames.append(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
            elif command.phase == SweepCommand.END and current is not None:
                sweep, current = current, None
                if sweep.broken:
                    skip(sweep, sweep.broken)
                    continue
                start = sweep.start
                if len(sweep.frames) != start.image_count:
                    skip(sweep, f"{len(sweep.frames)} images of the {start.image_count} commanded")
                    continue
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
                    skip(sweep, str(exc))
                    continue
                probe = None
                if start.probe:
                    probe = (
                        start.probe_kind,
                        start.probe_yaw_rad,
                        start.probe_forward_m,
                        start.probe_left_m,
                    )
                out.sweeps.append(
                    LoggedSweep(
                        command.sweep_id,
                        start.visit_id,
                        m.log_time_ns,
                        frames,
                        start.fov_rad,
                        start.camera_angle_rad,
                        probe,
                        tilt,
                    )
                )
    if current is not None:
        out.warnings.append(f"{name}: {current.label()} was cut off by the end of the log; skipped")
    if undecodable:
        out.warnings.append(
            f"{name}: {undecodable} camera command(s) do not decode as pipemap.SweepCommand; "
            "their sweeps are lost"
        )
    return out


def node_events_of(
    messages: list[LogMessage], warnings: list[str] | None = None, name: str = "log"
) -> dict[int, LoggedExits]:
    """Each visit's exit scan and departure from ordered ``/robot`` messages. Node
    events that do not decode are skipped, with a line in ``warnings``.

    A visit may have several departures: each but the last was given up (a
    ``pipemap.blocked`` event of ``/robot/events`` follows it) and the robot came
    back; the last is the pipe it left by (or another given up, when the run ended
    before it left again)."""
    scans: dict[int, NodeEvent] = {}
    departures: dict[int, list[float]] = {}
    given_up: dict[int, int] = {}
    undecodable = 0
    for m in messages:
        if m.topic == Topic.EVENTS:
            blocked = _blocked_event(m.data)
            if blocked is not None:
                given_up[blocked] = given_up.get(blocked, 0) + 1
            continue
        if m.topic != Topic.NODE:
            continue
        try:
            event = NodeEvent.FromString(m.data)
        except DecodeError:
            undecodable += 1
            continue
        if event.kind == NodeEvent.EXITS:
            scans.setdefault(event.visit_id, event)
        elif event.kind == NodeEvent.DEPARTURE:
            departures.setdefault(event.visit_id, []).append(event.exit_rad)
    if undecodable and warnings is not None:
        warnings.append(
            f"{name}: {undecodable} node event(s) do not decode as pipemap.NodeEvent; "
            "their visits' exits are lost"
        )
    out: dict[int, LoggedExits] = {}
    for visit_id in sorted(set(scans) | set(departures)):
        scan = scans.get(visit_id)
        left = departures.get(visit_id, [])
        blocked = min(given_up.get(visit_id, 0), len(left))
        out[visit_id] = LoggedExits(
            visit_id,
            None if scan is None else tuple(scan.exits_rad),
            0.0 if scan is None else scan.x_estimate_m,
            0.0 if scan is None else scan.y_estimate_m,
            None if scan is None else scan.odometer_m,
            left[blocked] if blocked < len(left) else None,
            tuple(left[:blocked]),
        )
    return out


def _blocked_event(data: bytes) -> int | None:
    """The visit id of a ``pipemap.blocked`` event, or ``None`` for any other line."""
    try:
        found = blocked_visit(Log.FromString(data))
    except DecodeError:
        return None
    return None if found is None else found[0]


class _LoggedProbes:
    """Answers probe requests from the probe sweeps the log holds for one visit (their
    image sets made here, before the decision: they are the camera's, not its work)."""

    def __init__(self, probes: list[LoggedSweep]) -> None:
        self.probes = [(sweep.probe, sweep.images) for sweep in probes]
        self.not_in_log = 0

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        wanted = (request.yaw_rad, request.forward_m, request.left_m)
        for probe, images in self.probes:
            assert probe is not None
            kind, *move = probe
            if kind == request.kind.value and all(
                math.isclose(a, b, rel_tol=0.0, abs_tol=_PROBE_MATCH)
                for a, b in zip(move, wanted, strict=True)
            ):
                return images
        self.not_in_log += 1
        return None


def answer_probes(
    localizer: Localizer,
    images: ImageSet,
    probes: list[LoggedSweep],
    exits_rad: tuple[float, ...] | None = None,
    odometer_m: float | None = None,
) -> tuple[Decision, int]:
    """``localizer``'s decision for a visit's ``images`` (and its exit scan, if
    logged), its probe requests answered from the visit's logged ``probes``; and how
    many requests the log could not answer."""
    answers = _LoggedProbes(probes)
    decision = localizer.localize(images, answers, exits_rad, odometer_m)
    return decision, answers.not_in_log


def replay(
    source: MessageSource,
    config: LocalizerConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ReplayResult:
    """Feed every visit's sweep of ``source`` to a new localizer, in the robot's order."""
    messages = source.robot_messages()
    found = sweeps_of(messages, source.name)
    sweeps, warnings = found.sweeps, list(found.warnings)
    visits = [s for s in sweeps if s.probe is None]
    # Where a visit may be lost, a jump in the visit numbers breaks the robot's path:
    # the junctions either side of a lost visit need not be neighbours.
    lossy = source.integrity is not Integrity.OK or bool(found.warnings)
    breaks: list[int] = []
    probes: dict[int, list[LoggedSweep]] = {}
    for s in sweeps:
        if s.probe is not None:
            probes.setdefault(s.visit_id, []).append(s)
    events = node_events_of(messages, warnings, source.name)
    # A lamp-lit camera's sweeps are normalised (unless the caller says otherwise).
    lit = lamp_strength(source.run_metadata()) > 0.0
    localizer = Localizer((config if config is not None else LocalizerConfig()).for_camera(lit))
    decided: list[VisitDecision] = []
    for i, sweep in enumerate(visits):
        if lossy and i > 0 and sweep.visit_id != visits[i - 1].visit_id + 1:
            localizer.map.new_traversal()
            breaks.append(i)
        scan = events.get(sweep.visit_id)
        exits = None if scan is None else scan.exits_rad
        odometer = None if scan is None else scan.odometer_m
        # The sets are made before the clock starts: the latency is the decision's.
        images, answers = sweep.images, _LoggedProbes(probes.get(sweep.visit_id, []))
        start = time.perf_counter()
        decision = localizer.localize(images, answers, exits, odometer)
        latency = time.perf_counter() - start
        missing = answers.not_in_log
        for given_up in () if scan is None else scan.blocked_rad:
            localizer.depart(given_up)
            localizer.block()
        if scan is not None and scan.departure_rad is not None:
            localizer.depart(scan.departure_rad)
        decided.append(
            VisitDecision(
                sweep.visit_id, sweep.sweep_id, sweep.end_ns, decision, latency, missing, scan
            )
        )
        if progress is not None:
            progress(i + 1, len(visits))
    asked = sum(v.probes_not_in_log for v in decided)
    if asked:
        warnings.append(
            f"{asked} probe sweep(s) asked for are not in the log; those visits were "
            "decided without them"
        )
    if not visits:
        warnings.append(f"{source.name}: no complete sweep of a visit in this log; an empty map")
    return ReplayResult(
        visits=decided,
        topomap=localizer.map,
        integrity=source.integrity,
        warnings=warnings,
        sweeps=len(sweeps),
        duration_ns=source.duration_ns,
        images=sum(s.count for s in sweeps),
        camera_angles={s.sweep_id: s.camera_angle_rad for s in sweeps},
        visit_sets=SweepSets({s.sweep_id: s for s in visits}),
        breaks=tuple(breaks),
        localizer=localizer,
        illumination=localizer.config.illumination if localizer.config.lamp else None,
    )
