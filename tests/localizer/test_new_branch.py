"""The branch "new, or a look-alike seen before" (:mod:`localizer.branching`): a
sweep that fits a known junction whose look repeats, where ports and odometry leave
open whether it is that junction or a new one of its look. Two maps live, and only
a later traversal decides; where none does, the map says so."""

from __future__ import annotations

import math
from dataclasses import replace

from pipemap.localizer import Decision, ImageSet, Localizer, LocalizerConfig, map_document
from pipemap.localizer.odometry import drift_allowed
from tests.conftest import PaperSet

#: A Y fitting (three pipes 120 degrees apart) and a cross, as the robot's exits.
Y = (math.pi / 3.0, math.pi, -math.pi / 3.0)
CROSS = (0.0, math.pi / 2.0, math.pi, -math.pi / 2.0)
#: A robot whose odometry drifts ten times the default's: at 20 m driven it allows
#: 1.3 m, so a junction of one look 0.8 m away is no longer ruled out.
DRIFTING = drift_allowed(LocalizerConfig(), 10.0)


def _turned(images: ImageSet, robot_turn_rad: float) -> ImageSet:
    """The same sweep seen by a robot turned by ``robot_turn_rad``."""
    return replace(images, camera_angle_rad=images.camera_angle_rad - robot_turn_rad)


def _to_the_twin(
    config: LocalizerConfig, paper_sets: dict[str, PaperSet]
) -> tuple[Localizer, list[Decision]]:
    """A, C: identical Y fittings (the very same sweep) 2 m apart, X and Z (crosses,
    each its own look) between and after them. The robot drives A -> X -> C -> Z, then
    by a pipe not driven yet into B, a third Y of the same look, 0.8 m from A by dead
    reckoning and entered through the pipe that on A is its left one (free). B fits
    A's keypoints and ports, and C's (far by odometry): the look repeats. Whether B is
    A or a new junction, nothing at the visit tells."""
    same = paper_sets["1"].images
    x, z = paper_sets["4"].images, paper_sets["10"].images
    loc = Localizer(config)
    out: list[Decision] = []

    def visit(images: ImageSet, exits, position, odometer: float, leave: float | None) -> None:  # type: ignore[no-untyped-def]
        out.append(loc.localize(images, exits_rad=exits, odometer_m=odometer, position_m=position))
        if leave is not None:
            loc.depart(leave)

    visit(same, Y, (0.0, 0.0), 16.0, -math.pi / 3.0)  # A: leave by its right pipe, to X
    visit(x, CROSS, (1.0, 0.0), 17.0, 0.0)  # X: straight on
    visit(same, Y, (2.0, 0.0), 18.0, -math.pi / 3.0)  # C: far from A by odometry
    visit(z, CROSS, (3.0, 0.0), 19.0, math.pi / 2.0)  # Z: left, a pipe not driven yet
    # B: the robot faces -120 degrees from A's first heading, so the pipe behind it is,
    # were B A, A's left pipe. Leaving by its exit at +60 degrees is, on A, the right
    # pipe: the one to X.
    visit(_turned(same, -2.0 * math.pi / 3.0), Y, (0.0, 0.8), 21.0, math.pi / 3.0)
    return loc, out


def test_a_twin_that_may_be_new_keeps_both_maps(paper_sets: dict[str, PaperSet]) -> None:
    loc, d = _to_the_twin(DRIFTING, paper_sets)
    b = d[4]
    # Taken as A on the heavier map (0.8 m is within the drift), deferred: the other
    # map has it as a new junction, id 4 of the pool.
    assert b.known and b.node == 0 and b.deferred == (4,) and b.hypotheses == 2
    assert loc.open_visits == {4: (0, 4)}
    assert loc.map.unused(4) and loc.map.used_node_count == 4


def _into_z_by_its_right_pipe(loc: Localizer, paper_sets: dict[str, PaperSet]) -> Decision:
    """From B by its exit at +60 degrees (on A, the pipe to X), 3 m into Z through Z's
    right pipe, not driven yet: the robot faces +90 degrees of Z's first heading."""
    z = _turned(paper_sets["10"].images, math.pi / 2.0)
    return loc.localize(z, exits_rad=CROSS, odometer_m=24.0, position_m=(3.0, 0.1))


