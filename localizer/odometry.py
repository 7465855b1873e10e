"""Dead reckoning as evidence of which known junction a visit is.

The robot's position by its own odometry (in the start's frame) drifts with the
distance driven, but not by metres: a known junction far from where the robot is
cannot be the visit's (:meth:`DeadReckoning.near`, ``LocalizerConfig.odometry_check``),
and among junctions that look alike, the nearer one is the likelier
(:meth:`DeadReckoning.log_likelihood`, :mod:`localizer.hypotheses`).

The tolerance stops growing at ``odometry_limit_m``, below the least distance
between two junctions, so look-alikes stay apart. A loop that closes on a junction
first seen hundreds of metres of driving ago can carry more drift than that: on
``random:200`` seed 4711 at 96 px the robot came back to a junction it had left
252 m of driving before 0.61 m from where its dead reckoning had put it, and the
limit made the revisit a false new junction. So a junction may also lie
``odometry_loop_drift_per_m`` of the distance driven since its first visit away
(:meth:`DeadReckoning.tolerance_for`); that allowance passes the limit only after
150 m of driving at the default.

Neither allowance follows what dead reckoning does over long straight pipes: the
robot's heading error grows with the distance it drives (the gyro's bias is measured
while it stands still, never exactly), and a heading error ``dθ`` met at a point of
the path swings all the path after it about that point. With the error growing at
``β`` radians a metre since a junction's first visit (odometer ``s_a``), the robot's
position is off by ``β`` times the path's moment ``|∫ (s - s_a) dp|`` over the path
``p(s)`` driven since (:class:`PathMoment`, from the dead reckoning at each visit,
each leg a straight line). The moment grows as the square of the distance driven
over a long loop, and it knows the shape of the path: a loop of long straight pipes
has a large one, a walk to and fro in a short pipe a small one. On ``random:200``
seed 4711 with pipes of 1-20 m every revisit's error was 3.7e-4 to 3.8e-4 of its
moment (up to 9.5 m after 779 m of driving, where the limits above allowed 3.1 m),
so a junction may also lie ``odometry_radius_m`` plus
``odometry_heading_drift_per_m`` (6e-4) times the moment away. It widens the
check only where the moment is large: every tolerance above still holds.

This is the uncertainty of the robot's own dead reckoning, a function of the
positions and odometer readings it gave at its visits, never of the truth. The same
allowance sets the sigma of :meth:`DeadReckoning.log_likelihood` (the competing
maps' odometry weight) and the explorer's revisit check
(:class:`localizer.explore.MapExplorer`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from pipemap.localizer.config import LocalizerConfig

__all__ = ["DeadReckoning", "PathMark", "PathMoment", "drift_allowed", "scaled"]


def drift_allowed(config: LocalizerConfig, factor: float) -> LocalizerConfig:
    """``config`` for a robot whose odometry drifts ``factor`` times as much as the
    simulator's default robot: the drift per metre and the limit of the odometry
    check (and so the sigma of its likelihood) and its allowances over a loop and
    for the heading's drift ``factor`` times as wide (the robot's gyro noise and bias
    are ``factor`` times as large, :meth:`sim.robot.RobotSpec.drifting`). The radius
    stays: it is where in a chamber the robot stops, not its odometry's drift."""
    if factor == 1.0:
        return config
    fields = ("odometry_drift_per_m", "odometry_limit_m", "odometry_loop_drift_per_m")
    return dataclasses.replace(
        config, **scaled(config, factor, (*fields, "odometry_heading_drift_per_m"))
    )


def scaled(config: object, factor: float, fields: tuple[str, ...]) -> dict[str, float]:
    """Each of ``config``'s ``fields`` ``factor`` times as large, by name (for
    :func:`dataclasses.replace`)."""
    return {f: float(getattr(config, f)) * factor for f in fields}


@dataclass(frozen=True)
class PathMark:
    """The path at one visit: the dead reckoning and the odometer there, and the sum
    over the legs before it of each leg's mid-odometer times its displacement."""

    odometer_m: float
    x_m: float
    y_m: float
    moment_x_m2: float
    moment_y_m2: float


