"""Tests of :mod:`sim.plan`: the right-most-branch tour used as ground truth."""

from __future__ import annotations

import math

import networkx as nx
import pytest

from pipemap.errors import SimError
from pipemap.sim.network import Network, Node, Pipe, build_network, wrap_rad
from pipemap.sim.plan import TourEnd, Visit, right_hand_tour, right_most_exit, tour_edges

#: The right-hand rule on the paper network, from each start. From S the robot goes
#: north; at A the right-most exit is B (east); back at A heading west it turns right
#: (north) to C; at C heading north it turns right to D (east); back at C heading
#: west, right is F (north), straight on is E (west): so F comes before E.
PAPER_TOURS = {
    "S": "S A B A C D C F C E C A S",
    "A": "A B A C D C F C E C A S A",
    "B": "B A C D C F C E C A S A B",
    "C": "C D C F C E C A S A B A C",
    "D": "D C F C E C A S A B A C D",
    "E": "E C A S A B A C D C F C E",
    "F": "F C E C A S A B A C D C F",
}


@pytest.fixture(scope="module")
def paper() -> Network:
    return build_network("paper")


def _turn_rad(net: Network, came_from: str, node: str, exit_to: str) -> float:
    heads = net.pipe_headings(node)
    return wrap_rad(heads[exit_to] - wrap_rad(heads[came_from] + math.pi))


def test_turn_convention_at_the_cross(paper: Network) -> None:
    # Arriving at C from A (heading north): D is a right turn, F straight, E left.
    assert _turn_rad(paper, "A", "C", "D") == pytest.approx(-math.pi / 2)
    assert _turn_rad(paper, "A", "C", "F") == pytest.approx(0.0)
    assert _turn_rad(paper, "A", "C", "E") == pytest.approx(math.pi / 2)
    # Back from D (heading west): F (north) is the right turn, E straight on.
    assert _turn_rad(paper, "D", "C", "F") == pytest.approx(-math.pi / 2)
    assert _turn_rad(paper, "D", "C", "E") == pytest.approx(0.0)
    assert _turn_rad(paper, "D", "C", "A") == pytest.approx(math.pi / 2)


@pytest.mark.parametrize(
    ("node", "came_from", "expected"),
    [
        ("A", "S", "B"),
        ("A", "B", "C"),
        ("C", "A", "D"),
        ("C", "D", "F"),
        ("C", "F", "E"),
        ("C", "E", "A"),
        ("A", "C", "S"),
        ("B", "A", "A"),
        ("S", "A", "A"),
    ],
)
def test_right_most_exit(paper: Network, node: str, came_from: str, expected: str) -> None:
    assert right_most_exit(paper, node, came_from) == expected


def test_right_most_exit_needs_a_real_pipe(paper: Network) -> None:
    with pytest.raises(SimError, match="'B'.*'C'"):
        right_most_exit(paper, "C", "B")


def test_paper_tour_from_the_entry(paper: Network) -> None:
    tour = right_hand_tour(paper)
    assert " ".join(tour.nodes) == PAPER_TOURS["S"]
    assert tour.complete and tour.end is TourEnd.COMPLETE
    assert tour.visits[0] == Visit("S", None, "A")
    assert tour.visits[1] == Visit("A", "S", "B")
    assert tour.visits[-1] == Visit("S", "A", None)


@pytest.mark.parametrize("start", sorted(PAPER_TOURS))
def test_paper_tour_from_every_start(paper: Network, start: str) -> None:
    tour = right_hand_tour(paper, start=start)
    assert " ".join(tour.nodes) == PAPER_TOURS[start]
    assert tour.complete
    assert tour.covered_nodes == frozenset(paper.labels)
    assert tour.covered_pipes == {tuple(sorted((p.a, p.b))) for p in paper.pipes}
    # A tree walked once round: every pipe twice, once each way.
    assert len(tour.visits) == 2 * len(paper.pipes) + 1


