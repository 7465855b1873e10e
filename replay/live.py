"""A run in rerun while it is recorded: the live view of ``pipemap record --view``.

:class:`LiveView` is a recorder observer (:data:`recorder.session.RunObserver`): the
recorder hands it the records of each sweep as they go to the log. It turns them
into the log's messages with the recorder's own converter (so it shows what the log
holds, nothing the log does not), logs them as :mod:`replay.view` does for a whole
log, and replays each visit as soon as the run has decided it, so the map grows
at each sweep. The records are only read: the log is the same with or without it.

The stream goes to a viewer it spawns or to a running viewer or server
(``connect``). The recording has the id a later ``pipemap view`` of the same log
gets, and the same ``sim_time`` timeline.
"""

from __future__ import annotations

import os
import queue
import signal
import sys
import threading
import traceback
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pipemap.errors import ViewerError
from pipemap.localizer import Localizer, LocalizerConfig, TopoMap
from pipemap.recorder import LogMessage, Topic
from pipemap.recorder.convert import LogRecord, RecordConverter
from pipemap.recorder.messages import ImageEncoding
from pipemap.recorder.metadata import lamp_strength
from pipemap.recorder.topics import ROBOT_PREFIX
from pipemap.replay.logged import NodeEvents
from pipemap.replay.replayer import (
    LoggedSweep,
    VisitDecision,
    answer_probes,
    makes_probes,
    sweeps_of,
)
from pipemap.replay.source import ordered
from pipemap.replay.view import MapLog, recording
from pipemap.replay.view_blueprint import view_blueprint
from pipemap.replay.view_topics import Carried, RobotGeometry, log_robot, log_truth

if TYPE_CHECKING:
    from multiprocessing.connection import Connection

    import rerun as rr

__all__ = ["LiveSummary", "LiveView", "LiveViewProcess"]


class _Collector:
    """Stands in for the log writer: keeps the converter's messages in memory."""

    def __init__(self) -> None:
        self.messages: list[LogMessage] = []
        self._sequence: dict[str, int] = defaultdict(int)

    def write(self, topic: str, log_time_ns: int, message: Any) -> None:
        self.write_serialized(topic, log_time_ns, message.SerializeToString())

    def write_serialized(self, topic: str, log_time_ns: int, data: bytes) -> None:
        self.messages.append(LogMessage(topic, log_time_ns, self._sequence[topic], data))
        self._sequence[topic] += 1

    def flush(self) -> None:
        """Nothing to flush: the messages are taken after every batch."""


@dataclass(frozen=True)
class LiveSummary:
    """What a live view showed."""

    sweeps: int
    images: int
    visits: int
    junctions: int


