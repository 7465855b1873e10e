"""Recording a run: the simulator, the localizer online, and every record to the log.

:func:`record_run` builds the world, runs the episode (the autonomous explorer, or
the paper's placement conditions), and writes each record the simulator emits as
it comes: sensors and the controller under ``/robot``, the true pose and the true
node of each sweep under ``/truth``, and the online localizer's decision for each
visit under ``/online``. The localizer sees exactly what the log holds: the robot's
images after a lossless PNG round trip, and its own camera angles.

Active vision: the localizer may ask for probe sweeps after small moves. In the
``active`` condition the robot makes them (they are logged as probe sweeps of the
visit). In every other condition it cannot, and the decision records the probes as
missing; a replay of the log then meets the same answer.

In the placement conditions (``perfect``, ``noise``, ``active``, ``entrance``) the
robot is put at each node by hand, as in the paper: there are no drive sensors,
and log time advances by the camera's steps and by the time the robot would take
to drive each pipe at its cruising speed.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from pipemap.errors import InputError
from pipemap.localizer import (
    Decision,
    ImageSet,
    Localizer,
    LocalizerConfig,
    ProbeRequest,
)
from pipemap.recorder import messages
from pipemap.recorder.background import BackgroundWriter
from pipemap.recorder.convert import LogRecord, ReadyMessage, SweepDone
from pipemap.recorder.inline import InlineWriter, RecordWriter
from pipemap.recorder.online import NoProbes, OnlineLocalizer, gray_set, make_policy
from pipemap.recorder.settings import RecordSettings
from pipemap.recorder.topics import Topic
from pipemap.sim.controller import ExplorerConfig, RunStatus, autonomous_run
from pipemap.sim.episode import Condition, Episode, Sweep, Visit
from pipemap.sim.network import Network
from pipemap.sim.obstacles import Obstacle, ObstacleKind
from pipemap.sim.robot import PlanarPose
from pipemap.sim.stream import (
    NodeArrival,
    NodeDeparture,
    NodeExits,
    SimRecord,
    SweepEnd,
    SweepImage,
    SweepStart,
    TruePose,
)
from pipemap.sim.world import CameraSpec, World

#: ``pipemap -v`` prints each online decision (stderr).
_LOG = logging.getLogger(__name__)

__all__ = [
    "Progress",
    "RecordResult",
    "RecordSettings",
    "RunObserver",
    "covers",
    "record_run",
]

_NS_PER_S = 1_000_000_000
#: Placement conditions: the camera motor's step, a probe move, the cruising speed.
_SWEEP_STEP_NS = 500_000_000
_PROBE_MOVE_NS = 2 * _NS_PER_S
_CRUISE_MPS = ExplorerConfig().speed_mps


@dataclass(frozen=True)
class Progress:
    """How far a recording has come."""

    sim_time_ns: int
    sweeps: int
    visits: int
    #: While the world is built, before the run: (pieces built, pieces in all).
    world_pieces: tuple[int, int] | None = None


#: Watches a run as it is recorded: called with the records sent to the log since the
#: last call, in the log's order, at the end of every sweep (visit or probe) and once
#: after the run. A batch holds whole sweeps; the records must not be changed.
RunObserver = Callable[[Sequence[LogRecord]], None]


@dataclass(frozen=True)
class RecordResult:
    """How a recording ended and what it holds.

    ``status`` is the robot's (``finished``, ``map inconsistent``, a watchdog's
    reason, or ``complete`` / ``incomplete`` for a placed tour). ``true_nodes`` is
    the set of nodes whose sweeps the log holds and ``pipes_driven`` the number of
    pipes between two consecutive ones, from the simulator's truth, for the summary
    only. ``ok``: the run finished and covered every node and pipe.
    """

    status: str
    ok: bool
    sweeps: int
    visits: int
    distance_m: float
    duration_ns: int
    messages: int
    true_nodes: frozenset[str]
    node_count: int
    pipes_driven: int = 0
    pipe_count: int = 0


class _OnlineSink:
    """Sends each simulator record to the writer and to the online localizer, which
    decides each visit (not probe sweeps) once its exits are in; logs each decision."""

    def __init__(
        self,
        writer: RecordWriter,
        localizer: Localizer,
        camera: CameraSpec,
        progress: Callable[[Progress], None] | None,
        observer: RunObserver | None = None,
    ) -> None:
        self.writer = writer
        self.camera = camera
        self.progress = progress
        self.observer = observer
        self.observed: list[LogRecord] = []
        self.online = OnlineLocalizer(localizer, camera.fov_rad, self._log_decision)
        self.sweeps = 0
        self.visits = 0
        self.true_nodes: set[str] = set()
        self.true_path: list[str] = []
        self.now_ns = 0

    @property
    def localizer(self) -> Localizer:
        """The online localizer."""
        return self.online.localizer

    def _log_decision(self, visit_id: int, decision: Decision) -> None:
        threshold = self.localizer.config.threshold
        message = messages.decision_message(self.now_ns, visit_id, decision, threshold)
        self.put(ReadyMessage.of(self.now_ns, Topic.DECISION, message))
        if _LOG.isEnabledFor(logging.DEBUG):
            _LOG.debug("visit %d at %.1f s: %s", visit_id, self.now_ns / 1e9, decision.describe())

    def __call__(self, record: SimRecord) -> None:
        self.now_ns = max(self.now_ns, record.t_ns)
        if isinstance(record, NodeArrival):
            self.visits += 1
        if isinstance(record, SweepEnd):
            sweep = record.sweep
            self.put(
                SweepDone(
                    record.t_ns,
                    record.sweep_id,
                    record.visit_id,
                    len(sweep.images),
                    sweep.start_pose,
                    sweep.true_node,
                )
            )
            self.sweeps += 1
            if sweep.probe is None:
                self.true_nodes.add(sweep.true_node)
                self.true_path.append(sweep.true_node)
        else:
            self.put(record)
        self.online(record)
        if isinstance(record, SweepEnd | NodeExits):
            self.writer.send()
            if self.progress is not None:
                self.progress(Progress(self.now_ns, self.sweeps, self.visits))
            self.show()

    def put(self, record: LogRecord) -> None:
        """Queue ``record`` for the log, and for the observer if there is one."""
        self.writer.put(record)
        if self.observer is not None:
            self.observed.append(record)

    def show(self) -> None:
        """Hand the records logged since the last call to the observer."""
        if self.observer is not None and self.observed:
            batch, self.observed = self.observed, []
            self.observer(batch)

    def finish(self) -> None:
        """Decide any sweep whose exits never came, and send what is left."""
        self.online.finish()
        self.writer.send()
        self.show()


class _PlacedProbes:
    """Probe moves of the ``active`` condition: each is swept and logged."""

    def __init__(self, sink: _OnlineSink, visit: Visit, visit_id: int, runner: _PlacedRun) -> None:
        self.sink, self.visit, self.visit_id, self.runner = sink, visit, visit_id, runner

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        sweep = self.visit.probe(request.yaw_rad, request.forward_m, request.left_m)
        self.runner.clock_ns += _PROBE_MOVE_NS
        probe = (request.kind.value, request.yaw_rad, request.forward_m, request.left_m)
        self.runner.emit_sweep(sweep, self.visit_id, probe)
        camera = self.sink.camera
        return gray_set(sweep.images, camera.fov_rad, sweep.camera_angle_rad, sweep.imu_tilt_rad)


class _PlacedRun:
    """The paper's placement conditions on a simulated clock."""

    def __init__(self, world: World, settings: RecordSettings, sink: _OnlineSink) -> None:
        self.world = world
        self.settings = settings
        self.sink = sink
        self.clock_ns = 0
        self.sweep_id = 0
        self.distance_m = 0.0

    def emit_sweep(
        self, sweep: Sweep, visit_id: int, probe: tuple[str, float, float, float] | None
    ) -> None:
        self.sweep_id += 1
        n = len(sweep.images)
        fov = self.settings.camera().fov_rad
        start = sweep.start_pose
        yaw = start.yaw_rad - sweep.camera_angle_rad  # the robot's heading
        self.sink(TruePose(self.clock_ns, PlanarPose(start.x_m, start.y_m, yaw)))
        self.sink(
            SweepStart(
                self.clock_ns,
                self.sweep_id,
                visit_id,
                n,
                sweep.camera_angle_rad,
                fov,
                probe,
                sweep.imu_tilt_rad,
            )
        )
        for j, image in enumerate(sweep.images):
            angle = sweep.camera_angle_rad - j * 2.0 * math.pi / n
            self.sink(SweepImage(self.clock_ns, self.sweep_id, visit_id, j, angle, image))
            self.clock_ns += _SWEEP_STEP_NS
        self.sink(SweepEnd(self.clock_ns, self.sweep_id, visit_id, sweep))

    def run(self) -> str:
        episode = Episode(self.world, self.settings.sim_config(), start=self.settings.start)
        network = self.world.network
        previous: str | None = None
        for visit in episode.visits():
            visit_id = visit.index + 1
            if previous is not None:
                length = network.length_m(previous, visit.node)
                self.distance_m += length
                self.clock_ns += round(length / _CRUISE_MPS * _NS_PER_S)
            self.sink(NodeArrival(self.clock_ns, visit_id))
            if self.settings.condition is Condition.ACTIVE:
                self.sink.online.probes = _PlacedProbes(self.sink, visit, visit_id, self)
            else:
                self.sink.online.probes = NoProbes()
            self.emit_sweep(visit.sweep, visit_id, None)
            # Placed by hand, the robot makes no exit scan: its exits are the
            # junction's pipes as placed (exact), as its exit count always was.
            headings = network.pipe_headings(visit.node)
            exits = tuple(
                math.remainder(headings[n] - visit.pose.yaw_rad, 2.0 * math.pi)
                for n in network.neighbours(visit.node)
            )
            here = visit.pose
            self.sink(
                NodeExits(self.clock_ns, visit_id, exits, here.x_m, here.y_m, self.distance_m)
            )
            leave = episode.tour.visits[visit.index].leave_to
            if leave is not None:
                turn = math.remainder(headings[leave] - visit.pose.yaw_rad, 2.0 * math.pi)
                exits_count = network.degree(visit.node)
                self.sink(NodeDeparture(self.clock_ns, visit_id, exits_count, turn))
            previous = visit.node
        return "complete" if episode.tour.complete else "incomplete"


