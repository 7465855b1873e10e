"""Scoring a replay against the log's ground truth.

Per visit: the true node (from ``/truth/sweep``), the predicted node, similarity,
margin, known or new, and the rotation estimate with its error against the true
heading change. Counts of correct and wrong decisions, whether the map is the
true network, how much of it the run covered and whether the map's ports are the
true pipe ends (:mod:`replay.coverage`), and the paper's Table 1 (similarity of
visits to known and to unknown junctions) and Table 2 (rotation error).

The map is ``correct`` when it is the true graph of the visited nodes under the
visit correspondence *and* the run visited every true node and drove every true
pipe; ``partial`` when it is right as far as it goes but the run missed some;
``wrong`` otherwise.

A decision is:

* ``correct_known``: declared known, and the junction it names is the true one;
* ``correct_new``: declared new, and the junction was not visited before;
* ``false_merge``: declared known, but the junction it names is another one, or
  the junction is new;
* ``false_new``: declared new, but the junction was visited before (a duplicate).
"""

from __future__ import annotations

import csv
import io
import json
import statistics
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from google.protobuf.message import DecodeError

from pipemap.errors import LogFormatError
from pipemap.localizer import (
    PHASES,
    FastConfig,
    LocalizerConfig,
    TopoMap,
    wrap_angle_rad,
)
from pipemap.recorder import Integrity, Topic
from pipemap.recorder.schemas import TrueSweep
from pipemap.replay.coverage import (
    BlockedPipes,
    Coverage,
    blocked_of,
    coverage_of,
    ports_correct,
    true_network,
)
from pipemap.replay.latency import latency_summary, phase_means
from pipemap.replay.pairs import PairStatistics, pair_statistics
from pipemap.replay.pairs import rounded as _round
from pipemap.replay.pairs import summary as _summary
from pipemap.replay.replayer import (
    REPLAY_TOPICS,
    ReplayResult,
    replay,
    takes_recorded_threshold,
    visit_label,
)
from pipemap.replay.source import MessageSource

__all__ = [
    "SCORE_TOPICS",
    "PairStatistics",
    "ScoreReport",
    "VisitScore",
    "latency_summary",
    "look_alike_groups",
    "phase_means",
    "pair_statistics",
    "score",
    "score_replay",
    "true_sweeps",
]


@dataclass(frozen=True)
class VisitScore:
    """One visit, predicted and true."""

    visit: str
    true_node: str
    predicted_node: int
    known: bool
    outcome: str
    #: ``None`` when the visit had no candidate (nothing to compare with).
    similarity: float | None
    margin: float | None
    candidate: int | None
    rotation_rad: float | None
    true_rotation_rad: float | None
    rotation_error_rad: float | None
    latency_ms: float
    arrival_port: int | None = None
    departure_port: int | None = None
    #: ``latency_ms`` by phase (:data:`localizer.phases.PHASES`); ``None`` untimed.
    ncc_ms: float | None = None
    keypoints_ms: float | None = None
    check_ms: float | None = None
    map_ms: float | None = None


