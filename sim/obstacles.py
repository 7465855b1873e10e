"""Deposits on the pipe floor that can stop the robot, seeded from the run's seed.

Sewer pipes collect sediment, grease and debris on their floor (the invert). Two
kinds are simulated, both a box on the floor a few centimetres high, lower than the
rangers (5 cm above the floor), so the robot cannot see them coming by range; the
camera sees them, and the robot finds them by running into them (a stall):

* **passable**: a deposit on one side of the floor, from the wall to
  :data:`PASSABLE_EDGE_M` short of the pipe's axis. The robot driving on the axis
  runs into it; driving a few centimetres off the axis on the other side, it passes.
* **blocking**: a deposit across the whole floor. Nothing passes; the robot must
  give the pipe up.

Placement: :func:`place_obstacles` draws, from its own stream of the run's seed, the
pipes (only pipes at least :data:`MIN_PIPE_M` long, at most one deposit each), where
along each pipe (the middle fifth, far from both junctions), the kind and the side.
The same network, count and seed give the same deposits; with no deposits nothing
else in the run changes (the robot's and the world's draws have their own streams).

The robot is kinematic (:mod:`sim.robot`): a move that would put its footprint into
a deposit's does not happen and its wheels stall, as a small geared robot's do.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from pipemap.errors import SimError
from pipemap.sim.network import Network

__all__ = [
    "DEPOSIT_HEIGHT_M",
    "MIN_PIPE_M",
    "Obstacle",
    "ObstacleKind",
    "footprint_hits",
    "place_obstacles",
]

#: The seed stream of obstacle placement (with the run's seed).
_OBSTACLE_STREAM = 21
#: Only pipes this long get a deposit: it then lies at least 0.38 m from either
#: junction centre, beyond where the robot leaves a junction or approaches one.
MIN_PIPE_M = 0.9
#: Deposits lie between these fractions of their pipe's length.
_ALONG = (0.42, 0.58)
#: Height of a deposit: below the rangers (5 cm), above what the wheels (28 mm) climb.
DEPOSIT_HEIGHT_M = 0.04
#: Length of a deposit along its pipe.
DEPOSIT_LENGTH_M = 0.08
#: A passable deposit ends this far from the axis, on its own side: a robot 7 cm wide
#: passes with its centre 1.5 cm or more off the axis on the other side.
PASSABLE_EDGE_M = 0.02


class ObstacleKind(enum.Enum):
    """Whether the robot can get past a deposit."""

    PASSABLE = "passable"
    BLOCKING = "blocking"


@dataclass(frozen=True)
class Obstacle:
    """A deposit on the floor of the pipe from node ``a`` to node ``b``.

    ``along_m`` is the distance from ``a``'s centre to the deposit's middle;
    ``left_m``/``right_m`` bound it across the pipe (metres to the left of the axis
    looking from ``a`` to ``b``; ``right_m < left_m``). ``centre_xy_m`` and
    ``heading_rad`` place it in the world.
    """

    a: str
    b: str
    kind: ObstacleKind
    along_m: float
    right_m: float
    left_m: float
    centre_xy_m: tuple[float, float]
    heading_rad: float
    length_m: float = DEPOSIT_LENGTH_M
    height_m: float = DEPOSIT_HEIGHT_M

    @property
    def pipe(self) -> tuple[str, str]:
        """The pipe it lies in, as a sorted pair of node labels."""
        return (min(self.a, self.b), max(self.a, self.b))

    @property
    def width_m(self) -> float:
        """Its extent across the pipe."""
        return self.left_m - self.right_m

    def corners(self) -> np.ndarray:
        """Its footprint on the floor: four corners (4, 2), counter-clockwise."""
        return _rectangle(
            self.centre_xy_m[0], self.centre_xy_m[1], self.heading_rad, self.length_m, self.width_m
        )


def _rectangle(x: float, y: float, yaw: float, length: float, width: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    forward, left = np.array([c, s]) * length / 2.0, np.array([-s, c]) * width / 2.0
    centre = np.array([x, y])
    return np.array(
        [centre + forward + left, centre - forward + left, centre - forward - left,
         centre + forward - left]
    )  # fmt: skip


def _overlap(p: np.ndarray, q: np.ndarray) -> bool:
    """Whether two convex polygons (corners in order) overlap: no separating axis."""
    for poly in (p, q):
        edges = np.roll(poly, -1, axis=0) - poly
        for nx, ny in edges:
            axis = np.array([-ny, nx])
            a, b = p @ axis, q @ axis
            if a.max() <= b.min() or b.max() <= a.min():
                return False
    return True


def footprint_hits(
    x_m: float, y_m: float, yaw_rad: float, length_m: float, width_m: float,
    obstacles: tuple[Obstacle, ...],
) -> bool:  # fmt: skip
    """Whether a robot footprint (a rectangle centred at ``x_m``, ``y_m``) overlaps a
    deposit's."""
    if not obstacles:
        return False
    robot = _rectangle(x_m, y_m, yaw_rad, length_m, width_m)
    reach = math.hypot(length_m, width_m) / 2.0
    for o in obstacles:
        near = reach + math.hypot(o.length_m, o.width_m) / 2.0
        if math.hypot(o.centre_xy_m[0] - x_m, o.centre_xy_m[1] - y_m) > near:
            continue
        if _overlap(robot, o.corners()):
            return True
    return False


def place_obstacles(
    network: Network, count: int, seed: int, blocking_share: float = 0.5
) -> tuple[Obstacle, ...]:
    """``count`` deposits in distinct pipes of ``network``, drawn from ``seed``.

    Each is blocking with probability ``blocking_share``, else passable (on a side
    drawn at random). Raises :class:`~pipemap.errors.SimError` when ``count`` is
    negative or the network has fewer than ``count`` pipes long enough.
    """
    if count < 0:
        raise SimError(f"obstacle count must be >= 0, got {count}")
    if not 0.0 <= blocking_share <= 1.0:
        raise SimError(f"blocking share must be in [0, 1], got {blocking_share}")
    if count == 0:
        return ()
    long_pipes = [p for p in network.pipes if network.length_m(p.a, p.b) >= MIN_PIPE_M]
    if count > len(long_pipes):
        raise SimError(
            f"{count} obstacles: the network has only {len(long_pipes)} pipes of at least "
            f"{MIN_PIPE_M} m to put them in"
        )
    rng = np.random.default_rng([seed, _OBSTACLE_STREAM])
    chosen = sorted(int(i) for i in rng.choice(len(long_pipes), size=count, replace=False))
    radius = network.diameter_m / 2.0
    out = []
    for i in chosen:
        pipe = long_pipes[i]
        a, b = network.node(pipe.a), network.node(pipe.b)
        length = network.length_m(pipe.a, pipe.b)
        along = length * float(rng.uniform(*_ALONG))
        blocking = bool(rng.random() < blocking_share)
        side = 1.0 if rng.random() < 0.5 else -1.0
        if blocking:
            right, left = -radius, radius
        elif side > 0:
            right, left = PASSABLE_EDGE_M, radius
        else:
            right, left = -radius, -PASSABLE_EDGE_M
        heading = math.atan2(b.y_m - a.y_m, b.x_m - a.x_m)
        middle = (left + right) / 2.0
        x = a.x_m + along * math.cos(heading) - middle * math.sin(heading)
        y = a.y_m + along * math.sin(heading) + middle * math.cos(heading)
        kind = ObstacleKind.BLOCKING if blocking else ObstacleKind.PASSABLE
        out.append(Obstacle(pipe.a, pipe.b, kind, along, right, left, (x, y), heading))
    return tuple(out)
