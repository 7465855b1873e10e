"""Competing maps where appearance cannot tell two junctions apart
(:mod:`localizer.hypotheses`): identical sweeps, told apart later by the graph (ports
and pipe lengths), or by nothing, in which case the localizer says so."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer import (
    Decision,
    ImageSet,
    Localizer,
    LocalizerConfig,
    TopoMap,
    map_document,
)
from pipemap.localizer.explore import MapExplorer, telling_exit
from pipemap.localizer.hypotheses import Branch, Hypotheses, embeds_in_plane
from tests.conftest import PaperSet

#: A Y fitting (three pipes 120 degrees apart) and a cross, as the robot's exits.
Y = (math.pi / 3.0, math.pi, -math.pi / 3.0)
CROSS = (0.0, math.pi / 2.0, math.pi, -math.pi / 2.0)


def _turned(images: ImageSet, robot_turn_rad: float) -> ImageSet:
    """The same sweep seen by a robot turned by ``robot_turn_rad``."""
    return replace(images, camera_angle_rad=images.camera_angle_rad - robot_turn_rad)


def _run(
    config: LocalizerConfig, paper_sets: dict[str, PaperSet], back_to_x: bool
) -> tuple[Localizer, list[Decision]]:
    """A and B: two identical Y fittings (the very same sweep), 2 m apart; X and Z
    between them, different. The robot drives A -> X -> B -> Z, then by a new pipe
    back into B through its left pipe, with no dead reckoning (lost, say): B is A
    as far as that visit can tell. With ``back_to_x`` it then leaves B by the pipe
    it first came in by, to X: only B's map has that pipe lead to X."""
    same = paper_sets["1"].images
    x, z = paper_sets["4"].images, paper_sets["10"].images
    loc = Localizer(config)
    out = []

    def visit(images, exits, position, odometer, leave):
        out.append(loc.localize(images, exits_rad=exits, odometer_m=odometer, position_m=position))
        if leave is not None:
            loc.depart(leave)

    visit(same, Y, (0.0, 0.0), 0.0, -math.pi / 3.0)  # A: leave by its right pipe
    visit(x, CROSS, (1.0, 0.0), 1.0, 0.0)  # X: straight on
    visit(same, Y, (2.0, 0.0), 2.0, -math.pi / 3.0)  # B: apart from A by odometry
    visit(z, CROSS, (3.0, 0.0), 3.0, math.pi / 2.0)  # Z: left, a pipe not yet driven
    # Back at B through its left pipe (at +60 degrees of B's first heading): the robot
    # faces -120 degrees from then. Its dead reckoning is lost.
    visit(_turned(same, -2.0 * math.pi / 3.0), Y, None, 4.5, -math.pi / 3.0 if back_to_x else None)
    if back_to_x:  # B's first pipe: 1 m back to X, arriving through X's front pipe
        visit(_turned(x, math.pi), CROSS, (1.02, 0.01), 5.5, None)
    return loc, out


def test_ports_and_pipe_lengths_tell_identical_junctions_apart(
    paper_sets: dict[str, PaperSet],
) -> None:
    loc, d = _run(LocalizerConfig(), paper_sets, back_to_x=True)
    # The revisit fits A and B alike: two maps live, the decision deferred.
    assert d[4].known and d[4].hypotheses == 2
    assert {d[4].node, *d[4].deferred} == {0, 2}
    assert "deferred: may be" in d[4].describe()
    # At X, only B's map has B's first pipe lead there: A's would join X's front pipe
    # twice (a port conflict). The revisit is settled as B, and the map is right.
    assert d[5].node == 1 and d[5].known
    assert d[5].settled == ((4, 2),) and d[5].hypotheses == 1
    assert loc.map.visits == (0, 1, 2, 3, 2, 1)
    assert all(v.conflict is None for v in loc.map.visit_records)
    assert loc.open_visits == {}
    doc = map_document(loc.map, [(str(i), x) for i, x in enumerate(d)], loc.open_visits)
    assert doc["visits"][4]["node"] == 2 and doc["visits"][4]["decided_node"] == d[4].node
    assert doc["visits"][5]["settled"] == [{"visit": 4, "node": 2}]


