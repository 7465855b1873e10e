"""Motor cut-outs: the drive stops for a few seconds with nothing in its way.

A small pipe robot's motor driver cuts the current when a motor draws too much (a
gearbox binding on grit, a wheel wrapped in fibres, a motor running hot) and gives it
back after a moment. To the robot that is a stall with nothing in front: the wheels
are commanded and do not turn, their encoders stand still, backwards as well as
forwards, and after a few seconds the motors turn again. Mistaken for a deposit, it
costs the robot a pipe it could have driven (:mod:`sim.recovery` tells them apart).

:func:`draw_motor_faults` draws, from its own stream of the run's seed, where each
cut-out happens (after how many metres of driving, either way, so that it happens
while the robot drives) and how long it lasts. The same network, count and seed give
the same cut-outs; with none nothing else in the run changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipemap.errors import SimError
from pipemap.sim.network import Network

__all__ = ["MOTOR_FAULT_S", "MotorFault", "draw_motor_faults"]

#: The seed stream of motor cut-outs (with the run's seed).
_MOTOR_STREAM = 23
#: How long a cut-out lasts, seconds (uniform): a motor driver's restart after an
#: over-current trip, up to a short cool-down.
MOTOR_FAULT_S = (1.0, 4.0)
#: No cut-out in the first metres of driving: the robot is still leaving its start.
_FIRST_M = 0.3


@dataclass(frozen=True)
class MotorFault:
    """The motors cut out once the robot has driven ``at_m`` metres (either way, in
    all), for ``duration_ns``."""

    at_m: float
    duration_ns: int

    def __post_init__(self) -> None:
        if not self.at_m >= 0.0 or self.duration_ns <= 0:
            raise SimError(f"a motor cut-out needs at_m >= 0 and a duration > 0: {self}")


def draw_motor_faults(network: Network, count: int, seed: int) -> tuple[MotorFault, ...]:
    """``count`` cut-outs spread over the first pass of the network's pipes (their total
    length: every exploration drives at least that), in the order they happen."""
    if count < 0:
        raise SimError(f"motor cut-outs: count must be >= 0, got {count}")
    if count == 0:
        return ()
    total_m = sum(network.length_m(p.a, p.b) for p in network.pipes)
    rng = np.random.default_rng([seed, _MOTOR_STREAM])
    at = np.sort(rng.uniform(_FIRST_M, max(total_m, 2 * _FIRST_M), count))
    seconds = rng.uniform(*MOTOR_FAULT_S, count)
    return tuple(
        MotorFault(float(a), int(round(s * 1e9))) for a, s in zip(at, seconds, strict=True)
    )
