"""Replay: rebuild the map from a log's ``/robot`` messages, deterministically.

The sweeps are put together from the camera's commands and images; every visit's
sweep goes to the localizer in the order the robot took them. When the localizer
asks for an active-vision probe, the probe sweeps the log holds for that visit
answer it, matched by kind and move; a probe the log does not hold is answered
``None``, and the decision records it as missing. Each visit's exit scan
(``/robot/node`` EXITS) goes with its sweep, and its departure tells the map which
port the robot left by, as online. Logs of format 1 have no exit scans: their maps
have no ports. The same log and settings give the same map, byte for byte.

Each visit is decided as soon as the log has told all of it (:func:`replay`), so
a replay of a log read as it goes holds the map and the visit at hand, not the log.

What cannot be read is lost alone: a sweep with an image missing, undecodable or
not a readable PNG is skipped with a warning, and the replay goes on. Where a visit
is lost (its sweep skipped, or in a damaged part of the log), the map's path is
broken there: the visits either side are not joined by an edge.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from pipemap.errors import InputError, LogFormatError
from pipemap.localizer import (
    Decision,
    FastConfig,
    IlluminationConfig,
    ImageSet,
    Localizer,
    LocalizerConfig,
    PreparedSet,
    TopoMap,
    for_pairs,
    map_document,
)
from pipemap.localizer.odometry import drift_allowed
from pipemap.recorder import Integrity, Topic
from pipemap.recorder.metadata import lamp_strength, odometry_drift
from pipemap.replay.logged import (
    LoggedExits,
    LoggedSweep,
    LogTimeWentBack,
    NodeEvents,
    SweepAssembler,
    Sweeps,
    SweepSets,
    in_order,
    node_events_of,
    sweeps_of,
)
from pipemap.replay.logged_probes import LoggedProbes, answer_probes, makes_probes
from pipemap.replay.source import MessageSource, ordered

__all__ = [
    "REPLAY_TOPICS",
    "LoggedExits",
    "LoggedSweep",
    "ReplayResult",
    "SweepSets",
    "Sweeps",
    "VisitDecision",
    "NodeEvents",
    "SweepAssembler",
    "answer_probes",
    "makes_probes",
    "node_events_of",
    "replay",
    "sweeps_of",
    "takes_recorded_threshold",
    "visit_label",
]

#: The topics a replay reads (:func:`sweeps_of`, :func:`node_events_of`): a source
#: may hold these alone (:class:`replay.source.FileSource`'s ``topics``).
REPLAY_TOPICS = (Topic.SWEEP, Topic.IMAGE, Topic.NODE, Topic.EVENTS)

#: ``pipemap -v`` prints each decision (stderr).
_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class VisitDecision:
    """The replay's decision for one node visit."""

    visit_id: int
    sweep_id: int
    time_ns: int
    decision: Decision
    #: Wall time of the decision (not part of any deterministic output).
    latency_s: float
    #: Probes the localizer asked for that the log does not hold, though the robot
    #: makes probe moves (its condition is ``active``, or the log does not say).
    probes_not_in_log: int
    #: The visit's exit scan and departure (robot data), if the log has them.
    exits: LoggedExits | None = None
    #: Wall time of the decision in each of its phases (:mod:`localizer.phases`),
    #: seconds; like ``latency_s``, not part of any deterministic output.
    phases_s: Mapping[str, float] = field(default_factory=dict)
    #: Probes the localizer asked for whose move the robot refused (its rangers found
    #: a wall within the move; the log's warning says so): not made, not missing.
    probes_refused: int = 0


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
    #: Each visit's own sweep as the localizer's matcher prepared it (lit as it saw
    #: it), in the compact form pairs of visits are compared from
    #: (:func:`pipemap.localizer.pairwise.for_pairs`), by sweep id; and the matcher's
    #: settings. About a tenth of the memory of :attr:`visit_sets`.
    visit_prepared: Mapping[int, PreparedSet] = field(default_factory=dict)
    fast: FastConfig | None = None
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
            self.topomap,
            [(visit_label(v.visit_id), v.decision) for v in self.visits],
            None if self.localizer is None else self.localizer.open_visits,
        )