def test_with_one_hypothesis_the_best_ranked_look_alike_is_taken(
    paper_sets: dict[str, PaperSet],
) -> None:
    # The same run with one map (today's rule): the revisit goes to the best ranked
    # of A and B, A (the earlier node), and the map is wrong: the pipe back to X
    # meets a port conflict.
    loc, d = _run(LocalizerConfig(hypotheses=1), paper_sets, back_to_x=True)
    assert d[4].node == 0 and d[4].deferred == () and d[4].hypotheses == 1
    assert loc.map.visits == (0, 1, 2, 3, 0, 1)
    assert loc.map.visit_records[5].conflict is not None


def test_where_nothing_tells_them_apart_the_map_says_so(
    paper_sets: dict[str, PaperSet],
) -> None:
    # The run ends at the revisit: A and B have the same look, the same ports, and no
    # dead reckoning or later pipe decides. The localizer keeps both and says so.
    loc, d = _run(LocalizerConfig(), paper_sets, back_to_x=False)
    assert d[4].deferred and loc.hypotheses_alive == 2
    assert loc.open_visits == {4: (d[4].node, *d[4].deferred)}
    doc = map_document(loc.map, [(str(i), x) for i, x in enumerate(d)], loc.open_visits)
    assert doc["open"] == [{"visit": 4, "nodes": [d[4].node, *d[4].deferred]}]
    assert doc["visits"][4]["deferred"] == list(d[4].deferred)


def test_odometry_weighs_look_alikes_within_the_gate(paper_sets: dict[str, PaperSet]) -> None:
    # A and B 0.5 m apart (both within the drift tolerance at 40 m driven: 0.5 m):
    # a revisit 0.05 m from B weighs B first by the odometry's likelihood (the gate
    # alone passes both, and the best ranked would be A); A, 0.45 m off (1.8 sigma,
    # sigma half the tolerance), is 0.2 as likely: above the prune ratio, it lives.
    same, other = paper_sets["1"].images, paper_sets["4"].images
    loc = Localizer()
    # The pipe from A to the other junction and from B to it are both 5 m: their
    # lengths do not tell A and B apart.
    loc.localize(same, position_m=(0.0, 0.0), odometer_m=15.0)
    loc.localize(other, position_m=(5.0, 0.0), odometer_m=20.0)
    loc.new_traversal()
    loc.localize(same, position_m=(0.5, 0.0), odometer_m=30.0)
    # (B is new: the check put A 0.5 m away, beyond 0.3 + 0.5 % of 30 m.)
    loc.localize(other, position_m=(5.0, 0.0), odometer_m=35.0)
    d = loc.localize(same, position_m=(0.45, 0.0), odometer_m=40.0)
    assert d.known and d.node == 2 and d.deferred == (0,)
    one = Localizer(LocalizerConfig(hypotheses=1))
    one.localize(same, position_m=(0.0, 0.0), odometer_m=15.0)
    one.localize(other, position_m=(5.0, 0.0), odometer_m=20.0)
    one.new_traversal()
    one.localize(same, position_m=(0.5, 0.0), odometer_m=30.0)
    one.localize(other, position_m=(5.0, 0.0), odometer_m=35.0)
    assert one.localize(same, position_m=(0.45, 0.0), odometer_m=40.0).node == 0


@pytest.mark.parametrize(("count", "ratio"), [(0, 0.01), (8, 0.0), (8, 1.0)])
def test_bad_hypothesis_settings_are_refused(count: int, ratio: float) -> None:
    with pytest.raises(LocalizerError, match="hypotheses"):
        LocalizerConfig(hypotheses=count, hypothesis_prune_ratio=ratio)


def _portless(limit: int = 8, second_m: float = 3.0) -> Hypotheses:
    """Junctions without ports (image folders without exits): 0 -> 1 (1 m) -> 2
    (``second_m``), then a new traversal from 3."""
    hyp = Hypotheses(TopoMap(), limit, 0.01)
    for node, odometer in ((0, 0.0), (1, 1.0), (2, 1.0 + second_m)):
        hyp.visit([Branch(node, None, None)], None, odometer)
        hyp.depart(None)
    hyp.new_traversal()
    hyp.visit([Branch(3, None, None)], None, 10.0)
    return hyp


