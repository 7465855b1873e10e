"""A batch's files: one folder per run, and one table of them all.

``DIR/runs/<run-id>/`` holds ``result.json`` (settings, status, the recording's
facts, the raw pair similarities for the plots, the commands that rebuild the run),
``score.json`` and ``visits.csv`` (what ``pipemap score --json`` and
``--save-results`` write) and, with ``--keep-logs``, ``run.mcap``. A run folder
appears whole or not at all (written beside, then renamed), so a batch stopped at
any moment holds only finished runs.

``DIR/results.csv`` and ``DIR/results.json`` have one row per finished run: a column
per grid key, named as the key, then the run's status and facts, then a column per
score named as in ``pipemap score --json`` (a nested name joined with dots:
``decisions.false_merge``, ``pairs.same.mean``).
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from pipemap.batch.run import LOG_NAME
from pipemap.batch.signals import held_signals
from pipemap.batch.spec import GRID_KEYS, RULES, BatchSpec, RunPoint
from pipemap.errors import WriteError
from pipemap.wholefile import write_whole

__all__ = [
    "COLUMNS",
    "RESULT_FILES",
    "SCORE_COLUMNS",
    "VOLATILE_COLUMNS",
    "flatten_score",
    "prepare_folder",
    "read_result",
    "read_table",
    "result_row",
    "write_failed",
    "write_recording",
    "write_run",
    "write_table",
]

#: The scores of ``pipemap score --json``, flattened (``per_visit`` is in visits.csv;
#: ``threshold`` is the grid's column; ``log`` is the run's folder).
SCORE_COLUMNS = (
    "integrity",
    "map_correct",
    "map",
    "coverage.nodes_visited",
    "coverage.nodes_total",
    "coverage.pipes_traversed",
    "coverage.pipes_total",
    "ports_correct",
    "visits",
    "true_nodes",
    "predicted_nodes",
    "decisions.correct_known",
    "decisions.correct_new",
    "decisions.false_merge",
    "decisions.false_new",
    "similarity.known.mean",
    "similarity.known.std",
    "similarity.known.n",
    "similarity.unknown.mean",
    "similarity.unknown.std",
    "similarity.unknown.n",
    "pairs.same.mean",
    "pairs.same.std",
    "pairs.same.n",
    "pairs.different.mean",
    "pairs.different.std",
    "pairs.different.n",
    "pairs.rotation_error_rad.mean",
    "pairs.rotation_error_rad.max",
    "pairs.rotation_error_rad.n",
    "rotation_error_rad.known.mean",
    "rotation_error_rad.known.max",
    "rotation_error_rad.known.n",
    "latency_ms.mean",
    "latency_ms.median",
    "latency_ms.p95",
    "latency_ms.max",
    "latency_ms.phases.ncc",
    "latency_ms.phases.keypoints",
    "latency_ms.phases.check",
    "latency_ms.phases.map",
    # With deposits (grid key ``obstacles``): how many pipes of each kind, counted.
    "blocked.marked",
    "blocked.truly_blocked",
    "blocked.true_positives",
    "blocked.false_blocked",
    "blocked.missed",
)
#: What a run is and how it went, between the grid's columns and the scores.
RUN_COLUMNS = (
    "rule_flags",
    "status",
    "reason",
    "run_status",
    "run_ok",
    "sweeps",
    "simulated_s",
    "record_wall_s",
    "score_wall_s",
    "worker",
)
COLUMNS = ("run_id", *GRID_KEYS, *RUN_COLUMNS, *SCORE_COLUMNS)
#: Columns that differ between two runs of the same settings (timing, where it ran).
VOLATILE_COLUMNS = (
    "record_wall_s",
    "score_wall_s",
    "worker",
    "latency_ms.mean",
    "latency_ms.median",
    "latency_ms.p95",
    "latency_ms.max",
    "latency_ms.phases.ncc",
    "latency_ms.phases.keypoints",
    "latency_ms.phases.check",
    "latency_ms.phases.map",
    # With deposits (grid key ``obstacles``): how many pipes of each kind, counted.
    "blocked.marked",
    "blocked.truly_blocked",
    "blocked.true_positives",
    "blocked.false_blocked",
    "blocked.missed",
)
RESULT_FILES = ("results.csv", "results.json")
_SKIPPED = ("per_visit", "log", "threshold")


def flatten_score(doc: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """The score document's values by dotted name (``per_visit``, ``log`` and
    ``threshold`` left out)."""
    flat: dict[str, Any] = {}
    for key, value in doc.items():
        if not prefix and key in _SKIPPED:
            continue
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten_score(value, f"{name}."))
        else:
            flat[name] = value
    return flat


def _run_folder(out: Path, run_id: str) -> Path:
    return out / "runs" / run_id


def _replace_folder(out: Path, run_id: str, files: Mapping[str, str | bytes | Path]) -> None:
    """Write ``files`` into ``runs/<run_id>/``, whole or not at all (a ``Path`` is a
    file to link, or copy where links cannot be made)."""
    final = _run_folder(out, run_id)
    partial = final.with_name(f".{run_id}.partial")
    if partial.exists():
        shutil.rmtree(partial)
    partial.mkdir(parents=True)
    try:
        for name, content in files.items():
            target = partial / name
            if isinstance(content, Path):
                try:
                    os.link(content, target)
                except OSError:
                    shutil.copyfile(content, target)
            elif isinstance(content, bytes):
                target.write_bytes(content)
            else:
                target.write_text(content)
    except OSError as exc:  # a full disk: no half-written run folder stays
        shutil.rmtree(partial, ignore_errors=True)
        raise WriteError(f"{final}: cannot write ({exc.strerror or exc})") from None
    if final.exists():
        shutil.rmtree(final)
    os.replace(partial, final)


def _base(point: RunPoint) -> dict[str, Any]:
    record, score = point.commands()
    return {
        "run_id": point.run_id,
        "settings": point.settings(),
        "rule_flags": " ".join(RULES[point.rule].flags),
        "commands": {"record": record, "score": score},
    }


def write_run(
    out: Path,
    point: RunPoint,
    outcome: Mapping[str, Any],
    keep_log: bool,
    log_of: str | None = None,
) -> dict[str, Any]:
    """Write a scored run (``outcome`` as :func:`batch.run.run_recording` returns
    it); returns its ``result.json`` document. ``log_of`` names a run of the same
    recording whose folder already holds the log: it is linked, not written again."""
    run = outcome["runs"][point.run_id]
    score = json.loads(run["score_json"])
    doc = {
        **_base(point),
        "status": "ok",
        "reason": None,
        "record": {**outcome["record"], "recording_cpu_s": round(outcome["cpu_s"], 3)},
        "score": {k: score[k] for k in ("map_correct", "visits", "decisions")},
        "score_wall_s": round(run["score_wall_s"], 3),
        "worker": outcome["worker"],
        "pipemap_version": outcome["pipemap_version"],
        "pairs": run["pairs"],
        "known_rotation_errors_rad": run["known_rotation_errors_rad"],
    }
    files: dict[str, str | bytes | Path] = {
        "result.json": json.dumps(doc, indent=2, allow_nan=False) + "\n",
        "score.json": run["score_json"],
        "visits.csv": run["visits_csv"],
    }
    if keep_log and outcome.get("log") is not None:
        shared = None if log_of is None else _run_folder(out, log_of) / LOG_NAME
        files[LOG_NAME] = shared if shared is not None and shared.is_file() else outcome["log"]
    _replace_folder(out, point.run_id, files)
    return doc


def write_recording(
    out: Path,
    points: tuple[RunPoint, ...],
    outcome: Mapping[str, Any] | None,
    reason: str,
    keep_log: bool,
) -> list[dict[str, Any]]:
    """Write the runs of one recording (``points``, one per rule) as one step: the
    scored runs of ``outcome`` (the first folder holds the log, the others link to
    it), or, without an outcome, each failed for ``reason``. Ctrl-C and SIGTERM wait
    until every folder is written (:func:`batch.signals.held_signals`), so a stopped
    batch keeps all of a recording's runs or none. Returns their ``result.json``
    documents, in order."""
    docs = []
    with held_signals():
        for point in points:
            if outcome is None:
                docs.append(write_failed(out, point, reason))
                continue
            first = points[0].run_id if point is not points[0] else None
            docs.append(write_run(out, point, outcome, keep_log, first))
    return docs


def write_failed(out: Path, point: RunPoint, reason: str) -> dict[str, Any]:
    """Write a run that failed (after its retry); returns its ``result.json`` document."""
    doc = {**_base(point), "status": "failed", "reason": reason, "record": None}
    _replace_folder(
        out, point.run_id, {"result.json": json.dumps(doc, indent=2, allow_nan=False) + "\n"}
    )
    return doc


def read_result(out: Path, run_id: str) -> dict[str, Any] | None:
    """A run's ``result.json`` document, or ``None`` if the run has no whole folder."""
    path = _run_folder(out, run_id) / "result.json"
    try:
        doc: dict[str, Any] = json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None
    if doc.get("status") == "ok" and not (path.parent / "score.json").is_file():
        return None
    return doc


