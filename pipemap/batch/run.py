"""One recording of a batch and every run scored from it: the work of one task.

:func:`run_recording` is what a Ray worker executes, on this machine or on any node
of a cluster. It records the log into a folder of its own (the worker's disk, not
the batch's output folder, which may be on another machine), replays and scores it
once per run with the same library calls as ``pipemap record`` and ``pipemap
score``, and returns everything as plain data; the driver writes the files.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import socket
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pipemap import __version__
from pipemap.batch.spec import RULES, RunPoint

__all__ = ["LOG_NAME", "run_recording"]

#: The log's name, in the worker's folder and in ``runs/<run-id>/`` with ``--keep-logs``.
LOG_NAME = "run.mcap"


#: The start of a task's folder's name; the host and the process follow, so that a
#: later task can tell the folders of processes that are gone.
SCRATCH_PREFIX = "pipemap-batch-"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    return True


def sweep_stale_folders(root: Path | None = None) -> list[Path]:
    """Remove the task folders that processes of this host left when they were ended
    without cleaning up (a batch stopped by Ctrl-C: Ray ends its workers mid-run, and
    each leaves a partial log that may be a hundred MB). Returns what was removed.
    A folder of a live process, or of another host, is left alone."""
    root = Path(tempfile.gettempdir()) if root is None else root
    mine = f"{SCRATCH_PREFIX}{socket.gethostname()}-"
    removed = []
    for path in root.glob(f"{mine}*"):
        pid = path.name[len(mine) :].split("-", 1)[0]
        if path.is_dir() and pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def _cpu_s() -> float:
    """CPU seconds of this process and its finished children (the log writer)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _score(path: Path, point: RunPoint) -> dict[str, Any]:
    """``pipemap score RULE_FLAGS path --threshold T``: its calls, its outputs."""
    from pipemap import api

    config = RULES[point.rule].config(point.threshold)
    started = time.perf_counter()
    report = api.score(path, config)
    known_errors = [
        abs(v.rotation_error_rad) for v in report.visits if v.rotation_error_rad is not None
    ]
    doc = report.document()
    doc["log"] = LOG_NAME  # not the worker's temporary folder
    return {
        "score_json": json.dumps(doc, indent=2, allow_nan=False) + "\n",
        "visits_csv": report.csv_text(),
        "pairs": {
            "same": list(report.pairs.same),
            "different": list(report.pairs.different),
            "rotation_error_rad": list(report.pairs.rotation_errors_rad),
        },
        "known_rotation_errors_rad": known_errors,
        "score_wall_s": time.perf_counter() - started,
    }


def run_recording(
    points: Sequence[RunPoint], keep_log: bool = False, inline: bool = True
) -> dict[str, Any]:
    """Record the run the ``points`` share, then score it once per point.

    The log is written in this process (``inline``): in a batch every core runs a
    recording, and a writer process of its own would only compete for them.
    ``inline=False`` records as ``pipemap record`` does, with a writer process (for
    ``benchmarks/bench_batch.py``'s comparison); the log's bytes are the same.

    Returns ``{"record": {...}, "runs": {run_id: {...}}, "log": bytes | None, ...}``.
    Raises whatever recording or scoring raises: the caller retries or records it.
    """
    from pipemap import api

    first = points[0]
    if any(p.recording_key != first.recording_key for p in points):
        raise ValueError("run_recording: the points do not share one recording")
    cpu = _cpu_s()
    started = time.perf_counter()
    sweep_stale_folders()
    prefix = f"{SCRATCH_PREFIX}{socket.gethostname()}-{os.getpid()}-"
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        path = Path(tmp) / LOG_NAME
        recorded = api.record(path, first.record_settings(), inline=inline)
        record_wall = time.perf_counter() - started
        runs = {p.run_id: _score(path, p) for p in points}
        log = path.read_bytes() if keep_log else None
    return {
        "record": {
            "run_status": recorded.status,
            "run_ok": recorded.ok,
            "sweeps": recorded.sweeps,
            "simulated_s": round(recorded.duration_ns / 1e9, 3),
            "record_wall_s": round(record_wall, 3),
        },
        "runs": runs,
        "log": log,
        "wall_s": time.perf_counter() - started,
        "cpu_s": _cpu_s() - cpu,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
        "pipemap_version": __version__,
    }