def _pipes_driven(network: Network, path: list[str]) -> int:
    """How many of the network's pipes join two consecutive nodes of ``path``."""
    pipes = {frozenset((p.a, p.b)) for p in network.pipes}
    return len({frozenset(ab) for ab in zip(path, path[1:], strict=False)} & pipes)


def covers(
    network: Network, deposits: tuple[Obstacle, ...], nodes: set[str], path: list[str]
) -> bool:
    """Whether a run whose sweeps were at true ``nodes`` along ``path`` covered the
    network: every node and pipe swept and driven; with blocking deposits, every
    node reachable without driving a blocked pipe, and every other pipe among them."""
    blocked = {o.pipe for o in deposits if o.kind is ObstacleKind.BLOCKING}
    if not blocked:
        return nodes - {"?"} == set(network.labels) and _pipes_driven(network, path) == len(
            network.pipes
        )
    start = path[0] if path else ""
    reach, todo = {start}, [start]
    while todo:
        here = todo.pop()
        for there in network.neighbours(here) if here in network.labels else ():
            pipe = (min(here, there), max(here, there))
            if pipe not in blocked and there not in reach:
                reach.add(there)
                todo.append(there)
    open_pipes = {(min(p.a, p.b), max(p.a, p.b)) for p in network.pipes if p.a in reach} - blocked
    driven = {(min(a, b), max(a, b)) for a, b in zip(path, path[1:], strict=False)}
    return reach <= nodes and open_pipes <= driven