@dataclass(frozen=True)
class ScoreReport:
    """The score of one replay."""

    log: str
    integrity: str
    threshold: float
    visits: tuple[VisitScore, ...]
    map_correct: bool
    true_nodes: int
    predicted_nodes: int
    pairs: PairStatistics
    #: ``None`` when the log holds no true network.
    coverage: Coverage | None = None
    #: ``None`` when the map has no ports.
    ports_correct: bool | None = None
    #: The map is right as far as the run went (``map_correct`` needs coverage too).
    mapped_part_correct: bool = False
    #: Blocked pipes, marked and true; ``None`` when the truth has no deposit and the
    #: map marks nothing blocked.
    blocked: BlockedPipes | None = None
    #: What of the truth could not be read (a line each); not part of the document.
    truth_notes: tuple[str, ...] = ()
    #: The replay's notes (:attr:`ReplayResult.warnings`); not part of the document.
    replay_notes: tuple[str, ...] = ()
    #: The true junctions that share a look (``record --alike``), each group's look's
    #: own junction first; empty when every junction looks like itself alone.
    look_alike: tuple[tuple[str, ...], ...] = ()
    #: The visits whose decision named other junctions as alike (``Decision.alike``):
    #: recognised as the best ranked of junctions nothing told apart.
    alike_visits: tuple[str, ...] = ()
    #: The visits whose decision was deferred: the localizer kept a map for each
    #: junction it might be (``Decision.deferred``); scored by the map's final node.
    deferred_visits: tuple[str, ...] = ()
    #: Of those, the ones still open when the run ended (nothing told them apart).
    open_visits: tuple[str, ...] = ()

    @property
    def map_status(self) -> str:
        """``correct``, ``partial`` (right as far as the run went) or ``wrong``."""
        if self.map_correct:
            return "correct"
        return "partial" if self.mapped_part_correct else "wrong"

    def counts(self) -> dict[str, int]:
        """Decisions by outcome."""
        names = ("correct_known", "correct_new", "false_merge", "false_new")
        return {n: sum(1 for v in self.visits if v.outcome == n) for n in names}

    def _undecided(self) -> dict[str, Any]:
        """The decisions made among junctions nothing told apart, and how they went."""
        outcomes = {v.visit: v.outcome for v in self.visits}
        # Right as the final map has it: one settled later as a new junction, rightly, is.
        right = sum(outcomes.get(v) in ("correct_known", "correct_new") for v in self.alike_visits)
        return {
            "visits": list(self.alike_visits),
            "right": right,
            "wrong": len(self.alike_visits) - right,
        }

    def _deferred(self) -> dict[str, Any]:
        """The deferred decisions: how the settled ones went, and those left open."""
        outcomes = {v.visit: v.outcome for v in self.visits}
        settled = [v for v in self.deferred_visits if v not in self.open_visits]
        right = sum(outcomes.get(v) in ("correct_known", "correct_new") for v in settled)
        return {
            "visits": list(self.deferred_visits),
            "right": right,
            "wrong": len(settled) - right,
            "open": list(self.open_visits),
        }

    def document(self, with_latency: bool = True) -> dict[str, Any]:
        """The JSON document of ``pipemap score --json``. Everything but the latency
        is deterministic; ``with_latency=False`` leaves it out (for comparisons)."""
        seen: set[str] = set()
        known_sims: list[float] = []
        unknown_sims: list[float] = []
        for v in self.visits:
            # A visit without a candidate had nothing to compare with: the first, and
            # the second, which cannot be the junction it came from.
            if v.similarity is None:
                pass
            elif v.true_node in seen:
                known_sims.append(v.similarity)
            else:
                unknown_sims.append(v.similarity)
            seen.add(v.true_node)
        errors = [
            abs(v.rotation_error_rad) for v in self.visits if v.rotation_error_rad is not None
        ]
        doc: dict[str, Any] = {
            "log": self.log,
            "integrity": self.integrity,
            "threshold": self.threshold,
            "map_correct": self.map_correct,
            "map": self.map_status,
            "coverage": None if self.coverage is None else self.coverage.document(),
            "ports_correct": self.ports_correct,
            **({} if self.blocked is None else {"blocked": self.blocked.document()}),
            **({"look_alike": [list(g) for g in self.look_alike]} if self.look_alike else {}),
            **({"undecided": self._undecided()} if self.alike_visits else {}),
            **({"deferred": self._deferred()} if self.deferred_visits else {}),
            "visits": len(self.visits),
            "true_nodes": self.true_nodes,
            "predicted_nodes": self.predicted_nodes,
            "decisions": self.counts(),
            "similarity": {"known": _summary(known_sims), "unknown": _summary(unknown_sims)},
            "pairs": self.pairs.document(),
            "rotation_error_rad": {
                "known": {
                    "mean": _round(statistics.fmean(errors)) if errors else None,
                    "max": _round(max(errors)) if errors else None,
                    "n": len(errors),
                }
            },
            "per_visit": [
                {
                    "visit": v.visit,
                    "true_node": v.true_node,
                    "predicted_node": v.predicted_node,
                    "known": v.known,
                    "outcome": v.outcome,
                    "similarity": _round(v.similarity),
                    "margin": _round(v.margin),
                    "candidate": v.candidate,
                    "rotation_rad": _round(v.rotation_rad),
                    "true_rotation_rad": _round(v.true_rotation_rad),
                    "rotation_error_rad": _round(v.rotation_error_rad),
                    "arrival_port": v.arrival_port,
                    "departure_port": v.departure_port,
                }
                for v in self.visits
            ],
        }
        if with_latency:
            phases = [{p: getattr(v, f"{p}_ms") for p in PHASES} for v in self.visits]
            latency = [v.latency_ms for v in self.visits]
            doc["latency_ms"] = {**latency_summary(latency), "phases": phase_means(phases)}
        return doc

    def csv_text(self) -> str:
        """One row per visit, like evo's result tables."""
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        fields = list(VisitScore.__dataclass_fields__)
        writer.writerow(fields)
        for v in self.visits:
            row = []
            for name in fields:
                value = getattr(v, name)
                row.append(_round(value) if isinstance(value, float) else value)
            writer.writerow(["" if x is None else x for x in row])
        return out.getvalue()

    def json_text(self, with_latency: bool = True) -> str:
        """Deterministic JSON text of :meth:`document` (latency aside)."""
        return json.dumps(self.document(with_latency), indent=2, allow_nan=False) + "\n"