def visit_label(visit_id: int) -> str:
    """A visit's name in the map document: its number, as ``pipemap sim`` names folders."""
    return f"{visit_id:04d}"


class _WholeLogNeeded(Exception):
    """The log cannot be replayed visit by visit as it is read (see :func:`replay`)."""


class _Replay:
    """One replay of a source, deciding each visit as soon as the log has told all of it.

    A visit is told in full when a message of a later visit comes: its sweep, its
    probe sweeps, its exit scan and every departure and blocked pipe come before the
    robot reaches the next junction. Deciding then, and dropping the visit's images,
    keeps what a replay holds to the map, whatever the log's length. ``whole``
    decides every visit after the whole log has been read (the replay of a log whose
    order or numbering does not allow the first way; see :func:`replay`)."""

    def __init__(
        self,
        source: MessageSource,
        config: LocalizerConfig,
        progress: Callable[[int, int | None], None] | None,
        keep_sets: bool,
        whole: bool,
        keep_prepared: bool = False,
        recorded_threshold: bool = False,
    ) -> None:
        self.source, self.config, self.progress = source, config, progress
        self.recorded_threshold = recorded_threshold
        self.threshold_note: str | None = None
        self.keep_sets, self.whole, self.keep_prepared = keep_sets, whole, keep_prepared
        self.visit_prepared: dict[int, PreparedSet] = {}
        self.sweeps = SweepAssembler(source.name)
        self.events = NodeEvents(source.name)
        self.localizer: Localizer | None = None
        self.metadata: dict[str, str] | None = None
        #: Probes asked for where the robot makes none (not a gap in the log).
        self.probes_not_made = 0
        self.pending: deque[LoggedSweep] = deque()  # visit sweeps not decided yet
        self.probes: dict[int, list[LoggedSweep]] = {}
        self.decided: list[VisitDecision] = []
        self.breaks: list[int] = []
        self.last_visit: int | None = None  # of the last visit decided
        self.unbroken_jumps = 0  # jumps in visit numbers decided with no loss seen yet
        self.total: int | None = None  # visits to decide, once the log has been read
        self.sweep_count = self.image_count = 0
        self.camera_angles: dict[int, float] = {}
        self.visit_sweeps: dict[int, LoggedSweep] = {}

    def run(self) -> ReplayResult:
        stream = self.source.robot_stream()
        checked = False
        for m in in_order(stream) if not self.whole else iter(ordered(list(stream))):
            if not checked:
                # The run's settings open the log: its camera is known before any sweep.
                _check_downsample(self.source, self.config)
                checked = True
            named = self.events.feed(m)
            sweep = self.sweeps.feed(m)
            if self.sweeps.started is not None:
                named = self.sweeps.started
            if sweep is not None:
                self._complete(sweep)
            if named is not None and not self.whole:
                if self.last_visit is not None and named <= self.last_visit:
                    raise _WholeLogNeeded(f"visit {named} is told after a later one was decided")
                while self.pending and self.pending[0].visit_id < named:
                    self._decide(self.pending.popleft(), bool(self.sweeps.warnings))
        self.sweeps.finish()
        lossy = self.source.integrity is not Integrity.OK or bool(self.sweeps.warnings)
        if not self.whole and (
            (lossy and self.unbroken_jumps)
            or (self.metadata is not None and self.metadata != self.source.run_metadata())
        ):
            raise _WholeLogNeeded("the log's damage or settings are known only at its end")
        self.total = len(self.decided) + len(self.pending)
        while self.pending:
            self._decide(self.pending.popleft(), lossy)
        return self._result()

    def _complete(self, sweep: LoggedSweep) -> None:
        self.sweep_count += 1
        self.image_count += sweep.count
        self.camera_angles[sweep.sweep_id] = sweep.camera_angle_rad
        if sweep.probe is not None:
            self.probes.setdefault(sweep.visit_id, []).append(sweep)
            return
        self.pending.append(sweep)
        if self.keep_sets:
            self.visit_sweeps[sweep.sweep_id] = sweep

    def _decide(self, sweep: LoggedSweep, lossy: bool) -> None:
        if self.localizer is None:
            # A lamp-lit camera's sweeps are normalised (unless the caller says otherwise);
            # the run's settings open the log, before its first sweep.
            self.metadata = _run_settings(self.source)
            self.config, self.threshold_note = _as_recorded(
                self.config, self.metadata, self.recorded_threshold
            )
            lit = lamp_strength(self.metadata) > 0.0
            self.localizer = Localizer(self.config.for_camera(lit), clock=time.perf_counter)
        localizer = self.localizer
        # Where a visit may be lost, a jump in the visit numbers breaks the robot's path:
        # the junctions either side of a lost visit need not be neighbours.
        jump = self.last_visit is not None and sweep.visit_id != self.last_visit + 1
        if jump and lossy:
            localizer.map.new_traversal()
            self.breaks.append(len(self.decided))
        elif jump:
            self.unbroken_jumps += 1
        scan = self.events.of(sweep.visit_id)
        exits = None if scan is None else scan.exits_rad
        odometer = None if scan is None else scan.odometer_m
        position = None if scan is None else scan.position_m
        # The sets are made before the clock starts: the latency is the decision's.
        images = sweep.images
        answers = LoggedProbes(
            self.probes.pop(sweep.visit_id, []), self.events.refused(sweep.visit_id)
        )
        start = time.perf_counter()
        decision = localizer.localize(images, answers, exits, odometer, position)
        latency = time.perf_counter() - start
        missing = answers.not_in_log
        if not makes_probes(self.metadata):
            self.probes_not_made += missing
            missing = 0
        if self.keep_prepared and localizer.last_prepared is not None:
            self.visit_prepared[sweep.sweep_id] = for_pairs(localizer.last_prepared)
        for given_up in () if scan is None else scan.blocked_rad:
            localizer.depart(given_up)
            localizer.block()
        if scan is not None and scan.departure_rad is not None:
            localizer.depart(scan.departure_rad)
        self.decided.append(
            VisitDecision(
                sweep.visit_id,
                sweep.sweep_id,
                sweep.end_ns,
                decision,
                latency,
                missing,
                scan,
                dict(localizer.last_phases),
                answers.refused,
            )
        )
        if _LOG.isEnabledFor(logging.DEBUG):
            _LOG.debug("visit %d: %s; %.1f ms", sweep.visit_id, decision.describe(), latency * 1e3)
        self.last_visit = sweep.visit_id
        if self.progress is not None:
            self.progress(len(self.decided), self.total)

    def _result(self) -> ReplayResult:
        warnings = list(self.sweeps.warnings)
        self.events.finish(warnings)
        name = self.source.name
        asked = sum(v.probes_not_in_log for v in self.decided)
        if asked:
            warnings.append(
                f"{asked} probe sweep(s) asked for are not in the log; those visits were "
                "decided without them"
            )
        if self.threshold_note is not None:
            warnings.append(f"{name}: {self.threshold_note}")
        refused = sum(v.probes_refused for v in self.decided)
        if refused:
            warnings.append(
                f"{refused} probe move(s) asked for were refused by the robot (a wall within "
                "the move, as the log says); those visits were decided without them, as online"
            )
        if self.probes_not_made:
            condition = (self.metadata or {}).get("condition")
            warnings.append(
                f"active vision asked for {self.probes_not_made} probe sweep(s); in condition "
                f"{condition!r} the robot makes no probe moves, so those visits were decided "
                "on their own sweeps, as online"
            )
        if not self.decided:
            warnings.append(f"{name}: no complete sweep of a visit in this log; an empty map")
        localizer = self.localizer
        if localizer is None:
            lit = lamp_strength(_run_settings(self.source)) > 0.0
            localizer = Localizer(self.config.for_camera(lit))
        return ReplayResult(
            visits=self.decided,
            topomap=localizer.map,
            integrity=self.source.integrity,
            warnings=warnings,
            sweeps=self.sweep_count,
            duration_ns=self.source.duration_ns,
            images=self.image_count,
            camera_angles=self.camera_angles,
            visit_sets=SweepSets(self.visit_sweeps),
            visit_prepared=self.visit_prepared,
            fast=localizer.config.fast,
            breaks=tuple(self.breaks),
            localizer=localizer,
            illumination=localizer.config.illumination if localizer.config.lamp else None,
        )


