"""Tests of :mod:`sim.network`: presets, node kinds, validation, seeded generation."""

from __future__ import annotations

import math
import time
from collections import Counter

import networkx as nx
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipemap.errors import SimError
from pipemap.sim.network import (
    Network,
    Node,
    NodeKind,
    Pipe,
    build_network,
    point_segment_distance_m,
    segments_touch,
    wrap_rad,
)

EXPECTED_PAPER_KINDS = {
    "S": NodeKind.ENTRY,
    "A": NodeKind.TEE,
    "B": NodeKind.DEAD_END,
    "C": NodeKind.CROSS,
    "D": NodeKind.DEAD_END,
    "E": NodeKind.DEAD_END,
    "F": NodeKind.DEAD_END,
}


def _net(
    spots: dict[str, tuple[float, float]] | list[tuple[str, float, float]],
    links: list[str],
    entry: str = "S",
    diameter_m: float = 0.2,
) -> Network:
    """A network from ``{label: (x, y)}`` (or a list, to allow duplicates) and ``["A-B"]``."""
    items = spots if isinstance(spots, list) else [(k, x, y) for k, (x, y) in spots.items()]
    nodes = tuple(Node(k, x, y) for k, x, y in items)
    pipes = tuple(Pipe(*link.split("-")) for link in links)
    return Network(nodes, pipes, entry=entry, diameter_m=diameter_m)


# A valid corner: S south of A, B east of A.
CORNER = {"S": (0.0, 0.0), "A": (0.0, 1.0), "B": (1.0, 1.0)}


def _raises(match: str, *args: object, **kwargs: object) -> str:
    with pytest.raises(SimError, match=match) as info:
        _net(*args, **kwargs)  # type: ignore[arg-type]
    return str(info.value)


# ---- presets -------------------------------------------------------------------


def test_paper_layout_and_kinds() -> None:
    net = build_network("paper")
    assert net.labels == ("S", "A", "B", "C", "D", "E", "F")
    assert net.entry == "S"
    assert {net.kind(label) for label in net.labels} == set(EXPECTED_PAPER_KINDS.values())
    assert {label: net.kind(label) for label in net.labels} == EXPECTED_PAPER_KINDS
    assert {frozenset((p.a, p.b)) for p in net.pipes} == {
        frozenset(s) for s in ("SA", "AB", "AC", "CD", "CE", "CF")
    }
    assert net.node("E") == Node("E", -1.2, 3.0)
    assert net.diameter_m == 0.2


def test_paper_headings_and_neighbour_order() -> None:
    net = build_network("paper")
    heads = net.pipe_headings("A")
    assert heads == pytest.approx({"S": -math.pi / 2, "B": 0.0, "C": math.pi / 2})
    # West is +pi, never -pi: headings live in (-pi, pi].
    assert net.pipe_headings("C")["E"] == math.pi
    assert net.neighbours("A") == ("S", "B", "C")
    assert net.neighbours("C") == ("A", "D", "F", "E")
    assert net.neighbours("B") == ("A",)


def test_paper_lengths_bounds_and_graph() -> None:
    net = build_network("paper")
    assert net.length_m("S", "A") == pytest.approx(1.5)
    assert net.length_m("C", "E") == pytest.approx(1.2)
    assert net.length_m("E", "C") == pytest.approx(1.2)
    assert net.bounds_m() == pytest.approx((-1.2, 0.0, 1.0, 4.0))
    g = net.to_networkx()
    assert list(g.nodes) == list(net.labels)
    assert g.nodes["D"]["pos"] == (0.75, 3.0)
    assert g.edges["C", "D"]["length_m"] == pytest.approx(0.75)
    assert nx.is_tree(g)


def test_unknown_label_and_missing_pipe_raise() -> None:
    net = build_network("paper")
    with pytest.raises(SimError, match="'Z'"):
        net.node("Z")
    with pytest.raises(SimError, match="'Z'"):
        net.kind("Z")
    with pytest.raises(SimError, match="'B'.*'C'"):
        net.length_m("B", "C")


