"""The two-view fits of one visit, each computed once (:mod:`localizer.fitcache`),
and the branch's far fit asked last (:mod:`localizer.branching`): both only save
work, so a fit given back must be the one fitting anew would give, and nothing may
be shared between what differs (another question, another junction under the same
id, another map's ports, another visit)."""

from __future__ import annotations

import math
import sys

import pytest

from pipemap.localizer import Decision, Localizer, LocalizerConfig, branching, fitcache
from pipemap.localizer.ports import (
    clockwise_ports,
    match_ports,
    port_assignments,
    port_rotations,
)
from pipemap.localizer.similarity import SetMatch
from pipemap.localizer.topomap import TopoMap
from pipemap.localizer.twoview import SweepFeatures, TwoViewFit, stored_features
from tests.conftest import PaperSet
from tests.localizer.test_new_branch import CROSS, DRIFTING, Y, _to_the_twin, _turned

CONFIG = LocalizerConfig()


def _known_two(paper_sets: dict[str, PaperSet]) -> tuple[Localizer, SweepFeatures]:
    """A localizer that knows junctions 0 (set 1, a Y) and 1 (set 4, a cross), and the
    keypoints of a revisit of junction 0, turned a sixth of a turn."""
    loc = Localizer(CONFIG)
    loc.localize(paper_sets["1"].images, exits_rad=Y)
    loc.depart(math.pi)
    loc.localize(paper_sets["4"].images, exits_rad=CROSS)
    revisit = _turned(paper_sets["1"].images, math.pi / 3.0)
    return loc, stored_features(revisit, CONFIG.two_view_config).features()


def _exits() -> tuple[float, ...]:
    return tuple(e - math.pi / 3.0 for e in Y)


def test_the_same_question_in_one_visit_is_fitted_once(paper_sets: dict[str, PaperSet]) -> None:
    loc, sweep = _known_two(paper_sets)
    first = loc._fit(0, sweep, 0.0, CONFIG.verify_inliers, _exits(), 0.0)
    again = loc._fit(0, sweep, 0.0, CONFIG.verify_inliers, _exits(), 0.0)
    assert first is not None and first.inliers >= CONFIG.verify_inliers
    assert again is first
    assert (loc._fits.computed, loc._fits.reused) == (1, 1)


@pytest.mark.parametrize(
    "change",
    ["needed", "guess", "exits", "turn", "node"],
)
def test_each_argument_of_a_fit_keys_it(paper_sets: dict[str, PaperSet], change: str) -> None:
    loc, sweep = _known_two(paper_sets)
    asked = {"node": 0, "guess": 0.0, "needed": CONFIG.verify_inliers, "exits": _exits()}
    asked["turn"] = 0.0
    loc._fit(asked["node"], sweep, asked["guess"], asked["needed"], asked["exits"], asked["turn"])
    other = {
        "needed": 0,
        "guess": 0.5,
        "exits": tuple(e + 0.1 for e in _exits()),
        "turn": 0.2,
        "node": 1,
    }
    asked[change] = other[change]
    loc._fit(asked["node"], sweep, asked["guess"], asked["needed"], asked["exits"], asked["turn"])
    assert (loc._fits.computed, loc._fits.reused) == (2, 0)


def test_another_map_s_ports_under_the_same_id_are_fitted_anew(
    paper_sets: dict[str, PaperSet],
) -> None:
    # Two maps may hold different junctions under one id (competing maps draw ids
    # from one pool): a fit checked against one map's ports is not the other's.
    loc, sweep = _known_two(paper_sets)
    args = (sweep, 0.0, CONFIG.verify_inliers, _exits(), 0.0)
    as_y = loc._fit(0, *args)
    other = TopoMap()
    other.visit(0, CROSS)  # junction 0 is a cross on this map
    loc.map = other
    as_cross = loc._fit(0, *args)
    assert (loc._fits.computed, loc._fits.reused) == (2, 0)
    assert as_y is not None and as_cross is not as_y


def test_another_junction_s_keypoints_under_the_same_id_are_fitted_anew(
    paper_sets: dict[str, PaperSet],
) -> None:
    loc, sweep = _known_two(paper_sets)
    args = (sweep, 0.0, CONFIG.verify_inliers, None, 0.0)
    own = loc._fit(0, *args)
    loc._features[0] = loc._features[1]  # id 0 now holds junction 1's keypoints
    stranger = loc._fit(0, *args)
    assert (loc._fits.computed, loc._fits.reused) == (2, 0)
    assert own is not None and own.inliers >= CONFIG.verify_inliers
    assert stranger is None or stranger.inliers < own.inliers


