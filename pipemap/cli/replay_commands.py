"""``pipemap replay`` and ``pipemap score``: a log through the localizer, and its score.

Both read the log's ``/robot`` messages only for the localizer; ``score`` also reads
``/truth`` to compare. A log cut short is replayed up to its last complete sweep,
with a warning, and exit 0. A wrong map is a result, not an error: exit 0.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, TextIO

from pipemap.cli.parser import fast_config, port_check, two_view_settings
from pipemap.errors import InputError

__all__ = [
    "check_output",
    "localizer_config",
    "open_source",
    "progress_printer",
    "run_replay",
    "run_score",
]


def localizer_config(args: argparse.Namespace) -> Any:
    """The localizer's settings from ``--threshold``, ``--no-active-vision``,
    ``--allow-repeat``, ``--no-verify``, ``--no-two-view``, ``--no-port-check`` and the
    similarity options (``--downsample``, ``--zoom``, ...)."""
    from pipemap.localizer import LocalizerConfig

    two_view, verify = two_view_settings(args)
    return LocalizerConfig(
        threshold=args.threshold,
        active_vision=not args.no_active_vision,
        fast=fast_config(args),
        distinct_consecutive=not args.allow_repeat,
        two_view=two_view,
        verify=verify,
        port_check=port_check(args),
    )


def open_source(args: argparse.Namespace, err: TextIO) -> Any:
    """The log ``args.log`` as a replay source; warns on ``err`` when it is cut or damaged."""
    from pipemap.recorder import Integrity
    from pipemap.replay import FileSource

    source = FileSource(Path(args.log))
    if source.integrity is Integrity.TRUNCATED:
        err.write(
            f"pipemap: warning: {args.log} is cut short ({source.problem}); "
            "replaying its complete part\n"
        )
    elif source.integrity is Integrity.CORRUPT:
        err.write(
            f"pipemap: warning: {args.log} is damaged ({source.problem}); "
            "replaying what came before the damage\n"
        )
    return source


def progress_printer(err: TextIO) -> Any:
    """A replay progress callback that writes to ``err`` when it is a terminal, else ``None``."""
    if not err.isatty():
        return None

    def show(done: int, total: int) -> None:
        err.write(f"\rreplaying: {done}/{total} visits ")
        if done == total:
            err.write("\n")
        err.flush()

    return show


def check_output(path: str | None, force: bool) -> Path | None:
    """``path`` as a file that may be written (refused if it exists, unless ``force``)."""
    if path is None:
        return None
    target = Path(path)
    if target.is_dir():
        raise InputError(f"{target}: is a folder, not a file")
    if not target.parent.is_dir():
        raise InputError(f"{target}: folder {target.parent} does not exist")
    if target.exists() and not force:
        raise InputError(f"{target}: exists; refusing to overwrite without --force")
    return target


def run_replay(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Replay a log and write its map document."""
    from pipemap.localizer import dumps_document
    from pipemap.replay import replay

    target = check_output(args.output, args.force)
    graphml = check_output(args.graphml, args.force)
    config = localizer_config(args)
    source = open_source(args, err)
    result = replay(source, config, progress_printer(err))
    for warning in result.warnings:
        err.write(f"pipemap: note: {warning}\n")
    text = dumps_document(result.document())
    if target is None:
        out.write(text)
    else:
        target.write_text(text)
        out.write(
            f"replayed {args.log}: {len(result.visits)} visits, {result.topomap.node_count} "
            f"junctions, map written to {target}\n"
        )
    if graphml is not None:
        import networkx as nx  # 0.09 s to import: only for GraphML

        nx.write_graphml(result.topomap.graph, graphml)
    return 0


def run_score(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Replay a log, compare with its truth, print (and save) the score."""
    from pipemap.replay import replay, score_replay

    folder = None
    if args.save_results is not None:
        folder = Path(args.save_results)
        if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
            raise InputError(f"{folder}: exists and is not an empty folder; refusing to overwrite")
    config = localizer_config(args)
    source = open_source(args, err)
    result = replay(source, config, progress_printer(err))
    report = score_replay(result, source, config.threshold, config.fast)
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "score.json").write_text(report.json_text())
        (folder / "visits.csv").write_text(report.csv_text())
    if args.json:
        out.write(report.json_text())
        return 0
    doc = report.document()
    counts = doc["decisions"]
    sim = doc["similarity"]
    rot = doc["rotation_error_rad"]["known"]
    cov = doc["coverage"]
    status = {"correct": "correct", "partial": "partial", "wrong": "WRONG"}[doc["map"]]
    lines = [
        f"log         {args.log} ({doc['integrity']})",
        f"map         {status}: {doc['predicted_nodes']} junctions for {doc['true_nodes']} "
        f"true nodes visited, {doc['visits']} visits",
    ]
    if cov is not None:
        lines.append(
            f"coverage    {cov['nodes_visited']}/{cov['nodes_total']} nodes, "
            f"{cov['pipes_traversed']}/{cov['pipes_total']} pipes"
        )
    ports = {True: "correct", False: "WRONG", None: "none (no exits in the log)"}
    lines += [
        f"ports       {ports[doc['ports_correct']]}",
        f"decisions   {counts['correct_known']} correct known, {counts['correct_new']} correct "
        f"new, {counts['false_merge']} false merges, {counts['false_new']} false new",
        f"similarity  known {_stat(sim['known'])}; unknown {_stat(sim['unknown'])}",
        f"pairs       same junction {_stat(doc['pairs']['same'])}; different "
        f"{_stat(doc['pairs']['different'])}",
        f"rotation    error on correct known visits: mean {_num(rot['mean'])} rad, "
        f"max {_num(rot['max'])} rad (n={rot['n']})",
        f"latency     mean {_num(doc['latency_ms']['mean'])} ms, "
        f"max {_num(doc['latency_ms']['max'])} ms per decision",
        "visit  true  node  known  similarity  margin    rotation  error      in  out  outcome",
    ]
    for v in doc["per_visit"]:
        # A visit without a candidate compared with nothing: no similarity to show.
        similarity = v["similarity"] if v["candidate"] is not None else None
        lines.append(
            f"{v['visit']}   {v['true_node']:<4}  {v['predicted_node']:<4}  "
            f"{'yes' if v['known'] else 'no':<5}  {_num(similarity):<10}  "
            f"{_num(v['margin']):<8}  {_num(v['rotation_rad']):<9}  "
            f"{_num(v['rotation_error_rad']):<9}  {_port(v['arrival_port']):<2}  "
            f"{_port(v['departure_port']):<3}  {v['outcome']}"
        )
    out.write("\n".join(lines) + "\n")
    return 0


def _port(value: int | None) -> str:
    return "-" if value is None else str(value)


def _num(value: float | None) -> str:
    return "-" if value is None else f"{value:.4f}"


def _stat(summary: dict[str, Any]) -> str:
    if not summary["n"]:
        return "none"
    return f"{summary['mean']:.3f} +- {summary['std']:.3f} (n={summary['n']})"
