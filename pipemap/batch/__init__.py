"""Batch experiments: many runs from one SPEC, on this machine or a Ray cluster.

A SPEC (:mod:`batch.spec`) is a TOML grid of ``pipemap record`` and ``pipemap
score`` settings; :func:`plan_batch` checks it against the output folder and the
cluster, :func:`run_batch` runs it on Ray (:mod:`batch.engine`), each run recorded,
replayed and scored as the two commands do (:mod:`batch.run`), into one results
table (:mod:`batch.results`) that :func:`write_report` summarises. ``pipemap
experiment paper`` is a preset SPEC run the same way (:mod:`batch.experiment`).

Only the command line imports this package; it may import every layer below it.
Ray is imported when a batch runs, not with this package.
"""

from __future__ import annotations

from pipemap.batch.engine import (
    BatchEvent,
    BatchOptions,
    BatchPlan,
    BatchSummary,
    check_address,
    plan_batch,
    run_batch,
)
from pipemap.batch.report import REPORT_FILES, report_document, write_report
from pipemap.batch.results import (
    COLUMNS,
    RESULT_FILES,
    SCORE_COLUMNS,
    VOLATILE_COLUMNS,
    read_result,
    read_table,
)
from pipemap.batch.run import run_recording
from pipemap.batch.spec import (
    GRID_KEYS,
    RULES,
    BatchSpec,
    Rule,
    RunPoint,
    SpecError,
    load_spec,
    parse_spec,
)

__all__ = [
    "COLUMNS",
    "GRID_KEYS",
    "REPORT_FILES",
    "RESULT_FILES",
    "RULES",
    "SCORE_COLUMNS",
    "VOLATILE_COLUMNS",
    "BatchEvent",
    "BatchOptions",
    "BatchPlan",
    "BatchSpec",
    "BatchSummary",
    "Rule",
    "RunPoint",
    "SpecError",
    "check_address",
    "load_spec",
    "parse_spec",
    "plan_batch",
    "read_result",
    "read_table",
    "report_document",
    "run_batch",
    "run_recording",
    "write_report",
]