def record_run(
    path: Path,
    settings: RecordSettings,
    network: Network,
    version: str,
    progress: Callable[[Progress], None] | None = None,
    overwrite: bool = False,
    observer: RunObserver | None = None,
    inline: bool = False,
) -> RecordResult:
    """Run ``settings`` on ``network`` and write its log to ``path``.

    The log is finished whatever ends the run; on an exception (Ctrl-C included)
    its result metadata says so and the exception propagates. Without
    ``overwrite`` an existing file is never touched. ``observer``, if given, sees
    every record as the log gets it (a live view); the log is the same without it.
    ``inline`` writes the log in this process rather than a writer process (for runs
    that share the cores, see :mod:`recorder.inline`): the same bytes.
    """
    if settings.start is not None and settings.start not in network.labels:
        raise InputError(f"--start {settings.start}: no such node in {settings.network}")
    camera = settings.camera()
    config = LocalizerConfig(threshold=settings.threshold)
    localizer = Localizer(config.for_camera(camera.lamp_strength > 0.0))
    deposits = settings.deposits(network)  # checked before the log is opened
    mode = "wb" if overwrite else "xb"
    opened = InlineWriter if inline else BackgroundWriter
    with opened(path, mode, settings.metadata(network, version)) as writer:
        sink = _OnlineSink(writer, localizer, camera, progress, observer)
        truth = messages.network_message(network, obstacles=deposits)
        sink.put(ReadyMessage.of(0, Topic.NETWORK, truth))
        on_build = None
        if progress is not None:
            report = progress

            def on_build(built: int, pieces: int) -> None:
                report(Progress(0, 0, 0, world_pieces=(built, pieces)))

        with World(network, seed=settings.seed, obstacles=deposits, on_build=on_build) as world:
            writer.send()  # the file is open before the run starts
            if settings.condition is Condition.AUTONOMOUS:
                explorer = settings.explorer_config()
                policy = make_policy(
                    settings.explore, sink.online, explorer.start_radius_m, explorer.drift_per_m
                )
                result = autonomous_run(
                    world,
                    camera,
                    settings.seed,
                    start=settings.start,
                    config=explorer,
                    sink=sink,
                    policy=policy,
                    motor_faults=settings.cut_outs(network),
                )
                status = result.status.value
                distance, duration = result.distance_m, result.duration_ns
                # The robot believes it is done; the truth says whether it covered all
                # it could reach (every pipe but the blocked ones).
                covered = covers(network, deposits, sink.true_nodes, sink.true_path)
                ok = result.status is RunStatus.FINISHED and covered
            else:
                placed = _PlacedRun(world, settings, sink)
                status = placed.run()
                distance, duration = placed.distance_m, placed.clock_ns
                ok = status == "complete"
            sink.finish()
        count = writer.finish(
            {
                "status": status,
                "sweeps": str(sink.sweeps),
                "visits": str(sink.visits),
                "distance_m": repr(round(distance, 6)),
                "duration_ns": str(duration),
            }
        )
    return RecordResult(
        status=status,
        ok=ok,
        sweeps=sink.sweeps,
        visits=sink.visits,
        distance_m=distance,
        duration_ns=duration,
        messages=count,
        true_nodes=frozenset(sink.true_nodes - {"?"}),
        pipes_driven=_pipes_driven(network, sink.true_path),
        pipe_count=len(network.pipes),
        node_count=len(network.nodes),
    )