def test_a_new_visit_forgets_every_fit(paper_sets: dict[str, PaperSet]) -> None:
    loc, sweep = _known_two(paper_sets)
    args = (0.0, CONFIG.verify_inliers, _exits(), 0.0)
    loc._fit(0, sweep, *args)
    again = stored_features(
        _turned(paper_sets["1"].images, math.pi / 3.0), CONFIG.two_view_config
    ).features()
    loc._fit(0, again, *args)
    assert (loc._fits.computed, loc._fits.reused) == (1, 0)  # counted from the new visit


def _to_the_second_of_two_twins(
    paper_sets: dict[str, PaperSet],
) -> tuple[Localizer, list[Decision], int]:
    """A, C: identical Y fittings 2 m apart, X and Z crosses. The robot drives A -> X
    -> C -> Z (leaving A by its right pipe, C by its left one), then by a pipe not
    driven yet into C again, 1 m from either by dead reckoning, through C's right
    pipe. A fits first and is passed over (its right pipe leads to X); C is taken;
    the branch then asks whether A's keypoints fit: the question the choice asked.
    Returns the localizer, the decisions, and the fits given back at the last."""
    same = paper_sets["1"].images
    loc = Localizer(DRIFTING)
    decisions = []
    for images, exits, position, odometer, leave in (
        (same, Y, (0.0, 0.0), 16.0, -math.pi / 3.0),
        (paper_sets["4"].images, CROSS, (1.0, 0.0), 17.0, 0.0),
        (same, Y, (2.0, 0.0), 18.0, math.pi / 3.0),
        (paper_sets["10"].images, CROSS, (2.5, 0.8), 19.0, math.pi / 2.0),
    ):
        decisions.append(
            loc.localize(images, exits_rad=exits, odometer_m=odometer, position_m=position)
        )
        loc.depart(leave)
    turned = _turned(same, 2.0 * math.pi / 3.0)  # the pipe behind is A's and C's right one
    decisions.append(loc.localize(turned, exits_rad=Y, odometer_m=21.0, position_m=(1.0, 0.3)))
    return loc, decisions, loc._fits.reused


def test_fits_given_back_make_the_decisions_of_fitting_anew(
    paper_sets: dict[str, PaperSet], monkeypatch: pytest.MonkeyPatch
) -> None:
    loc, decisions, reused = _to_the_second_of_two_twins(paper_sets)
    last = decisions[-1]
    assert last.known and last.node == 2 and [i for i, _ in last.rejected] == [0]
    assert last.hypotheses == 2 and last.deferred == (4,)  # C, or a new junction of its look
    assert reused == 1  # A's fit, asked again by the branch
    real = fitcache.VisitFits.fit

    def anew(self, sweep, node, stored, key, compute):  # type: ignore[no-untyped-def]
        self.start(None)  # forget: every fit is computed
        return real(self, sweep, node, stored, key, compute)

    monkeypatch.setattr(fitcache.VisitFits, "fit", anew)
    fresh, fresh_decisions, fresh_reused = _to_the_second_of_two_twins(paper_sets)
    assert fresh_reused == 0
    assert fresh_decisions == decisions
    assert fresh.map.to_dict() == loc.map.to_dict() and fresh.open_visits == loc.open_visits


def test_the_far_fit_is_not_made_where_its_answer_cannot_count(
    paper_sets: dict[str, PaperSet], monkeypatch: pytest.MonkeyPatch
) -> None:
    # The twin run, but B is where A was by dead reckoning: B may not be new whatever
    # the look does, so C (far by odometry) is not fitted to see whether it repeats.
    far_fits: list[int] = []
    real = branching._repeats_far

    def counted(*args):  # type: ignore[no-untyped-def]
        far_fits.append(1)
        return real(*args)

    monkeypatch.setattr(branching, "_repeats_far", counted)
    same = paper_sets["1"].images
    loc = Localizer(DRIFTING)
    for images, exits, position, odometer, leave in (
        (same, Y, (0.0, 0.0), 16.0, -math.pi / 3.0),
        (paper_sets["4"].images, CROSS, (1.0, 0.0), 17.0, 0.0),
        (same, Y, (2.0, 0.0), 18.0, -math.pi / 3.0),
        (paper_sets["10"].images, CROSS, (3.0, 0.0), 19.0, math.pi / 2.0),
    ):
        loc.localize(images, exits_rad=exits, odometer_m=odometer, position_m=position)
        loc.depart(leave)
    b = loc.localize(
        _turned(same, -2.0 * math.pi / 3.0), exits_rad=Y, odometer_m=21.0, position_m=(0.0, 0.0)
    )
    assert b.known and b.node == 0 and b.hypotheses == 1
    assert far_fits == []
    # Where B is 0.8 m off A the answer counts, and C is fitted (test_new_branch).
    _to_the_twin(DRIFTING, paper_sets)
    assert far_fits == [1]


