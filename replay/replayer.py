"""Replay: rebuild the map from a log's ``/robot`` messages, deterministically.

The sweeps are put together from the camera's commands and images; every visit's
sweep goes to the localizer in the order the robot took them. When the localizer
asks for an active-vision probe, the probe sweeps the log holds for that visit
answer it, matched by kind and move; a probe the log does not hold is answered
``None``, and the decision records it as missing. Each visit's exit scan
(``/robot/node`` EXITS) goes with its sweep, and its departure tells the map which
port the robot left by, as online. Logs of format 1 have no exit scans: their maps
have no ports. The same log and settings give the same map, byte for byte.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from pipemap.errors import LogFormatError, PipemapError
from pipemap.localizer import (
    Decision,
    ImageSet,
    Localizer,
    LocalizerConfig,
    ProbeRequest,
    TopoMap,
    map_document,
)
from pipemap.recorder import Integrity, LogMessage, Topic
from pipemap.recorder.messages import decode_png
from pipemap.recorder.schemas import CompressedImage, NodeEvent, SweepCommand
from pipemap.replay.source import MessageSource

__all__ = [
    "LoggedExits",
    "LoggedSweep",
    "ReplayResult",
    "VisitDecision",
    "node_events_of",
    "replay",
    "sweeps_of",
    "visit_label",
]

#: A probe in the log answers a request for the same kind and move, to this much.
_PROBE_MATCH = 1e-9


@dataclass(frozen=True, eq=False)
class LoggedSweep:
    """A complete sweep of the log, as the localizer sees it."""

    sweep_id: int
    visit_id: int
    end_ns: int
    images: ImageSet
    #: ``(kind, yaw_rad, forward_m, left_m)`` of a probe sweep, else ``None``.
    probe: tuple[str, float, float, float] | None = None


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
    duration_ns: int = 0
    images: int = 0
    #: Camera angle of each sweep's first image relative to the robot (robot data).
    camera_angles: dict[int, float] = field(default_factory=dict)
    #: The image set of each visit's own sweep (probes aside), by sweep id.
    visit_sets: dict[int, ImageSet] = field(default_factory=dict)
    #: The localizer after the replay: its map and its junctions' sweeps, ready to
    #: go on (to drive a route on the same map, say).
    localizer: Localizer | None = None

    def document(self) -> dict[str, Any]:
        """The map document, in the format of ``pipemap map --json``."""
        return map_document(
            self.topomap, [(visit_label(v.visit_id), v.decision) for v in self.visits]
        )


def visit_label(visit_id: int) -> str:
    """A visit's name in the map document: its number, as ``pipemap sim`` names folders."""
    return f"{visit_id:04d}"


def _gray(png: bytes, where: str) -> np.ndarray:
    rgb = decode_png(png)
    if rgb is None:
        raise LogFormatError(f"{where}: the image is not a readable PNG")
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)


def sweeps_of(messages: list[LogMessage], name: str = "log") -> tuple[list[LoggedSweep], list[str]]:
    """Every complete sweep of ``messages`` (ordered ``/robot`` messages), and warnings
    about sweeps that are not complete."""
    images_at: dict[int, bytes] = {}
    sweeps: list[LoggedSweep] = []
    warnings: list[str] = []
    start: Any = None
    frames: list[np.ndarray] = []
    for m in messages:
        if m.topic == Topic.IMAGE:
            image = CompressedImage.FromString(m.data)
            if image.format != "png":
                raise LogFormatError(f"{name}: image at {m.log_time_ns} ns is {image.format!r}")
            images_at[m.log_time_ns] = image.data
        elif m.topic == Topic.SWEEP:
            command = SweepCommand.FromString(m.data)
            where = f"{name}: sweep {command.sweep_id}"
            if command.phase == SweepCommand.START:
                if start is not None:
                    warnings.append(f"sweep {start.sweep_id} never ended; skipped")
                start, frames = command, []
            elif command.phase == SweepCommand.IMAGE and start is not None:
                png = images_at.pop(m.log_time_ns, None)
                if png is None:
                    raise LogFormatError(f"{where}: no image at {m.log_time_ns} ns")
                frames.append(_gray(png, f"{where}, image {command.image_index}"))
            elif command.phase == SweepCommand.END and start is not None:
                if len(frames) != start.image_count:
                    raise LogFormatError(
                        f"{where}: {len(frames)} images where {start.image_count} were commanded"
                    )
                try:
                    images = ImageSet(
                        np.stack(frames),
                        fov_rad=start.fov_rad,
                        camera_angle_rad=start.camera_angle_rad,
                    )
                except (PipemapError, ValueError) as exc:
                    raise LogFormatError(f"{where}: {exc}") from None
                probe = None
                if start.probe:
                    probe = (
                        start.probe_kind,
                        start.probe_yaw_rad,
                        start.probe_forward_m,
                        start.probe_left_m,
                    )
                sweeps.append(
                    LoggedSweep(command.sweep_id, start.visit_id, m.log_time_ns, images, probe)
                )
                start = None
    if start is not None:
        warnings.append(f"sweep {start.sweep_id} was cut off by the end of the log; skipped")
    return sweeps, warnings


