"""The localizer online, and the exploration policy that reads its map.

:class:`OnlineLocalizer` takes a run's records as they come: it keeps each visit's
sweep until the robot's exit scan arrives (:class:`~pipemap.sim.stream.NodeExits`),
then decides the visit with the sweep and the exits, and records the port the robot
leaves by (:class:`~pipemap.sim.stream.NodeDeparture`). A replay of the log does the
same from ``/robot``, so it makes the same decisions.

:class:`MapPolicy` is the simulator's :class:`~pipemap.sim.policy.ExitPolicy` for
map-driven exploration: at each junction it asks the pure
:class:`~pipemap.localizer.MapExplorer` for a port of the localizer's map and turns
it into one of the robot's exits. The controller emits the exits before it asks its
policy, so the decision is made by then.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from pipemap.localizer import (
    Decision,
    ExploreConfig,
    ExploreEnd,
    ImageSet,
    Localizer,
    MapExplorer,
    Planner,
    ProbeRequest,
    RouteFollower,
    RouteStep,
)
from pipemap.sim.controller import ExplorationResult, ExplorerConfig, autonomous_run
from pipemap.sim.episode import Sweep
from pipemap.sim.policy import (
    BlockedExits,
    ExitChoice,
    ExitPolicy,
    Junction,
    RightHandPolicy,
    RunStatus,
)
from pipemap.sim.policy import is_behind as _is_behind
from pipemap.sim.policy import right_most as _right_most
from pipemap.sim.stream import NodeDeparture, NodeExits, PipeBlocked, SimRecord, SweepEnd
from pipemap.sim.world import CameraSpec, World

__all__ = [
    "Explore",
    "MapPolicy",
    "NoProbes",
    "OnlineLocalizer",
    "drive_route",
    "gray_set",
    "make_policy",
]


class Explore(enum.Enum):
    """How the autonomous robot chooses its exits."""

    #: Trémaux-style over the localizer's port-level map (pipemap's default).
    MAP = "map"
    #: The paper's right-most-branch rule.
    RIGHT_HAND = "right-hand"


def gray_set(
    images: np.ndarray,
    fov_rad: float,
    camera_angle_rad: float,
    imu_tilt_rad: tuple[float, float] = (0.0, 0.0),
) -> ImageSet:
    """The image set of RGB sweep images, as the localizer (and a replay) sees it."""
    gray = np.stack([cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in images])
    return ImageSet(gray, fov_rad, camera_angle_rad=camera_angle_rad, imu_tilt_rad=imu_tilt_rad)


class NoProbes:
    """A robot that cannot make probe moves: every request is answered ``None``."""

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        """Always ``None``."""
        return None


class OnlineLocalizer:
    """Decides each visit when its sweep and exits are in; calls ``on_decision``
    with the visit id and the decision (to log it)."""

    def __init__(
        self,
        localizer: Localizer,
        fov_rad: float,
        on_decision: Callable[[int, Decision], None] | None = None,
    ) -> None:
        self.localizer = localizer
        self.fov_rad = fov_rad
        self.on_decision = on_decision
        self.probes: Any = NoProbes()  # set per visit by a placement run
        self.decisions: dict[int, Decision] = {}
        self._pending: dict[int, Sweep] = {}

    def __call__(self, record: SimRecord) -> None:
        """Take one record of the run."""
        if isinstance(record, SweepEnd) and record.sweep.probe is None:
            self._pending[record.visit_id] = record.sweep
        elif isinstance(record, NodeExits):
            self._decide(
                record.visit_id, record.exits_rad, record.odometer_m, (record.x_m, record.y_m)
            )
        elif isinstance(record, NodeDeparture) and record.visit_id in self.decisions:
            self.localizer.depart(record.exit_rad)
        elif isinstance(record, PipeBlocked) and record.visit_id in self.decisions:
            self.localizer.block()

    def _decide(
        self,
        visit_id: int,
        exits: tuple[float, ...] | None,
        odometer_m: float | None,
        position_m: tuple[float, float] | None = None,
    ) -> None:
        sweep = self._pending.pop(visit_id, None)
        if sweep is None:
            return
        seen = gray_set(sweep.images, self.fov_rad, sweep.camera_angle_rad, sweep.imu_tilt_rad)
        decision = self.localizer.localize(seen, self.probes, exits, odometer_m, position_m)
        self.decisions[visit_id] = decision
        if self.on_decision is not None:
            self.on_decision(visit_id, decision)

    def finish(self) -> None:
        """Decide the sweeps whose exits never came (the run ended in between)."""
        for visit_id in sorted(self._pending):
            self._decide(visit_id, None, None)


class MapPolicy:
    """A map planner (map-driven exploration by default, or a route to drive) as the
    controller's exit policy."""

    def __init__(self, online: OnlineLocalizer, explorer: Planner | None = None) -> None:
        self.online = online
        self.explorer: Planner = explorer if explorer is not None else MapExplorer()
        #: Where the map cannot choose, the right-most exit (and the next after a
        #: blocked one).
        self._fallback = BlockedExits()

    def _right_hand(self, junction: Junction, again: bool, notes: tuple[str, ...]) -> ExitChoice:
        fallback = self._fallback
        if again:
            choice = fallback.next_right_most(junction)
            return ExitChoice(choice.exit_index, notes=notes + choice.notes)
        return fallback.take(junction.visit_id, _right_most(junction.exits_rad), notes)

    def choose(self, junction: Junction) -> ExitChoice:
        """The exit to the port the explorer chooses, or the end of the run."""
        return self._choice(junction, again=False)

    def blocked(self, junction: Junction) -> ExitChoice:
        """The explorer's choice again, the port last chosen now blocked in the map
        (the online localizer marked it from the robot's
        :class:`~pipemap.sim.stream.PipeBlocked`)."""
        return self._choice(junction, again=True)

    def _choice(self, junction: Junction, again: bool) -> ExitChoice:
        decision = self.online.decisions.get(junction.visit_id)
        if decision is None:  # no sweep was decided here: nothing to go by
            return self._right_hand(junction, again, ("no decision here",))
        ask = self.explorer.blocked if again else self.explorer.step
        step = ask(
            self.online.localizer.map, decision, junction.x_m, junction.y_m, junction.odometer_m
        )
        if step.stop is not None:
            status = (
                RunStatus.FINISHED if step.stop is ExploreEnd.FINISHED else RunStatus.INCONSISTENT
            )
            return ExitChoice(stop=status, notes=step.notes)
        if step.port is None or decision.exit_ports is None:
            return self._right_hand(junction, again, step.notes)
        index = decision.exit_ports.index(step.port)
        # Back the way it came (as the right-hand rule turns): the heading it drove in
        # on is better known than the scan's opening.
        behind = _is_behind(junction.exits_rad[index])
        return self._fallback.take(junction.visit_id, None if behind else index, step.notes)