#: A T fitting: its pipes line up with the exits at one turn only.
T = (0.0, math.pi / 2.0, math.pi)


def _into_the_twin_t_by_a_pipe_taken(
    paper_sets: dict[str, PaperSet], fitted: list[tuple[str, int]], x_m: float = 1.7
) -> tuple[Localizer, Decision]:
    """A, C: identical T fittings 2 m apart, X and Z crosses. The robot drives A -> X
    -> C -> Z (leaving A by its left pipe, C straight on), then by a pipe not driven
    yet into C, ``x_m`` from A along the line to C by dead reckoning (within the
    drift of both), through C's left pipe: on A that pipe leads to X, at the one
    turn a T allows. ``fitted`` gets (caller, node) of every fit asked."""
    same = paper_sets["1"].images
    loc = Localizer(DRIFTING)
    for images, exits, position, odometer, leave in (
        (same, T, (0.0, 0.0), 16.0, math.pi / 2.0),
        (paper_sets["4"].images, CROSS, (1.0, 0.0), 17.0, 0.0),
        (same, T, (2.0, 0.0), 18.0, 0.0),
        (paper_sets["10"].images, CROSS, (2.5, 0.8), 19.0, math.pi / 2.0),
    ):
        loc.localize(images, exits_rad=exits, odometer_m=odometer, position_m=position)
        loc.depart(leave)
    fitted.clear()
    exits = tuple(e + math.pi / 2.0 for e in T)  # the robot faces A's and C's right
    turned = _turned(same, -math.pi / 2.0)
    return loc, loc.localize(turned, exits_rad=exits, odometer_m=30.0, position_m=(x_m, 0.0))


def test_a_junction_no_fit_can_make_a_branch_is_not_fitted_for_the_branch(
    paper_sets: dict[str, PaperSet], monkeypatch: pytest.MonkeyPatch
) -> None:
    # B is C: A fits too but is passed over (its pipe behind leads to X), and the
    # new map is pruned at once (B is 0.3 m from C). Whether A's look repeats then
    # counts for nothing, and at every turn a fit could agree with, A's pipe behind
    # is taken: the branch does not ask A's fit again.
    fitted: list[tuple[str, int]] = []
    real = Localizer._fit

    def asked(self, node, *args):  # type: ignore[no-untyped-def]
        fitted.append((sys._getframe(1).f_code.co_name, node))
        return real(self, node, *args)

    monkeypatch.setattr(Localizer, "_fit", asked)
    loc, b = _into_the_twin_t_by_a_pipe_taken(paper_sets, fitted)
    assert b.known and b.node == 2 and [i for i, _ in b.rejected] == [0]
    assert b.hypotheses == 1 and b.deferred == ()
    assert fitted == [("_verified", 0), ("_verified", 2)]
    # The same decision and map where every junction is fitted.
    monkeypatch.setattr(branching, "_never_a_branch", lambda *args: False)
    again, b_again = _into_the_twin_t_by_a_pipe_taken(paper_sets, fitted)
    assert ("_repeats", 0) in fitted
    assert b_again == b and again.map.to_dict() == loc.map.to_dict()
    monkeypatch.undo()
    monkeypatch.setattr(Localizer, "_fit", asked)
    # 1 m from C the new map lives, and whether the look repeats counts: A is fitted
    # (its fit kept from the choice) and says it does, so B may be new.
    _, b_new = _into_the_twin_t_by_a_pipe_taken(paper_sets, fitted, x_m=1.0)
    assert b_new.node == 2 and b_new.hypotheses == 2 and b_new.deferred == (4,)
    assert fitted == [("_verified", 0), ("_verified", 2), ("_repeats", 0)]


class _LookAlikes:
    """The parts of a localizer :func:`branching.alike_branches` reads, for a visit
    recognised as one junction with look-alikes: every fit asked is recorded (and
    fails, so no branch is made), and the arrival rule rejects ``conflicted`` at
    every turn a fit could agree with."""

    def __init__(self, conflicted: set[int], port_check: bool = True) -> None:
        self.config = LocalizerConfig(port_check=port_check)
        self.fitted: list[int] = []
        self._hypotheses = self
        self._conflicted = conflicted

    def arrival_conflict_at_every_turn(self, node: int, exits: object, tolerance: float) -> bool:
        return node in self._conflicted

    def _fit(self, node: int, *args: object) -> None:
        self.fitted.append(node)