class PathMoment:
    """The path the robot drove, from its dead reckoning at each visit (each leg from
    one visit to the next taken as straight), as prefix sums: the moment
    ``|∫ (s - s_a) dp|`` since any earlier visit ``a`` costs O(1)
    (:meth:`since`). A heading error growing by ``β`` a metre puts the robot ``β``
    times that moment off where its dead reckoning says."""

    def __init__(self) -> None:
        #: The last visit with a position and an odometer (``None``: none yet).
        self.mark: PathMark | None = None

    def add(self, position_m: tuple[float, float] | None, odometer_m: float | None) -> None:
        """The robot is at ``position_m`` after ``odometer_m`` driven (either ``None``:
        not given; the next leg then runs from the last visit that gave both)."""
        if position_m is None or odometer_m is None:
            return
        x, y, s = float(position_m[0]), float(position_m[1]), float(odometer_m)
        last = self.mark
        if last is None:
            self.mark = PathMark(s, x, y, 0.0, 0.0)
            return
        mid = 0.5 * (last.odometer_m + s)
        self.mark = PathMark(
            s,
            x,
            y,
            last.moment_x_m2 + mid * (x - last.x_m),
            last.moment_y_m2 + mid * (y - last.y_m),
        )

    def since(self, then: PathMark) -> float:
        """The moment (m²) of the path from ``then`` to the last visit:
        ``|sum over legs of (mid-odometer - then's odometer) * displacement|``."""
        now = self.mark
        if now is None:
            return 0.0
        mx = now.moment_x_m2 - then.moment_x_m2 - then.odometer_m * (now.x_m - then.x_m)
        my = now.moment_y_m2 - then.moment_y_m2 - then.odometer_m * (now.y_m - then.y_m)
        return math.hypot(mx, my)


class DeadReckoning:
    """Each junction's position at its first visit, and the current visit's."""

    def __init__(self, config: LocalizerConfig) -> None:
        self.config = config
        #: Dead reckoning at each junction's first visit (``None``: not given).
        self.positions: dict[int, tuple[float, float] | None] = {}
        #: The odometer at each junction's first visit (``None``: not given).
        self.odometers: dict[int, float | None] = {}
        #: The path at each junction's first visit (absent: position not given).
        self.marks: dict[int, PathMark] = {}
        self.path = PathMoment()
        self.here: tuple[float, float] | None = None
        self.odometer_m: float | None = None
        self.tolerance_m = 0.0

    def at(self, position_m: tuple[float, float] | None, odometer_m: float | None) -> None:
        """The current visit is at ``position_m`` after ``odometer_m`` driven (either
        ``None``: not given). The tolerance is ``odometry_radius_m`` plus
        ``odometry_drift_per_m`` of the distance driven, at most ``odometry_limit_m``."""
        self.here = None if position_m is None else (float(position_m[0]), float(position_m[1]))
        self.odometer_m = None if odometer_m is None else float(odometer_m)
        self.path.add(position_m, odometer_m)
        c = self.config
        driven = 0.0 if odometer_m is None else odometer_m
        self.tolerance_m = min(
            c.odometry_radius_m + c.odometry_drift_per_m * driven, c.odometry_limit_m
        )

    def remember(self, node: int) -> None:
        """The current visit is new junction ``node``'s first."""
        self.positions[node] = self.here
        self.odometers[node] = self.odometer_m
        if self.here is not None and self.odometer_m is not None and self.path.mark is not None:
            self.marks[node] = self.path.mark

    def tolerance_for(self, node: int) -> float:
        """How far known junction ``node`` may lie from the current visit's dead
        reckoning: the largest of :attr:`tolerance_m`, ``odometry_loop_drift_per_m``
        of the distance driven since the junction's first visit, and
        ``odometry_radius_m`` plus ``odometry_heading_drift_per_m`` times the path's
        moment since then (:class:`PathMoment`)."""
        c = self.config
        tolerance = self.tolerance_m
        then = self.odometers.get(node)
        if then is not None and self.odometer_m is not None:
            tolerance = max(tolerance, c.odometry_loop_drift_per_m * (self.odometer_m - then))
        mark = self.marks.get(node)
        if mark is not None and self.here is not None and self.odometer_m is not None:
            heading_m = c.odometry_radius_m + c.odometry_heading_drift_per_m * self.path.since(mark)
            tolerance = max(tolerance, heading_m)
        return tolerance

    def near(self, node: int) -> bool:
        """Whether the robot may be at known junction ``node`` by its dead reckoning
        (it may when either position is unknown or the check is off)."""
        there = self.positions.get(node)
        if not self.config.odometry_check or self.here is None or there is None:
            return True
        return math.dist(self.here, there) <= self.tolerance_for(node)

    def log_likelihood(self, node: int) -> float:
        """The log-likelihood of the robot's being at known junction ``node``: a
        Gaussian in the distance between the two positions, sigma half the junction's
        tolerance (:meth:`tolerance_for`; 0 when either position is unknown)."""
        there = self.positions.get(node)
        if self.here is None or there is None:
            return 0.0
        tolerance = self.tolerance_for(node)
        if tolerance <= 0.0:
            return 0.0
        return -0.5 * (math.dist(self.here, there) / (0.5 * tolerance)) ** 2
