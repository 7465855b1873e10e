"""``pipemap replay`` and ``pipemap score``: a log through the localizer, and its score.

Both read the log's ``/robot`` messages only for the localizer; ``score`` also reads
``/truth`` to compare. A log cut short is replayed up to its last complete sweep,
with a warning, and exit 0; so is a damaged one, every sweep of its intact parts,
with a warning naming each damaged part and each sweep skipped. A wrong map is a
result, not an error: exit 0.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Collection
from pathlib import Path
from typing import Any, TextIO

from pipemap.cli.localizer_options import (
    fast_config,
    hypotheses,
    illumination_setting,
    odometry_check,
    port_check,
    rule_config,
    two_view_settings,
)
from pipemap.cli.outputs import output_file, output_folder, write_text
from pipemap.errors import InputError, WriteError
from pipemap.wholefile import partial_path, write_all

__all__ = [
    "localizer_config",
    "open_source",
    "progress_printer",
    "run_replay",
    "run_score",
]


def localizer_config(args: argparse.Namespace) -> Any:
    """The localizer's settings from ``--threshold``, ``--no-active-vision``,
    ``--rule``, ``--allow-repeat``, ``--no-verify``, ``--no-two-view``, ``--no-port-check``,
    ``--no-odometry-check`` and the
    similarity options (``--downsample``, ``--zoom``, ...)."""
    from pipemap.localizer import LocalizerConfig

    two_view, verify = two_view_settings(args)
    config = LocalizerConfig(
        threshold=args.threshold,
        active_vision=not args.no_active_vision,
        fast=fast_config(args),
        distinct_consecutive=not args.allow_repeat,
        two_view=two_view,
        verify=verify,
        port_check=port_check(args),
        odometry_check=odometry_check(args),
        hypotheses=hypotheses(args),
        lamp=illumination_setting(args),
    )
    return rule_config(args, config)


def open_source(
    args: argparse.Namespace, err: TextIO, topics: Collection[str] | None = None
) -> Any:
    """The log ``args.log`` as a replay source holding ``topics`` (default: every
    ``/robot`` and ``/truth`` topic), read whole; warns on ``err`` when it is cut or
    damaged."""
    from pipemap.replay import FileSource

    source = FileSource(Path(args.log), topics)
    report_damage(args.log, source.contents, err)
    return source


def report_damage(log: str, contents: Any, err: TextIO) -> None:
    """Warn on ``err`` when the log ``contents`` says was read is cut or damaged."""
    from pipemap.recorder import Integrity

    for damage in contents.damage:
        err.write(f"pipemap: warning: {log}: damaged {damage.describe()}\n")
    if contents.truncated:
        err.write(f"pipemap: warning: {log} is cut short: {contents.truncated}\n")
    if contents.integrity is not Integrity.OK:
        err.write(f"pipemap: warning: {log}: the sweeps its intact parts hold are replayed\n")


def progress_printer(err: TextIO) -> Any:
    """A replay progress callback that writes to ``err`` when it is a terminal, else ``None``."""
    if not err.isatty():
        return None

    def show(done: int, total: int | None) -> None:
        # The total is known once the whole log has been read.
        told = f"{done}/{total}" if total else f"{done}"
        err.write(f"\rreplaying: {told} visits ")
        if done == total:
            err.write("\n")
        err.flush()

    return show


def run_replay(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Replay a log and write its map document."""
    from pipemap import api
    from pipemap.localizer import dumps_document
    from pipemap.replay import REPLAY_TOPICS, StreamSource

    target = output_file(args.output, "-o", args.force)
    graphml = output_file(args.graphml, "--graphml", args.force)
    results_log = output_file(args.save_log, "--save-log", args.force)
    config = localizer_config(args)
    # Read as the replay goes: it holds the map, not the log.
    source = StreamSource(Path(args.log), REPLAY_TOPICS)
    recorded = not getattr(args, "threshold_given", True)
    result = api.replay(source, config, progress_printer(err), False, False, recorded)
    report_damage(args.log, source.contents, err)
    for warning in result.warnings:
        err.write(f"pipemap: note: {warning}\n")
    text = dumps_document(result.document())
    if target is None:
        out.write(text)
    else:
        write_text(target, text)
        out.write(
            f"replayed {args.log}: {len(result.visits)} visits, {result.topomap.used_node_count} "
            f"junctions, map written to {target}\n"
        )
    if results_log is not None:
        used = config if result.localizer is None else result.localizer.config
        api.save_results_log(result, results_log, used.threshold)
    if graphml is not None:
        import networkx as nx  # 0.09 s to import: only for GraphML

        try:
            with partial_path(graphml) as partial:
                nx.write_graphml(result.topomap.graph, partial)
        except OSError as exc:
            raise WriteError(f"{graphml}: cannot write ({exc.strerror or exc})") from None
    return 0


