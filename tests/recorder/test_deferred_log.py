"""Deferred and settled decisions in the log: the online localizer's
``/online/decision`` messages say when more than one map was alive, what a visit
may still be, and which later visit settled it, as the map document does; a replay
of the same visits makes the very same messages."""

from __future__ import annotations

from pathlib import Path

from pipemap.localizer import Decision, LocalizerConfig, map_document
from pipemap.recorder import LogWriter, read_log, schemas
from pipemap.recorder.messages import decision_message
from pipemap.recorder.topics import Topic
from tests.conftest import PaperSet
from tests.localizer.test_hypotheses import _run

THRESHOLD = 0.36


def _log(path: Path, decisions: list[Decision]) -> list[schemas.Decision]:
    """Write the decisions to a log as the recorder does (one message per visit)
    and read them back."""
    with path.open("wb") as f, LogWriter(f, {"pipemap_version": "test"}) as writer:
        for k, d in enumerate(decisions):
            t_ns = (k + 1) * 1_000_000_000
            writer.write(Topic.DECISION, t_ns, decision_message(t_ns, k, d, THRESHOLD))
    contents = read_log(path, keep=lambda topic: topic == Topic.DECISION)
    return [schemas.Decision.FromString(m.data) for m in contents.messages]


def _hypotheses(m: schemas.Decision) -> tuple[int, list[int], list[tuple[int, int]]]:
    alive = m.hypotheses if m.HasField("hypotheses") else 1
    return alive, list(m.deferred), [(s.visit, s.node) for s in m.settled]


def test_a_deferred_visit_and_its_settling_are_in_the_logged_decisions(
    tmp_path: Path, paper_sets: dict[str, PaperSet]
) -> None:
    # Two identical Y fittings; the robot comes back into one with no dead reckoning
    # (two maps: deferred), then a pipe only one map can join settles it.
    loc, decisions = _run(LocalizerConfig(), paper_sets, back_to_x=True)
    logged = _log(tmp_path / "online.mcap", decisions)
    assert [_hypotheses(m) for m in logged] == [
        (1, [], []),
        (1, [], []),
        (1, [], []),
        (1, [], []),
        (2, [2], []),  # decided as A (node 0), may be B
        (1, [], [(4, 2)]),
    ]
    # The log says what the map document says.
    doc = map_document(loc.map, [(str(i), d) for i, d in enumerate(decisions)], loc.open_visits)
    assert doc["visits"][4]["hypotheses"] == logged[4].hypotheses
    assert doc["visits"][4]["deferred"] == list(logged[4].deferred)
    assert doc["visits"][5]["settled"] == [
        {"visit": s.visit, "node": s.node} for s in logged[5].settled
    ]
    # A replay (a fresh localizer on the same visits) logs the same messages, byte
    # for byte: the deferral and the settling included.
    _, again = _run(LocalizerConfig(), paper_sets, back_to_x=True)
    replayed = _log(tmp_path / "replay.mcap", again)
    assert [m.SerializeToString() for m in replayed] == [m.SerializeToString() for m in logged]


def test_a_visit_left_open_is_logged_as_deferred_with_both_maps_alive(
    tmp_path: Path, paper_sets: dict[str, PaperSet]
) -> None:
    loc, decisions = _run(LocalizerConfig(), paper_sets, back_to_x=False)
    logged = _log(tmp_path / "online.mcap", decisions)
    assert _hypotheses(logged[-1]) == (2, list(decisions[-1].deferred), [])
    assert {logged[-1].node, *logged[-1].deferred} == set(loc.open_visits[4])


def test_a_decision_with_one_map_logs_no_hypothesis_fields(
    tmp_path: Path, paper_sets: dict[str, PaperSet]
) -> None:
    # With one map nothing is deferred: the messages carry none of the fields, so a
    # run that never branches logs the bytes it did before they existed.
    _, decisions = _run(LocalizerConfig(hypotheses=1), paper_sets, back_to_x=True)
    for m in _log(tmp_path / "one.mcap", decisions):
        assert not m.HasField("hypotheses") and not m.deferred and not m.settled
        fields = {f.name for f, _ in m.ListFields()}
        assert not fields & {"hypotheses", "deferred", "settled"}