def _check_downsample(source: MessageSource, config: LocalizerConfig) -> None:
    """Refuse a refinement that downsamples beyond the log's images (the localizer
    checks each image too, for a log whose settings do not give its resolution)."""
    factor = config.fast.fine_downsample
    resolution = source.run_metadata().get("resolution_px", "")
    if resolution.isdigit() and factor > int(resolution) // 2:
        raise InputError(
            f"{source.name}: downsampling by {factor} (--downsample) leaves less than two "
            f"pixels of its {resolution} px wide images: at most {int(resolution) // 2}"
        )


def _as_recorded(
    config: LocalizerConfig, run: dict[str, str], recorded: bool
) -> tuple[LocalizerConfig, str | None]:
    """``config``, with the threshold of the run's settings ``run`` if ``recorded``;
    and a note when the threshold then differs from the run's (``None`` when they
    agree, or the settings do not say)."""
    config = drift_allowed(config, odometry_drift(run))  # the allowance it was recorded with
    try:
        threshold = float(run["threshold"])
    except (KeyError, ValueError):
        return config, None
    if recorded:
        config = replace(config, threshold=threshold)
    if config.threshold == threshold:
        return config, None
    return config, (
        f"replayed at threshold {config.threshold:g}, though recorded at {threshold:g}: its "
        f"probes were asked for, and its online decisions made, at {threshold:g}"
    )


