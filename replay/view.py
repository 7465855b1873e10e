"""A log and a replay of it as one rerun recording, on simulated time.

The recording has a single timeline, ``sim_time``, taken from log time: rerun's
wall-clock ``log_time`` and ``log_tick`` are switched off, no recording
properties (which hold a start time) are sent, and the recording id is derived
from the run's metadata. So the same log and settings give the same recording,
as ``rerun rrd compare`` sees it. What it shows:

* ``world/``: the network (truth), the robot's true pose, body and trajectory,
  its three range rays and the camera's direction during sweeps;
* ``camera/image``: every camera image, when it was taken;
* ``sensors/``, ``controller/``: ranges, IMU, wheels, commands as time series;
* ``map``: the replay's topological map, growing at each decision's time;
* ``log/``: decisions (similarity, margin, known or new, probes), controller
  states and events.

rerun is imported inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

import itertools
import json
import uuid
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from pipemap.errors import InputError, ViewerError, WriteError
from pipemap.localizer import TopoMap
from pipemap.recorder.reader import LogMessage
from pipemap.recorder.topics import ROBOT_PREFIX
from pipemap.replay.replayer import ReplayResult, VisitDecision, visit_label
from pipemap.replay.source import MessageSource
from pipemap.replay.view_blueprint import view_blueprint
from pipemap.replay.view_topics import (
    DEFAULT_MAX_RATE_HZ,
    Carried,
    RobotGeometry,
    log_robot,
    log_truth,
    set_time,
)
from pipemap.wholefile import partial_path

if TYPE_CHECKING:
    import rerun as rr

__all__ = [
    "APPLICATION_ID",
    "VIEW_WINDOW",
    "MapLog",
    "Replayed",
    "describe_decision",
    "log_view",
    "recording",
    "save_view",
    "spawn_view",
]

APPLICATION_ID = "pipemap"
_NAMESPACE = uuid.UUID("5f1d2c1e-8f0b-4a8e-9d4e-70697065de4d")
_NODE = (150, 150, 150)
_NODE_NOW = (255, 140, 0)


def _recording_id(run_metadata: dict[str, str]) -> str:
    """The same for every view of one log: a name-based UUID of the run's metadata."""
    run = json.dumps(run_metadata, sort_keys=True)
    return str(uuid.uuid5(_NAMESPACE, run))


def _recording(source: MessageSource) -> rr.RecordingStream:
    return recording(source.run_metadata())


def recording(run_metadata: dict[str, str]) -> rr.RecordingStream:
    """A recording stream for the run of ``run_metadata``, on ``sim_time`` alone."""
    import rerun as rr

    # No properties: they would carry the wall-clock start of the recording.
    rec = rr.RecordingStream(
        APPLICATION_ID, recording_id=_recording_id(run_metadata), send_properties=False
    )
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    return rec


def _num(value: float | None, fmt: str = ".3f") -> str:
    return "-" if value is None else format(value, fmt)


def describe_decision(visit: VisitDecision) -> str:
    """One line for a visit's decision: node, known or new, similarity, margin, probes."""
    d = visit.decision
    parts = [
        f"visit {visit_label(visit.visit_id)} -> node {d.node}",
        "known" if d.known else "new",
        "similarity -" if d.candidate is None else f"similarity {d.similarity:.3f}",
        f"margin {_num(d.margin)}",
        f"candidate {'-' if d.candidate is None else d.candidate}",
    ]
    if d.match is not None:
        parts.append(f"rotation {d.match.rotation_rad:+.3f} rad")
    if d.two_view is not None:
        fit = d.two_view
        of = "" if fit.stages is None else f" of the first {fit.stages} stage(s)"
        parts.append(f"two-view rotation {fit.rotation_rad:+.4f} rad ({fit.inliers} inliers{of})")
    if d.probes:
        probes = []
        for p in d.probes:
            if p.similarity is None:
                probes.append(f"{p.request.kind.value} not in log")
            else:
                better = " (improved)" if p.improved else ""
                probes.append(f"{p.request.kind.value} {p.similarity:.3f}{better}")
        parts.append("probes: " + ", ".join(probes))
    else:
        parts.append("no probes")
    return "; ".join(parts)