def test_grid_kinds() -> None:
    net = build_network("grid:3x4", spacing_m=1.5)
    assert net.entry == "S"
    assert net.node("S") == Node("S", 0.0, -1.5)
    assert net.node("r2c3") == Node("r2c3", 4.5, 3.0)
    assert len(net.labels) == 3 * 4 + 1
    assert len(net.pipes) == 1 + 3 * 3 + 2 * 4
    kinds = {label: net.kind(label) for label in net.labels}
    assert kinds["S"] is NodeKind.ENTRY
    assert kinds["r0c0"] is NodeKind.TEE
    assert [kinds[c] for c in ("r0c3", "r2c0", "r2c3")] == [NodeKind.CORNER] * 3
    assert [kinds[c] for c in ("r0c1", "r0c2", "r1c0", "r1c3", "r2c1", "r2c2")] == [
        NodeKind.TEE
    ] * 6
    assert [kinds[c] for c in ("r1c1", "r1c2")] == [NodeKind.CROSS] * 2
    assert len(nx.cycle_basis(net.to_networkx())) == (3 - 1) * (4 - 1)


def test_grid_2x2_is_a_loop_with_the_entry() -> None:
    net = build_network("grid:2x2")
    assert net.kind("r0c0") is NodeKind.TEE
    assert [net.kind(c) for c in ("r0c1", "r1c0", "r1c1")] == [NodeKind.CORNER] * 3


BAD_SPECS = "nope grid grid:3 grid:1x3 grid:3x1 grid:axb random:2 random:x tree:1 tree: paper:2"


@pytest.mark.parametrize("spec", ["", "random:-5", *BAD_SPECS.split()])
def test_bad_spec_names_the_spec(spec: str) -> None:
    with pytest.raises(SimError) as info:
        build_network(spec)
    assert repr(spec) in str(info.value)


def test_bad_spacing_names_the_spec() -> None:
    with pytest.raises(SimError, match="'grid:2x2'"):
        build_network("grid:2x2", spacing_m=0.0)
    with pytest.raises(SimError, match="shorter than"):
        build_network("grid:2x2", spacing_m=0.5)


# ---- validation: one rule per test ------------------------------------------------


def test_valid_corner_builds() -> None:
    net = _net(CORNER, ["S-A", "A-B"])
    assert net.kind("A") is NodeKind.CORNER
    assert net.kind("B") is NodeKind.DEAD_END


def test_duplicate_label() -> None:
    spots = [("S", 0.0, 0.0), ("A", 0.0, 1.0), ("A", 1.0, 1.0)]
    assert "'A'" in _raises("duplicate node label", spots, ["S-A"])


def test_pipe_to_unknown_node() -> None:
    msg = _raises("unknown node", CORNER, ["S-A", "A-Z"])
    assert "A-Z" in msg and "'Z'" in msg


def test_pipe_to_itself() -> None:
    assert "A-A" in _raises("to itself", CORNER, ["S-A", "A-B", "A-A"])


def test_duplicate_pipe_either_way() -> None:
    assert "B-A" in _raises("duplicate pipe", CORNER, ["S-A", "A-B", "B-A"])
    assert "A-B" in _raises("duplicate pipe", CORNER, ["S-A", "A-B", "A-B"])


def test_pipe_shorter_than_three_diameters() -> None:
    spots = {"S": (0.0, 0.0), "A": (0.0, 1.0), "B": (0.5, 1.0)}
    assert "A-B" in _raises("shorter than 3 diameters", spots, ["S-A", "A-B"])
    # Exactly three diameters is long enough.
    spots["B"] = (0.6, 1.0)
    assert _net(spots, ["S-A", "A-B"]).length_m("A", "B") == pytest.approx(0.6)


def test_crossing_pipes() -> None:
    spots = {
        "S": (0.0, 0.0),
        "A": (0.0, 2.0),
        "B": (3.0, 2.0),
        "C": (3.0, 5.0),
        "D": (0.0, 5.0),
        "E": (1.5, 0.5),
    }
    msg = _raises("cross or touch", spots, ["S-A", "A-B", "B-C", "C-D", "D-E"])
    assert "A-B" in msg and "D-E" in msg


def test_collinear_overlapping_pipes() -> None:
    spots = {
        "S": (0.0, -1.0),
        "A": (0.0, 0.0),
        "B": (3.0, 0.0),
        "C": (3.0, 3.0),
        "G": (8.0, 3.0),
        "E": (8.0, 0.0),
        "D": (1.0, 0.0),
    }
    msg = _raises("cross or touch", spots, ["S-A", "A-B", "B-C", "C-G", "G-E", "E-D"])
    assert "A-B" in msg and "E-D" in msg


