"""The autonomous explorer: exploration from the robot's own sensors.

It never reads ground truth: only the three rangers, the gyro and the encoders. Which
pipe to take at a junction is its :class:`~pipemap.sim.policy.ExitPolicy`'s choice
(the paper's right-most-branch rule unless it is given another).

* **Calibrate**: stand still for 2 s first; whenever the robot stands still (here
  and during every sweep) the gyro's reading is taken as its bias, and the heading
  estimate integrates the rate less that bias.
* **Follow** a pipe at constant speed, steering to balance the front-left and
  front-right ranges (which measures both offset and heading error). A node is
  detected ahead when a side ray finds an opening or the front ray a wall; the
  ranges give the distance to its centre.
* **Approach**: drive that distance by odometry, holding the heading by gyro.
* **Sweep** the camera (N images, clockwise, from the multiple of ``2*pi/N`` nearest
  the heading estimate, see :func:`sim.episode.sweep_start_angle`), then **scan**:
  turn in place once round while the front ranger looks for openings. Openings, not a lookup table
  of junction types, give the exits, so junctions at any angle work.
* **Choose**: the exits (relative to the arrival heading) and the odometry go to the
  policy, which names the exit to take (or straight back), or stops the run. The
  right-hand policy takes the right-most exit (turns around at a dead end) and stops
  when back at the start (by odometry) as many times as it has pipes: on a tree the
  rule has then covered everything. **Turn** to the exit by gyro and **leave** until
  the node is behind.
* **Get unstuck** (:mod:`sim.recovery`): a stall in a pipe (commanded motion, the
  wheels not turning) starts a bounded recovery: back off, re-centre, retry to
  either side. When every try stalls the pipe is given up: the robot logs it
  (:class:`~pipemap.sim.stream.PipeBlocked`), drives back to the junction it came
  from, faces as it did there, and asks its policy again
  (:meth:`~pipemap.sim.policy.ExitPolicy.blocked`), without a new sweep.
* A watchdog ends a run whose robot touches a wall or stops making progress, with
  that reason: the last resort.

This module holds the loop that strings these together (:class:`Explorer`) and
:func:`autonomous_run`. The pieces are each in their own module: the settings and
result (:mod:`sim.explorer_config`), the driving primitives and the estimates
(:mod:`sim.motion`), following a pipe (:mod:`sim.follow`), the actions at a node
(:mod:`sim.junction_actions`) on the scan's pure geometry
(:mod:`sim.scan_geometry`), and getting past a stall or giving a pipe up
(:mod:`sim.unstuck`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pipemap.sim.episode import TILT_STREAM
from pipemap.sim.explorer_config import (
    MIN_TIME_LIMIT_S,
    TIME_LIMIT_S_PER_PIPE_M,
    ExplorationResult,
    ExplorerConfig,
    default_time_limit_ns,
)
from pipemap.sim.follow import Bend
from pipemap.sim.junction_actions import recentre, scan, sweep
from pipemap.sim.motion import Motion
from pipemap.sim.motor_faults import MotorFault
from pipemap.sim.policy import ExitPolicy, Junction, RightHandPolicy, RunStatus
from pipemap.sim.recovery import RecoveryConfig
from pipemap.sim.robot import PlanarPose, Robot, RobotSpec
from pipemap.sim.stream import NodeDeparture, NodeExits, RecordSink, TruePose
from pipemap.sim.unstuck import Left, choose_again, give_up, travel
from pipemap.sim.world import CameraSpec, World

__all__ = [
    "MIN_TIME_LIMIT_S",
    "TIME_LIMIT_S_PER_PIPE_M",
    "ExplorationResult",
    "Explorer",
    "ExplorerConfig",
    "RunStatus",
    "autonomous_run",
    "default_time_limit_ns",
]


class Explorer:
    """Drives a :class:`Robot` through its world; ``policy`` chooses the exits (default:
    the right-most-branch rule with the config's start radius and drift)."""

    def __init__(
        self,
        robot: Robot,
        camera: CameraSpec,
        config: ExplorerConfig | None = None,
        true_node_of: Callable[[PlanarPose], str] | None = None,
        sink: RecordSink | None = None,
        policy: ExitPolicy | None = None,
        recovery: RecoveryConfig | None = None,
        tilt_rng: np.random.Generator | None = None,
    ) -> None:
        self.robot = robot
        #: Draws the robot's tilt at each junction (``ExplorerConfig.tilt_rad``).
        self._tilt_rng = tilt_rng
        self.recovery = recovery if recovery is not None else RecoveryConfig()
        self.camera = camera
        self.config = config if config is not None else ExplorerConfig()
        if policy is None:
            policy = RightHandPolicy(self.config.start_radius_m, self.config.drift_per_m)
        self.policy = policy
        limit = self.config.time_limit_ns
        self.time_limit_ns = (
            limit if limit is not None else default_time_limit_ns(robot.world.network)
        )
        # Ground truth only labels the sweeps for scoring; no decision reads it.
        self._true_node_of = true_node_of
        self.motion = Motion(robot, self.config, self.recovery, sink, self.time_limit_ns)
        #: At the junction of the latest sweep: the robot's (roll, pitch) and its IMU's
        #: reading of them, and its heading estimate when it swept (for probe moves).
        self.junction_tilt: tuple[tuple[float, float], tuple[float, float]] = ((0.0, 0.0),) * 2
        self.sweep_heading = self.motion.yaw_est

    @property
    def true_node_of(self) -> Callable[[PlanarPose], str] | None:
        """Labels a sweep with the node it was truly taken at (for scoring only)."""
        return self._true_node_of

    def _tilt(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The robot's (roll, pitch) at this junction, and its IMU's reading of them."""
        c = self.config
        rng = self._tilt_rng
        if c.tilt_rad <= 0.0 or rng is None:
            return (0.0, 0.0), (0.0, 0.0)
        roll, pitch = (float(v) for v in rng.uniform(-1.0, 1.0, 2) * c.tilt_rad)
        noise = c.imu_tilt_noise_rad
        imu = (roll + float(rng.normal(0.0, noise)), pitch + float(rng.normal(0.0, noise)))
        return (roll, pitch), imu

    def run(self) -> ExplorationResult:
        """Explore until the policy stops the run, or the watchdog does.

        At each junction the exits go to the sink (as :class:`NodeExits`) before the
        policy is asked, so that whatever listens (an online localizer) can decide
        where the robot is first.
        """
        c = self.config
        m = self.motion
        arrival = m.yaw_est
        expected = m.xy_est.copy()
        first = True
        returning: Left | None = None  # from a blocked pipe, to this junction
        m.drive(0.0, 0.0, c.calibrate_ns)  # stand still: measure the gyro bias
        while True:
            if not first:
                status = recentre(m, expected)
                if status is not None:
                    m.result.status = status
                    m.event(f"watchdog: {status.value}", warning=True)
                    break
            first = False
            if returning is not None:
                junction, exits, steer = returning.junction, returning.exits, returning.steer
                arrival = returning.arrival
                choice = choose_again(m, self.policy, returning)
                returning = None
            else:
                self.junction_tilt = self._tilt()
                self.sweep_heading = m.yaw_est
                sweep(m, self.camera, self._true_node_of, *self.junction_tilt)
                exits, steer = scan(m)
                relative = tuple(math.remainder(e - arrival, 2.0 * math.pi) for e in exits)
                x, y = (float(v) for v in m.xy_est)
                odometer = m.result.distance_m
                junction = Junction(len(m.result.sweeps), relative, x, y, odometer)
                if m.sink is not None:
                    m.sink(NodeExits(m.robot.t_ns, junction.visit_id, relative, x, y, odometer))
                choice = self.policy.choose(junction)
            visit = junction.visit_id
            for note in choice.notes:
                m.event(note)
            if choice.stop is not None:
                m.result.status = choice.stop
                if choice.stop is not RunStatus.FINISHED:
                    m.event(f"stopped: {choice.stop.value}", warning=True)
                break
            back = arrival + math.pi
            reported = back if choice.exit_index is None else exits[choice.exit_index]
            heading = back if choice.exit_index is None else steer[choice.exit_index]
            turn = math.remainder(reported - arrival, 2.0 * math.pi)
            if m.sink is not None:
                m.sink(NodeDeparture(m.robot.t_ns, visit, len(exits), turn))
            origin = m.xy_est.copy()
            m.turn_to(heading)
            m.state = "leaving node"
            status = m.straight(0.2, heading)
            if status is None:
                found = travel(m, origin)
                if found is None:
                    returning = Left(junction, exits, steer, arrival, turn)
                    status = give_up(m, returning, origin)
                    if status is None:
                        expected = origin
                        continue  # re-centre at the junction and choose again
                elif isinstance(found, RunStatus):
                    status = found
                elif isinstance(found, Bend):
                    # Back to the bend's centre, facing the way the robot came in.
                    m.event("bend passed")
                    move = found.centre - m.xy_est
                    back = math.atan2(move[1], move[0])
                    m.turn_to(back)
                    m.state = "returning to bend"
                    status = m.straight(float(np.linalg.norm(move)), back)
                    m.turn_to(found.arrival_heading)
                    expected = found.centre
                    if status is None:
                        arrival = found.arrival_heading
                        continue
                else:
                    toward = np.array([math.cos(m.yaw_est), math.sin(m.yaw_est)])
                    expected = m.xy_est + found * toward
                    m.state = "approaching node"
                    status = m.straight(c.approach_fraction * found, m.yaw_est)
            if status is not None:
                m.result.status = status
                m.event(f"watchdog: {status.value}", warning=True)
                break
            arrival = m.yaw_est
        m.result.duration_ns = m.robot.t_ns
        if m.sink is not None:
            m.sink(TruePose(m.robot.t_ns, m.robot.pose))
        return m.result


def autonomous_run(
    world: World,
    camera: CameraSpec,
    seed: int,
    start: str | None = None,
    config: ExplorerConfig | None = None,
    sink: RecordSink | None = None,
    policy: ExitPolicy | None = None,
    motor_faults: tuple[MotorFault, ...] = (),
    recovery: RecoveryConfig | None = None,
    on_explorer: Callable[[Explorer], None] | None = None,
    robot_spec: RobotSpec | None = None,
) -> ExplorationResult:
    """Place the robot at the start node (default the entry) and explore, choosing
    exits by ``policy`` (default the right-most-branch rule).

    It starts as if it had just arrived from its first neighbour (in counter-clockwise
    order from the smallest heading), facing away from it: the convention of
    :func:`sim.plan.right_hand_tour`, so that the two tours can be compared.

    Ground truth labels each sweep with the node within 15 cm of the camera, the
    radius the paper's own data uses for "the same junction" (for scoring only);
    the explorer itself never sees it. ``robot_spec`` is the robot's build (default
    :class:`RobotSpec`'s; :meth:`RobotSpec.drifting` for poorer odometry).
    """
    network = world.network
    label = start if start is not None else network.entry
    node = network.node(label)
    heading = network.pipe_headings(label)[network.neighbours(label)[0]] + math.pi
    pose = PlanarPose(node.x_m, node.y_m, heading)
    robot = Robot(world, pose, np.random.default_rng(seed), robot_spec, motor_faults)

    def true_node(pose: PlanarPose) -> str:
        nearest = min(network.nodes, key=lambda n: math.hypot(n.x_m - pose.x_m, n.y_m - pose.y_m))
        off = math.hypot(nearest.x_m - pose.x_m, nearest.y_m - pose.y_m)
        return nearest.label if off < 0.15 else "?"

    tilts = np.random.default_rng([seed, TILT_STREAM])  # a level run draws nothing from it
    explorer = Explorer(
        robot,
        camera,
        config,
        true_node_of=true_node,
        sink=sink,
        policy=policy,
        recovery=recovery,
        tilt_rng=tilts,
    )
    if on_explorer is not None:
        on_explorer(explorer)
    return explorer.run()