class MapLog:
    """The map as it grows, and each decision as text, at the time of the decision.

    Fed one decision at a time, so a live view grows the map as the run goes. Given
    the ports, edges join ports, as in the replay's map: a traversal that conflicts
    with the map adds none.
    """

    def __init__(self, rec: rr.RecordingStream) -> None:
        self.rec = rec
        self.topomap = TopoMap()
        self._visits: dict[int, list[str]] = {}

    def add(
        self,
        v: VisitDecision,
        ports: tuple[float, ...] | None = None,
        arrival_port: int | None = None,
        *,
        new_traversal: bool = False,
    ) -> None:
        """Log the map after ``v``'s decision, and the decision, at its time.
        ``ports`` are the junction's (used when it is new); ``new_traversal``: the
        path is broken before this visit."""
        import rerun as rr

        rec, topomap = self.rec, self.topomap
        node = v.decision.node
        if new_traversal:
            topomap.new_traversal()
        new = node >= topomap.node_count or topomap.unused(node)
        topomap.visit(node, ports if new else None, arrival_port, pooled=True)
        self._visits.setdefault(node, []).append(visit_label(v.visit_id))
        set_time(rec, v.time_ns)
        count = topomap.node_count
        ids = [str(n) for n in range(count)]
        labels = [f"{n}: {', '.join(self._visits.get(n, []))}" for n in range(count)]
        colors = [_NODE_NOW if n == node else _NODE for n in range(count)]
        edges = [(str(e.u), str(e.v)) for e in topomap.edges()]
        rec.log(
            "map",
            rr.GraphNodes(ids, labels=labels, colors=colors),
            rr.GraphEdges(edges, graph_type="undirected"),
        )
        level = "INFO" if v.probes_not_in_log == 0 else "WARN"
        rec.log("log/decisions", rr.TextLog(describe_decision(v), level=level))

    def depart(self, port: int | None) -> None:
        """The robot left the junction of the last visit by ``port``."""
        self.topomap.depart(port)


def _log_map(rec: rr.RecordingStream, result: ReplayResult) -> None:
    grown = MapLog(rec)
    records = result.topomap.visit_records
    for i, v in enumerate(result.visits):
        record = records[i] if i < len(records) else None
        grown.add(
            v,
            result.topomap.ports(v.decision.node),
            None if record is None else record.arrival_port,
            new_traversal=i in result.breaks,
        )
        if record is not None:
            grown.depart(record.departure_port)


#: A replay's result, or a function that waits for one being made elsewhere.
Replayed = ReplayResult | Callable[[], ReplayResult]


#: Messages a view hands to rerun at a time: a log is read and logged in windows
#: of this many, so a view holds a window, not the log (a 100-junction run's log
#: is 1.4 million messages).
VIEW_WINDOW = 50_000


def _viewed(source: MessageSource) -> Iterator[LogMessage]:
    """The ``/robot`` and ``/truth`` messages of ``source``, in file order."""
    return (m for m in source.every_message() if m.topic.startswith((ROBOT_PREFIX, "/truth/")))


def log_view(
    rec: rr.RecordingStream,
    source: MessageSource,
    result: Replayed,
    max_rate_hz: float = DEFAULT_MAX_RATE_HZ,
) -> None:
    """Log everything a view shows of ``source`` and its replay ``result`` to ``rec``.

    The log's own streams go first, :data:`VIEW_WINDOW` messages at a time (what
    one window leaves for the next carried over, as the live view does: the
    recording is the one a single window would make, chunked otherwise);
    ``result``, if a function, is called only then, so a replay running in another
    process overlaps them. The range, IMU and wheel streams are shown at most
    ``max_rate_hz`` messages a second each (0: all; :func:`view_topics.decimated`).
    """
    geometry = RobotGeometry.from_run(source.run_metadata())
    carried = Carried(max_rate_hz=max_rate_hz)
    messages = _viewed(source)
    while window := list(itertools.islice(messages, VIEW_WINDOW)):
        by_topic: dict[str, list[LogMessage]] = defaultdict(list)
        for m in window:
            by_topic[m.topic].append(m)
        log_robot(rec, by_topic, geometry, carried)
        log_truth(rec, by_topic, carried.trail)
    _log_map(rec, result if isinstance(result, ReplayResult) else result())


def save_view(
    source: MessageSource,
    result: Replayed,
    path: Path | str,
    max_rate_hz: float = DEFAULT_MAX_RATE_HZ,
) -> None:
    """Write the view of ``source`` and ``result`` to the ``.rrd`` file ``path``.

    The file appears whole or not at all: it is written beside ``path`` under a
    temporary name and renamed when complete (:mod:`pipemap.wholefile`). An existing
    ``path`` is replaced. A write that fails in rerun's file writer (a full disk) is
    one :class:`WriteError`.
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise InputError(f"{path}: folder {path.parent} does not exist")
    rec = _recording(source)
    with partial_path(path) as partial:
        rec.save(partial, default_blueprint=view_blueprint())
        try:
            log_view(rec, source, result, max_rate_hz)
            rec.flush()
        except RuntimeError as exc:  # rerun's file writer stopped: it could not write
            # Not disconnected: that would flush the dead writer again, and rerun
            # would print its own error line besides this one.
            raise WriteError(f"{path}: cannot write (rerun: {exc})") from None
        except BaseException:
            rec.disconnect()
            raise
        rec.disconnect()


def spawn_view(
    source: MessageSource, result: Replayed, max_rate_hz: float = DEFAULT_MAX_RATE_HZ
) -> None:
    """Open the view of ``source`` and ``result`` in a rerun viewer (started if need be)."""
    rec = _recording(source)
    rec.spawn(default_blueprint=view_blueprint())
    log_view(rec, source, result, max_rate_hz)
    try:
        rec.flush()
    except RuntimeError as exc:  # rerun's report of a viewer it cannot reach
        raise ViewerError(f"the rerun viewer did not take the recording ({exc})") from None
    finally:
        rec.disconnect()