def test_node_on_another_pipe() -> None:
    spots = {
        "S": (0.0, -1.0),
        "A": (0.0, 0.0),
        "B": (3.0, 0.0),
        "C": (0.0, 3.0),
        "Y": (1.5, 3.0),
        "X": (1.5, 0.15),
    }
    msg = _raises("from pipe", spots, ["S-A", "A-B", "A-C", "C-Y", "Y-X"])
    assert "'X'" in msg and "A-B" in msg
    spots["X"] = (1.5, 0.25)
    assert _net(spots, ["S-A", "A-B", "A-C", "C-Y", "Y-X"]).kind("X") is NodeKind.DEAD_END


def test_pipes_at_the_same_angle() -> None:
    spots = {"S": (0.0, -1.0), "A": (0.0, 0.0), "B": (2.0, 0.0), "C": (1.0, 0.0)}
    msg = _raises("degrees apart", spots, ["S-A", "A-B", "A-C"])
    assert "'A'" in msg and "'B'" in msg and "'C'" in msg and "0.0 degrees" in msg


def test_pipes_closer_than_60_degrees() -> None:
    spots = {"S": (0.0, 0.0), "A": (0.0, 1.0), "B": (1.0, 0.0)}
    msg = _raises("degrees apart", spots, ["S-A", "A-B"])
    assert "'A'" in msg and "45.0 degrees" in msg
    # 60 degrees exactly is buildable.
    spots["B"] = (math.sin(math.radians(60.0)), 1.0 - math.cos(math.radians(60.0)))
    assert _net(spots, ["S-A", "A-B"]).kind("A") is NodeKind.CORNER


def test_node_without_pipe() -> None:
    spots = {**CORNER, "Z": (5.0, 5.0)}
    assert "'Z'" in _raises("no pipe", spots, ["S-A", "A-B"])


def test_node_with_more_than_four_pipes() -> None:
    spots = {"A": (0.0, 0.0)}
    links = []
    for i, label in enumerate(("S", "B", "C", "D", "E")):
        angle = -math.pi / 2 + i * 2 * math.pi / 5
        spots[label] = (math.cos(angle), math.sin(angle))
        links.append(f"A-{label}")
    assert "'A'" in _raises("5 pipes", spots, links)


@pytest.mark.parametrize("x_m", [0.0, 0.02])
def test_straight_corner_is_not_a_node(x_m: float) -> None:
    spots = {"S": (0.0, 0.0), "A": (0.0, 1.0), "B": (x_m, 2.5)}
    assert "'A'" in _raises("collinear", spots, ["S-A", "A-B"])


def test_two_degree_bend_is_a_corner() -> None:
    spots = {"S": (0.0, 0.0), "A": (0.0, 1.0), "B": (1.5 * math.sin(math.radians(2)), 2.5)}
    assert _net(spots, ["S-A", "A-B"]).kind("A") is NodeKind.CORNER


def test_entry_not_a_node() -> None:
    assert "'Q'" in _raises("not a node", CORNER, ["S-A", "A-B"], entry="Q")


def test_entry_with_more_than_one_pipe() -> None:
    assert "'A'" in _raises("2 pipes", CORNER, ["S-A", "A-B"], entry="A")


def test_disconnected_network() -> None:
    spots = {**CORNER, "X": (5.0, 0.0), "Y": (5.0, 2.0)}
    msg = _raises("disconnected", spots, ["S-A", "A-B", "X-Y"])
    assert "'X'" in msg


@pytest.mark.parametrize("diameter_m", [0.0, -0.2, math.nan])
def test_bad_diameter(diameter_m: float) -> None:
    assert str(diameter_m) in _raises("diameter", CORNER, ["S-A", "A-B"], diameter_m=diameter_m)