def true_sweeps(source: MessageSource, problems: list[str] | None = None) -> dict[int, TrueSweep]:
    """The truth of every sweep of the log (``/truth/sweep``), by sweep id; how many
    do not decode is added to ``problems``."""
    truths = {}
    lost = 0
    for m in source.truth():
        if m.topic == Topic.TRUE_SWEEP:
            try:
                t = TrueSweep.FromString(m.data)
            except DecodeError:
                lost += 1  # unreadable: that sweep's truth is lost, as if damaged
                continue
            truths[t.sweep_id] = t
    if lost and problems is not None:
        problems.append(
            f"{lost} {Topic.TRUE_SWEEP} message(s) do not decode: their sweeps' truth is lost"
        )
    if not truths:
        raise LogFormatError(f"{source.name}: no ground truth (/truth/sweep) to score against")
    return truths


#: The topics a score reads: the replay's and the truth of sweeps and of the network.
SCORE_TOPICS = (*REPLAY_TOPICS, Topic.TRUE_SWEEP, Topic.NETWORK)


def _map_correct(predicted: list[int], true: list[str], breaks: set[int] | None = None) -> bool:
    """The predicted map is the true one under the visit correspondence: the same
    visits to the same junctions (one map node per true node), so the same edges in
    the same order. ``breaks`` are the visits before which the path is broken (a
    visit was lost); the true map is then built with the same gaps."""
    breaks = breaks or set()
    to_true: dict[int, str] = {}
    to_predicted: dict[str, int] = {}
    for p, t in zip(predicted, true, strict=True):
        if to_true.setdefault(p, t) != t or to_predicted.setdefault(t, p) != p:
            return False
    order = {label: i for i, label in enumerate(dict.fromkeys(true))}
    true_map = TopoMap()
    for i, t in enumerate(true):
        if i in breaks:
            true_map.new_traversal()
        true_map.visit(order[t])
    first = {node: i for i, node in enumerate(dict.fromkeys(predicted))}
    predicted_map = TopoMap()
    for i, p in enumerate(predicted):
        if i in breaks:
            predicted_map.new_traversal()
        predicted_map.visit(first[p])
    relabel = {first[p]: order[t] for p, t in to_true.items()}
    mapped = [(relabel[e.u], relabel[e.v], e.label) for e in predicted_map.edges()]
    return mapped == [(e.u, e.v, e.label) for e in true_map.edges()]


