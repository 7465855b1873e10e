"""Tests of :mod:`localizer.topomap` (Algorithm 4) and the map document of
:mod:`localizer.mapjson`."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence

import pytest

from pipemap.localizer.localizer import Decision, ProbeKind, ProbeOutcome, ProbeRequest
from pipemap.localizer.mapjson import FLOAT_DECIMALS, decision_record, dumps_document, map_document
from pipemap.localizer.similarity import SetMatch
from pipemap.localizer.topomap import MapEdge, TopoMap
from pipemap.localizer.twoview import TwoViewFit

#: A tree explored depth first: S A B A C D C E C F C A S.
TREE_VISITS = (0, 1, 2, 1, 3, 4, 3, 5, 3, 6, 3, 1, 0)
TREE_EDGES = [
    MapEdge(0, 1, 1),  # S-A
    MapEdge(1, 2, 2),  # A-B
    MapEdge(1, 3, 3),  # A-C
    MapEdge(3, 4, 4),  # C-D
    MapEdge(3, 5, 5),  # C-E
    MapEdge(3, 6, 6),  # C-F
]


def _built(visits: Sequence[int]) -> TopoMap:
    m = TopoMap()
    for node in visits:
        m.visit(node)
    return m


# --- TopoMap.visit ------------------------------------------------------------------


def test_empty_map() -> None:
    m = TopoMap()
    assert m.node_count == 0
    assert m.visits == ()
    assert m.edges() == []
    assert m.to_dict() == {"nodes": [], "edges": []}


def test_first_visit_adds_node_zero_and_no_edge() -> None:
    m = TopoMap()
    assert m.visit(0) is None
    assert m.node_count == 1
    assert m.edges() == []
    assert m.visits == (0,)


def test_first_visit_must_be_node_zero() -> None:
    m = TopoMap()
    with pytest.raises(ValueError):
        m.visit(1)
    assert m.node_count == 0
    assert m.visits == ()


def test_nodes_are_numbered_in_first_visit_order() -> None:
    m = TopoMap()
    for expected_count, node in enumerate([0, 1, 2, 3], start=1):
        m.visit(node)
        assert m.node_count == expected_count
    assert sorted(m.graph.nodes) == [0, 1, 2, 3]


def test_consecutive_visits_add_labelled_edges_in_order() -> None:
    m = TopoMap()
    assert m.visit(0) is None
    assert m.visit(1) == MapEdge(0, 1, 1)
    assert m.visit(2) == MapEdge(1, 2, 2)
    assert m.visit(0) == MapEdge(2, 0, 3)  # a known node, but a new edge
    assert m.node_count == 3
    assert m.edges() == [MapEdge(0, 1, 1), MapEdge(1, 2, 2), MapEdge(2, 0, 3)]


def test_a_lost_visit_breaks_the_path_and_adds_no_edge() -> None:
    m = TopoMap()
    m.visit(0)
    m.visit(1)
    assert m.previous == 1
    m.new_traversal()  # the visit after 1 was lost: 2 need not be 1's neighbour
    assert m.previous is None
    assert m.visit(2) is None
    assert m.visit(0) == MapEdge(2, 0, 2)  # back on track: edges again
    assert [(e.u, e.v) for e in m.edges()] == [(0, 1), (2, 0)]
    assert m.visits == (0, 1, 2, 0)


def test_after_a_lost_visit_the_last_junction_may_be_recognised_again() -> None:
    """A pipe joins two different junctions, so a visit is never the junction it just
    left; but after a lost visit the robot may be back where it was."""
    from pipemap.localizer import Localizer, LocalizerConfig

    localizer = Localizer(LocalizerConfig(distinct_consecutive=True))
    localizer.map.visit(0)
    assert localizer._excluded() == 0
    localizer.map.new_traversal()
    assert localizer._excluded() is None


def test_retraversing_an_edge_forward_adds_nothing() -> None:
    m = _built([0, 1, 2])
    assert m.visit(1) is None  # 2 -> 1 is edge 1-2 backwards
    assert m.visit(2) is None  # and forwards again
    assert m.edges() == [MapEdge(0, 1, 1), MapEdge(1, 2, 2)]
    assert m.graph.number_of_edges() == 2


def test_retraversing_an_edge_backwards_adds_nothing() -> None:
    m = _built([0, 1])
    assert m.visit(0) is None
    assert m.visit(1) is None
    assert m.visit(0) is None
    assert m.edges() == [MapEdge(0, 1, 1)]
    assert m.visits == (0, 1, 0, 1, 0)


def test_labels_continue_after_retraversals() -> None:
    m = _built([0, 1, 0, 1])
    assert m.visit(2) == MapEdge(1, 2, 2)
    assert m.visit(0) == MapEdge(2, 0, 3)
    assert [e.label for e in m.edges()] == [1, 2, 3]


@pytest.mark.parametrize(
    "prefix,bad",
    [((0,), 2), ((0,), 5), ((0, 1, 2), 4), ((0, 1), -1), ((), 1), ((), -1)],
)
def test_node_neither_known_nor_next_raises(prefix: tuple[int, ...], bad: int) -> None:
    m = _built(prefix)
    before = (m.node_count, m.visits, m.edges())
    with pytest.raises(ValueError):
        m.visit(bad)
    assert (m.node_count, m.visits, m.edges()) == before  # nothing recorded


def test_next_new_node_is_accepted_after_known_revisits() -> None:
    m = _built([0, 1, 0])
    assert m.visit(2) == MapEdge(0, 2, 2)
    assert m.node_count == 3


def test_edges_keep_first_traversal_direction() -> None:
    # Edge 1-2 is first traversed 2 -> 1; edge 0-2 first traversed 0 -> 2.
    m = _built([0, 1, 0, 2, 1, 2, 0])
    assert m.edges() == [MapEdge(0, 1, 1), MapEdge(0, 2, 2), MapEdge(2, 1, 3)]


def test_edges_are_in_label_order_not_node_order() -> None:
    m = _built([0, 1, 2, 3, 0, 2])
    edges = m.edges()
    assert [e.label for e in edges] == [1, 2, 3, 4, 5]
    assert [(e.u, e.v) for e in edges] == [(0, 1), (1, 2), (2, 3), (3, 0), (0, 2)]


def test_graph_is_a_copy_with_labels() -> None:
    m = _built([0, 1, 2])
    g = m.graph
    # A multigraph keyed by label: two pipes may join the same two junctions.
    assert g.edges[0, 1, 1]["label"] == 1
    assert g.edges[2, 1, 2]["label"] == 2
    g.add_edge(0, 2, label=99)
    g.add_node(7)
    assert m.node_count == 3
    assert m.graph.number_of_edges() == 2


def test_visits_record_every_visit() -> None:
    m = _built(TREE_VISITS)
    assert m.visits == TREE_VISITS
    assert isinstance(m.visits, tuple)


def test_the_counts_and_last_visit_are_those_of_the_full_lists() -> None:
    m = TopoMap()
    assert (m.visit_count, m.last_visit, m.edge_count) == (0, None, 0)
    for k, node in enumerate(TREE_VISITS):
        m.visit(node)
        assert m.visit_count == len(m.visit_records) == k + 1
        assert m.last_visit == m.visit_records[-1] and m.last_visit.node == node
        assert m.edge_count == len(m.edges())


def test_tree_exploration() -> None:
    m = TopoMap()
    added = [m.visit(node) for node in TREE_VISITS]
    assert m.node_count == 7
    assert m.edges() == TREE_EDGES
    # New edges appear exactly when the robot first goes down a pipe.
    assert [e for e in added if e is not None] == TREE_EDGES
    assert [i for i, e in enumerate(added) if e is not None] == [1, 2, 4, 5, 7, 9]
    assert m.to_dict() == {
        "nodes": [{"id": i, "ports": []} for i in range(7)],
        "edges": [
            {"u": e.u, "u_port": None, "v": e.v, "v_port": None, "label": e.label, "length_m": None}
            for e in TREE_EDGES
        ],
    }


# --- to_dict / to_json --------------------------------------------------------------


def test_to_dict_structure() -> None:
    d = _built([0, 1, 2, 1]).to_dict()
    assert list(d) == ["nodes", "edges"]
    assert d["nodes"] == [{"id": 0, "ports": []}, {"id": 1, "ports": []}, {"id": 2, "ports": []}]
    assert [(e["u"], e["v"], e["label"]) for e in d["edges"]] == [(0, 1, 1), (1, 2, 2)]
    for node in d["nodes"]:
        assert list(node) == ["id", "ports"]
        assert type(node["id"]) is int
    for edge in d["edges"]:
        assert list(edge) == ["u", "u_port", "v", "v_port", "label", "length_m"]
        assert all(type(edge[k]) is int for k in ("u", "v", "label"))


def test_to_json_is_deterministic_and_parses() -> None:
    a = _built(TREE_VISITS).to_json()
    b = _built(TREE_VISITS).to_json()
    assert a.encode() == b.encode()
    assert a.endswith("\n")
    assert json.loads(a) == _built(TREE_VISITS).to_dict()


def test_to_json_differs_for_different_maps() -> None:
    assert _built([0, 1, 2]).to_json() != _built([0, 1, 0, 2]).to_json()


def test_to_json_of_empty_map() -> None:
    assert json.loads(TopoMap().to_json()) == {"nodes": [], "edges": []}


# --- map document -------------------------------------------------------------------


def _decision(
    node: int,
    known: bool,
    similarity: float,
    margin: float | None,
    match: SetMatch | None = None,
    probes: tuple[ProbeOutcome, ...] = (),
    candidate: int | None = None,
    two_view: TwoViewFit | None = None,
) -> Decision:
    return Decision(
        node=node,
        known=known,
        candidate=candidate,
        similarity=similarity,
        margin=margin,
        match=match,
        probes=probes,
        two_view=two_view,
    )


def _document_inputs() -> tuple[TopoMap, list[tuple[str, Decision]]]:
    m = _built([0, 1, 0])
    match = SetMatch(
        similarity=0.912345678,
        image_shift=3,
        pixel_shift=-1.23456789,
        rotation_rad=math.pi - 1e-9,
        rotation_pinhole_rad=-2.0000004,
    )
    visits = [
        ("set_a", _decision(0, False, 0.0, None)),
        (
            "set_b",
            _decision(
                1,
                False,
                0.1234567891,
                None,
                SetMatch(0.1234567891, 0, 0.0, 0.0, 0.0, refined=False),
                probes=(
                    ProbeOutcome(ProbeRequest(ProbeKind.ROTATE, yaw_rad=0.5), 0.2000000001, True),
                ),
                candidate=0,
            ),
        ),
        (
            "set_a_again",
            _decision(
                0,
                True,
                0.912345678,
                0.7888888888,
                match,
                probes=(
                    ProbeOutcome(ProbeRequest(ProbeKind.FORWARD, forward_m=0.03), None, False),
                ),
                candidate=0,
                two_view=TwoViewFit(3.1234567891, 0.5, inliers=250, matches=400, stages=1),
            ),
        ),
    ]
    return m, visits


def test_map_document_structure() -> None:
    m, visits = _document_inputs()
    doc = map_document(m, visits)
    assert list(doc) == ["nodes", "edges", "visits"]
    assert doc["nodes"] == m.to_dict()["nodes"]
    assert doc["edges"] == m.to_dict()["edges"]
    assert [v["set"] for v in doc["visits"]] == ["set_a", "set_b", "set_a_again"]
    first, second, third = doc["visits"]
    assert first == {
        "set": "set_a",
        "node": 0,
        "known": False,
        "similarity": None,  # no candidate: nothing was compared
        "margin": None,
        "candidate": None,
        "image_shift": None,
        "pixel_shift": None,
        "rotation_rad": None,
        "rotation_pinhole_rad": None,
        "rotation_two_view_rad": None,
        "two_view_inliers": None,
        "two_view_stages": None,
        "probes": [],
        "exits_rad": None,
        "exit_ports": None,
        "arrival_port": None,
        "departure_port": None,
        "port_residual_rad": None,
        "rejected": [],
        "conflict": None,
    }
    assert second["probes"] == [{"kind": "rotate", "similarity": 0.2, "improved": True}]
    assert third["probes"] == [{"kind": "forward", "similarity": None, "improved": False}]
    assert third["known"] is True
    assert third["image_shift"] == 3
    assert third["candidate"] == 0


def test_document_floats_are_rounded_to_six_decimals() -> None:
    assert FLOAT_DECIMALS == 6
    m, visits = _document_inputs()
    third = map_document(m, visits)["visits"][2]
    assert third["similarity"] == 0.912346
    assert third["margin"] == 0.788889
    assert third["pixel_shift"] == -1.234568
    assert third["rotation_rad"] == round(math.pi, 6)
    assert third["rotation_pinhole_rad"] == -2.0
    assert third["rotation_two_view_rad"] == 3.123457
    assert third["two_view_inliers"] == 250
    assert third["two_view_stages"] == 1  # a fit of the first quarter alone
    text = dumps_document(map_document(m, visits))
    assert "0.912346" in text
    assert "0.912345678" not in text
    assert "0.7888888888" not in text


def test_decision_record_equals_document_visit() -> None:
    m, visits = _document_inputs()
    doc = map_document(m, visits)
    for (label, decision), record in zip(visits, doc["visits"], strict=True):
        assert decision_record(label, decision) == record


def test_dumps_document_is_deterministic() -> None:
    m1, v1 = _document_inputs()
    m2, v2 = _document_inputs()
    t1 = dumps_document(map_document(m1, v1))
    t2 = dumps_document(map_document(m2, v2))
    assert t1.encode() == t2.encode()
    assert t1.endswith("\n")
    assert json.loads(t1) == map_document(m1, v1)
    # Two-space indentation, key order as built.
    assert t1.startswith('{\n  "nodes": [')
    assert t1.index('"nodes"') < t1.index('"edges"') < t1.index('"visits"')


@pytest.mark.parametrize("tiny", [-1e-9, -4.9e-7, -0.0, 1e-12 * -1.0])
def test_document_never_emits_negative_zero(tiny: float) -> None:
    match = SetMatch(
        similarity=tiny,
        image_shift=0,
        pixel_shift=tiny,
        rotation_rad=tiny,
        rotation_pinhole_rad=tiny,
    )
    d = _decision(0, False, tiny, tiny, match, candidate=0)
    record = decision_record("x", d)
    for key in ("similarity", "margin", "pixel_shift", "rotation_rad", "rotation_pinhole_rad"):
        assert record[key] == 0.0
        assert math.copysign(1.0, record[key]) == 1.0, key
    text = dumps_document(map_document(_built([0]), [("x", d)]))
    assert "-0.0" not in text
    assert "-0" not in text


def test_small_negative_values_keep_their_sign_when_not_zero() -> None:
    d = _decision(1, False, -0.25, -1e-6, candidate=0)
    record = decision_record("x", d)
    assert record["similarity"] == -0.25
    assert record["margin"] == -1e-6


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_dumps_document_rejects_non_finite(bad: float) -> None:
    d = _decision(1, False, bad, None, candidate=0)
    doc = map_document(_built([0, 1]), [("x", d)])
    with pytest.raises(ValueError):
        dumps_document(doc)


def test_dumps_document_rejects_nan_in_margin_and_probes() -> None:
    with pytest.raises(ValueError):
        dumps_document(map_document(_built([0]), [("x", _decision(0, False, 0.5, math.nan))]))
    probe = ProbeOutcome(ProbeRequest(ProbeKind.LEFT, left_m=0.03), math.nan, False)
    d = _decision(0, False, 0.5, None, probes=(probe,))
    with pytest.raises(ValueError):
        dumps_document(map_document(_built([0]), [("x", d)]))


# --- ports ----------------------------------------------------------------------------

#: Port angles of a T (behind, left, right) and of a dead end.
TEE = (math.pi, math.pi / 2, -math.pi / 2)
DEAD_END = (math.pi,)


def _ported() -> TopoMap:
    """S (dead end) -> A (T, in by port 0) -> B (dead end) -> back to A by port 2."""
    m = TopoMap()
    m.visit(0, DEAD_END, None, 0.0)
    m.depart(0)
    m.visit(1, TEE, 0, 1.5)
    m.depart(2)
    m.visit(2, DEAD_END, 0, 2.6)
    m.depart(0)
    m.visit(1, None, 2, 3.7)
    return m


def test_edges_join_ports_and_carry_the_driven_length() -> None:
    m = _ported()
    assert m.edges() == [
        MapEdge(0, 1, 1, u_port=0, v_port=0, length_m=1.5),
        MapEdge(1, 2, 2, u_port=2, v_port=0, length_m=pytest.approx(1.1)),  # type: ignore[arg-type]
    ]
    assert m.ports(1) == TEE
    assert m.edge_at(1, 2) == m.edges()[1]
    assert m.edge_at(1, 1) is None
    assert m.has_ports


def test_untraversed_ports_are_those_never_arrived_or_left_by() -> None:
    m = _ported()
    assert m.untraversed(0) == []
    assert m.untraversed(1) == [1]
    assert m.untraversed(2) == []
    assert [(v.node, v.arrival_port, v.departure_port) for v in m.visit_records] == [
        (0, None, 0),
        (1, 0, 2),
        (2, 0, 0),
        (1, 2, None),
    ]


def test_two_pipes_between_the_same_junctions_are_two_edges() -> None:
    m = TopoMap()
    m.visit(0, TEE)
    m.depart(1)
    m.visit(1, TEE, 0)
    m.depart(2)
    added = m.visit(0, None, 2)
    assert added is not None and (added.u_port, added.v_port) == (2, 2)
    assert len(m.edges()) == 2
    assert m.graph.number_of_edges() == 2


def test_a_pipe_end_joined_elsewhere_is_a_conflict_and_adds_no_edge() -> None:
    m = _ported()
    m.depart(1)
    m.visit(3, DEAD_END, 0)  # a new junction 3 beyond A's port 1
    m.depart(0)
    # Back at A, but by port 2, which already leads to B; and 3's only pipe leads to
    # A's port 1: the map says otherwise at both ends. The first end is named.
    assert m.visit(1, None, 2) is None
    conflict = m.visit_records[-1].conflict
    assert conflict == "port 0 of node 3 already leads to port 1 of node 1, not to port 2 of node 1"
    assert len(m.edges()) == 3


def test_ports_are_checked() -> None:
    m = TopoMap()
    m.visit(0, DEAD_END)
    with pytest.raises(ValueError, match="no port 1"):
        m.depart(1)
    with pytest.raises(ValueError, match="no port 3"):
        m.visit(1, TEE, 3)
    with pytest.raises(ValueError, match="no visit"):
        TopoMap().depart(0)


def test_a_new_traversal_joins_nothing_to_the_last_visit() -> None:
    m = _ported()
    assert m.previous == 1
    m.new_traversal()
    assert m.previous is None
    assert m.visit(0) is None
    assert len(m.edges()) == 2


def test_ports_in_the_document_and_from_it() -> None:
    m = _ported()
    d = m.to_dict()
    assert d["nodes"][1] == {
        "id": 1,
        "ports": [
            {"port": 0, "angle_rad": round(math.pi, 6)},
            {"port": 1, "angle_rad": round(math.pi / 2, 6)},
            {"port": 2, "angle_rad": round(-math.pi / 2, 6)},
        ],
    }
    assert d["edges"][0] == {
        "u": 0,
        "u_port": 0,
        "v": 1,
        "v_port": 0,
        "label": 1,
        "length_m": 1.5,
    }
    loaded = TopoMap.from_dict(json.loads(m.to_json()))
    assert loaded.to_dict() == d
    assert loaded.has_ports
    assert loaded.untraversed(1) == [0, 1, 2]  # a loaded map has no traversals


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.pop("edges"), "no list of nodes"),
        (lambda d: d["nodes"].reverse(), "in id order"),
        (lambda d: d["nodes"][1]["ports"].pop(0), "port 0 is not"),
        (lambda d: d["nodes"][1]["ports"][0].update(angle_rad="x"), "port 0 is not"),
        (lambda d: d["edges"][0].update(v=9), "names node 9"),
        (lambda d: d["edges"][0].update(v_port=5), "has no port 5"),
        (lambda d: d["edges"][1].update(u_port=0), "joined twice"),
        (lambda d: d["edges"][0].update(label="one"), "label"),
        (lambda d: d["edges"][0].update(length_m=-1), "length_m"),
        (lambda d: d["edges"].append(dict(d["edges"][0])), "joined twice"),
    ],
)
def test_a_malformed_document_is_refused_with_the_reason(change, message: str) -> None:  # type: ignore[no-untyped-def]
    d = json.loads(_ported().to_json())
    change(d)
    with pytest.raises(ValueError, match=message):
        TopoMap.from_dict(d)


def test_not_a_document_is_refused() -> None:
    for bad in ([], "map", {"nodes": {}, "edges": []}):
        with pytest.raises(ValueError, match="map document"):
            TopoMap.from_dict(bad)


def _left_by_a_blocked_pipe() -> TopoMap:
    """Junction 0 (three pipes) left by port 1, which was given up; then port 2."""
    m = TopoMap()
    m.visit(0, (math.pi, 1.0, -1.0))
    m.depart(1)
    assert m.block() == 1
    m.depart(2)
    m.visit(1, (math.pi,), arrival_port=0)
    return m


def test_a_blocked_port_is_neither_untraversed_nor_joined() -> None:
    m = _left_by_a_blocked_pipe()
    assert m.blocked(0) == [1] and m.is_blocked(0, 1) and not m.is_blocked(0, 2)
    assert m.untraversed(0) == [0]  # 1 blocked, 2 driven
    assert [(e.u, e.u_port, e.v, e.v_port) for e in m.edges()] == [(0, 2, 1, 0)]
    assert m.visit_records[0].departure_port == 2


def test_blocking_an_unknown_departure_marks_nothing() -> None:
    m = TopoMap()
    m.visit(0, (math.pi, 1.0))
    m.depart(None)
    assert m.block() is None and m.blocked(0) == []
    with pytest.raises(ValueError, match="no visit"):
        TopoMap().block()


def test_blocked_ports_are_in_the_json_and_the_graph_and_read_back() -> None:
    m = _left_by_a_blocked_pipe()
    doc = m.to_dict()
    assert doc["nodes"][0]["ports"][1] == {"port": 1, "angle_rad": 1.0, "blocked": True}
    assert "blocked" not in doc["nodes"][0]["ports"][2]
    assert TopoMap.from_dict(json.loads(m.to_json())).blocked(0) == [1]
    assert m.graph.nodes[0]["blocked"] == "1" and "blocked" not in m.graph.nodes[1]


def test_a_map_without_blocked_ports_says_nothing_of_them() -> None:
    m = TopoMap()
    m.visit(0, (math.pi, 1.0))
    assert "blocked" not in m.to_json()


def test_a_bad_blocked_value_is_refused() -> None:
    doc = _left_by_a_blocked_pipe().to_dict()
    doc["nodes"][0]["ports"][1]["blocked"] = "yes"
    with pytest.raises(ValueError, match="blocked"):
        TopoMap.from_dict(doc)


def test_a_pooled_id_past_the_next_leaves_the_ids_between_unused() -> None:
    m = TopoMap()
    m.visit(0, (0.0, 3.1))
    m.depart(1)
    m.visit(2, (0.0, 2.0, -2.0), 0, pooled=True)
    assert m.node_count == 3
    assert m.used_node_count == 2
    assert m.unused(1) and not m.unused(2)
    assert sorted(m.graph.nodes) == [0, 2]
    assert m.has_ports
    doc = m.to_dict()
    assert doc["nodes"][1] == {"id": 1, "unused": True, "ports": []}
    again = TopoMap.from_dict(doc)
    assert again.to_json() == m.to_json()
    assert again.unused(1)
    with pytest.raises(ValueError):
        m.visit(1)  # an unused id only as a pooled one
    m.visit(1, (0.0,), pooled=True)
    assert not m.unused(1)
    assert m.ports(1) == (0.0,)
    assert m.used_node_count == 3


def test_a_document_that_joins_an_unused_id_is_refused() -> None:
    doc = {
        "nodes": [{"id": 0, "ports": [{"port": 0, "angle_rad": 0.0}]}, {"id": 1, "unused": True}],
        "edges": [{"u": 0, "u_port": 0, "v": 1, "v_port": None, "label": 1}],
    }
    with pytest.raises(ValueError, match="does not have"):
        TopoMap.from_dict(doc)


def test_a_copy_grows_apart_from_its_original() -> None:
    m = TopoMap()
    m.visit(0, (0.0, 3.0))
    m.depart(1)
    twin = m.copy()
    assert twin.to_json() == m.to_json() and twin.visits == m.visits
    twin.visit(2, (0.0, 2.0, -2.0), 0, 1.0, pooled=True)
    twin.block()
    assert m.node_count == 1 and m.visits == (0,) and m.edges() == []
    assert m.untraversed(0) == [0] and twin.unused(1) and not m.blocked(0)
    m.visit(1, (1.0,), 0)
    assert twin.visits == (0, 2) and twin.ports(1) is None