def test_geometry_helpers() -> None:
    assert segments_touch((0, 0), (2, 2), (0, 2), (2, 0))
    assert segments_touch((0, 0), (2, 0), (1, 0), (3, 0))  # collinear overlap
    assert segments_touch((0, 0), (2, 0), (2, 0), (2, 3))  # end on end
    assert not segments_touch((0, 0), (1, 0), (2, 0), (3, 0))  # collinear, apart
    assert not segments_touch((0, 0), (2, 0), (0, 0.1), (2, 0.1))  # parallel
    assert point_segment_distance_m((1, 1), (0, 0), (2, 0)) == pytest.approx(1.0)
    assert point_segment_distance_m((3, 0), (0, 0), (2, 0)) == pytest.approx(1.0)
    assert wrap_rad(-math.pi) == math.pi
    assert wrap_rad(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


def test_lists_are_stored_as_tuples_and_networks_hash() -> None:
    net = Network([Node("S", 0, 0), Node("A", 0, 1)], [Pipe("S", "A")], "S")  # type: ignore[arg-type]
    assert isinstance(net.nodes, tuple) and isinstance(net.pipes, tuple)
    assert hash(net) == hash(Network(net.nodes, net.pipes, "S"))


# ---- seeded random networks ------------------------------------------------------


@pytest.mark.parametrize("spec", ["random:12", "tree:12", "random:5", "grid:3x3", "paper"])
def test_same_spec_and_seed_give_equal_networks(spec: str) -> None:
    assert build_network(spec, seed=7) == build_network(spec, seed=7)


def test_different_seeds_give_different_networks() -> None:
    assert build_network("random:12", seed=1) != build_network("random:12", seed=2)
    assert build_network("tree:12", seed=1) != build_network("tree:12", seed=2)


def _revalidated(net: Network) -> Network:
    return Network(net.nodes, net.pipes, net.entry, net.diameter_m)


@pytest.mark.parametrize("n", [3, 4, 5, 8, 12, 20, 30])
def test_random_networks_are_valid(n: int) -> None:
    for seed in range(8):
        net = build_network(f"random:{n}", seed=seed)
        assert _revalidated(net) == net
        assert len(net.labels) == n
        assert net.kind(net.entry) is NodeKind.ENTRY
        cycles = nx.cycle_basis(net.to_networkx())
        if n >= 5:
            assert cycles, f"random:{n} seed {seed} has no loop"


def test_random_networks_mix_node_kinds_and_angles() -> None:
    kinds: Counter[NodeKind] = Counter()
    off_axis = 0
    for seed in range(20):
        net = build_network("random:12", seed=seed)
        kinds.update(net.kind(label) for label in net.labels)
        for label in net.labels:
            for h in net.pipe_headings(label).values():
                quarter = h / (math.pi / 2)
                off_axis += abs(quarter - round(quarter)) > 0.05
    assert set(kinds) == set(NodeKind)
    assert kinds[NodeKind.ENTRY] == 20
    assert off_axis > 100


def test_random_network_scale_follows_spacing() -> None:
    small = build_network("random:12", seed=3)
    large = build_network("random:12", seed=3, spacing_m=2.0)
    lengths = [small.length_m(p.a, p.b) for p in small.pipes]
    lengths_large = [large.length_m(p.a, p.b) for p in large.pipes]
    assert sum(lengths_large) / len(lengths_large) > 1.4 * sum(lengths) / len(lengths)


@pytest.mark.parametrize("n", [2, 5, 12, 30])
def test_tree_networks_have_no_loop(n: int) -> None:
    for seed in range(5):
        net = build_network(f"tree:{n}", seed=seed)
        assert len(net.labels) == n
        assert nx.is_tree(net.to_networkx())


def test_fifty_tree_12_networks() -> None:
    nets = [build_network("tree:12", seed=k) for k in range(50)]
    for net in nets:
        assert nx.is_tree(net.to_networkx())
        assert net.kind(net.entry) is NodeKind.ENTRY
    assert len(set(nets)) == 50


def test_random_30_is_fast() -> None:
    worst_s = 0.0
    for seed in range(5):
        t0 = time.perf_counter()
        build_network("random:30", seed=seed)
        worst_s = max(worst_s, time.perf_counter() - t0)
    assert worst_s < 1.0


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(5, 16))
def test_any_seed_gives_a_valid_looped_network(seed: int, n: int) -> None:
    net = build_network(f"random:{n}", seed=seed)
    assert _revalidated(net) == net
    assert nx.cycle_basis(net.to_networkx())
