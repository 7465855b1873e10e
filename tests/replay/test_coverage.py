"""Coverage and port correctness against the truth (:mod:`replay.coverage`), and the
score's map verdict: correct, partial or wrong."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from pipemap.localizer import TopoMap, clockwise_ports
from pipemap.replay import FileSource, replay, score_replay
from pipemap.replay.coverage import TrueNetwork, coverage_of, ports_correct, true_network

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"

#: S - A - B in a line north, C east of A: A is a T.
NETWORK = TrueNetwork(
    {"S": (0.0, 0.0), "A": (0.0, 1.0), "B": (0.0, 2.0), "C": (1.0, 1.0)},
    frozenset({("A", "S"), ("A", "B"), ("A", "C")}),
)


def test_coverage_counts_true_nodes_and_driven_pipes() -> None:
    cov = coverage_of(NETWORK, ["S", "A", "B", "A", "?"])
    assert cov.document() == {
        "nodes_visited": 3,
        "nodes_total": 4,
        "pipes_traversed": 2,
        "pipes_total": 3,
    }
    assert not cov.complete
    assert coverage_of(NETWORK, list("SABACAS")).complete
    assert NETWORK.total_length_m() == pytest.approx(3.0)


def _map(a_ports: tuple[float, ...], edge_ports: tuple[int, int]) -> TopoMap:
    """S (the robot facing away from its pipe) then A (heading north), joined
    S:0 - A:``edge_ports``."""
    m = TopoMap()
    m.visit(0, clockwise_ports([math.pi])[0])
    m.depart(0)
    m.visit(1, a_ports, edge_ports[1])
    return m


def test_ports_are_right_when_they_are_the_true_pipes_and_edges_join_them() -> None:
    north = math.pi / 2
    created = {0: ("S", -north), 1: ("A", north)}
    tee = clockwise_ports([math.pi, 0.0, -math.pi / 2])[0]  # S behind, B ahead, C right
    assert ports_correct(_map(tee, (0, 0)), NETWORK, created) is True
    # The edge from S arrives by A's port 1 (the pipe to B): wrong end.
    assert ports_correct(_map(tee, (0, 1)), NETWORK, created) is False
    # A corner's ports for a T.
    corner = clockwise_ports([math.pi, 0.0])[0]
    assert ports_correct(_map(corner, (0, 0)), NETWORK, created) is False
    # A pipe 40 degrees off.
    bent = clockwise_ports([math.pi, 0.7, -math.pi / 2])[0]
    assert ports_correct(_map(bent, (0, 0)), NETWORK, created) is False
    # No ports at all: nothing to say.
    m = TopoMap()
    m.visit(0)
    assert ports_correct(m, NETWORK, {0: ("S", north)}) is None


def test_a_stored_log_reads_its_network_and_scores_it() -> None:
    source = FileSource(RECORDINGS / "random8_loops.mcap")
    network = true_network(source)
    assert network is not None and len(network.positions) == 8 and len(network.pipes) == 8
    report = score_replay(replay(source), source, 0.36)
    assert report.map_status == "correct" and report.ports_correct is True
    doc = report.document(with_latency=False)
    assert doc["coverage"] == {
        "nodes_visited": 8,
        "nodes_total": 8,
        "pipes_traversed": 8,
        "pipes_total": 8,
    }
    assert list(doc)[:7] == [
        "log",
        "integrity",
        "threshold",
        "map_correct",
        "map",
        "coverage",
        "ports_correct",
    ]
    assert doc["per_visit"][1]["arrival_port"] == 0
    assert doc["per_visit"][0]["departure_port"] == 0


def test_a_right_map_of_part_of_the_network_is_partial(tmp_path: Path) -> None:
    from dataclasses import replace

    source = FileSource(RECORDINGS / "random8_loops.mcap")
    report = score_replay(replay(source), source, 0.36)
    assert report.coverage is not None
    short = replace(report, map_correct=False, coverage=replace(report.coverage, pipes_total=9))
    assert short.map_status == "partial"
    assert short.document()["map"] == "partial"
    wrong = replace(short, mapped_part_correct=False)
    assert wrong.map_status == "wrong"
    json.dumps(wrong.document())


#: NETWORK with a blocking deposit between A and C and a passable one between A and B.
BLOCKED = TrueNetwork(
    NETWORK.positions, NETWORK.pipes, ((("A", "C"), "blocking"), (("A", "B"), "passable"))
)


def test_a_truly_blocked_pipe_and_what_lies_behind_it_are_not_missed() -> None:
    assert BLOCKED.blocked_pipes == {("A", "C")}
    assert BLOCKED.reachable("S") == {"S", "A", "B"}
    cov = coverage_of(BLOCKED, list("SABAS"))
    assert cov.complete  # C is reachable only through the blocked pipe
    assert cov.document()["reachable_nodes"] == 3 and cov.document()["open_pipes"] == 2
    assert not coverage_of(BLOCKED, list("SAS")).complete  # A-B is open
    assert not coverage_of(NETWORK, list("SABAS")).complete  # without the deposit


def _tee_with_marks(*blocked_ports: int) -> TopoMap:
    """S then A (a T, ports: 0 to S, 1 to B, 2 to C) with ``blocked_ports`` given up."""
    m = _map(clockwise_ports([math.pi, 0.0, -math.pi / 2])[0], (0, 0))
    for port in blocked_ports:
        m.depart(port)
        m.block()
    return m


def test_blocked_marks_are_scored_against_the_truth() -> None:
    from pipemap.replay.coverage import blocked_of

    north = math.pi / 2
    created = {0: ("S", -north), 1: ("A", north)}
    right = blocked_of(_tee_with_marks(2), BLOCKED, created, "S")
    assert (right.true_positives, right.false_blocked, right.missed) == ([("A", "C")], [], [])
    assert right.correct
    assert right.document()["marked"] == ["A-C"]
    wrong = blocked_of(_tee_with_marks(1), BLOCKED, created, "S")  # gave up the passable one
    assert (wrong.true_positives, wrong.false_blocked, wrong.missed) == (
        [],
        [("A", "B")],
        [("A", "C")],
    )
    assert not wrong.correct
    # Truly blocked but never reached (the run started behind nothing): not missed.
    far = blocked_of(_tee_with_marks(), BLOCKED, {}, "C")
    assert far.missed == [("A", "C")]  # C's own pipe is the blocked one: reachable
    unreachable = TrueNetwork(
        {**NETWORK.positions, "D": (2.0, 1.0)},
        NETWORK.pipes | {("C", "D")},
        ((("A", "C"), "blocking"), (("C", "D"), "blocking")),
    )
    assert blocked_of(_tee_with_marks(2), unreachable, created, "S").missed == []