def node_events_of(messages: list[LogMessage]) -> dict[int, LoggedExits]:
    """Each visit's exit scan and departure from ordered ``/robot`` messages."""
    scans: dict[int, NodeEvent] = {}
    departures: dict[int, float] = {}
    for m in messages:
        if m.topic != Topic.NODE:
            continue
        event = NodeEvent.FromString(m.data)
        if event.kind == NodeEvent.EXITS:
            scans.setdefault(event.visit_id, event)
        elif event.kind == NodeEvent.DEPARTURE:
            departures.setdefault(event.visit_id, event.exit_rad)
    out: dict[int, LoggedExits] = {}
    for visit_id in sorted(set(scans) | set(departures)):
        scan = scans.get(visit_id)
        out[visit_id] = LoggedExits(
            visit_id,
            None if scan is None else tuple(scan.exits_rad),
            0.0 if scan is None else scan.x_estimate_m,
            0.0 if scan is None else scan.y_estimate_m,
            None if scan is None else scan.odometer_m,
            departures.get(visit_id),
        )
    return out


class _LoggedProbes:
    """Answers probe requests from the probe sweeps the log holds for one visit."""

    def __init__(self, probes: list[LoggedSweep]) -> None:
        self.probes = probes
        self.not_in_log = 0

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        wanted = (request.yaw_rad, request.forward_m, request.left_m)
        for sweep in self.probes:
            assert sweep.probe is not None
            kind, *move = sweep.probe
            if kind == request.kind.value and all(
                math.isclose(a, b, rel_tol=0.0, abs_tol=_PROBE_MATCH)
                for a, b in zip(move, wanted, strict=True)
            ):
                return sweep.images
        self.not_in_log += 1
        return None


def replay(
    source: MessageSource,
    config: LocalizerConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ReplayResult:
    """Feed every visit's sweep of ``source`` to a new localizer, in the robot's order."""
    messages = source.robot_messages()
    sweeps, warnings = sweeps_of(messages, source.name)
    visits = [s for s in sweeps if s.probe is None]
    probes: dict[int, list[LoggedSweep]] = {}
    for s in sweeps:
        if s.probe is not None:
            probes.setdefault(s.visit_id, []).append(s)
    events = node_events_of(messages)
    localizer = Localizer(config)
    decided: list[VisitDecision] = []
    for i, sweep in enumerate(visits):
        answers = _LoggedProbes(probes.get(sweep.visit_id, []))
        scan = events.get(sweep.visit_id)
        exits = None if scan is None else scan.exits_rad
        odometer = None if scan is None else scan.odometer_m
        start = time.perf_counter()
        decision = localizer.localize(sweep.images, answers, exits, odometer)
        latency = time.perf_counter() - start
        if scan is not None and scan.departure_rad is not None:
            localizer.depart(scan.departure_rad)
        decided.append(
            VisitDecision(
                sweep.visit_id,
                sweep.sweep_id,
                sweep.end_ns,
                decision,
                latency,
                answers.not_in_log,
                scan,
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
    duration = messages[-1].log_time_ns - messages[0].log_time_ns if messages else 0
    return ReplayResult(
        visits=decided,
        topomap=localizer.map,
        integrity=source.integrity,
        warnings=warnings,
        sweeps=len(sweeps),
        duration_ns=duration,
        images=sum(s.images.count for s in sweeps),
        camera_angles={s.sweep_id: s.images.camera_angle_rad for s in sweeps},
        visit_sets={s.sweep_id: s.images for s in visits},
        localizer=localizer,
    )