def test_a_pipe_driven_again_at_its_length_settles_a_visit() -> None:
    # A visit that may be 0 or 2 (no ports to tell), then 1.0 m on to junction 1: the
    # pipe 0-1 is 1 m long, the pipe 2-1 is 3 m. Only the map where it was 0 fits.
    hyp = _portless()
    assert hyp.visit([Branch(0, None, None), Branch(2, None, None)], None, 12.0) == ()
    assert hyp.open == {4: (0, 2)} and len(hyp.live) == 2
    assert hyp.visit([Branch(1, None, None)], None, 13.02) == ((4, 0),)
    assert len(hyp.live) == 1 and hyp.leader.map.visits[-2:] == (0, 1)


def test_pipes_of_one_length_settle_nothing() -> None:
    # Both pipes to junction 1 are 1 m long: driven 1 m, both maps fit; both live.
    hyp = _portless(second_m=1.0)
    hyp.visit([Branch(0, None, None), Branch(2, None, None)], None, 12.0)
    assert hyp.visit([Branch(1, None, None)], None, 13.02) == ()
    assert hyp.open == {4: (0, 2)}


def test_the_bound_keeps_the_heaviest_and_the_ratio_drops_the_unlikely() -> None:
    hyp = _portless(limit=2)
    branches = [
        Branch(0, None, None, -1.0),
        Branch(1, None, None, 0.0),
        Branch(2, None, None, -0.5),
    ]
    hyp.visit(branches, None, 12.0)
    assert [h.map.visits[-1] for h in hyp.live] == [1, 2]  # at most 2, heaviest first
    unlikely = _portless()
    unlikely.visit([Branch(0, None, None), Branch(2, None, None, math.log(0.005))], None, 12.0)
    assert len(unlikely.live) == 1 and unlikely.open == {}


#: A cross fitting's ports in clockwise order (as ``clockwise_ports`` numbers them).
CROSS_PORTS = (math.pi / 2.0, 0.0, -math.pi / 2.0, -math.pi)


def _loops(pairs: list[tuple[int, int]]) -> TopoMap:
    """One cross whose pipes loop back to it: each pair leaves by one port and comes
    back by the other."""
    topomap = TopoMap()
    topomap.visit(0, CROSS_PORTS)
    for out, back in pairs:
        topomap.depart(out)
        topomap.visit(0, None, back)
    return topomap


def test_a_map_is_planar_only_if_its_ports_order_allows_a_plane_drawing() -> None:
    # Two loops on one cross: north-east and south-west can be drawn without a
    # crossing; north-south and east-west cannot (each loop splits the plane, and
    # the other's ends lie on either side).
    assert embeds_in_plane(_loops([(0, 1), (2, 3)]))
    assert not embeds_in_plane(_loops([(0, 2), (1, 3)]))
    assert embeds_in_plane(_loops([(0, 2)]))  # the other ports not driven yet
    assert embeds_in_plane(TopoMap())


def test_a_map_that_cannot_be_drawn_in_the_plane_is_dropped() -> None:
    # Two twin crosses, 0 and 1. From 0 the robot drives a loop (out by port 0, back
    # by port 2), then leaves by port 1 and arrives by port 3 at a junction that may
    # be 0 (a second loop, crossing the first) or its twin 1. No port end is joined
    # twice either way, and there is no odometry: only planarity tells.
    exits = (0, 1, 2, 3)
    hyp = Hypotheses(TopoMap(), 8, 0.01)
    hyp.visit([Branch(0, None, exits)], CROSS_PORTS, None)
    hyp.new_traversal()
    hyp.visit([Branch(1, None, exits)], CROSS_PORTS, None)
    hyp.new_traversal()
    hyp.visit([Branch(0, None, exits)], None, None)
    hyp.depart(0)
    hyp.visit([Branch(0, 2, exits)], None, None)
    hyp.depart(1)
    # Best ranked first: 0, which would win a tie; planarity leaves only 1.
    hyp.visit([Branch(0, 3, exits), Branch(1, 3, exits)], None, None)
    assert len(hyp.live) == 1 and hyp.leader.map.visits[-1] == 1
    assert all(r.conflict is None for r in hyp.leader.map.visit_records)