def result_row(out: Path, doc: Mapping[str, Any]) -> dict[str, Any]:
    """A run's row of the results table."""
    record = doc.get("record") or {}
    row: dict[str, Any] = dict.fromkeys(COLUMNS)
    row.update(run_id=doc["run_id"], **doc["settings"])
    row.update(rule_flags=doc["rule_flags"], status=doc["status"], reason=doc["reason"])
    row.update({k: record.get(k) for k in RUN_COLUMNS if k in record})
    if doc["status"] == "ok":
        row["score_wall_s"] = doc.get("score_wall_s")
        row["worker"] = doc.get("worker")
        score = json.loads((_run_folder(out, doc["run_id"]) / "score.json").read_text())
        flat = flatten_score(score)
        # Lists of pipes (``blocked.*``) are counted: a table's cell is a number.
        row.update({k: _cell(flat.get(k)) for k in SCORE_COLUMNS})
    return row


def _cell(value: Any) -> Any:
    return len(value) if isinstance(value, list) else value


def _csv_value(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def prepare_folder(out: Path, spec_text: str, replaced: Iterable[str]) -> None:
    """Make the batch folder ``out`` with its ``runs/`` and its SPEC's text, after
    removing the ``replaced`` entries of an earlier batch (``--force``)."""
    for name in replaced:
        entry = out / name
        if entry.is_dir():
            shutil.rmtree(entry)
        elif entry.exists():
            entry.unlink()
    (out / "runs").mkdir(parents=True, exist_ok=True)
    write_whole(out / "spec.toml", spec_text)


def _atomic_write(path: Path, text: str) -> None:
    write_whole(path, text)


def write_table(
    out: Path, spec: BatchSpec, rows: Iterable[Mapping[str, Any]], version: str
) -> list[dict[str, Any]]:
    """Write ``results.csv`` and ``results.json`` with a row per finished run (rows of
    :func:`result_row`), in the grid's order; returns the rows in that order."""
    order = {p.run_id: k for k, p in enumerate(spec.points)}
    ordered = [dict(r) for r in sorted(rows, key=lambda r: order[r["run_id"]])]
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(COLUMNS)
    for row in ordered:
        writer.writerow([_csv_value(row[c]) for c in COLUMNS])
    _atomic_write(out / "results.csv", text.getvalue())
    table = {
        "pipemap_version": version,
        "spec": spec.name,
        "description": spec.description,
        "runs_total": len(spec.points),
        "runs_finished": len(ordered),
        "runs_failed": sum(1 for r in ordered if r["status"] != "ok"),
        "rules": {
            name: {"flags": list(rule.flags), "description": rule.description}
            for name, rule in RULES.items()
            if any(p.rule == name for p in spec.points)
        },
        "columns": list(COLUMNS),
        "runs": ordered,
    }
    _atomic_write(out / "results.json", json.dumps(table, indent=2, allow_nan=False) + "\n")
    return ordered


def read_table(out: Path) -> dict[str, Any]:
    """``results.json`` of a batch folder."""
    from pipemap.errors import InputError

    path = out / "results.json"
    try:
        doc: dict[str, Any] = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(
            f"{out}: no results.json (not a batch folder, or no run finished)"
        ) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON ({exc})") from None
    return doc
