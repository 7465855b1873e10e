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

That allowance had to grow to about 14 other junctions a revisit late in a run of
long pipes. So the heading error itself is fitted to the loops the robot closes
(:class:`HeadingBias`, ``odometry_heading_bias``): each recognised revisit says the
dead reckoning between its two visits should add up to nothing; the heading error,
a broken line in the odometer, is fitted to all of them, and the check compares
positions with it taken out. Once the loops pin it down, the allowance is what the
fit leaves uncertain times the moment since the junction's last recognised visit
(:meth:`DeadReckoning.tolerance_for`).

This is the uncertainty of the robot's own dead reckoning, a function of the
positions and odometer readings it gave at its visits and of the localizer's own
decisions, never of the truth. The same
allowance sets the sigma of :meth:`DeadReckoning.log_likelihood` (the competing
maps' odometry weight) and the explorer's revisit check
(:class:`localizer.explore.MapExplorer`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipemap.localizer.config import LocalizerConfig

__all__ = ["DeadReckoning", "HeadingBias", "PathMark", "PathMoment", "drift_allowed", "scaled"]


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
    heading = ("odometry_heading_drift_per_m", "odometry_heading_residual_per_m")
    return dataclasses.replace(config, **scaled(config, factor, (*fields, *heading)))


def scaled(config: object, factor: float, fields: tuple[str, ...]) -> dict[str, Any]:
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


#: The heading's error is fitted as a broken line in the odometer with a knot every
#: this many metres (:class:`HeadingBias`).
KNOT_M = 100.0
#: How much the drift's rate may bend at a knot (rad, one sigma of the second
#: difference of the heading's error between three knots).
BEND_RAD = 0.01


class HeadingBias:
    """The heading's error along the path, fitted to the loops the robot closed.

    The dead reckoning's heading error grows with driving and turning at a rate that
    itself wanders slowly (the gyro's bias left over after each stop's estimate).
    It is modelled as a broken line ``h(s)`` in the odometer ``s``, zero at the start
    (where the heading is known), with a knot every :data:`KNOT_M` metres. Given
    ``h``, the path is corrected leg by leg: each leg from one visit to the next
    (taken as straight) is turned back by ``h`` at its middle, about the start. A
    recognised revisit says that the corrected path comes back to where it was at
    the junction's first visit (to within ``sigma_m``: the odometry check's capped
    tolerance, where in a chamber the robot stops plus a loop's drift); the knots are
    the least-squares fit of every such closure, with the bends of the line (second
    differences, sigma :data:`BEND_RAD`) as a prior, so the line runs on straight
    past the last closure. The fit uses only the robot's own dead reckoning and
    odometer at each visit and the localizer's decisions,
    never the truth.
    """

    def __init__(self, sigma_m: float) -> None:
        self.sigma_m = sigma_m
        #: Dead reckoning (x, y) and odometer at each visit that gave both, in order.
        self.points: list[tuple[float, float, float]] = []
        #: Closed loops: (point of the junction's first visit, point of the revisit).
        self.closures: list[tuple[int, int]] = []
        #: The heading's error at knots 1, 2, ... (rad; knot 0 is the start's, 0).
        self.knots = np.zeros(0)
        #: The sum of the squared moments of the closed loops (m⁴): how well they pin
        #: a steady drift down (:meth:`DeadReckoning.heading_drift_per_m`).
        self.information_m4 = 0.0
        self._corrected: np.ndarray | None = None

    def add(self, x_m: float, y_m: float, odometer_m: float) -> int:
        """A visit at (``x_m``, ``y_m``) after ``odometer_m``; returns its point."""
        self.points.append((x_m, y_m, odometer_m))
        self._corrected = None
        return len(self.points) - 1

    def corrected(self, point: int) -> tuple[float, float]:
        """The dead reckoning at ``point`` with the fitted heading error taken out."""
        if self._corrected is None:
            self._corrected = self._path(self.knots)[0]
        x, y = self._corrected[point]
        return float(x), float(y)

    def heading_rad(self, odometer_m: float) -> float:
        """The fitted heading error after ``odometer_m`` driven."""
        return float(self._weights(np.array([odometer_m]), len(self.knots) + 1)[0] @ self.knots)

    def close(self, first: int, now: int, moment_m2: float, iterations: int = 3) -> None:
        """The visit at point ``now`` is the junction first visited at ``first``
        (``moment_m2``: the path's moment between them): refit the heading's error
        to every loop closed so far."""
        if now <= first:
            return
        self.closures.append((first, now))
        self.information_m4 += moment_m2 * moment_m2
        p = np.asarray(self.points, dtype=np.float64)
        count = int(p[-1, 2] // KNOT_M) + 2  # knots 0 .. past the last point
        # New knots start on the line run on straight past the last.
        at = KNOT_M * np.arange(1, count)
        knots: np.ndarray = (
            self._weights(at, len(self.knots) + 1) @ self.knots if len(self.knots) else 0.0 * at
        )
        bends = np.zeros((max(count - 2, 0), count))
        for i in range(count - 2):
            bends[i, i : i + 3] = (1.0, -2.0, 1.0)
        bends = bends[:, 1:] / BEND_RAD
        pairs = np.asarray(self.closures)
        first_i, now_i = pairs[:, 0], pairs[:, 1]
        for _ in range(iterations):
            path, turned, weights = self._path(knots, count)
            # A leg turned by -h(mid) moves by -(its weight) times the leg turned a
            # further quarter for each knot's change.
            quarter = np.stack((-turned[:, 1], turned[:, 0]), 1)
            slopes = [
                np.vstack((np.zeros(count - 1), np.cumsum(-weights * quarter[:, [c]], 0)))
                for c in (0, 1)
            ]
            residual = np.concatenate([path[now_i, c] - path[first_i, c] for c in (0, 1)])
            jacobian = np.vstack([slopes[c][now_i] - slopes[c][first_i] for c in (0, 1)])
            residual /= self.sigma_m
            jacobian /= self.sigma_m
            normal = jacobian.T @ jacobian + bends.T @ bends + 1e-12 * np.eye(count - 1)
            gradient = jacobian.T @ residual + bends.T @ (bends @ knots)
            knots = knots - np.linalg.solve(normal, gradient)
        self.knots = knots
        self._corrected = None

    @staticmethod
    def _weights(odometer_m: np.ndarray, count: int) -> np.ndarray:
        """Each odometer's weights on knots 1 .. ``count - 1`` (a broken line through
        the knots, run on straight past the last)."""
        u = odometer_m / KNOT_M
        left = np.minimum(np.floor(u).astype(int), max(count - 2, 0))
        frac = u - left
        weights = np.zeros((len(u), count))
        rows = np.arange(len(u))
        weights[rows, left] = 1.0 - frac
        if count > 1:
            weights[rows, np.minimum(left + 1, count - 1)] += frac
        return weights[:, 1:]

    def _path(
        self, knots: np.ndarray, count: int | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The path's points corrected by ``knots``, its legs turned, and the legs'
        weights on the knots."""
        count = len(knots) + 1 if count is None else count
        p = np.asarray(self.points, dtype=np.float64).reshape(-1, 3)
        legs = p[1:, :2] - p[:-1, :2]
        weights = self._weights(0.5 * (p[1:, 2] + p[:-1, 2]), count)
        angle = -(weights @ knots) if len(knots) else np.zeros(len(legs))
        cos, sin = np.cos(angle), np.sin(angle)
        turned = np.stack(
            (cos * legs[:, 0] - sin * legs[:, 1], sin * legs[:, 0] + cos * legs[:, 1]), 1
        )
        path = np.zeros((len(p), 2))
        if len(p):
            path[0] = p[0, :2]
            path[1:] = path[0] + np.cumsum(turned, 0)
        return path, turned, weights


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
        #: The heading's drift estimated from closed loops, and the point on its path
        #: of each junction's first visit and of the current visit (``None``: not given).
        self.bias = HeadingBias(config.odometry_limit_m)
        self.points: dict[int, int] = {}
        #: The path at each junction's last recognised visit (the fit closes there).
        self.anchors: dict[int, PathMark] = {}
        self.point: int | None = None
        self.here: tuple[float, float] | None = None
        self.odometer_m: float | None = None
        self.tolerance_m = 0.0
        #: The check of the last recognised visit as it was made, before the loop it
        #: closed refitted the drift: (its point, junction, offset, tolerance).
        self._closing: tuple[int, int, float | None, float] | None = None

    def at(self, position_m: tuple[float, float] | None, odometer_m: float | None) -> None:
        """The current visit is at ``position_m`` after ``odometer_m`` driven (either
        ``None``: not given). The tolerance is ``odometry_radius_m`` plus
        ``odometry_drift_per_m`` of the distance driven, at most ``odometry_limit_m``."""
        self.here = None if position_m is None else (float(position_m[0]), float(position_m[1]))
        self.odometer_m = None if odometer_m is None else float(odometer_m)
        self.path.add(position_m, odometer_m)
        self.point = None
        if self.here is not None and self.odometer_m is not None:
            self.point = self.bias.add(self.here[0], self.here[1], self.odometer_m)
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
        if self.point is not None:
            self.points[node] = self.point

    def closed(self, node: int) -> None:
        """The current visit is known junction ``node``'s: a loop closed, from which
        (with ``odometry_heading_bias``) the heading's drift is fitted again."""
        first = self.points.get(node)
        if not self.config.odometry_heading_bias or first is None or self.point is None:
            return
        if self.bias.closures and self.bias.closures[-1][1] == self.point:
            return
        mark = self.marks.get(node)
        moment = 0.0 if mark is None else self.path.since(mark)
        self._closing = (self.point, node, self.offset_m(node), self.tolerance_for(node))
        self.bias.close(first, self.point, moment)
        if self.path.mark is not None:
            self.anchors[node] = self.path.mark

    def closing_check(self, node: int) -> tuple[float, float] | None:
        """The offset and tolerance known junction ``node`` was checked with at the
        current visit, before the loop it closed (:meth:`closed`) was fitted: the
        localizer's check as it decided. ``None`` when the current visit closed no
        fitted loop at ``node`` or either position is unknown."""
        closing = self._closing
        if closing is None or closing[:2] != (self.point, node) or closing[2] is None:
            return None
        return closing[2], closing[3]

    def heading_drift_per_m(self) -> float:
        """The heading drift the check allows for: ``odometry_heading_drift_per_m``
        until the closed loops pin the drift down, then what the fit leaves
        uncertain: ``odometry_heading_residual_per_m`` plus ``odometry_limit_m`` over
        the square root of the fit's information, never more than the first."""
        c = self.config
        prior = c.odometry_heading_drift_per_m
        information = self.bias.information_m4
        if not c.odometry_heading_bias or information <= 0.0:
            return prior
        return min(
            prior, c.odometry_heading_residual_per_m + c.odometry_limit_m / math.sqrt(information)
        )

    def fitted(self) -> bool:
        """Whether the closed loops pin the heading's drift down: the fit's allowance
        (:meth:`heading_drift_per_m`) is below ``odometry_heading_drift_per_m``."""
        return self.heading_drift_per_m() < self.config.odometry_heading_drift_per_m

    def offset_m(self, node: int) -> float | None:
        """How far known junction ``node``'s first visit is from the current visit by
        dead reckoning (once the closed loops pin the heading's drift down,
        :meth:`fitted`, both with the fitted drift taken out; until then as given, so
        short runs decide as without the fit); ``None`` when either position is
        unknown."""
        there = self.positions.get(node)
        if self.here is None or there is None:
            return None
        first = self.points.get(node)
        if self.fitted() and first is not None and self.point is not None:
            return math.dist(self.bias.corrected(self.point), self.bias.corrected(first))
        return math.dist(self.here, there)

    def tolerance_for(self, node: int) -> float:
        """How far known junction ``node`` may lie from the current visit's dead
        reckoning: the largest of :attr:`tolerance_m`, ``odometry_loop_drift_per_m``
        of the distance driven since the junction's first visit, and
        ``odometry_radius_m`` plus ``odometry_heading_drift_per_m`` times the path's
        moment since then (:class:`PathMoment`).

        Once the loops closed so far pin the heading's drift down
        (:meth:`heading_drift_per_m` below ``odometry_heading_drift_per_m``), the
        positions compared have that drift taken out (:meth:`offset_m`): what is
        left is the fit's uncertainty, so the allowance is ``odometry_radius_m`` plus
        :meth:`heading_drift_per_m` times the moment since the junction's last
        recognised visit (where the fit made the path close), and the loop
        allowance, which stood for the same drift, no longer applies."""
        c = self.config
        tolerance = self.tolerance_m
        if self.here is None or self.odometer_m is None:
            return tolerance
        rate = self.heading_drift_per_m()
        if self.fitted():
            anchor = self.anchors.get(node, self.marks.get(node))
            if anchor is not None:
                tolerance = max(tolerance, c.odometry_radius_m + rate * self.path.since(anchor))
            return tolerance
        then = self.odometers.get(node)
        if then is not None:
            tolerance = max(tolerance, c.odometry_loop_drift_per_m * (self.odometer_m - then))
        mark = self.marks.get(node)
        if mark is not None:
            tolerance = max(tolerance, c.odometry_radius_m + rate * self.path.since(mark))
        return tolerance

    def near(self, node: int) -> bool:
        """Whether the robot may be at known junction ``node`` by its dead reckoning
        (it may when either position is unknown or the check is off)."""
        off = self.offset_m(node)
        if not self.config.odometry_check or off is None:
            return True
        return off <= self.tolerance_for(node)

    def log_likelihood(self, node: int) -> float:
        """The log-likelihood of the robot's being at known junction ``node``: a
        Gaussian in the distance between the two positions, sigma half the junction's
        tolerance (:meth:`tolerance_for`; 0 when either position is unknown)."""
        off = self.offset_m(node)
        if off is None:
            return 0.0
        tolerance = self.tolerance_for(node)
        if tolerance <= 0.0:
            return 0.0
        return -0.5 * (off / (0.5 * tolerance)) ** 2