def test_start_leaves_as_if_arrived_from_first_neighbour(paper: Network) -> None:
    # C's first neighbour by heading is A (south, -pi/2): it leaves as if come from A.
    assert paper.neighbours("C")[0] == "A"
    tour = right_hand_tour(paper, start="C")
    assert tour.visits[0] == Visit("C", None, right_most_exit(paper, "C", "A"))
    assert tour.visits[-1].arrived_from == "A"


def test_visits_are_consistent() -> None:
    for spec in ("paper", "grid:3x3", "random:12", "random:20"):
        net = build_network(spec, seed=3)
        tour = right_hand_tour(net)
        for prev, cur in zip(tour.visits, tour.visits[1:], strict=False):
            assert prev.leave_to == cur.node
            assert cur.arrived_from == prev.node
            assert cur.node in net.pipe_headings(prev.node)
            assert prev.leave_to == right_most_exit(
                net, prev.node, prev.arrived_from or net.neighbours(prev.node)[0]
            )


def test_tour_edges(paper: Network) -> None:
    assert tour_edges(right_hand_tour(paper)) == [
        ("S", "A"),
        ("A", "B"),
        ("A", "C"),
        ("C", "D"),
        ("C", "F"),
        ("C", "E"),
    ]
    assert tour_edges(right_hand_tour(paper, start="E"))[:2] == [("E", "C"), ("C", "A")]


def test_tree_12_tours_are_complete() -> None:
    for seed in range(50):
        net = build_network("tree:12", seed=seed)
        tour = right_hand_tour(net)
        assert tour.complete, f"tree:12 seed {seed}"
        assert tour.nodes[0] == tour.nodes[-1] == net.entry
        assert tour.covered_nodes == frozenset(net.labels)
        assert len(tour_edges(tour)) == len(net.pipes)
        assert len(tour.visits) == 2 * len(net.pipes) + 1


def test_grid_tour_follows_the_outer_wall() -> None:
    net = build_network("grid:3x3")
    tour = right_hand_tour(net)
    assert not tour.complete
    assert tour.end is TourEnd.REPEATED_STATE
    assert " ".join(tour.nodes) == "S r0c0 r0c1 r0c2 r1c2 r2c2 r2c1 r2c0 r1c0 r0c0 S"
    assert len(tour.covered_pipes) == 9 < len(net.pipes)
    assert "r1c1" not in tour.covered_nodes
    assert len(tour.covered_nodes) == 9


def test_grid_tour_from_the_centre_goes_round_one_cell() -> None:
    net = build_network("grid:3x3")
    tour = right_hand_tour(net, start="r1c1")
    assert tour.end is TourEnd.REPEATED_STATE
    assert tour.nodes[0] == tour.nodes[-1] == "r1c1"
    assert len(tour.covered_pipes) == 4


def test_random_tours_terminate_by_repeated_state_or_completion() -> None:
    for seed in range(10):
        net = build_network("random:15", seed=seed)
        tour = right_hand_tour(net)
        assert tour.end in (TourEnd.COMPLETE, TourEnd.REPEATED_STATE)
        assert tour.nodes[-1] == net.entry
        has_loop = bool(nx.cycle_basis(net.to_networkx()))
        # With a loop there is an inner face the outer walk never enters.
        assert tour.complete is not has_loop


def test_max_steps_stops_the_tour(paper: Network) -> None:
    tour = right_hand_tour(paper, max_steps=3)
    assert tour.end is TourEnd.MAX_STEPS and not tour.complete
    assert tour.nodes == ("S", "A", "B", "A")
    assert tour.visits[-1].leave_to is None
    assert right_hand_tour(paper, max_steps=0).nodes == ("S",)


def test_bad_start_or_max_steps(paper: Network) -> None:
    with pytest.raises(SimError, match="'Z'"):
        right_hand_tour(paper, start="Z")
    with pytest.raises(SimError, match="-1"):
        right_hand_tour(paper, max_steps=-1)


def test_two_node_network() -> None:
    net = Network((Node("S", 0, 0), Node("B", 1, 0)), (Pipe("S", "B"),), "S")
    tour = right_hand_tour(net)
    assert tour.nodes == ("S", "B", "S") and tour.complete