def test_the_explorer_drives_an_exit_that_one_map_cannot_take(
    paper_sets: dict[str, PaperSet],
) -> None:
    # At the deferred revisit (A or B), exit 0 is A's right pipe in one map (to X's
    # back port) and B's right pipe in the other (to Z's): each far end is joined to
    # the other twin in the other map, so arriving either way drops a map. The plain
    # explorer takes the right-most untraversed port instead (port 0).
    loc, d = _run(LocalizerConfig(), paper_sets, back_to_x=False)
    plain = MapExplorer().step(loc.map, d[4], 0.0, 0.0, 4.5)
    told = MapExplorer(rivals=loc.hypothesis_exits).step(loc.map, d[4], 0.0, 0.0, 4.5)
    assert telling_exit(loc.hypothesis_exits()) == 0
    assert d[4].exit_ports is not None and told.port == d[4].exit_ports[0] != plain.port
    assert "cannot take" in told.notes[-1]
    # Driven (B's right pipe, 1 m, into Z as the first time): A's map would join Z's
    # pipe end twice. The revisit is settled as B, and the map is right.
    loc.depart(Y[0])
    arrived = loc.localize(paper_sets["10"].images, exits_rad=CROSS, odometer_m=5.5)
    assert arrived.node == 3 and arrived.settled == ((4, 2),)
    assert loc.map.visits == (0, 1, 2, 3, 2, 3) and loc.hypotheses_alive == 1
    assert all(v.conflict is None for v in loc.map.visit_records)
    # One map: nothing to tell apart.
    assert telling_exit(loc.hypothesis_exits()) is None


def _twin_through_a_joined_pipe(config: LocalizerConfig, paper_sets: dict[str, PaperSet]):  # type: ignore[no-untyped-def]
    """A, then X, then B: A's twin (the very same sweep), reached from X by a pipe
    not driven yet and entered through the pipe that, on A, leads to X. No dead
    reckoning at B (lost), so only the graph can tell it from A."""
    same, x = paper_sets["1"].images, paper_sets["4"].images
    loc = Localizer(config)
    d = [loc.localize(same, exits_rad=Y, odometer_m=0.0, position_m=(0.0, 0.0))]
    loc.depart(-math.pi / 3.0)  # A's right pipe, to X
    d.append(loc.localize(x, exits_rad=CROSS, odometer_m=1.0, position_m=(1.0, 0.0)))
    loc.depart(0.0)  # straight on: a pipe not driven yet
    # B is turned 120 degrees from A: the pipe behind the robot is, on A, A's right one.
    b = _turned(same, 2.0 * math.pi / 3.0)
    d.append(loc.localize(b, exits_rad=Y, odometer_m=2.0, position_m=None))
    return loc, d


def test_a_twin_entered_through_a_pipe_end_the_map_has_joined_is_new(
    paper_sets: dict[str, PaperSet],
) -> None:
    # B fits A's keypoints and ports, but the pipe it came in by is, on A, the pipe to
    # X: a pipe has two ends, and A's is taken. B is new, and the map is right.
    loc, d = _twin_through_a_joined_pipe(LocalizerConfig(), paper_sets)
    assert not d[2].known and d[2].node == 2
    assert [n for n, _ in d[2].rejected] == [0]
    assert "already leads to port" in d[2].rejected[0][1]
    assert loc.map.visits == (0, 1, 2)
    assert all(v.conflict is None for v in loc.map.visit_records)
    # With one map (the rule as before competing maps), B is merged into A, and the
    # map meets the conflict.
    one, d1 = _twin_through_a_joined_pipe(LocalizerConfig(hypotheses=1), paper_sets)
    assert d1[2].known and d1[2].node == 0
    assert one.map.visit_records[2].conflict is not None