def score_replay(
    result: ReplayResult,
    source: MessageSource,
    threshold: float,
    fast: FastConfig | None = None,
) -> ScoreReport:
    """Compare a replay's decisions with the log's truth; ``fast`` is the matcher's
    configuration for the pair statistics (the replay's own, by default)."""
    truth_notes: list[str] = []
    truths = true_sweeps(source, truth_notes) if result.visits else {}
    created: dict[int, tuple[str, float]] = {}  # map node -> (true label, true heading)
    seen: set[str] = set()
    visits: list[VisitScore] = []
    breaks: list[int] = []  # positions in ``visits`` where the path is broken
    records = result.topomap.visit_records
    met: set[int] = set()  # the map's nodes of the visits so far
    for index, v in enumerate(result.visits):
        if index in result.breaks:
            breaks.append(len(visits))
        truth = truths.get(v.sweep_id)
        # The map's node for the visit: a deferred decision is scored as settled.
        node = records[index].node if index < len(records) else v.decision.node
        # Known as the map has it: a visit decided known may have settled as new.
        known = node in met if index < len(records) else v.decision.known
        met.add(node)
        unknown = known and node not in created
        if truth is None or unknown:
            if source.integrity is Integrity.OK and not truth_notes and truth is None:
                raise LogFormatError(f"{source.name}: no ground truth for sweep {v.sweep_id}")
            if unknown and truth is not None:
                result.warnings.append(
                    f"{source.name}: visit {visit_label(v.visit_id)} revisits a junction "
                    "whose first visit is not scored; it is not scored either"
                )
                breaks.append(len(visits))
                continue
            # Its truth was in a damaged part: the visit cannot be scored.
            result.warnings.append(
                f"{source.name}: the truth of sweep {v.sweep_id} (visit {v.visit_id}) is "
                "lost; that visit is not scored"
            )
            breaks.append(len(visits))
            continue
        d = v.decision
        heading = truth.yaw_rad - _camera_angle(result, v.sweep_id)
        if known:
            right = created[node][0] == truth.node and truth.node in seen
            outcome = "correct_known" if right else "false_merge"
        else:
            outcome = "false_new" if truth.node in seen else "correct_new"
            created[node] = (truth.node, heading)
        seen.add(truth.node)
        estimate = true_turn = error = None
        if d.match is not None and d.candidate is not None:
            estimate = d.rotation_rad
            if outcome == "correct_known" and estimate is not None and d.candidate in created:
                # Rotation from this visit's heading to the candidate junction's stored sweep.
                true_turn = wrap_angle_rad(created[d.candidate][1] - heading)
                error = wrap_angle_rad(estimate - true_turn)
        visits.append(
            VisitScore(
                visit=visit_label(v.visit_id),
                true_node=truth.node,
                predicted_node=node,
                known=known,
                outcome=outcome,
                similarity=None if d.candidate is None else d.similarity,
                margin=d.margin,
                candidate=d.candidate,
                rotation_rad=estimate,
                true_rotation_rad=true_turn,
                rotation_error_rad=error,
                latency_ms=1000.0 * v.latency_s,
                **{f"{k}_ms": 1000.0 * t for k, t in v.phases_s.items()},
                arrival_port=d.arrival_port,
                departure_port=records[index].departure_port if index < len(records) else None,
            )
        )
    predicted = [v.predicted_node for v in visits]
    true = [v.true_node for v in visits]
    mapped = bool(visits) and _map_correct(predicted, true, set(breaks))
    network = true_network(source, truth_notes)
    if network is None and truth_notes and Topic.NETWORK in truth_notes[-1]:
        truth_notes[-1] += ": coverage, ports and blocked pipes are not scored"
    coverage = None if network is None else coverage_of(network, true)
    ports = None
    if network is not None:
        ports = ports_correct(result.topomap, network, created)
    complete = coverage is None or coverage.complete
    blocked = None
    marks = any(result.topomap.blocked(n) for n in range(result.topomap.node_count))
    if network is not None and (network.deposits or marks):
        blocked = blocked_of(result.topomap, network, created, true[0] if true else None)
        # A blocked pipe cannot be mapped: the map is correct when every reachable
        # node and open pipe is, and it marks exactly the reachable blocked pipes.
        complete = complete and blocked.correct
    return ScoreReport(
        log=source.name,
        integrity=result.integrity.value,
        threshold=threshold,
        visits=tuple(visits),
        map_correct=mapped and complete,
        true_nodes=len(set(true)),
        predicted_nodes=result.topomap.used_node_count,
        pairs=pair_statistics(result, truths, fast),
        coverage=coverage,
        ports_correct=ports,
        mapped_part_correct=mapped,
        blocked=blocked,
        truth_notes=tuple(truth_notes),
        replay_notes=tuple(result.warnings),
        look_alike=look_alike_groups(source.run_metadata()),
        alike_visits=tuple(visit_label(v.visit_id) for v in result.visits if v.decision.alike),
        deferred_visits=tuple(
            visit_label(v.visit_id) for v in result.visits if v.decision.deferred
        ),
        open_visits=_open_visits(result),
    )


def _open_visits(result: ReplayResult) -> tuple[str, ...]:
    """The visits the localizer's maps still disagree on at the end of the replay."""
    if result.localizer is None:
        return ()
    open_ = result.localizer.open_visits
    return tuple(visit_label(v.visit_id) for i, v in enumerate(result.visits) if i in open_)


def look_alike_groups(run: dict[str, str]) -> tuple[tuple[str, ...], ...]:
    """The groups of true junctions that share a look, from the run metadata's
    simulator settings (``record --alike``); none when it names none."""
    try:
        simulator = json.loads(run.get("simulator", "{}"))
    except ValueError:
        return ()
    alike = simulator.get("alike") if isinstance(simulator, dict) else None
    groups = alike.get("groups") if isinstance(alike, dict) else None
    if not isinstance(groups, list):
        return ()
    return tuple(
        tuple(str(label) for label in g) for g in groups if isinstance(g, list) and len(g) > 1
    )


def _camera_angle(result: ReplayResult, sweep_id: int) -> float:
    return result.camera_angles.get(sweep_id, 0.0)


def score(
    source: MessageSource,
    config: LocalizerConfig | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    recorded_threshold: bool | None = None,
) -> ScoreReport:
    """Replay ``source`` and score the result against its truth; ``progress`` and
    ``recorded_threshold`` as :func:`replay` takes them."""
    recorded = takes_recorded_threshold(recorded_threshold, config)
    config = config if config is not None else LocalizerConfig()
    result = replay(source, config, progress, keep_sets=False, recorded_threshold=recorded)
    used = config if result.localizer is None else result.localizer.config
    return score_replay(result, source, used.threshold, config.fast)
