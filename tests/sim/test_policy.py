"""The exit policy seam: the right-hand rule as a policy, and the controller asking one."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pytest

from pipemap.sim import CameraSpec, World, build_network
from pipemap.sim.controller import autonomous_run
from pipemap.sim.policy import (
    BEHIND_RAD,
    ExitChoice,
    Junction,
    RightHandPolicy,
    RunStatus,
    is_behind,
    right_most,
)
from pipemap.sim.stream import NodeDeparture, NodeExits

PI = math.pi


def test_right_most_skips_the_way_back() -> None:
    # Behind, left, ahead, right: the right one (most negative turn).
    assert right_most((PI, PI / 2, 0.0, -PI / 2)) == 3
    assert right_most((-PI + 0.1, 1.0)) == 1
    assert right_most((PI - 0.2,)) is None  # a dead end: straight back
    assert right_most(()) is None
    assert is_behind(PI - BEHIND_RAD) and not is_behind(PI - BEHIND_RAD - 0.01)


def test_right_hand_stops_after_as_many_returns_as_the_start_has_pipes() -> None:
    policy = RightHandPolicy(start_radius_m=0.3, drift_per_m=0.0)
    tee = (PI, PI / 2, -PI / 2)
    assert policy.choose(Junction(1, tee, 0.0, 0.0, 0.0)) == ExitChoice(2)
    far = policy.choose(Junction(2, tee, 5.0, 0.0, 5.0))
    assert far.stop is None
    for visit in (3, 4):
        assert policy.choose(Junction(visit, tee, 0.1, 0.0, 9.0)).stop is None
    done = policy.choose(Junction(5, tee, 0.1, 0.0, 12.0))
    assert done == ExitChoice(stop=RunStatus.FINISHED, notes=("back at the start",))
    # A place near the start with another number of pipes is not the start.
    other = RightHandPolicy()
    other.choose(Junction(1, (PI,), 0.0, 0.0, 0.0))
    assert other.choose(Junction(2, tee, 0.0, 0.0, 3.0)).stop is None
    assert Junction(1, (), 0.0, 0.0, 0.0).first and not Junction(2, (), 0.0, 0.0, 0.0).first


@dataclass
class Recording:
    """A policy that takes the left-most exit and stops at its ``stop_at``-th junction,
    keeping what it was shown."""

    stop_at: int
    seen: list[Junction] = field(default_factory=list)

    def choose(self, junction: Junction) -> ExitChoice:
        self.seen.append(junction)
        if junction.visit_id == self.stop_at:
            return ExitChoice(stop=RunStatus.INCONSISTENT, notes=("told to stop",))
        ahead = [i for i, e in enumerate(junction.exits_rad) if not is_behind(e)]
        if not ahead:
            return ExitChoice(None)
        return ExitChoice(max(ahead, key=lambda i: junction.exits_rad[i]))

    def blocked(self, junction: Junction) -> ExitChoice:
        return ExitChoice(None)


def test_the_controller_asks_its_policy_and_stops_when_told() -> None:
    records: list[object] = []
    policy = Recording(stop_at=4)
    with World(build_network("paper"), seed=0, texture_px=32) as world:
        result = autonomous_run(
            world, CameraSpec(resolution_px=32), 1, sink=records.append, policy=policy
        )
    assert result.status is RunStatus.INCONSISTENT
    assert [e for _, e in result.events][-2:] == ["told to stop", "stopped: map inconsistent"]
    # Left-most: from S to A; A has no pipe to the left, so on to C; C's left is E.
    assert [s.node for s in result.sweep_truths] == list("SACE")
    assert [len(j.exits_rad) for j in policy.seen] == [1, 3, 4, 1]
    assert [j.visit_id for j in policy.seen] == [1, 2, 3, 4]
    odometers = [j.odometer_m for j in policy.seen]
    assert odometers == sorted(odometers) and odometers[0] == pytest.approx(0.0, abs=0.01)
    # The exits reach the sink before the policy is asked; departures follow.
    exits = [r for r in records if isinstance(r, NodeExits)]
    departures = [r for r in records if isinstance(r, NodeDeparture)]
    assert [r.exits_rad for r in exits] == [j.exits_rad for j in policy.seen]
    assert [d.visit_id for d in departures] == [1, 2, 3]
    assert records.index(exits[1]) < records.index(departures[1])


def test_the_right_hand_rule_takes_the_next_exit_after_a_blocked_one() -> None:
    policy = RightHandPolicy()
    cross = Junction(1, (math.pi, -math.pi / 2, 0.0, math.pi / 2), 0.0, 0.0, 0.0)
    assert policy.choose(cross).exit_index == 1  # right
    assert policy.blocked(cross).exit_index == 2  # then straight on
    assert policy.blocked(cross).exit_index == 3  # then left
    back = policy.blocked(cross)
    assert back.exit_index is None and back.notes  # then back the way it came
    # At the next junction nothing is blocked any more.
    tee = Junction(2, (math.pi, -math.pi / 2, math.pi / 2), 1.0, 0.0, 1.0)
    assert policy.choose(tee).exit_index == 1
    assert policy.blocked(tee).exit_index == 2