def make_policy(
    explore: Explore,
    online: OnlineLocalizer,
    robot: ExplorerConfig,
    config: ExploreConfig | None = None,
) -> ExitPolicy:
    """The controller's policy for ``explore``: the right-hand rule with the robot's
    search for its start, or the map's explorer with ``config``."""
    if explore is Explore.RIGHT_HAND:
        return RightHandPolicy(robot.start_radius_m, robot.drift_per_m)
    explorer = MapExplorer(config if config is not None else ExploreConfig())
    explorer.rivals = online.localizer.hypothesis_exits
    explorer.odometry = online.localizer.dead_reckoning
    return MapPolicy(online, explorer)


def drive_route(
    world: World,
    camera: CameraSpec,
    localizer: Localizer,
    route: list[RouteStep],
    seed: int = 0,
    start: str | None = None,
    config: ExplorerConfig | None = None,
) -> tuple[ExplorationResult, OnlineLocalizer]:
    """Put the robot at ``start`` (default the entry) and drive ``route`` over the map
    ``localizer`` holds (a replay's, say): at each junction the localizer decides
    where the robot is, and the robot leaves by the route's port. The run ends
    ``finished`` when the localizer says the robot is at the route's goal."""
    localizer.new_traversal()
    online = OnlineLocalizer(localizer, camera.fov_rad)
    policy = MapPolicy(online, RouteFollower(list(route)))
    result = autonomous_run(
        world, camera, seed, start=start, config=config, sink=online, policy=policy
    )
    online.finish()
    return result, online