class LiveView:
    """Streams a run to rerun as it is recorded; call it with each batch of records.

    Use as a context manager, or call :meth:`close`: it replays what is left,
    sends everything and lets the viewer go.
    """

    def __init__(
        self, rec: rr.RecordingStream, run_metadata: dict[str, str], config: LocalizerConfig
    ) -> None:
        self.rec = rec
        self._geometry = RobotGeometry.from_run(run_metadata)
        self._collector = _Collector()
        # The images as the log stores them (a JPEG run replays JPEG-decoded pixels).
        self._convert = RecordConverter(
            self._collector, encoding=ImageEncoding.of_run(run_metadata)
        )
        self._carried = Carried()
        self._map = MapLog(rec)
        # As a replay of the log would: a lamp-lit camera's sweeps are normalised.
        lit = lamp_strength(run_metadata) > 0.0
        self._localizer = Localizer(config.for_camera(lit))
        # As a replay: probes a robot that makes no probe moves never made are not missing.
        self._makes_probes = makes_probes(run_metadata)
        self._waiting: list[LoggedSweep] = []  # visits' sweeps the run has not decided yet
        self._probes: dict[int, list[LoggedSweep]] = defaultdict(list)
        self._node_events: list[LogMessage] = []  # exit scans, departures, refusals, blocks
        self._last_visit: int | None = None  # decided, its departure not yet applied
        self._sweeps = self._images = self._visits = 0
        self._closed = False

    @classmethod
    def spawn(cls, run_metadata: dict[str, str], config: LocalizerConfig) -> LiveView:
        """A live view in a rerun viewer, started if none is running."""
        rec = recording(run_metadata)
        rec.spawn(default_blueprint=view_blueprint())
        return cls(rec, run_metadata, config)

    @classmethod
    def connect(cls, url: str, run_metadata: dict[str, str], config: LocalizerConfig) -> LiveView:
        """A live view sent to the rerun viewer or server at the gRPC ``url``."""
        rec = recording(run_metadata)
        rec.connect_grpc(url, default_blueprint=view_blueprint())
        return cls(rec, run_metadata, config)

    def __call__(self, records: Sequence[LogRecord]) -> None:
        """Show ``records`` (the records of one or more whole sweeps, in log order)."""
        for record in records:
            self._convert(record)
        batch = ordered(self._collector.messages)
        self._collector.messages = []
        self.show(batch)

    def show(self, batch: Sequence[LogMessage]) -> None:
        """Show ``batch`` (the log messages of one or more whole sweeps, in log order),
        as the log holds them: a stored log's messages show as its run did live."""
        by_topic: dict[str, list[LogMessage]] = defaultdict(list)
        robot: list[LogMessage] = []
        for m in batch:
            by_topic[m.topic].append(m)
            if m.topic.startswith(ROBOT_PREFIX):
                robot.append(m)
            if m.topic in (Topic.NODE, Topic.EVENTS):
                self._node_events.append(m)
        log_robot(self.rec, by_topic, self._geometry, self._carried)
        log_truth(self.rec, by_topic, self._carried.trail)
        sweeps = sweeps_of(robot, "live run").sweeps
        for sweep in sweeps:
            self._sweeps += 1
            self._images += sweep.count
            if sweep.probe is None:
                self._waiting.append(sweep)
            else:
                self._probes[sweep.visit_id].append(sweep)
        # The run has decided (so every probe of the visit is in): replay the visit.
        if Topic.DECISION in by_topic:
            self._decide()

    def _decide(self) -> None:
        # As the replay does: each visit with its exit scan, and the departure from
        # the visit before it (logged after that visit's decision) applied first.
        events = NodeEvents("live run")
        for message in self._node_events:
            events.feed(message)
        events.finish([])
        for sweep in self._waiting:
            last = None if self._last_visit is None else events.of(self._last_visit)
            for given_up in () if last is None else last.blocked_rad:
                self._localizer.depart(given_up)
                self._localizer.block()
            if last is not None and last.departure_rad is not None:
                self._localizer.depart(last.departure_rad)
                self._map.depart(self._localizer.map.visit_records[-1].departure_port)
            scan = events.of(sweep.visit_id)
            probes = self._probes.pop(sweep.visit_id, [])
            decision, missing, refused = answer_probes(
                self._localizer,
                sweep.images,
                probes,
                None if scan is None else scan.exits_rad,
                None if scan is None else scan.odometer_m,
                None if scan is None else scan.position_m,
                events.refused(sweep.visit_id),
            )
            # A probe the robot refused to move for is not missing, nor is one a robot
            # that makes no probe moves never made.
            missing = missing if self._makes_probes else 0
            self._map.add(
                VisitDecision(
                    sweep.visit_id,
                    sweep.sweep_id,
                    sweep.end_ns,
                    decision,
                    0.0,
                    missing,
                    scan,
                    probes_refused=refused,
                ),
                self._localizer.map.ports(decision.node),
                decision.arrival_port,
            )
            self._visits += 1
            self._last_visit = sweep.visit_id
        self._waiting = []

    @property
    def map(self) -> TopoMap:
        """The map the view's localizer has built from the visits decided so far."""
        return self._localizer.map

    def close(self) -> LiveSummary:
        """Replay the visits not yet decided, send everything, let the viewer go."""
        if not self._closed:
            self._closed = True
            self._decide()
            try:
                self.rec.flush(timeout_sec=10.0)
            finally:
                self.rec.disconnect()
        return LiveSummary(self._sweeps, self._images, self._visits, self._localizer.map.node_count)

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class LiveViewProcess:
    """A :class:`LiveView` in a forked child process, so that the run does not wait
    for it: the view's replay and rerun's encoding take a core of their own.

    Call it with each batch of records, as a :class:`LiveView`; the batches go down a
    pipe, which a thread of the child empties as fast as they come (the run never
    waits on a full pipe). :meth:`close` waits until the child has shown everything.
    The child ignores Ctrl-C, which the terminal sends to both: ending the view is
    the parent's call. rerun is imported in the child only.
    """

    def __init__(self, make: Callable[[], LiveView]) -> None:
        import multiprocessing

        batches, self._batches = multiprocessing.Pipe(duplex=False)
        self._summary, summary = multiprocessing.Pipe(duplex=False)
        sys.stdout.flush()
        sys.stderr.flush()
        self._pid = os.fork()
        if self._pid == 0:
            self._batches.close()
            self._summary.close()
            _show_batches(make, batches, summary)  # never returns
        batches.close()
        summary.close()
        self._lost = False
        self._result: LiveSummary | None = None

    def __call__(self, records: Sequence[LogRecord]) -> None:
        """Hand ``records`` to the child (dropped if it has gone; :meth:`close` says so)."""
        if self._lost:
            return
        try:
            self._batches.send(list(records))
        except OSError:  # a broken pipe: the child ended, and said why on stderr
            self._lost = True

    def close(self) -> LiveSummary:
        """Wait for the child to show everything and end; what it showed."""
        if self._result is None:
            self._batches.close()
            try:
                self._result = self._summary.recv()
            except EOFError:
                self._result = None
            finally:
                self._summary.close()
                os.waitpid(self._pid, 0)
            if self._result is None:
                raise ViewerError("the live view stopped before the end of the run")
        return self._result


def _show_batches(make: Callable[[], LiveView], batches: Connection, summary: Connection) -> None:
    """The child of :class:`LiveViewProcess`: show every batch, send the summary, exit."""
    status = 1
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        received: queue.SimpleQueue[list[LogRecord] | None] = queue.SimpleQueue()

        def drain() -> None:
            try:
                while True:
                    received.put(batches.recv())
            except (EOFError, OSError):
                received.put(None)

        threading.Thread(target=drain, daemon=True).start()
        view = make()
        while (batch := received.get()) is not None:
            view(batch)
        summary.send(view.close())
        status = 0
    except BaseException:  # noqa: BLE001 - reported here; the parent says the view stopped
        traceback.print_exc()
    finally:
        sys.stderr.flush()
        os._exit(status)