def _run_settings(source: MessageSource) -> dict[str, str]:
    """The run's ``pipemap.run`` settings, read before the first sweep (the record
    opens the log). Absent, its record was damaged (the reader accepts such a log for
    ``info``): the settings, the camera's lamp among them, are not guessed."""
    run = source.run_metadata()
    if not run:
        raise LogFormatError(
            f"{source.name}: its pipemap.run record is damaged: the run's settings are "
            "lost, so it cannot be replayed as it was recorded (pipemap info lists what "
            "the log still holds)"
        )
    return run


def replay(
    source: MessageSource,
    config: LocalizerConfig | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    keep_sets: bool = True,
    keep_prepared: bool = True,
    recorded_threshold: bool | None = None,
) -> ReplayResult:
    """Feed every visit's sweep of ``source`` to a new localizer, in the robot's order.

    With ``recorded_threshold`` the threshold is the one the log's run was recorded
    with (its ``pipemap.run`` settings say it), not ``config``'s; ``None`` takes it
    so when no ``config`` is given (:func:`takes_recorded_threshold`). Either way a
    warning says when the replay's threshold differs from the recorded one: that one
    chose the probes the robot made and its online decisions.

    Each visit is decided as soon as the log has told all of it, and its images are
    then dropped (kept only with ``keep_sets``, for :attr:`ReplayResult.visit_sets`;
    as the matcher prepared them, compactly, with ``keep_prepared``, for
    :attr:`ReplayResult.visit_prepared`, which a score compares in pairs):
    a replay of a source that reads its file as it goes
    (:class:`replay.source.StreamSource`) holds the map, not the log. The map is the
    one of deciding every visit after reading the whole log, byte for byte: where the
    log cannot tell that soon enough (its log time goes back, a visit is told after a
    later one, damage or a skipped sweep comes after a jump in the visit numbers, its
    run settings come after its first sweep), the replay starts again and decides
    after reading it whole. ``progress`` gets the visits decided so far and their
    total, once known (``None`` before).
    """
    recorded = takes_recorded_threshold(recorded_threshold, config)
    config = config if config is not None else LocalizerConfig()
    args = (source, config, progress, keep_sets)
    try:
        return _Replay(*args, False, keep_prepared, recorded).run()
    except (_WholeLogNeeded, LogTimeWentBack):
        return _Replay(*args, True, keep_prepared, recorded).run()


def takes_recorded_threshold(recorded_threshold: bool | None, config: object | None) -> bool:
    """Whether a replay takes the threshold its log was recorded with: as asked, or,
    when not asked (``None``), when it is given no localizer settings of its own, so
    that ``replay(log)`` builds the map ``pipemap replay LOG`` builds."""
    if recorded_threshold is not None:
        return recorded_threshold
    return config is None