@pytest.mark.parametrize(
    ("conflicted", "port_check", "fitted"),
    [({3}, True, [5]), (set(), True, [3, 5]), ({3, 5}, True, []), ({3}, False, [3, 5])],
    ids=["one-conflicted", "none-conflicted", "both-conflicted", "port-check-off"],
)
def test_a_look_alike_no_fit_can_make_a_branch_is_not_fitted(
    conflicted: set[int], port_check: bool, fitted: list[int]
) -> None:
    # A look-alike whose pipe behind the robot leads elsewhere at every turn a fit
    # could agree with would be passed over by the arrival rule whatever its fit:
    # alike_branches does not ask it. Without the port check a fit whose ports
    # disagree is not passed over, so every look-alike is fitted.
    loc = _LookAlikes(conflicted, port_check)
    matched = [SetMatch(0.5, 0, 0.0, 0.0, 0.0)] * 6
    branches = branching.alike_branches(
        loc,  # type: ignore[arg-type]
        (3, 5),
        None,  # type: ignore[arg-type]
        matched,
        0.0,
        T,
        0,
        {},
    )
    assert branches == [] and loc.fitted == fitted


@pytest.mark.parametrize(
    "first_exits",
    [Y, T, CROSS, (0.3, 1.9, 3.0, -1.2), (0.0, math.pi)],
    ids=["Y", "T", "cross", "irregular", "straight"],
)
def test_every_assignment_a_fit_agrees_with_is_one_of_the_port_assignments(
    first_exits: tuple[float, ...],
) -> None:
    ports, _ = clockwise_ports(first_exits)
    tolerance = CONFIG.port_tolerance_rad
    for turn in (0.0, 0.7, -2.0, 3.0):
        for noise in (0.0, 0.15, -0.3):
            exits = tuple(p + turn + noise * (k % 2) for k, p in enumerate(ports))
            assignments = {a for _, a in port_assignments(ports, exits, tolerance)}
            agreeing = set()
            for step in range(720):
                match = match_ports(ports, exits, -math.pi + step * math.pi / 360.0, tolerance)
                if match.exit_ports is not None:
                    agreeing.add(match.exit_ports)
            assert agreeing and agreeing <= assignments
            assert port_rotations(ports, exits, tolerance) == tuple(
                r for r, _ in port_assignments(ports, exits, tolerance)
            )


class _RepeatsAsked:
    """The parts of a localizer :func:`branching._repeats` reads, for a visit whose
    sweep the keypoints of every junction asked fit (each fit asked is recorded):
    junctions 0..5 known, all near by odometry, ranked by ``similarity``."""

    def __init__(self, similarity: list[float]) -> None:
        self.config = LocalizerConfig()
        self.fitted: list[int] = []
        self._hypotheses = self
        self._odometry = self
        self.map = self
        self.matched = [SetMatch(s, 0, 0.0, 0.0, 0.0) for s in similarity]

    def near(self, node: int) -> bool:
        return True

    def unused(self, node: int) -> bool:
        return False

    def _excluded(self) -> None:
        return None

    def _allowed_rotations(self, node: int, exits: object, turn: float) -> None:
        return None

    def arrival_conflict_at_every_turn(self, node: int, exits: object, tolerance: float) -> bool:
        return False

    def arrival_conflict(self, node: int, ports: object, exits: object) -> None:
        return None

    def _fit(self, node: int, *args: object) -> TwoViewFit:
        self.fitted.append(node)
        return TwoViewFit(0.0, 0.0, 2 * self.config.verify_inliers, 300)

    def _ports_of(self, node: int, exits: object, rotation_rad: float) -> None:
        return None

    def _evidence(self, node: int, ports: object) -> float:
        return 0.0


@pytest.mark.parametrize(
    ("alike", "counts", "fitted"),
    [((3,), False, []), ((), False, [3]), ((5,), False, [3]), ((3,), True, [3])],
    ids=["look-alike-asked-before", "no-look-alike", "another-look-alike", "answer-counts"],
)
def test_a_look_alike_is_asked_once_whether_it_is_a_branch(
    alike: tuple[int, ...], counts: bool, fitted: list[int]
) -> None:
    # Junction 3 ranks first among those that may show the look repeats, 4 next.
    # Where 3 is a look-alike the visit named, alike_branches asked already whether
    # it is a branch (it is none: branches hold 1 alone): whether the look repeats
    # counts for nothing then, and 3 is not fitted again, nor 4 in its stead (the
    # ranking stays). Any other junction is fitted, and so is 3 where the answer
    # counts (it could make the visit new).
    loc = _RepeatsAsked([0.1, 0.9, 0.2, 0.8, 0.7, 0.3])
    branches = [branching.Branch(1, None, None)]
    fits: dict[int, branching.Fit] = {}
    repeats = branching._repeats(
        loc,  # type: ignore[arg-type]
        branches,
        None,  # type: ignore[arg-type]
        loc.matched,
        T,
        0,
        fits,
        counts,
        alike,
    )
    assert loc.fitted == fitted
    assert repeats == bool(fitted) and [b.node for b in branches] == [1, *fitted]
    assert sorted(fits) == fitted
