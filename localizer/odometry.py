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
"""

from __future__ import annotations

import dataclasses
import math

from pipemap.localizer.config import LocalizerConfig

__all__ = ["DeadReckoning", "drift_allowed"]


def drift_allowed(config: LocalizerConfig, factor: float) -> LocalizerConfig:
    """``config`` for a robot whose odometry drifts ``factor`` times as much as the
    simulator's default robot: the drift per metre and the limit of the odometry
    check (and so the sigma of its likelihood) and its allowance over a loop
    ``factor`` times as wide. The radius stays: it is where in a chamber the robot
    stops, not its odometry's drift."""
    if factor == 1.0:
        return config
    return dataclasses.replace(
        config,
        odometry_drift_per_m=config.odometry_drift_per_m * factor,
        odometry_limit_m=config.odometry_limit_m * factor,
        odometry_loop_drift_per_m=config.odometry_loop_drift_per_m * factor,
    )


class DeadReckoning:
    """Each junction's position at its first visit, and the current visit's."""

    def __init__(self, config: LocalizerConfig) -> None:
        self.config = config
        #: Dead reckoning at each junction's first visit (``None``: not given).
        self.positions: dict[int, tuple[float, float] | None] = {}
        #: The odometer at each junction's first visit (``None``: not given).
        self.odometers: dict[int, float | None] = {}
        self.here: tuple[float, float] | None = None
        self.odometer_m: float | None = None
        self.tolerance_m = 0.0

    def at(self, position_m: tuple[float, float] | None, odometer_m: float | None) -> None:
        """The current visit is at ``position_m`` after ``odometer_m`` driven (either
        ``None``: not given). The tolerance is ``odometry_radius_m`` plus
        ``odometry_drift_per_m`` of the distance driven, at most ``odometry_limit_m``."""
        self.here = None if position_m is None else (float(position_m[0]), float(position_m[1]))
        self.odometer_m = None if odometer_m is None else float(odometer_m)
        c = self.config
        driven = 0.0 if odometer_m is None else odometer_m
        self.tolerance_m = min(
            c.odometry_radius_m + c.odometry_drift_per_m * driven, c.odometry_limit_m
        )

    def remember(self, node: int) -> None:
        """The current visit is new junction ``node``'s first."""
        self.positions[node] = self.here
        self.odometers[node] = self.odometer_m

    def tolerance_for(self, node: int) -> float:
        """How far known junction ``node`` may lie from the current visit's dead
        reckoning: :attr:`tolerance_m`, or ``odometry_loop_drift_per_m`` of the
        distance driven since the junction's first visit when that is more."""
        then = self.odometers.get(node)
        if then is None or self.odometer_m is None:
            return self.tolerance_m
        loop_m = self.config.odometry_loop_drift_per_m * (self.odometer_m - then)
        return max(self.tolerance_m, loop_m)

    def near(self, node: int) -> bool:
        """Whether the robot may be at known junction ``node`` by its dead reckoning
        (it may when either position is unknown or the check is off)."""
        there = self.positions.get(node)
        if not self.config.odometry_check or self.here is None or there is None:
            return True
        return math.dist(self.here, there) <= self.tolerance_for(node)

    def log_likelihood(self, node: int) -> float:
        """The log-likelihood of the robot's being at known junction ``node``: a
        Gaussian in the distance between the two positions, sigma half the
        tolerance (0 when either position is unknown)."""
        there = self.positions.get(node)
        if self.here is None or there is None or self.tolerance_m <= 0.0:
            return 0.0
        return -0.5 * (math.dist(self.here, there) / (0.5 * self.tolerance_m)) ** 2