def run_score(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Replay each log, compare with its truth, print (and save) the scores: one
    report per log, in the order given (``--json``: one object, a list of them for
    several logs)."""
    from pipemap.replay import SCORE_TOPICS, StreamSource

    logs = list(args.log)
    folder = None
    if args.save_results is not None:
        if len(logs) > 1:
            raise InputError(
                f"--save-results {args.save_results}: takes one log's score, got {len(logs)} "
                "logs (score them one at a time)"
            )
        folder = output_folder(args.save_results, "--save-results", args.force)
    config = localizer_config(args)
    # Every log is opened before the first is replayed: a missing one is found first.
    sources = [StreamSource(Path(log), SCORE_TOPICS) for log in logs]
    pairs = zip(logs, sources, strict=True)
    recorded = not getattr(args, "threshold_given", True)
    reports = [_score_log(log, source, config, recorded, err) for log, source in pairs]
    if folder is not None:
        _save_results(folder, reports[0])
    if args.json:
        texts = [report.json_text() for report in reports]
        if len(texts) == 1:
            out.write(texts[0])
        else:
            out.write("[\n" + ",\n".join(t.rstrip("\n") for t in texts) + "\n]\n")
        return 0
    texts = [_report_text(log, report) for log, report in zip(logs, reports, strict=True)]
    out.write("\n".join(texts))
    return 0


def _save_results(folder: Path, report: Any) -> None:
    """``score.json`` and ``visits.csv`` in ``folder``, both or neither: a folder made
    here is removed again when they could not be written."""
    made = not folder.exists()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WriteError(f"{folder}: cannot make the folder ({exc.strerror})") from None
    files = {folder / "score.json": report.json_text(), folder / "visits.csv": report.csv_text()}
    try:
        write_all(files)
    except BaseException:
        if made:
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


def _score_log(log: str, source: Any, config: Any, recorded: bool, err: TextIO) -> Any:
    """The score report of one log (``recorded``: at the threshold it was recorded
    with), its damage and the replay's notes said on ``err``."""
    from pipemap import api

    report = api.score(source, config, progress_printer(err), recorded)
    report_damage(log, source.contents, err)
    for warning in report.replay_notes:
        err.write(f"pipemap: note: {warning}\n")
    for note in report.truth_notes:
        err.write(f"pipemap: warning: {log}: {note}\n")
    return report


def _report_text(log: str, report: Any) -> str:
    """``pipemap score``'s text report of one log."""
    doc = report.document()
    counts = doc["decisions"]
    sim = doc["similarity"]
    rot = doc["rotation_error_rad"]["known"]
    cov = doc["coverage"]
    status = {"correct": "correct", "partial": "partial", "wrong": "WRONG"}[doc["map"]]
    lines = [
        f"log         {log} ({doc['integrity']})",
        f"map         {status}: {doc['predicted_nodes']} junctions for {doc['true_nodes']} "
        f"true nodes visited, {doc['visits']} visits",
    ]
    if cov is not None:
        lines.append(
            f"coverage    {cov['nodes_visited']}/{cov['nodes_total']} nodes, "
            f"{cov['pipes_traversed']}/{cov['pipes_total']} pipes"
            + (
                f"; reachable past blocked pipes: {cov['reachable_nodes_visited']}/"
                f"{cov['reachable_nodes']} nodes, {cov['open_pipes_traversed']}/"
                f"{cov['open_pipes']} open pipes"
                if "reachable_nodes" in cov
                else ""
            )
        )
    blocked = doc.get("blocked")
    if blocked is not None:
        lines.append(
            f"blocked     {len(blocked['marked'])} marked for {len(blocked['truly_blocked'])} "
            f"truly blocked: {len(blocked['true_positives'])} right, "
            f"{len(blocked['false_blocked'])} false, {len(blocked['missed'])} missed"
            f" ({', '.join(blocked['marked']) or 'none marked'})"
        )
    if "look_alike" in doc:
        groups = doc["look_alike"]
        lines.append(
            f"look-alike  {sum(len(g) for g in groups)} junctions share {len(groups)} looks: "
            + "; ".join("=".join(g) for g in groups)
        )
    if "undecided" in doc:
        undecided = doc["undecided"]
        lines.append(
            f"undecided   {len(undecided['visits'])} visits recognised among junctions "
            f"nothing told apart: {undecided['right']} right, {undecided['wrong']} wrong "
            f"({', '.join(undecided['visits'])})"
        )
    if "deferred" in doc:
        deferred = doc["deferred"]
        lines.append(
            f"deferred    {len(deferred['visits'])} decisions kept open among look-alikes: "
            f"settled {deferred['right']} right, {deferred['wrong']} wrong, "
            f"{len(deferred['open'])} still open ({', '.join(deferred['visits'])})"
        )
    ports = {True: "correct", False: "WRONG", None: "none (no exits in the log)"}
    latency = doc["latency_ms"]
    lines += [
        f"ports       {ports[doc['ports_correct']]}",
        f"decisions   {counts['correct_known']} correct known, {counts['correct_new']} correct "
        f"new, {_count(counts['false_merge'], 'false merge')}, {counts['false_new']} false new",
        f"similarity  known {_stat(sim['known'])}; unknown {_stat(sim['unknown'])}",
        f"pairs       same junction {_stat(doc['pairs']['same'])}; different "
        f"{_stat(doc['pairs']['different'])}",
        f"rotation    error on correct known visits: mean {_num(rot['mean'])} rad, "
        f"max {_num(rot['max'])} rad (n={rot['n']})",
        f"latency     mean {_num(latency['mean'], 1)} ms, median {_num(latency['median'], 1)}"
        f", 95th percentile {_num(latency['p95'], 1)}, max {_num(latency['max'], 1)} ms "
        "per decision",
        "            of the mean: "
        + ", ".join(f"{k} {_num(t, 1)}" for k, t in latency["phases"].items())
        + " ms",
        "visit  true  node  known  similarity  margin    rotation  error      in  out  outcome",
    ]
    for v in doc["per_visit"]:
        lines.append(
            f"{v['visit']}   {v['true_node']:<4}  {v['predicted_node']:<4}  "
            f"{'yes' if v['known'] else 'no':<5}  {_num(v['similarity'], 3):<10}  "
            f"{_num(v['margin'], 3):<8}  {_num(v['rotation_rad']):<9}  "
            f"{_num(v['rotation_error_rad']):<9}  {_port(v['arrival_port']):<2}  "
            f"{_port(v['departure_port']):<3}  {v['outcome']}"
        )
    return "\n".join(lines) + "\n"


def _num(value: float | None, decimals: int = 4) -> str:
    """A number as the text outputs print it: similarities and margins to 3
    decimals, radians to 4, milliseconds to 1; ``-`` for none."""
    return "-" if value is None else f"{value:.{decimals}f}"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _port(value: int | None) -> str:
    return "-" if value is None else str(value)


def _stat(summary: dict[str, Any]) -> str:
    if not summary["n"]:
        return "none"
    sample = f" of {summary['of']}" if "of" in summary else ""
    return f"{summary['mean']:.3f} +- {summary['std']:.3f} (n={summary['n']}{sample})"