def test_a_later_pipe_that_leads_elsewhere_settles_it_as_new(
    paper_sets: dict[str, PaperSet],
) -> None:
    # B is new: its pipe (on A, the one to X) leads to Z. A's map would join A's pipe
    # to X to Z as well (a conflict) and is dropped: B is new.
    loc, d = _to_the_twin(DRIFTING, paper_sets)
    z = _into_z_by_its_right_pipe(loc, paper_sets)
    assert z.known and z.node == 3
    assert z.settled == ((4, 4),) and z.hypotheses == 1
    assert loc.map.visits == (0, 1, 2, 3, 4, 3)
    assert loc.map.used_node_count == 5 and not loc.map.unused(4)
    assert all(v.conflict is None for v in loc.map.visit_records)
    doc = map_document(loc.map, [(str(i), x) for i, x in enumerate([*d, z])], loc.open_visits)
    assert doc["visits"][4]["node"] == 4 and doc["visits"][4]["decided_node"] == 0
    assert doc["visits"][5]["settled"] == [{"visit": 4, "node": 4}]
    assert "open" not in doc
    # One map (the rule before competing maps): B is merged into A, and the pipe to Z
    # meets the conflict.
    one, d1 = _to_the_twin(replace(DRIFTING, hypotheses=1), paper_sets)
    _into_z_by_its_right_pipe(one, paper_sets)
    assert d1[4].node == 0 and one.map.visits[4] == 0
    assert one.map.visit_records[5].conflict is not None


def test_a_later_pipe_that_leads_where_a_s_does_settles_it_as_a(
    paper_sets: dict[str, PaperSet],
) -> None:
    # B is A: its pipe leads 1 m to X, into X's back pipe (the one from A). The
    # new junction's map would join X's back pipe twice and is dropped: B is A, and
    # the pool's id 4 stays unused in the map.
    loc, d = _to_the_twin(DRIFTING, paper_sets)
    x = loc.localize(
        paper_sets["4"].images,
        exits_rad=CROSS,
        odometer_m=22.0,
        position_m=(1.0, 0.1),
    )
    assert x.known and x.node == 1
    assert x.settled == ((4, 0),) and x.hypotheses == 1
    assert loc.map.visits == (0, 1, 2, 3, 0, 1)
    assert loc.map.unused(4) and loc.map.used_node_count == 4
    assert all(v.conflict is None for v in loc.map.visit_records)
    doc = map_document(loc.map, [(str(i), v) for i, v in enumerate([*d, x])], loc.open_visits)
    assert len(doc["nodes"]) == 4  # the pool's id 4 is past this map's ids
    assert doc["visits"][4]["node"] == 0 and "decided_node" not in doc["visits"][4]
    # A new junction after it (a Y of the same look, far from every one by odometry)
    # takes the pool's next id, 5: the map leaves 4 unused.
    loc.depart(math.pi / 2.0)
    far = loc.localize(paper_sets["1"].images, exits_rad=Y, odometer_m=30.0, position_m=(1.0, 9.0))
    assert not far.known and far.node == 5 and loc.map.used_node_count == 5
    assert loc.map.unused(4) and loc.map.visits[-1] == 5
    assert loc.map.to_dict()["nodes"][4] == {"id": 4, "unused": True, "ports": []}


def test_where_nothing_decides_the_map_says_it_cannot_tell(
    paper_sets: dict[str, PaperSet],
) -> None:
    # B's pipe back to Z is the one it came by: both maps have it, at the same length,
    # so driving it tells nothing. The map keeps both and names the visit as open
    # instead of passing A (its leader's guess) off as certain.
    loc, d = _to_the_twin(DRIFTING, paper_sets)
    # The exit straight behind B: back to Z, into the pipe Z left by.
    loc.depart(math.pi)
    z = loc.localize(
        _turned(paper_sets["10"].images, -math.pi / 2.0),
        exits_rad=CROSS,
        odometer_m=23.0,
        position_m=(3.0, 0.1),
    )
    assert z.known and z.node == 3 and z.settled == ()
    assert z.hypotheses == 2 and loc.open_visits == {4: (0, 4)}
    doc = map_document(loc.map, [(str(i), v) for i, v in enumerate([*d, z])], loc.open_visits)
    assert doc["open"] == [{"visit": 4, "nodes": [0, 4]}]


def test_where_the_look_does_not_repeat_a_fitting_sweep_is_the_junction(
    paper_sets: dict[str, PaperSet],
) -> None:
    # Without C (no other junction of A's look known), a sweep that fits A is A: the
    # junctions of this network each look like themselves, as at --alike 0.
    same, x, z = (paper_sets[k].images for k in ("1", "4", "10"))
    loc = Localizer(DRIFTING)
    loc.localize(same, exits_rad=Y, odometer_m=16.0, position_m=(0.0, 0.0))
    loc.depart(-math.pi / 3.0)
    loc.localize(x, exits_rad=CROSS, odometer_m=17.0, position_m=(1.0, 0.0))
    loc.depart(math.pi / 2.0)
    loc.localize(z, exits_rad=CROSS, odometer_m=19.0, position_m=(1.0, 1.0))
    loc.depart(math.pi / 2.0)
    b = loc.localize(
        _turned(same, -2.0 * math.pi / 3.0), exits_rad=Y, odometer_m=21.0, position_m=(0.0, 0.8)
    )
    assert b.known and b.node == 0 and b.hypotheses == 1 and b.deferred == ()
    assert loc.map.node_count == 3
