"""The simulated world: pipe networks, their look, the robot's tours and sweeps.

Knows nothing of MCAP or of the localizer. Uses PyBullet (DIRECT, TinyRenderer)
for rendering and range rays; everything random draws from the run's seed.
"""

from __future__ import annotations

from pipemap.sim.episode import Condition, Episode, Pose, SimConfig, Sweep, Visit
from pipemap.sim.network import Network, Node, NodeKind, Pipe, build_network
from pipemap.sim.obstacles import Obstacle, ObstacleKind, place_obstacles
from pipemap.sim.plan import Tour, right_hand_tour, tour_edges
from pipemap.sim.policy import ExitChoice, ExitPolicy, Junction, RightHandPolicy, RunStatus
from pipemap.sim.recovery import RecoveryConfig
from pipemap.sim.robot import PlanarPose, Robot, RobotSpec
from pipemap.sim.stream import (
    ControlStep,
    NodeArrival,
    NodeDeparture,
    NodeExits,
    Note,
    PipeBlocked,
    RecordSink,
    SimRecord,
    SweepEnd,
    SweepImage,
    SweepStart,
    TruePose,
)
from pipemap.sim.world import CameraSpec, World

__all__ = [
    "CameraSpec",
    "Condition",
    "ControlStep",
    "Episode",
    "ExitChoice",
    "ExitPolicy",
    "Junction",
    "Network",
    "Node",
    "NodeArrival",
    "NodeDeparture",
    "NodeExits",
    "NodeKind",
    "Note",
    "Obstacle",
    "ObstacleKind",
    "Pipe",
    "PipeBlocked",
    "PlanarPose",
    "Pose",
    "RecordSink",
    "RecoveryConfig",
    "RightHandPolicy",
    "Robot",
    "RobotSpec",
    "RunStatus",
    "SimConfig",
    "SimRecord",
    "Sweep",
    "SweepEnd",
    "SweepImage",
    "SweepStart",
    "Tour",
    "TruePose",
    "Visit",
    "World",
    "build_network",
    "place_obstacles",
    "right_hand_tour",
    "tour_edges",
]
