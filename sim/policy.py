"""Which pipe to take at a junction: the seam between the controller and its policy.

The controller (:mod:`sim.controller`) drives, centres, sweeps and scans; at each
junction it hands what it measured (:class:`Junction`: the exits its range scan
found and its own odometry, never ground truth) to an :class:`ExitPolicy`, and
leaves by the exit the policy chooses, or stops when the policy says the run is
over. The simulator ships the paper's policy, :class:`RightHandPolicy`. Policies
that need a map (``pipemap.localizer.explore``) live outside ``sim/`` and are handed
to the controller by whoever runs it (the recorder).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Protocol

__all__ = [
    "BEHIND_RAD",
    "BlockedExits",
    "ExitChoice",
    "ExitPolicy",
    "Junction",
    "RightHandPolicy",
    "RunStatus",
    "is_behind",
    "right_most",
]


class RunStatus(enum.Enum):
    """How an exploration ended."""

    FINISHED = "finished"
    #: The policy stopped because what the robot saw contradicted its map too often.
    INCONSISTENT = "map inconsistent"
    STUCK = "stuck"
    LEFT_PIPE = "left the pipe"
    TIME_LIMIT = "time limit"


@dataclass(frozen=True)
class Junction:
    """What the robot knows when it must choose a pipe (robot data only).

    ``exits_rad`` are the pipes the exit scan found, as headings relative to the
    heading the robot arrived with (0 straight on, positive to the left, in
    (-pi, pi]), in the order the scan met them; the pipe it came in by is among them.
    ``x_m``, ``y_m`` and ``odometer_m`` are its dead reckoning: position in the start's
    frame and the distance driven so far.
    """

    visit_id: int
    exits_rad: tuple[float, ...]
    x_m: float
    y_m: float
    odometer_m: float

    @property
    def first(self) -> bool:
        """The run's first junction (the robot was put there; it came by no pipe)."""
        return self.visit_id == 1


@dataclass(frozen=True)
class ExitChoice:
    """A policy's answer: leave by ``exits_rad[exit_index]``, or straight back the way
    the robot came (``exit_index`` ``None``), or stop with ``stop`` as the run's status.
    ``notes`` are logged as the robot's events."""

    exit_index: int | None = None
    stop: RunStatus | None = None
    notes: tuple[str, ...] = ()


class ExitPolicy(Protocol):
    """Chooses the pipe to leave a junction by."""

    def choose(self, junction: Junction) -> ExitChoice:
        """The choice at ``junction``; called once per visit, after the exit scan."""
        ...

    def blocked(self, junction: Junction) -> ExitChoice:
        """The exit last chosen at ``junction`` is blocked (the robot gave the pipe up
        and is back there, facing as at the visit): the choice now."""
        ...


#: An exit within this of straight behind is the pipe the robot came in by.
BEHIND_RAD = 0.5


def is_behind(exit_rad: float) -> bool:
    """Whether an exit (relative to the arrival heading) is the way back."""
    return abs(math.remainder(exit_rad - math.pi, 2.0 * math.pi)) <= BEHIND_RAD


def right_most(exits_rad: tuple[float, ...], excluded: frozenset[int] = frozenset()) -> int | None:
    """The index of the right-most exit that is not the way back (more than
    :data:`BEHIND_RAD` from behind) nor ``excluded`` (given up as blocked), or
    ``None`` when there is none (a dead end)."""
    choices = [i for i, e in enumerate(exits_rad) if not is_behind(e) and i not in excluded]
    if not choices:
        return None
    return min(choices, key=lambda i: math.remainder(exits_rad[i], 2.0 * math.pi))


@dataclass
class RightHandPolicy:
    """The paper's rule: take the right-most exit; stop when back at the start (by
    odometry) as many times as it has pipes. On a tree that has covered everything;
    on a network with loops it covers the face it started on.

    The start is looked for within ``start_radius_m`` plus ``drift_per_m`` per metre
    driven, and only at a junction with as many pipes as the start has.
    """

    start_radius_m: float = 0.3
    drift_per_m: float = 0.005
    _start: tuple[float, float] | None = None
    _returns_needed: int = 1
    _returns: int = 0
    _blocked: BlockedExits = field(default_factory=lambda: BlockedExits())

    def choose(self, junction: Junction) -> ExitChoice:
        """The right-most exit, or stop back at the start."""
        exits = junction.exits_rad
        if self._start is None:
            self._start = (junction.x_m, junction.y_m)
            self._returns_needed = max(1, len(exits))
        elif len(exits) == self._returns_needed:
            off = math.hypot(junction.x_m - self._start[0], junction.y_m - self._start[1])
            if off < self.start_radius_m + self.drift_per_m * junction.odometer_m:
                self._returns += 1
                if self._returns >= self._returns_needed:
                    return ExitChoice(stop=RunStatus.FINISHED, notes=("back at the start",))
        return self._blocked.take(junction.visit_id, right_most(exits))

    def blocked(self, junction: Junction) -> ExitChoice:
        """The next exit counter-clockwise from the blocked one (the rule's next
        choice), or straight back when none is left."""
        return self._blocked.next_right_most(junction)


@dataclass
class BlockedExits:
    """The exits of the current visit given up as blocked, for a policy that takes
    the right-most exit: after a blocked one, the next one counter-clockwise."""

    visit_id: int = 0
    last: int | None = None
    given_up: frozenset[int] = frozenset()

    def take(self, visit_id: int, index: int | None, notes: tuple[str, ...] = ()) -> ExitChoice:
        """Leave visit ``visit_id`` by exit ``index`` (``None``: straight back)."""
        if visit_id != self.visit_id:
            self.visit_id, self.given_up = visit_id, frozenset()
        self.last = index
        return ExitChoice(exit_index=index, notes=notes)

    def next_right_most(self, junction: Junction) -> ExitChoice:
        """The exit taken last at ``junction`` is blocked: the right-most of the rest."""
        if junction.visit_id == self.visit_id and self.last is not None:
            self.given_up = self.given_up | {self.last}
        index = right_most(junction.exits_rad, self.given_up)
        notes = ("every other pipe is blocked: going back",) if index is None else ()
        return self.take(junction.visit_id, index, notes)
