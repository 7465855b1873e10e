"""Ports: the pipes of a junction, numbered, and a revisit's exits mapped onto them.

At each junction the robot's range scan gives its pipes as headings relative to the
robot ("exits"). A map node keeps them as its *ports*, in the frame of the node's
first visit (relative to the robot's heading then): numbered clockwise seen from
above, port 0 the pipe behind the robot (the one it came in by), then its left,
ahead, its right. Clockwise is the camera's sweep direction.

On a revisit the localizer measures the rotation from the robot's heading now to
its heading at the first visit (``rotation``): a pipe at ``a`` now lies at
``a - rotation`` in the first visit's frame. The revisit's exits, turned so, must
line up one to one with the node's ports. Junction pipes are at least 60 degrees
apart, so two ports are never within :data:`PORT_TOLERANCE_RAD` of one exit and
the assignment, if there is one, is unique.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = [
    "PORT_TOLERANCE_RAD",
    "PortMatch",
    "clockwise_ports",
    "match_ports",
    "nearest_exit",
    "port_assignments",
    "port_rotations",
]

#: A revisit's exit and the port it maps to may differ by this much. Measured at
#: 96 px (``benchmarks/bench_explore.py``, see the README): the exit scan misses the
#: true pipe by up to 0.22 rad (at crosses, from a robot a few cm off the centre),
#: so a revisit's exits, turned by the localizer's rotation, miss the first visit's
#: by up to twice that in the worst case; measured, by at most 0.23 rad. Junction
#: pipes are at least 60 degrees (1.05 rad) apart, so below half that (0.52 rad)
#: an exit still names one port at most. 0.40 rad (23 degrees) keeps a margin of
#: 1.7 over the measured misfit and 0.12 rad below the ambiguity.
PORT_TOLERANCE_RAD = 0.40
#: Port 0 starts this far counter-clockwise of straight behind, so that the pipe the
#: robot came in by (behind it, give or take the scan's error) is always port 0.
_ORDER_START_RAD = math.pi + math.pi / 6.0
_TWO_PI = 2.0 * math.pi


def _wrap(angle_rad: float) -> float:
    """``angle_rad`` in (-pi, pi]."""
    wrapped = math.remainder(angle_rad, _TWO_PI)
    return wrapped + _TWO_PI if wrapped <= -math.pi else wrapped


def _clockwise_key(angle_rad: float) -> float:
    return (_ORDER_START_RAD - angle_rad) % _TWO_PI


def clockwise_ports(exits_rad: Sequence[float]) -> tuple[tuple[float, ...], tuple[int, ...]]:
    """A new node's ports from its first visit's exits: the angles (wrapped into
    (-pi, pi]) in port order, and the port of each exit, in the exits' order."""
    order = sorted(range(len(exits_rad)), key=lambda i: (_clockwise_key(exits_rad[i]), i))
    port_of = [0] * len(exits_rad)
    for port, i in enumerate(order):
        port_of[i] = port
    return tuple(_wrap(exits_rad[i]) for i in order), tuple(port_of)


@dataclass(frozen=True)
class PortMatch:
    """How a visit's exits map onto a node's ports.

    ``exit_ports`` is the port of each exit (in the exits' order) when they agree,
    else ``None``; ``residual_rad`` the largest angle between an exit (turned into
    the node's frame) and its port; ``reason`` says why they do not agree.
    """

    exit_ports: tuple[int, ...] | None
    residual_rad: float | None
    reason: str = ""

    @property
    def agrees(self) -> bool:
        """The exits line up with the ports."""
        return self.exit_ports is not None


def match_ports(
    ports_rad: Sequence[float],
    exits_rad: Sequence[float],
    rotation_rad: float,
    tolerance_rad: float = PORT_TOLERANCE_RAD,
) -> PortMatch:
    """Map ``exits_rad`` (this visit's frame) onto ``ports_rad`` (the node's frame),
    given the ``rotation_rad`` from this visit's heading to the first visit's.

    They agree when there are as many exits as ports and, turned into the node's
    frame, each exit is within ``tolerance_rad`` of its own port (the assignment
    keeps the clockwise order, so it is one of the cyclic shifts).
    """
    n = len(ports_rad)
    if len(exits_rad) != n:
        return PortMatch(None, None, f"{len(exits_rad)} exits where the junction has {n} ports")
    if n == 0:
        return PortMatch((), 0.0)
    turned = [_wrap(e - rotation_rad) for e in exits_rad]
    order = sorted(range(n), key=lambda i: (_clockwise_key(turned[i]), i))
    best_shift, best_error = 0, math.inf
    for shift in range(n):
        error = max(abs(_wrap(turned[order[(k + shift) % n]] - ports_rad[k])) for k in range(n))
        if error < best_error:
            best_shift, best_error = shift, error
    if best_error > tolerance_rad:
        return PortMatch(
            None,
            best_error,
            f"exits are {best_error:.2f} rad off the junction's ports (at most "
            f"{tolerance_rad:.2f})",
        )
    port_of = [0] * n
    for k in range(n):
        port_of[order[(k + best_shift) % n]] = k
    return PortMatch(tuple(port_of), best_error)


def port_rotations(
    ports_rad: Sequence[float],
    exits_rad: Sequence[float],
    tolerance_rad: float = PORT_TOLERANCE_RAD,
) -> tuple[float, ...]:
    """Every rotation (as :func:`match_ports` takes it) at which ``exits_rad`` line up
    with ``ports_rad``: one for each cyclic assignment whose exits ask for rotations
    within twice the tolerance of one another, the middle of what they ask. None
    when the counts differ; several when the junction looks the same turned (a
    cross: four), which only the images can tell apart."""
    return tuple(r for r, _ in port_assignments(ports_rad, exits_rad, tolerance_rad))


def port_assignments(
    ports_rad: Sequence[float],
    exits_rad: Sequence[float],
    tolerance_rad: float = PORT_TOLERANCE_RAD,
) -> tuple[tuple[float, tuple[int, ...]], ...]:
    """The assignments of :func:`port_rotations`, each with its rotation and the port
    of each exit (in the exits' order). Every assignment :func:`match_ports` finds
    agreeing, at any rotation, is one of them: its exits ask for rotations within
    the tolerance of that one."""
    n = len(ports_rad)
    if len(exits_rad) != n or n == 0:
        return ()
    order = sorted(range(n), key=lambda i: (_clockwise_key(exits_rad[i]), i))
    found = []
    for shift in range(n):
        asked = [_wrap(exits_rad[order[(k + shift) % n]] - ports_rad[k]) for k in range(n)]
        spread = [_wrap(r - asked[0]) for r in asked]
        if max(spread) - min(spread) <= 2.0 * tolerance_rad:
            port_of = [0] * n
            for k in range(n):
                port_of[order[(k + shift) % n]] = k
            rotation = _wrap(asked[0] + (max(spread) + min(spread)) / 2.0)
            found.append((rotation, tuple(port_of)))
    return tuple(found)


def nearest_exit(
    exits_rad: Sequence[float], angle_rad: float, tolerance_rad: float = PORT_TOLERANCE_RAD
) -> int | None:
    """The index of the exit nearest to ``angle_rad``, if within ``tolerance_rad``."""
    if not exits_rad:
        return None
    best = min(range(len(exits_rad)), key=lambda i: (abs(_wrap(exits_rad[i] - angle_rad)), i))
    return best if abs(_wrap(exits_rad[best] - angle_rad)) <= tolerance_rad else None
