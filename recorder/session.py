"""Recording a run: the simulator, the localizer online, and every record to the log.

:func:`record_run` builds the world, runs the episode (the autonomous explorer, or
the paper's placement conditions), and writes each record the simulator emits as
it comes: sensors and the controller under ``/robot``, the true pose and the true
node of each sweep under ``/truth``, and the online localizer's decision for each
visit under ``/online``. The localizer sees exactly what the log holds: the robot's
images after a lossless PNG round trip, and its own camera angles.

Active vision: the localizer may ask for probe sweeps after small moves. In the
``active`` condition the experimenter puts the robot down after each move; the
autonomous robot makes the moves itself, checked by its rangers
(:mod:`recorder.probe_moves`), unless its settings turn them off
(``probe_moves``). Either way they are logged as probe sweeps of the visit. In the
other placed conditions, and with the moves off, it makes none, and the decision
records the probes as missing; a replay of the log then meets the same answer.

In the placement conditions (``perfect``, ``noise``, ``active``, ``entrance``) the
robot is carried along the tour and put down at each node by hand, as in the paper;
there it sweeps, re-centres and scans for the exits with its own sensors, as the
autonomous robot does, and its node events hold only what it measured (see
:class:`_PlacedRun`). Ground truth reaches the log's ``/truth`` topics alone.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from pipemap.errors import InputError
from pipemap.localizer import (
    Decision,
    ImageSet,
    Localizer,
    LocalizerConfig,
    ProbeRequest,
)
from pipemap.localizer.odometry import drift_allowed
from pipemap.recorder import messages
from pipemap.recorder.background import BackgroundWriter
from pipemap.recorder.convert import LogRecord, ReadyMessage, SweepDone
from pipemap.recorder.inline import InlineWriter, NoLog, RecordWriter
from pipemap.recorder.online import NoProbes, OnlineLocalizer, gray_set, make_policy
from pipemap.recorder.probe_moves import RobotProbes
from pipemap.recorder.settings import RecordSettings
from pipemap.recorder.topics import Topic
from pipemap.sim.controller import RunStatus, autonomous_run
from pipemap.sim.episode import Condition, Episode, Pose, Sweep, SweepTruth, Visit
from pipemap.sim.junction_actions import recentre, scan
from pipemap.sim.motion import Motion
from pipemap.sim.network import Network
from pipemap.sim.obstacles import Obstacle, ObstacleKind
from pipemap.sim.policy import right_most
from pipemap.sim.recovery import RecoveryConfig
from pipemap.sim.robot import PlanarPose, Robot
from pipemap.sim.stream import (
    NodeArrival,
    NodeDeparture,
    NodeExits,
    SimRecord,
    SweepEnd,
    SweepImage,
    SweepStart,
)
from pipemap.sim.world import CameraSpec, World
from pipemap.sim.world_process import WorldProcess

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
#: Placement conditions: carrying the robot to the next node, a probe move.
_CARRY_NS = 10 * _NS_PER_S
_PROBE_MOVE_NS = 2 * _NS_PER_S
#: A placed robot has no watchdog: it only sweeps and scans where it is put down.
_NO_TIME_LIMIT = 2**62
#: The seed stream of a placed robot's sensors (with the run's seed).
PLACED_ROBOT_STREAM = 21


@dataclass(frozen=True)
class Progress:
    """How far a recording has come: as the world is built (``world_pieces``: a large
    network's takes a minute), and at the end of every sweep."""

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
    #: Autonomous runs: stalls the robot got past, and pipes it gave up as blocked.
    stalls_recovered: int = 0
    pipes_given_up: int = 0


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
            sweep, truth = record.sweep, record.truth
            self.put(
                SweepDone(
                    record.t_ns,
                    record.sweep_id,
                    record.visit_id,
                    len(sweep.images),
                    truth.camera_pose,
                    truth.node,
                )
            )
            self.sweeps += 1
            if sweep.probe is None:
                self.true_nodes.add(truth.node)
                self.true_path.append(truth.node)
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
        moved = self.visit.moved(request.yaw_rad, request.forward_m, request.left_m)
        m = self.runner.put_down(moved, self.runner.robot_time_ns() + _PROBE_MOVE_NS)
        sweep, truth = self.visit.probe(
            request.yaw_rad, request.forward_m, request.left_m, m.yaw_est
        )
        probe = (request.kind.value, request.yaw_rad, request.forward_m, request.left_m)
        self.runner.emit_sweep(sweep, truth, self.visit_id, probe)
        camera = self.sink.camera
        return gray_set(sweep.images, camera.fov_rad, sweep.camera_angle_rad, sweep.imu_tilt_rad)


class _PlacedRun:
    """The paper's placement conditions: the robot carried by hand along the tour and
    put down at each node, where it sweeps its camera and scans for the exits with its
    own range sensors, as the autonomous robot does. Its node events hold only what
    it measured: the exits from its scan, relative to its gyro's heading estimate
    when put down (the gyro runs while it is carried, see :meth:`Robot.place`); its
    dead reckoning since it was put down; its odometer, which counts only its own
    wheels. Its sweeps start at the multiple of ``2*pi/N`` nearest that estimate. It
    leaves by its right-most measured exit, the tour's rule, and the experimenter
    carries it along the tour. Log time is the robot's, a fixed carry time between
    nodes."""

    def __init__(self, world: World, settings: RecordSettings, sink: _OnlineSink) -> None:
        self.world = world
        self.settings = settings
        self.sink = sink
        self.sweep_id = 0
        self.distance_m = 0.0  # carried, from the truth: the summary's only
        self.config = settings.explorer_config()
        self.motion: Motion | None = None

    def robot_time_ns(self) -> int:
        """The robot's clock (0 before it is first put down)."""
        return 0 if self.motion is None else self.motion.robot.t_ns

    def put_down(self, where: Pose, t_ns: int) -> Motion:
        """Carry the robot to ``where`` (its body; the camera's tilt aside) and put it
        down at ``t_ns``; it stands still a control period, its gyro reading the turn."""
        pose = PlanarPose(where.x_m, where.y_m, where.yaw_rad)
        if self.motion is None:
            rng = np.random.default_rng([self.settings.seed, PLACED_ROBOT_STREAM])
            robot = Robot(self.world, pose, rng, self.settings.robot_spec())
            robot.place(pose, t_ns)
            self.motion = Motion(robot, self.config, RecoveryConfig(), self.sink, _NO_TIME_LIMIT)
            # Its frame is the start's, as the autonomous robot's is.
        else:
            self.motion.robot.place(pose, t_ns)
        m = self.motion
        m.put_down()
        m.state = "put down"
        m.drive(0.0, 0.0, self.config.control_period_ns)
        return m

    def emit_sweep(
        self,
        sweep: Sweep,
        truth: SweepTruth,
        visit_id: int,
        probe: tuple[str, float, float, float] | None,
    ) -> None:
        """Log ``sweep`` as the robot takes it, standing still for each image."""
        m = self.motion
        assert m is not None
        self.sweep_id += 1
        n = len(sweep.images)
        fov = self.settings.camera().fov_rad
        m.state = "sweeping"
        t = m.robot.t_ns
        angle = sweep.camera_angle_rad
        self.sink(SweepStart(t, self.sweep_id, visit_id, n, angle, fov, probe, sweep.imu_tilt_rad))
        for j, image in enumerate(sweep.images):
            step = angle - j * 2.0 * math.pi / n
            self.sink(SweepImage(m.robot.t_ns, self.sweep_id, visit_id, j, step, image))
            m.drive(0.0, 0.0, self.config.sweep_step_ns)  # the camera motor turns
        self.sink(SweepEnd(m.robot.t_ns, self.sweep_id, visit_id, sweep, truth))

    def run(self) -> str:
        episode = Episode(self.world, self.settings.sim_config(), start=self.settings.start)
        network = episode.network  # the experimenter's: the distance carried, for the summary
        previous: str | None = None
        for visit in episode.visits():
            visit_id = visit.index + 1
            if previous is not None:
                self.distance_m += network.length_m(previous, visit.node)
            m = self.put_down(visit.pose, self.robot_time_ns() + _CARRY_NS)
            arrival = m.yaw_est
            self.sink(NodeArrival(m.robot.t_ns, visit_id))
            if self.settings.condition is Condition.ACTIVE:
                self.sink.online.probes = _PlacedProbes(self.sink, visit, visit_id, self)
            else:
                self.sink.online.probes = NoProbes()
            sweep, truth = visit.take_sweep(arrival)
            self.emit_sweep(sweep, truth, visit_id, None)
            # As the autonomous robot: to the centre its range scan finds (where it can
            # turn clear of the walls), then the exit scan.
            recentre(m, m.xy_est.copy())
            exits, _steer = scan(m)
            relative = tuple(math.remainder(e - arrival, 2.0 * math.pi) for e in exits)
            x, y = (float(v) for v in m.xy_est)
            odometer = m.result.distance_m
            self.sink(NodeExits(m.robot.t_ns, visit_id, relative, x, y, odometer))
            if episode.tour.visits[visit.index].leave_to is not None:
                chosen = right_most(relative)
                turn = math.pi if chosen is None else relative[chosen]
                self.sink(NodeDeparture(m.robot.t_ns, visit_id, len(relative), turn))
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
    path: Path | None,
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
    that share the cores, see :mod:`recorder.inline`): the same bytes. Without a
    ``path`` the same run is made and no log is written (``pipemap sim``: the observer
    keeps what it needs).
    """
    if settings.start is not None and settings.start not in network.labels:
        raise InputError(f"--start {settings.start}: no such node in {settings.network}")
    camera = settings.camera()
    config = drift_allowed(
        LocalizerConfig(
            threshold=settings.threshold,
            odometry_check=settings.odometry_check,
            hypotheses=settings.hypotheses,
        ),
        settings.odometry_drift,
    )
    localizer = Localizer(config.for_camera(camera.lamp_strength > 0.0))
    deposits = settings.deposits(network)  # checked before the log is opened
    mode = "wb" if overwrite else "xb"
    metadata = settings.metadata(network, version)
    opened: NoLog | InlineWriter | BackgroundWriter
    if path is None:
        opened = NoLog()
    elif inline:
        opened = InlineWriter(path, mode, metadata)
    else:
        opened = BackgroundWriter(path, mode, metadata)
    with opened as writer:
        sink = _OnlineSink(writer, localizer, camera, progress, observer)
        truth = messages.network_message(network, obstacles=deposits)
        sink.put(ReadyMessage.of(0, Topic.NETWORK, truth))
        looks = settings.looks(network)
        on_build = None
        if progress is not None:
            report = progress

            def on_build(built: int, pieces: int) -> None:
                report(Progress(0, 0, 0, world_pieces=(built, pieces)))

        budget = settings.world_memory_mib
        world_type: Any = partial(WorldProcess, memory_budget_mib=budget) if budget else World
        with world_type(
            network,
            seed=settings.seed,
            obstacles=deposits,
            looks=looks,
            on_build=on_build,
        ) as world:
            writer.send()  # the file is open before the run starts
            if settings.condition is Condition.AUTONOMOUS:
                explorer, plan = settings.explorer_config(), settings.explore_config()
                policy = make_policy(settings.explore, sink.online, explorer, plan)
                robot_probes = RobotProbes(camera.fov_rad) if settings.probe_moves else None
                if robot_probes is not None:
                    sink.online.probes = robot_probes  # active vision: the robot moves
                result = autonomous_run(
                    world,
                    camera,
                    settings.seed,
                    start=settings.start,
                    config=explorer,
                    sink=sink,
                    policy=policy,
                    motor_faults=settings.cut_outs(network),
                    on_explorer=None if robot_probes is None else robot_probes.attach,
                    robot_spec=settings.robot_spec(),
                )
                status = result.status.value
                distance, duration = result.distance_m, result.duration_ns
                # The robot believes it is done; the truth says whether it covered all
                # it could reach (every pipe but the blocked ones).
                covered = covers(network, deposits, sink.true_nodes, sink.true_path)
                ok = result.status is RunStatus.FINISHED and covered
                events = [text for _, text in result.events]
                recovered = sum(text.startswith("stall: past it") for text in events)
                given_up = sum(text.startswith("pipe blocked") for text in events)
            else:
                recovered = given_up = 0
                placed = _PlacedRun(world, settings, sink)
                status = placed.run()
                distance, duration = placed.distance_m, placed.robot_time_ns()
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
        stalls_recovered=recovered,
        pipes_given_up=given_up,
    )
